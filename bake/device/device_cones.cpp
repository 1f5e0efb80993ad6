// bake/device/device_cones.cpp - the renderer's cone maps made on its device (bake/device/device_cones.h,
// DeviceCones): cone_cells.comp.glsl takes each cell's maximum and the surface's Lipschitz constant,
// cone_reduce.comp.glsl builds the max pyramid over cells a level at a time, cone_texel.comp.glsl
// searches it per texel (bake/cone_bilinear.cpp's bounds, ported, with a first pass cut at a coarse
// level) and writes the encoded (ratio, apex) layers, which one copy puts into the image the renderer
// samples. The one fact: every stored ratio is valid from every point of the texel's square for the
// apex stored beside it, at every budget - docs/design/device-cones.md has the proof and the margins.
#include "bake/device/device_cones.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>

#include "bake/device/shaders/cones.h"
#include "bake/lagged.h"
#include "spirv/cone_cells_comp.h"
#include "spirv/cone_compose_comp.h"
#include "spirv/cone_group_far_comp.h"
#include "spirv/cone_lift_comp.h"
#include "spirv/cone_reduce_comp.h"
#include "spirv/cone_texel_comp.h"
#include "vulkan/compute.h"
#include "vulkan/device_maps.h"
#include "vulkan/frames.h"

namespace displace::bake {

using namespace vulkan;  // the Vulkan base (vulkan/): Context, Buffer, Image, kernels, barriers

static_assert(sizeof(gpu::ConeCellsPush) == 32);
static_assert(sizeof(gpu::ConeReducePush) == 32);
static_assert(sizeof(gpu::ConeTexelPush) == 52 + 4 * CONE_MAX_LEVELS);  // within 128 bytes, Vulkan's least
static_assert(offsetof(gpu::ConeTexelPush, level_offset) == 52);
static_assert(sizeof(gpu::ConeLiftPush) == 16);
static_assert(sizeof(gpu::ConeComposePush) == 16);

namespace {

// the first pass opens no pyramid node at or below this level: blocks of 2^2 x 2^2 cells are bounded
// whole (levels; the figures behind it:
// docs/figures.md#the-searchs-walk-on-the-h200-and-where-the-first-passs-time-goes)
constexpr int first_pass_level = 2;
static_assert(max_first_pass_window == CONE_SLOPE_WINDOW);

constexpr VkDescriptorType storage_buffer = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
constexpr VkDescriptorType storage_image = VK_DESCRIPTOR_TYPE_STORAGE_IMAGE;
constexpr VkDescriptorType cells_bindings[] = {storage_image, storage_buffer, storage_buffer};
constexpr VkDescriptorType reduce_bindings[] = {storage_buffer};
constexpr VkDescriptorType texel_bindings[] = {storage_image, storage_buffer, storage_buffer, storage_buffer,
                                               storage_buffer};
constexpr VkDescriptorType lift_bindings[] = {storage_image, storage_image, storage_buffer};
constexpr VkDescriptorType compose_bindings[] = {storage_buffer, storage_buffer, storage_buffer};

// Transfer writes (fills, copies) made visible to the compute shaders recorded after them.
void transfer_to_compute_barrier(VkCommandBuffer commands) {
  VkMemoryBarrier barrier{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  barrier.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
  barrier.dstAccessMask = VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT;
  vkCmdPipelineBarrier(commands, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 1,
                       &barrier, 0, nullptr, 0, nullptr);
}

// Compute work recorded so far before the compute work recorded after it (its shader writes visible,
// its reads done): the only barrier the bands' command buffers take, since a compute-only queue
// family's barriers name no graphics stage.
void compute_to_compute_barrier(VkCommandBuffer commands) {
  VkMemoryBarrier barrier{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  barrier.srcAccessMask = VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT;
  barrier.dstAccessMask = VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT;
  vkCmdPipelineBarrier(commands, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                       0, 1, &barrier, 0, nullptr, 0, nullptr);
}

// Copies `bytes` of `source` into host-visible `target`, readable by the host once the frame is done.
void copy_to_host(VkCommandBuffer commands, VkBuffer source, VkDeviceSize source_offset, VkBuffer target,
                  VkDeviceSize target_offset, VkDeviceSize bytes) {
  const VkBufferCopy region{source_offset, target_offset, bytes};
  vkCmdCopyBuffer(commands, source, target, 1, &region);
  host_read_barrier(commands);
}

// Throws vulkan::Error unless the shape is one the kernels take.
void validate_shape(int width, int height, int sector_count) {
  if (width < 1 || height < 1 || width > vulkan::max_map_side || height > vulkan::max_map_side) {
    throw vulkan::Error("DeviceCones: a " + std::to_string(width) + " x " + std::to_string(height) +
                        " map; each side must be between 1 and " + std::to_string(vulkan::max_map_side) +
                        " texels");
  }
  if (sector_count != 1 && sector_count != 4 && sector_count != 8)
    throw vulkan::Error("DeviceCones: a cone map has 1, 4 or 8 sectors, not " + std::to_string(sector_count));
}

// A bake's work: the cut texels searched again past the first pass (device_refine_limit) and the
// first pass's shape.
struct Work {
  long long texels = unlimited_texels;
  DeviceFirstPass first_pass = {};
};

// Throws vulkan::Error unless the first pass is one the search kernel takes.
void validate_budget(const Work& budget) {
  const DeviceFirstPass& first = budget.first_pass;
  if (first.window_radius < 1 || first.window_radius > max_first_pass_window)
    throw vulkan::Error("DeviceCones: a first pass's window radius is 1 to " +
                        std::to_string(max_first_pass_window) + " cells, not " +
                        std::to_string(first.window_radius));
  if (first.ring_radius < 0 || first.ring_radius > max_first_pass_rings)
    throw vulkan::Error("DeviceCones: a first pass's ring radius is 0 to " +
                        std::to_string(max_first_pass_rings) + " nodes, not " +
                        std::to_string(first.ring_radius));
  if (first.group && first.ring_radius > 0)
    throw vulkan::Error("DeviceCones: a first pass is by rings or by its group, not both (ring radius " +
                        std::to_string(first.ring_radius) + " with group)");
}

}  // namespace

// The texel kernel's forms: its specialization constants FIRST_PASS_RINGS (bit 0), REFINES (bit 1) and
// FIRST_PASS_GROUP (bit 2), so that a form's pipeline holds only the code it runs (llvmpipe compiles
// the whole kernel into one function, and a GPU gives every invocation the registers of the kernel's
// largest path); and form 8, the groups' far ratios, the module built apart (cone_group_far_comp).
constexpr int texel_forms = 9;
constexpr int group_far_form = 8;
int texel_form(const Work& budget) {
  if (budget.texels < 0) return 0;  // every texel searched to the cells: the search, nothing refined
  return (budget.first_pass.ring_radius > 0 ? 1 : 0) | (budget.texels > 0 ? 2 : 0) |
         (budget.first_pass.group ? 4 : 0);
}

// The kernels' pipelines, made once per Frames (lavapipe compiles the search for about 0.15 s), the
// texel kernel's forms when a bake first asks for them; each DeviceCones binds its own siblings.
struct DeviceConeKernels {
  ComputeKernel cells, reduce, lift, compose;
  std::array<ComputeKernel, texel_forms> texel;
  const ComputeKernel& texel_pipeline(const Context& context, int form) {
    ComputeKernel& kernel = texel[std::size_t(form)];
    if (!kernel.made()) {
      const std::int32_t constants[] = {form & 1, (form >> 1) & 1, (form >> 2) & 1};
      const std::span<const std::uint32_t> module =
          form == group_far_form ? std::span<const std::uint32_t>(spirv_cone_group_far_comp)
                                 : std::span<const std::uint32_t>(spirv_cone_texel_comp);
      kernel = ComputeKernel(context, module, texel_bindings, sizeof(gpu::ConeTexelPush), constants);
    }
    return kernel;
  }
};

struct DeviceCones::State {
  vulkan::Frames& frames;
  int width = 0, height = 0, sectors = 0;
  bake::Address address = bake::Address::wrap;
  int cells_u = 0, cells_v = 0, levels = 0, layers = 0;
  std::vector<int> level_width, level_height, level_offset;  // the pyramid's levels, in the buffer (floats)
  const Image* source = nullptr;                             // the heights read (own_heights or a stage's)
  std::shared_ptr<const DeviceHeightImages> stage_heights;   // the stage whose heights it reads (or null)
  Image own_heights;
  Buffer pyramid, counters, cone_values, readback;
  Buffer group_far;  // a group first pass's far ratios (cone_texel.comp.glsl's GroupFar)
  int groups_u = 0;  // 8 x 8 texel groups along u
  Image cones;
  std::shared_ptr<DeviceConeKernels> kernels;  // compiled once per Frames (Frames::shared)
  ComputeKernel cells_kernel, reduce_kernel;
  // the texel kernel's forms (texel_form) bound to the heights read: [0] the source, [1 + k] snapshot k
  std::array<std::array<ComputeKernel, texel_forms>, 3> texel_kernels;
  std::shared_ptr<DeviceConeImage>
      map;                     // the renderer's handle (map_set.h), its image cleared when this goes
  long long refine_limit = 0;  // of the last bake(); unlimited_texels: every texel searched to the cells
  bool baked = false;
  StageTimer timer;

  // lagged maps (bake_lagged), made on its first call: the heights of the map in progress and of the
  // served one (snapshots[progress], snapshots[progress ^ 1]), the served map's values and the values
  // the frame samples, and each frame's lift for the host (a float per frame slot)
  Image snapshots[2];
  Buffer served, composed, lift_host;
  Buffer served_counters;  // the counters of the served map, copied when it is served
  // the last bake was lagged: read_back reads served_counters, and its device time is three timers'
  bool lagged = false;
  ComputeKernel snapshot_cells[2], lift_kernel[2], compose_kernel;
  // their schedule (bake/lagged.h), by calls: a band of group rows a call beside the draw, served the
  // call after the last
  bake::LagSchedule schedule{bake::LagSchedule::Lands::after_draw};
  int progress = 0;        // the snapshot the map in progress reads
  int rows_done = 0;       // group rows of the map in progress whose band went in
  long long calls = 0;     // bake_lagged calls so far
  int advanced_slot = -1;  // the frame slot of an advance_lagged() not yet composed
  // the bands go to the async queue (Context::async_queue), beside the frame's draw: command buffers
  // taken in turn (one more than the frames in flight, so that the one taken was submitted three
  // frames before), the async value of each one's last submission, and the bands' own timer
  static constexpr int band_buffers = frames_in_flight + 1;
  std::array<VkCommandBuffer, band_buffers> band_commands{};
  std::array<std::uint64_t, band_buffers> band_value{};
  long long bands_made = 0;     // bands submitted so far
  std::uint64_t last_band = 0;  // the async value of the last band submitted (0: none)
  StageTimer band_timer;        // by band command buffer
  // a lagged frame's own device time: `timer` around advance_lagged's commands up to a flush (so that
  // a band on the same queue falls outside it), this one around compose_lagged's
  StageTimer compose_timer;

  explicit State(vulkan::Frames& device_frames) : frames(device_frames) {}
  std::size_t texels() const { return std::size_t(width) * std::size_t(height); }
  void make(const Image& heights, int sector_count, bake::Address address_mode);
  void make_lagged();
  void check_source() const;
  void record_pyramid(VkCommandBuffer commands, const ComputeKernel& cells);
  const ComputeKernel& texel_kernel(int heights, int form);
  void record_texels(VkCommandBuffer commands, int heights, const Work& budget, int first_group_row,
                     int group_rows);
  void record_to_image(VkCommandBuffer commands, VkBuffer values);
};

void DeviceCones::State::make(const Image& heights, int sector_count, bake::Address address_mode) {
  timer = StageTimer(frames.context());
  sectors = sector_count;
  address = address_mode;
  source = &heights;
  const bool wrap = address == bake::Address::wrap;
  cells_u = wrap ? width : width + 1;
  cells_v = wrap ? height : height + 1;
  // the pyramid's levels: ceil(n / 2^L) nodes along an axis, down to 1 x 1
  int offset = 0;
  for (int level = 0;; ++level) {
    const int w = (cells_u + (1 << level) - 1) >> level, h = (cells_v + (1 << level) - 1) >> level;
    level_width.push_back(w);
    level_height.push_back(h);
    level_offset.push_back(offset);
    offset += w * h;
    if (w == 1 && h == 1) break;
  }
  levels = int(level_width.size());
  layers = cone_layer_count(sectors, false);

  // buffers and the cone image, made once
  const Context& context = frames.context();
  const VkMemoryPropertyFlags device_local = VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT;
  // what a lagged map's bands use on the async queue is shared with it (Context::async_queue)
  const bool shared = true;
  pyramid =
      Buffer(context, VkDeviceSize(offset) * 4,
             VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT, device_local, shared);
  counters = Buffer(context, CONE_COUNTERS * 4,
                    VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT |
                        VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                    device_local, shared);
  cone_values =
      Buffer(context, texels() * VkDeviceSize(layers) * cone_texel_bytes,
             VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT, device_local, shared);
  groups_u = int(group_count(std::uint32_t(width), CONE_TILE));
  const VkDeviceSize groups = VkDeviceSize(groups_u) * group_count(std::uint32_t(height), CONE_TILE);
  group_far = Buffer(context, groups * CONE_GROUP_LEVELS * (1 + sectors) * 4,
                     VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, device_local, shared);
  cones =
      Image(context, cone_format, std::uint32_t(width), std::uint32_t(height), std::uint32_t(layers),
            VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT,
            VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_VIEW_TYPE_2D_ARRAY);
  context.submit_and_wait([&](VkCommandBuffer commands) {
    image_barrier(commands, cones.handle(), std::uint32_t(layers), VK_IMAGE_LAYOUT_UNDEFINED,
                  VK_IMAGE_LAYOUT_GENERAL, 0, VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT,
                  VK_PIPELINE_STAGE_TRANSFER_BIT);
  });

  // kernels
  std::shared_ptr<void>& made = frames.shared("bake::DeviceCones kernels");
  if (!made) {
    made = std::make_shared<DeviceConeKernels>(DeviceConeKernels{
        ComputeKernel(context, spirv_cone_cells_comp, cells_bindings, sizeof(gpu::ConeCellsPush)),
        ComputeKernel(context, spirv_cone_reduce_comp, reduce_bindings, sizeof(gpu::ConeReducePush)),
        ComputeKernel(context, spirv_cone_lift_comp, lift_bindings, sizeof(gpu::ConeLiftPush)),
        ComputeKernel(context, spirv_cone_compose_comp, compose_bindings, sizeof(gpu::ConeComposePush)),
        {}});
  }
  kernels = std::static_pointer_cast<DeviceConeKernels>(made);
  cells_kernel = kernels->cells.sibling();
  cells_kernel.bind_image(0, heights.view());
  cells_kernel.bind_buffer(1, pyramid.handle());
  cells_kernel.bind_buffer(2, counters.handle());
  reduce_kernel = kernels->reduce.sibling();
  reduce_kernel.bind_buffer(0, pyramid.handle());

  map = std::make_shared<DeviceConeImage>(DeviceConeImage{&frames, &cones, width, height, sectors,
                                                          address == Address::wrap, pyramid.handle(),
                                                          VkDeviceSize(level_offset.back()) * 4});
}

DeviceCones::DeviceCones(vulkan::Frames& frames, std::shared_ptr<const DeviceHeightImages> heights,
                         int sector_count, bake::Address address)
    : state_(std::make_unique<State>(frames)) {
  State& s = *state_;
  if (!heights || heights->owner != &s.frames || heights->heights == nullptr)
    throw vulkan::Error("DeviceCones: the heights of a device stage on the same Frames, alive, are needed");
  s.width = int(heights->heights->width());
  s.height = int(heights->heights->height());
  validate_shape(s.width, s.height, sector_count);
  s.stage_heights = std::move(heights);
  s.make(*s.stage_heights->heights, sector_count, address);
}

DeviceCones::DeviceCones(vulkan::Frames& frames, bake::HeightView heights, int sector_count,
                         bake::Address address)
    : state_(std::make_unique<State>(frames)) {
  State& s = *state_;
  validate_shape(heights.width, heights.height, sector_count);
  s.width = heights.width;
  s.height = heights.height;
  if (heights.data == nullptr) throw vulkan::Error("DeviceCones: no heights were given");
  for (std::size_t t = 0; t < s.texels(); ++t) {
    if (!(heights.data[t] >= 0.0f && heights.data[t] <= 1.0f)) {
      throw vulkan::Error("DeviceCones: height " + std::to_string(t) + " (row " +
                          std::to_string(t / s.width) + ", column " + std::to_string(t % s.width) + ") is " +
                          std::to_string(heights.data[t]) + ", not a finite value in [0, 1]");
    }
  }
  // the heights, uploaded once through a staging buffer
  const Context& context = s.frames.context();
  s.own_heights =
      Image(context, VK_FORMAT_R32_SFLOAT, std::uint32_t(s.width), std::uint32_t(s.height), 1,
            VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT,
            VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_VIEW_TYPE_2D);
  {
    Buffer staging(context, s.texels() * 4, VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                   VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
    std::memcpy(staging.mapped(), heights.data, s.texels() * 4);
    context.submit_and_wait([&](VkCommandBuffer commands) {
      image_barrier(commands, s.own_heights.handle(), 1, VK_IMAGE_LAYOUT_UNDEFINED,
                    VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 0, VK_ACCESS_TRANSFER_WRITE_BIT,
                    VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT);
      VkBufferImageCopy region{};
      region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
      region.imageExtent = {std::uint32_t(s.width), std::uint32_t(s.height), 1};
      vkCmdCopyBufferToImage(commands, staging.handle(), s.own_heights.handle(),
                             VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &region);
      image_barrier(commands, s.own_heights.handle(), 1, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                    VK_IMAGE_LAYOUT_GENERAL, VK_ACCESS_TRANSFER_WRITE_BIT, VK_ACCESS_SHADER_READ_BIT,
                    VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT);
    });
  }
  s.make(s.own_heights, sector_count, address);
}

DeviceCones::~DeviceCones() {
  State& s = *state_;
  s.frames.wait_submitted();  // the async bands too
  for (VkCommandBuffer commands : s.band_commands)
    if (commands != VK_NULL_HANDLE) s.frames.context().free_async_command_buffer(commands);
  s.map->image = nullptr;  // (a MapSet may still name it: the renderer then refuses the frame)
}

void DeviceCones::State::check_source() const {
  if (stage_heights && stage_heights->heights == nullptr)
    throw vulkan::Error("DeviceCones::bake: the stage whose heights it reads is gone");
}

// Clears the counters, then the cells (their maxima, the Lipschitz constant, the heights' check) and
// the max pyramid above them, a level at a time, of the heights `cells` reads.
void DeviceCones::State::record_pyramid(VkCommandBuffer commands, const ComputeKernel& cells) {
  vkCmdFillBuffer(commands, counters.handle(), 0, VK_WHOLE_SIZE, 0);
  transfer_to_compute_barrier(commands);
  gpu::ConeCellsPush cells_push{};
  cells_push.width = width;
  cells_push.height = height;
  cells_push.cells_u = cells_u;
  cells_push.cells_v = cells_v;
  cells_push.wrap = address == bake::Address::wrap ? 1 : 0;
  cells.record(commands, group_count(std::uint32_t(cells_u), CONE_TILE),
               group_count(std::uint32_t(cells_v), CONE_TILE), 1, &cells_push);
  compute_barrier(commands);
  for (int level = 0; level + 1 < levels; ++level) {
    gpu::ConeReducePush reduce_push{};
    reduce_push.source_offset = level_offset[std::size_t(level)];
    reduce_push.source_width = level_width[std::size_t(level)];
    reduce_push.source_height = level_height[std::size_t(level)];
    reduce_push.target_offset = level_offset[std::size_t(level) + 1];
    reduce_push.target_width = level_width[std::size_t(level) + 1];
    reduce_push.target_height = level_height[std::size_t(level) + 1];
    reduce_kernel.record(commands, group_count(std::uint32_t(reduce_push.target_width), CONE_TILE),
                         group_count(std::uint32_t(reduce_push.target_height), CONE_TILE), 1, &reduce_push);
    compute_barrier(commands);
  }
}

// The texel kernel's `form` reading `heights` (0: the source, 1 + k: snapshot k), made and bound when a
// bake first asks for it: a pipeline and a descriptor set, no device memory.
const ComputeKernel& DeviceCones::State::texel_kernel(int heights, int form) {
  ComputeKernel& kernel = texel_kernels[std::size_t(heights)][std::size_t(form)];
  if (!kernel.made()) {
    kernel = kernels->texel_pipeline(frames.context(), form).sibling();
    kernel.bind_image(0, heights == 0 ? source->view() : snapshots[heights - 1].view());
    kernel.bind_buffer(1, pyramid.handle());
    kernel.bind_buffer(2, counters.handle());
    kernel.bind_buffer(3, cone_values.handle());
    kernel.bind_buffer(4, group_far.handle());
  }
  return kernel;
}

// The texels' searches for the groups of rows [first_group_row, + group_rows) of `heights` (0: the
// source, 1 + k: snapshot k), into cone_values.
void DeviceCones::State::record_texels(VkCommandBuffer commands, int heights, const Work& budget,
                                       int first_group_row, int group_rows) {
  const ComputeKernel& texel = texel_kernel(heights, texel_form(budget));
  gpu::ConeTexelPush texel_push{};
  texel_push.width = width;
  texel_push.height = height;
  texel_push.cells_u = cells_u;
  texel_push.cells_v = cells_v;
  texel_push.wrap = address == bake::Address::wrap ? 1 : 0;
  texel_push.sectors = sectors;
  texel_push.levels = levels;
  for (int level = 0; level < levels; ++level)
    texel_push.level_offset[level] = level_offset[std::size_t(level)];
  const bool unlimited = budget.texels < 0;
  texel_push.first_pass_level = unlimited ? -1 : first_pass_level;
  texel_push.refine_limit =
      unlimited ? 0 : int(std::min<long long>(budget.texels, std::numeric_limits<int>::max()));
  texel_push.first_row = first_group_row * CONE_TILE;
  texel_push.window_radius = unlimited ? CONE_SLOPE_WINDOW : budget.first_pass.window_radius;
  texel_push.ring_radius = unlimited ? 0 : budget.first_pass.ring_radius;
  if (!unlimited && budget.first_pass.group) {  // the groups' far ratios first, searched to the cells
    gpu::ConeTexelPush far_push = texel_push;
    far_push.first_pass_level = -1;
    const auto row = std::uint32_t(groups_u * CONE_GROUP_LEVELS);  // invocations, a group row's
    texel_kernel(heights, group_far_form)
        .record(commands, group_count(row, CONE_TILE * CONE_TILE), std::uint32_t(group_rows), 1, &far_push);
    compute_to_compute_barrier(commands);  // (a band's command buffer may be a compute-only queue's)
  }
  texel.record(commands, group_count(std::uint32_t(width), CONE_TILE), std::uint32_t(group_rows), 1,
               &texel_push);
  refine_limit = unlimited ? unlimited_texels : budget.texels;
}

// `values` (cone_values' layout) into the cone image, given back in GENERAL for the frame's draw.
void DeviceCones::State::record_to_image(VkCommandBuffer commands, VkBuffer values) {
  // copied in the transfer layout (earlier frames' reads are behind the rewrite barrier)
  const auto image_layers = std::uint32_t(layers);
  image_barrier(commands, cones.handle(), image_layers, VK_IMAGE_LAYOUT_GENERAL,
                VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 0, VK_ACCESS_TRANSFER_WRITE_BIT,
                VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT);
  VkBufferImageCopy region{};
  region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, image_layers};
  region.imageExtent = {std::uint32_t(width), std::uint32_t(height), 1};
  vkCmdCopyBufferToImage(commands, values, cones.handle(), VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &region);
  image_barrier(commands, cones.handle(), image_layers, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                VK_IMAGE_LAYOUT_GENERAL, VK_ACCESS_TRANSFER_WRITE_BIT,
                VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_TRANSFER_READ_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
                VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT);
}

long long device_refine_limit(const Budget& budget) {
  if (budget.max_work >= 0) return budget.max_work;
  return std::isfinite(budget.milliseconds) ? 0 : unlimited_texels;
}

void DeviceCones::bake(const Budget& frame_budget, const DeviceFirstPass& first_pass) {
  const Work budget{device_refine_limit(frame_budget), first_pass};
  validate_budget(budget);
  State& s = *state_;
  s.check_source();
  const int slot = s.frames.slot();
  const VkCommandBuffer commands = s.frames.begin();
  s.timer.begin(commands, slot);
  // the frames before read the cone image and the buffers this one writes, and so may a lagged
  // map's band on the async queue
  s.frames.frame_waits_for_async(s.last_band);
  rewrite_barrier(commands);
  s.record_pyramid(commands, s.cells_kernel);
  s.record_texels(commands, 0, budget, 0, int(group_count(std::uint32_t(s.height), CONE_TILE)));
  compute_barrier(commands);
  s.record_to_image(commands, s.cone_values.handle());
  s.timer.end(commands, slot);
  s.schedule.drop_in_progress();  // a lagged map in progress used the pyramid and counters rewritten here
  s.lagged = false;
  if (s.lift_host.handle() != VK_NULL_HANDLE) static_cast<float*>(s.lift_host.mapped())[slot] = 0.0f;
  s.baked = true;
}

void DeviceCones::State::make_lagged() {
  if (served.handle() != VK_NULL_HANDLE) return;
  const Context& context = frames.context();
  const VkDeviceSize value_bytes = texels() * VkDeviceSize(layers) * cone_texel_bytes;
  served = Buffer(context, value_bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                  VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
  composed =
      Buffer(context, value_bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
             VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
  served_counters =
      Buffer(context, CONE_COUNTERS * 4, VK_BUFFER_USAGE_TRANSFER_DST_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
             VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
  lift_host = Buffer(context, frames_in_flight * 4, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                     VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
  std::memset(lift_host.mapped(), 0, frames_in_flight * 4);
  for (int k = 0; k < 2; ++k) {
    snapshots[k] = Image(context, VK_FORMAT_R32_SFLOAT, std::uint32_t(width), std::uint32_t(height), 1,
                         VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT,
                         VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_VIEW_TYPE_2D, true);  // the bands read it
    snapshot_cells[k] = kernels->cells.sibling();
    snapshot_cells[k].bind_image(0, snapshots[k].view());
    snapshot_cells[k].bind_buffer(1, pyramid.handle());
    snapshot_cells[k].bind_buffer(2, counters.handle());
    lift_kernel[k] = kernels->lift.sibling();
    lift_kernel[k].bind_image(0, source->view());
    lift_kernel[k].bind_image(1, snapshots[k].view());
    lift_kernel[k].bind_buffer(2, counters.handle());
  }
  for (VkCommandBuffer& commands : band_commands) commands = context.allocate_async_command_buffer();
  band_timer = StageTimer(context);
  compose_timer = StageTimer(context);
  compose_kernel = kernels->compose.sibling();
  compose_kernel.bind_buffer(0, served.handle());
  compose_kernel.bind_buffer(1, counters.handle());
  compose_kernel.bind_buffer(2, composed.handle());
  context.submit_and_wait([&](VkCommandBuffer commands) {
    for (const Image& snapshot : snapshots) {
      image_barrier(commands, snapshot.handle(), 1, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_GENERAL, 0,
                    VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT,
                    VK_PIPELINE_STAGE_TRANSFER_BIT);
    }
  });
}

long long DeviceCones::bake_lagged(const Budget& budget, int lag_frames, const DeviceFirstPass& first_pass) {
  State& s = *state_;
  if (lag_frames == 0) {
    bake(budget, first_pass);
    s.schedule.restart();  // what was served is not this frame's map
    return 0;
  }
  advance_lagged(budget, lag_frames, first_pass);
  return compose_lagged();
}

void DeviceCones::advance_lagged(const Budget& frame_budget, int lag_frames,
                                 const DeviceFirstPass& first_pass) {
  const Work budget{device_refine_limit(frame_budget), first_pass};
  State& s = *state_;
  if (lag_frames < 1)
    throw vulkan::Error("DeviceCones: a lagged map's lag of " + std::to_string(lag_frames) +
                        " frames; it is 1 or more (bake_lagged: 0 or more)");
  validate_budget(budget);
  s.check_source();
  s.make_lagged();
  const int slot = s.frames.slot();
  s.advanced_slot = slot;
  VkCommandBuffer commands = s.frames.begin();
  s.timer.begin(commands, slot);
  // the first map is made whole in this frame (on the frame's queue, after any band of a map before)
  const bake::LagSchedule::Share share = s.schedule.next(s.calls, lag_frames);
  if (share.whole) s.frames.frame_waits_for_async(s.last_band);
  rewrite_barrier(commands);
  const int group_rows = int(group_count(std::uint32_t(s.height), CONE_TILE));
  // Serves the map in progress from this frame on (its values are complete once `last_band` is).
  auto serve = [&] {
    const VkBufferCopy all{0, 0, s.texels() * VkDeviceSize(s.layers) * cone_texel_bytes};
    vkCmdCopyBuffer(commands, s.cone_values.handle(), s.served.handle(), 1, &all);
    const VkBufferCopy counters{0, 0, CONE_COUNTERS * 4};  // its stats and heights' check, for read_back
    vkCmdCopyBuffer(commands, s.counters.handle(), s.served_counters.handle(), 1, &counters);
    // before this frame writes the counters and values again (the lift, a next map's pyramid)
    VkMemoryBarrier copied{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    copied.srcAccessMask = VK_ACCESS_TRANSFER_READ_BIT | VK_ACCESS_TRANSFER_WRITE_BIT;
    copied.dstAccessMask =
        VK_ACCESS_TRANSFER_WRITE_BIT | VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT;
    vkCmdPipelineBarrier(commands, VK_PIPELINE_STAGE_TRANSFER_BIT,
                         VK_PIPELINE_STAGE_TRANSFER_BIT | VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 1, &copied,
                         0, nullptr, 0, nullptr);
    s.progress ^= 1;
  };
  // this frame's band of the map in progress (its share of the group rows) on the async queue, after
  // the frame queue's value
  // `after` (0: nothing): nothing in this frame waits for it (its command buffer was last submitted
  // three frames ago: waited for on the host, long done in a frame loop)
  auto submit_band = [&](std::uint64_t after) {
    const auto index = std::size_t(s.bands_made++ % State::band_buffers);
    s.frames.wait_async(s.band_value[index]);
    const VkCommandBuffer band = s.band_commands[index];
    DISPLACE_VK_CHECK(vkResetCommandBuffer(band, 0));
    VkCommandBufferBeginInfo begin{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
    begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
    DISPLACE_VK_CHECK(vkBeginCommandBuffer(band, &begin));
    s.band_timer.begin(band, int(index));
    const int first = s.rows_done;
    const int end = share.last() ? group_rows : std::max(first, (share.index + 1) * group_rows / share.count);
    if (end > first) {
      compute_to_compute_barrier(band);  // the band before read group_far, whose other rows this one writes
      s.record_texels(band, 1 + s.progress, budget, first, end - first);
    }
    s.band_timer.end(band, int(index));
    DISPLACE_VK_CHECK(vkEndCommandBuffer(band));
    s.band_value[index] = s.last_band = s.frames.submit_async(band, after);
    s.rows_done = end;
  };
  if (share.serve) {  // every band of the map in progress went in a frame before
    s.frames.frame_waits_for_async(s.last_band);
    serve();
  }
  std::uint64_t map_begun = 0;  // the frame queue's value once a map begun here has its snapshot and pyramid
  if (share.begin) {            // a map begins: its heights' snapshot, then its pyramid
    const VkImage source = s.source->handle(), snapshot = s.snapshots[s.progress].handle();
    const VkPipelineStageFlags transfer = VK_PIPELINE_STAGE_TRANSFER_BIT;
    const VkPipelineStageFlags readers =
        VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT;
    image_barrier(commands, source, 1, VK_IMAGE_LAYOUT_GENERAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                  VK_ACCESS_SHADER_WRITE_BIT, VK_ACCESS_TRANSFER_READ_BIT,
                  VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, transfer);
    image_barrier(commands, snapshot, 1, VK_IMAGE_LAYOUT_GENERAL, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 0,
                  VK_ACCESS_TRANSFER_WRITE_BIT, transfer, transfer);
    VkImageCopy region{};
    region.srcSubresource = region.dstSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    region.extent = {std::uint32_t(s.width), std::uint32_t(s.height), 1};
    vkCmdCopyImage(commands, source, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, snapshot,
                   VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &region);
    image_barrier(commands, source, 1, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_IMAGE_LAYOUT_GENERAL,
                  VK_ACCESS_TRANSFER_READ_BIT, VK_ACCESS_SHADER_READ_BIT, transfer, readers);
    image_barrier(commands, snapshot, 1, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_IMAGE_LAYOUT_GENERAL,
                  VK_ACCESS_TRANSFER_WRITE_BIT, VK_ACCESS_SHADER_READ_BIT, transfer, readers);
    s.record_pyramid(commands, s.snapshot_cells[s.progress]);
    s.rows_done = 0;
    if (share.whole) {  // every row now, served from this frame on
      s.record_texels(commands, 1 + s.progress, budget, 0, group_rows);
      compute_barrier(commands);
      s.schedule.finished(true);
      serve();
    } else {  // submitted now, so that this frame's band can follow it on the async queue
      s.timer.end(commands, slot);
      map_begun = s.frames.flush();
      commands = s.frames.begin();
    }
  }
  if (map_begun == 0) s.timer.end(commands, slot);
  if (!share.whole) {
    submit_band(map_begun);
    s.schedule.finished(share.last());
  }
}

long long DeviceCones::compose_lagged() {
  State& s = *state_;
  const int slot = s.advanced_slot;
  if (slot < 0 || slot != s.frames.slot())
    throw vulkan::Error("DeviceCones::compose_lagged: no advance_lagged() in this frame before it");
  s.advanced_slot = -1;
  const VkCommandBuffer commands = s.frames.begin();
  s.compose_timer.begin(commands, slot);
  // this frame's lift over the served map's heights, and the served map with its apexes raised by it
  vkCmdFillBuffer(commands, s.counters.handle(), CONE_COUNTER_LIFT * 4, 4, 0);
  transfer_to_compute_barrier(commands);
  const gpu::ConeLiftPush lift_push{s.width, s.height, 0, 0};
  s.lift_kernel[s.progress ^ 1].record(commands, group_count(std::uint32_t(s.width), CONE_TILE),
                                       group_count(std::uint32_t(s.height), CONE_TILE), 1, &lift_push);
  compute_barrier(commands);
  const gpu::ConeComposePush compose_push{s.width, s.height, s.layers, 0};
  s.compose_kernel.record(commands, group_count(std::uint32_t(s.width), CONE_TILE),
                          group_count(std::uint32_t(s.height), CONE_TILE), 1, &compose_push);
  compute_barrier(commands);
  copy_to_host(commands, s.counters.handle(), CONE_COUNTER_LIFT * 4, s.lift_host.handle(),
               VkDeviceSize(slot) * 4, 4);
  s.record_to_image(commands, s.composed.handle());
  s.compose_timer.end(commands, slot);
  s.baked = true;
  s.lagged = true;
  const long long age = s.calls - s.schedule.served_frame();
  ++s.calls;
  return age;
}

float DeviceCones::lift() const {
  const State& s = *state_;
  const int slot = s.timer.last_slot();
  if (slot < 0 || s.lift_host.handle() == VK_NULL_HANDLE || !s.frames.finished(slot)) return 0.0f;
  return static_cast<const float*>(s.lift_host.mapped())[slot];
}

double DeviceCones::device_milliseconds() const {
  State& s = *state_;
  const double frame_part = s.frames.finished_milliseconds(s.timer);
  if (!s.lagged) return frame_part;
  const double compose_part = s.frames.finished_milliseconds(s.compose_timer);
  const int band_slot = s.band_timer.last_slot();
  if (band_slot >= 0 && s.frames.async_finished(s.band_value[std::size_t(band_slot)]))
    s.band_timer.read(band_slot);
  return frame_part + compose_part + s.band_timer.milliseconds();
}

BakeStats DeviceCones::read_back(std::vector<float>* ratios, std::vector<float>* apex) {
  State& s = *state_;
  if (!s.baked) throw vulkan::Error("DeviceCones::read_back: nothing was baked");
  const VkDeviceSize image_bytes = s.texels() * VkDeviceSize(s.layers) * cone_texel_bytes;
  if (s.readback.handle() == VK_NULL_HANDLE) {
    s.readback = Buffer(s.frames.context(), image_bytes + CONE_COUNTERS * 4, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                        VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
  }
  const bool image_wanted = ratios != nullptr || apex != nullptr;
  const VkCommandBuffer commands = s.frames.begin();  // bake() waited for any band
  if (image_wanted) {                                 // the image itself: what the renderer samples
    const auto layers = std::uint32_t(s.layers);
    image_barrier(commands, s.cones.handle(), layers, VK_IMAGE_LAYOUT_GENERAL,
                  VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_ACCESS_TRANSFER_WRITE_BIT,
                  VK_ACCESS_TRANSFER_READ_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
                  VK_PIPELINE_STAGE_TRANSFER_BIT);
    VkBufferImageCopy region{};
    region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, layers};
    region.imageExtent = {std::uint32_t(s.width), std::uint32_t(s.height), 1};
    vkCmdCopyImageToBuffer(commands, s.cones.handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                           s.readback.handle(), 1, &region);
    image_barrier(commands, s.cones.handle(), layers, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                  VK_IMAGE_LAYOUT_GENERAL, VK_ACCESS_TRANSFER_READ_BIT, VK_ACCESS_SHADER_READ_BIT,
                  VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT);
  }
  copy_to_host(commands, (s.lagged ? s.served_counters : s.counters).handle(), 0, s.readback.handle(),
               image_bytes, CONE_COUNTERS * 4);
  s.frames.submit(true);

  const auto* bytes = static_cast<const std::byte*>(s.readback.mapped());
  std::uint32_t counter_values[CONE_COUNTERS];
  std::memcpy(counter_values, bytes + image_bytes, sizeof counter_values);
  if (counter_values[CONE_COUNTER_BAD] != 0)
    throw vulkan::Error(
        "DeviceCones: the heights hold a NaN or a value outside [0, 1]; the cone map is not valid");
  BakeStats stats;
  stats.mode = s.refine_limit < 0 ? Mode::bilinear : Mode::bilinear_budgeted;
  stats.width = s.width;
  stats.height = s.height;
  stats.sector_count = s.sectors;
  const long long cut = s.refine_limit < 0 ? 0 : counter_values[CONE_COUNTER_TICKETS];
  stats.texels_refined = s.refine_limit < 0 ? (long long)s.texels() : std::min(cut, s.refine_limit);
  stats.texels_fallback = s.refine_limit < 0 ? 0 : cut - stats.texels_refined;
  stats.milliseconds = device_milliseconds();
  // layer k < n: (r_k, H_c), decoded as the shaders read them
  const auto* values = reinterpret_cast<const std::uint32_t*>(bytes);
  if (ratios) {
    ratios->resize(s.texels() * std::size_t(s.sectors));
    for (int k = 0; k < s.sectors; ++k)
      for (std::size_t t = 0; t < s.texels(); ++t)
        (*ratios)[t * std::size_t(s.sectors) + std::size_t(k)] =
            vulkan::decode_ratio(std::uint16_t(values[std::size_t(k) * s.texels() + t] & 0xffffu));
    double sum = 0.0;
    for (float ratio : *ratios) sum += ratio;
    stats.mean_ratio = ratios->empty() ? 0.0 : sum / double(ratios->size());
  }
  if (apex) {
    apex->resize(s.texels());
    for (std::size_t t = 0; t < s.texels(); ++t)
      (*apex)[t] = vulkan::decode_apex(std::uint16_t(values[t] >> 16));
  }
  return stats;
}

std::shared_ptr<const DeviceConeImage> DeviceCones::map() const { return state_->map; }
int DeviceCones::width() const { return state_->width; }
int DeviceCones::height() const { return state_->height; }
int DeviceCones::sector_count() const { return state_->sectors; }
bake::Address DeviceCones::address() const { return state_->address; }

}  // namespace displace::bake
