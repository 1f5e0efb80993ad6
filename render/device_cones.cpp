// render/device_cones.cpp - the renderer's cone maps made on its device (render/device.h,
// DeviceCones): cone_cells.comp.glsl takes each cell's maximum and the surface's Lipschitz constant,
// cone_reduce.comp.glsl builds the max pyramid over cells a level at a time, cone_texel.comp.glsl
// searches it per texel (bake/cone_bilinear.cpp's bounds, ported, with a first pass cut at a coarse
// level) and writes the encoded (ratio, apex) layers, which one copy puts into the image the renderer
// samples. The one fact: every stored ratio is valid from every point of the texel's square for the
// apex stored beside it, at every budget - docs/design/device-cones.md has the proof and the margins.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>

#include "render/compute.h"
#include "render/device.h"
#include "render/map_pack.h"
#include "render/renderer_impl.h"
#include "render/shaders/cones.h"
#include "spirv/cone_cells_comp.h"
#include "spirv/cone_reduce_comp.h"
#include "spirv/cone_texel_comp.h"

namespace displace::render {

static_assert(sizeof(gpu::ConeCellsPush) == 32);
static_assert(sizeof(gpu::ConeReducePush) == 32);
static_assert(sizeof(gpu::ConeTexelPush) == 36 + 4 * CONE_MAX_LEVELS);  // within 128 bytes, Vulkan's least
static_assert(offsetof(gpu::ConeTexelPush, level_offset) == 36);

namespace {

// the first pass opens no pyramid node at or below this level: blocks of 2^2 x 2^2 cells are bounded
// whole (levels, docs/design/device-cones.md#budget for the figures behind it)
constexpr int first_pass_level = 2;

constexpr VkDescriptorType storage_buffer = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
constexpr VkDescriptorType storage_image = VK_DESCRIPTOR_TYPE_STORAGE_IMAGE;
constexpr VkDescriptorType cells_bindings[] = {storage_image, storage_buffer, storage_buffer};
constexpr VkDescriptorType reduce_bindings[] = {storage_buffer};
constexpr VkDescriptorType texel_bindings[] = {storage_image, storage_buffer, storage_buffer, storage_buffer};

// Throws RenderError unless the shape is one the kernels take.
void validate_shape(int width, int height, int sector_count) {
  if (width < 1 || height < 1 || width > max_map_side || height > max_map_side) {
    throw RenderError("DeviceCones: a " + std::to_string(width) + " x " + std::to_string(height) +
                      " map; each side must be between 1 and " + std::to_string(max_map_side) + " texels");
  }
  if (sector_count != 1 && sector_count != 4 && sector_count != 8)
    throw RenderError("DeviceCones: a cone map has 1, 4 or 8 sectors, not " + std::to_string(sector_count));
}

}  // namespace

// The kernels' pipelines, made once per renderer (lavapipe compiles the search for about 0.15 s); each
// DeviceCones binds its own siblings.
struct DeviceConeKernels {
  ComputeKernel cells, reduce, texel;
};

struct DeviceCones::State {
  Renderer::Impl& impl;
  int width = 0, height = 0, sectors = 0;
  bake::Address address = bake::Address::wrap;
  int cells_u = 0, cells_v = 0, levels = 0, layers = 0;
  std::vector<int> level_width, level_height, level_offset;  // the pyramid's levels, in the buffer (floats)
  const Image* source = nullptr;                             // the heights read (own_heights or the ocean's)
  Image own_heights;
  Buffer pyramid, counters, cone_values, readback;
  Image cones;
  ComputeKernel cells_kernel, reduce_kernel, texel_kernel;
  Renderer::Impl::DeviceConeImage registration;
  long long refine_limit = 0;  // of the last bake(); unlimited_texels: every texel searched to the cells
  bool baked = false;
  StageTimer timer;

  explicit State(Renderer::Impl& renderer) : impl(renderer) {}
  std::size_t texels() const { return std::size_t(width) * std::size_t(height); }
  void make(const Image& heights, int sector_count, bake::Address address_mode);
};

void DeviceCones::State::make(const Image& heights, int sector_count, bake::Address address_mode) {
  timer = StageTimer(impl.context);
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
  const Context& context = impl.context;
  const VkMemoryPropertyFlags device_local = VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT;
  pyramid = Buffer(context, VkDeviceSize(offset) * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, device_local);
  counters = Buffer(context, CONE_COUNTERS * 4,
                    VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT |
                        VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                    device_local);
  cone_values = Buffer(context, texels() * VkDeviceSize(layers) * cone_texel_bytes,
                       VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT, device_local);
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
  if (!impl.cone_kernels) {
    impl.cone_kernels = std::make_shared<const DeviceConeKernels>(DeviceConeKernels{
        ComputeKernel(context, spirv_cone_cells_comp, cells_bindings, sizeof(gpu::ConeCellsPush)),
        ComputeKernel(context, spirv_cone_reduce_comp, reduce_bindings, sizeof(gpu::ConeReducePush)),
        ComputeKernel(context, spirv_cone_texel_comp, texel_bindings, sizeof(gpu::ConeTexelPush))});
  }
  cells_kernel = impl.cone_kernels->cells.sibling();
  cells_kernel.bind_image(0, heights.view());
  cells_kernel.bind_buffer(1, pyramid.handle());
  cells_kernel.bind_buffer(2, counters.handle());
  reduce_kernel = impl.cone_kernels->reduce.sibling();
  reduce_kernel.bind_buffer(0, pyramid.handle());
  texel_kernel = impl.cone_kernels->texel.sibling();
  texel_kernel.bind_image(0, heights.view());
  texel_kernel.bind_buffer(1, pyramid.handle());
  texel_kernel.bind_buffer(2, counters.handle());
  texel_kernel.bind_buffer(3, cone_values.handle());

  registration = {&cones, width, height, sectors, address};
  impl.device_cones[std::size_t(cone_slot(sectors))] = &registration;
}

DeviceCones::DeviceCones(Renderer& renderer, int sector_count, bake::Address address)
    : state_(std::make_unique<State>(*renderer.impl_)) {
  State& s = *state_;
  if (s.impl.device_heights == nullptr)
    throw RenderError("DeviceCones: this renderer has no DeviceSim whose heights it could read");
  s.width = int(s.impl.device_heights->width());
  s.height = int(s.impl.device_heights->height());
  validate_shape(s.width, s.height, sector_count);
  s.make(*s.impl.device_heights, sector_count, address);
}

DeviceCones::DeviceCones(Renderer& renderer, bake::HeightView heights, int sector_count,
                         bake::Address address)
    : state_(std::make_unique<State>(*renderer.impl_)) {
  State& s = *state_;
  validate_shape(heights.width, heights.height, sector_count);
  s.width = heights.width;
  s.height = heights.height;
  if (heights.data == nullptr) throw RenderError("DeviceCones: no heights were given");
  for (std::size_t t = 0; t < s.texels(); ++t) {
    if (!(heights.data[t] >= 0.0f && heights.data[t] <= 1.0f)) {
      throw RenderError("DeviceCones: height " + std::to_string(t) + " (row " + std::to_string(t / s.width) +
                        ", column " + std::to_string(t % s.width) + ") is " +
                        std::to_string(heights.data[t]) + ", not a finite value in [0, 1]");
    }
  }
  // the heights, uploaded once through a staging buffer
  const Context& context = s.impl.context;
  s.own_heights = Image(context, VK_FORMAT_R32_SFLOAT, std::uint32_t(s.width), std::uint32_t(s.height), 1,
                        VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT,
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
  s.impl.wait_submitted();
  const std::size_t slot = std::size_t(cone_slot(s.sectors));
  if (s.impl.device_cones[slot] == &s.registration) {
    s.impl.device_cones[slot] = nullptr;
    s.impl.cones_from_device[slot] = false;
  }
}

void DeviceCones::bake(const DeviceConeBudget& budget) {
  State& s = *state_;
  if (s.own_heights.handle() == VK_NULL_HANDLE && s.impl.device_heights != s.source)
    throw RenderError("DeviceCones::bake: the DeviceSim whose heights it reads is gone");
  const int slot = s.impl.slot;
  const VkCommandBuffer commands = s.impl.begin_slot().commands;
  s.timer.begin(commands, slot);

  // the frames before read the cone image and the buffers this one writes
  rewrite_barrier(commands);
  vkCmdFillBuffer(commands, s.counters.handle(), 0, VK_WHOLE_SIZE, 0);
  VkMemoryBarrier cleared{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  cleared.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
  cleared.dstAccessMask = VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT;
  vkCmdPipelineBarrier(commands, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 1,
                       &cleared, 0, nullptr, 0, nullptr);

  // cells and the Lipschitz constant
  const int wrap = s.address == bake::Address::wrap ? 1 : 0;
  gpu::ConeCellsPush cells_push{};
  cells_push.width = s.width;
  cells_push.height = s.height;
  cells_push.cells_u = s.cells_u;
  cells_push.cells_v = s.cells_v;
  cells_push.wrap = wrap;
  s.cells_kernel.record(commands, group_count(std::uint32_t(s.cells_u), CONE_TILE),
                        group_count(std::uint32_t(s.cells_v), CONE_TILE), 1, &cells_push);
  compute_barrier(commands);

  // the max pyramid, a level at a time
  for (int level = 0; level + 1 < s.levels; ++level) {
    gpu::ConeReducePush reduce_push{};
    reduce_push.source_offset = s.level_offset[std::size_t(level)];
    reduce_push.source_width = s.level_width[std::size_t(level)];
    reduce_push.source_height = s.level_height[std::size_t(level)];
    reduce_push.target_offset = s.level_offset[std::size_t(level) + 1];
    reduce_push.target_width = s.level_width[std::size_t(level) + 1];
    reduce_push.target_height = s.level_height[std::size_t(level) + 1];
    s.reduce_kernel.record(commands, group_count(std::uint32_t(reduce_push.target_width), CONE_TILE),
                           group_count(std::uint32_t(reduce_push.target_height), CONE_TILE), 1, &reduce_push);
    compute_barrier(commands);
  }

  // the texels' searches, then their layers into the image the renderer samples
  gpu::ConeTexelPush texel_push{};
  texel_push.width = s.width;
  texel_push.height = s.height;
  texel_push.cells_u = s.cells_u;
  texel_push.cells_v = s.cells_v;
  texel_push.wrap = wrap;
  texel_push.sectors = s.sectors;
  texel_push.levels = s.levels;
  for (int level = 0; level < s.levels; ++level) texel_push.level_offset[level] = s.level_offset[std::size_t(level)];
  const bool unlimited = budget.texels < 0;
  texel_push.first_pass_level = unlimited ? -1 : first_pass_level;
  texel_push.refine_limit =
      unlimited ? 0 : int(std::min<long long>(budget.texels, std::numeric_limits<int>::max()));
  s.texel_kernel.record(commands, group_count(std::uint32_t(s.width), CONE_TILE),
                        group_count(std::uint32_t(s.height), CONE_TILE), 1, &texel_push);
  compute_barrier(commands);
  // copied in the transfer layout (earlier frames' reads are behind `before`), given back in GENERAL
  const auto layers = std::uint32_t(s.layers);
  image_barrier(commands, s.cones.handle(), layers, VK_IMAGE_LAYOUT_GENERAL,
                VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 0, VK_ACCESS_TRANSFER_WRITE_BIT,
                VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT);
  VkBufferImageCopy region{};
  region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, layers};
  region.imageExtent = {std::uint32_t(s.width), std::uint32_t(s.height), 1};
  vkCmdCopyBufferToImage(commands, s.cone_values.handle(), s.cones.handle(),
                         VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &region);
  image_barrier(commands, s.cones.handle(), layers, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                VK_IMAGE_LAYOUT_GENERAL, VK_ACCESS_TRANSFER_WRITE_BIT,
                VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_TRANSFER_READ_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
                VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT);
  s.timer.end(commands, slot);
  s.refine_limit = unlimited ? unlimited_texels : budget.texels;
  s.baked = true;
}

double DeviceCones::device_milliseconds() const {
  State& s = *state_;
  if (s.timer.last_slot() >= 0 && s.impl.slot_finished(s.timer.last_slot()))
    s.timer.read(s.timer.last_slot());
  return s.timer.milliseconds();
}

DeviceConeStats DeviceCones::read_back(std::vector<float>* ratios, std::vector<float>* apex) {
  State& s = *state_;
  if (!s.baked) throw RenderError("DeviceCones::read_back: nothing was baked");
  const VkDeviceSize image_bytes = s.texels() * VkDeviceSize(s.layers) * cone_texel_bytes;
  if (s.readback.handle() == VK_NULL_HANDLE) {
    s.readback = Buffer(s.impl.context, image_bytes + CONE_COUNTERS * 4, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                        VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
  }
  const bool image_wanted = ratios != nullptr || apex != nullptr;
  const VkCommandBuffer commands = s.impl.begin_slot().commands;
  if (image_wanted) {  // the image itself: what the renderer samples
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
  const VkBufferCopy counters_copy{0, image_bytes, CONE_COUNTERS * 4};
  vkCmdCopyBuffer(commands, s.counters.handle(), s.readback.handle(), 1, &counters_copy);
  VkMemoryBarrier to_host{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  to_host.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
  to_host.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
  vkCmdPipelineBarrier(commands, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &to_host,
                       0, nullptr, 0, nullptr);
  s.impl.submit_slot(true);

  const auto* bytes = static_cast<const std::byte*>(s.readback.mapped());
  std::uint32_t counter_values[CONE_COUNTERS];
  std::memcpy(counter_values, bytes + image_bytes, sizeof counter_values);
  if (counter_values[CONE_COUNTER_BAD] != 0)
    throw RenderError(
        "DeviceCones: the heights hold a NaN or a value outside [0, 1]; the cone map is not valid");
  DeviceConeStats stats;
  const long long tickets = counter_values[CONE_COUNTER_TICKETS];
  stats.texels_cut = s.refine_limit < 0 ? 0 : tickets;
  stats.texels_refined = s.refine_limit < 0 ? (long long)s.texels() : std::min(tickets, s.refine_limit);
  // layer k < n: (r_k, H_c), decoded as the shaders read them
  const auto* values = reinterpret_cast<const std::uint32_t*>(bytes);
  if (ratios) {
    ratios->resize(s.texels() * std::size_t(s.sectors));
    for (int k = 0; k < s.sectors; ++k)
      for (std::size_t t = 0; t < s.texels(); ++t)
        (*ratios)[t * std::size_t(s.sectors) + std::size_t(k)] =
            detail::decode_ratio(std::uint16_t(values[std::size_t(k) * s.texels() + t] & 0xffffu));
  }
  if (apex) {
    apex->resize(s.texels());
    for (std::size_t t = 0; t < s.texels(); ++t)
      (*apex)[t] = detail::decode_apex(std::uint16_t(values[t] >> 16));
  }
  return stats;
}

int DeviceCones::width() const { return state_->width; }
int DeviceCones::height() const { return state_->height; }
int DeviceCones::sector_count() const { return state_->sectors; }
bake::Address DeviceCones::address() const { return state_->address; }

}  // namespace displace::render
