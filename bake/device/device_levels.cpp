// bake/device/device_levels.cpp - the levels of detail made on the renderer's device
// (bake/device/device_cones.h, DeviceLevels): level_down.comp.glsl makes each level's heights and slope
// moments from the level below (bake/detail_levels.cpp's chain, in its order of operations) into an image of
// the level's own and the heights atlas the renderer samples; a DeviceCones per level bakes that level's
// cones (the bilinear contract for its surface, docs/design/device-cones.md), copied into the cone atlas, and
// the top of its max pyramid - the level's highest height - into a small buffer that each frame copies into
// its uniforms (render/frame.cpp). docs/design/levels.md, "On the device".
#include <cstring>
#include <string>
#include <utility>

#include "bake/device/device_cones.h"
#include "bake/device/shaders/cones.h"
#include "spirv/level_down_comp.h"
#include "vulkan/compute.h"
#include "vulkan/device_maps.h"
#include "vulkan/frames.h"

namespace displace::bake {

using namespace vulkan;  // the Vulkan base (vulkan/): Context, Buffer, Image, kernels, barriers

static_assert(sizeof(gpu::LevelDownPush) == 32);

namespace {

constexpr VkDescriptorType level_down_bindings[] = {
    VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE};
constexpr VkDeviceSize tops_bytes = 16 * 4;  // FrameUniforms::level_tops: vec4[4]
static_assert(bake::max_detail_levels <= 16);

}  // namespace

struct DeviceLevels::State {
  vulkan::Frames& frames;
  int width = 0, height = 0, count = 0, sectors = 0;  // level 0's size
  bake::Address address = bake::Address::wrap;
  std::shared_ptr<const DeviceHeightImages> source;  // level 0's heights: a DeviceSim's
  std::vector<Image> heights;  // levels 1 .. count, R32F: what each level's cone bake reads
  std::vector<std::shared_ptr<DeviceHeightImages>> level_maps;  // level l's heights at l - 1, for its bake
  Image atlas_heights, atlas_cones;
  Buffer tops, readback;
  std::vector<ComputeKernel> down;                  // level l's kernel at l - 1, its images bound
  std::vector<std::unique_ptr<DeviceCones>> cones;  // level l's at l - 1
  std::shared_ptr<DeviceLevelImages> map;  // the renderer's handle (map_set.h), cleared when this goes
  StageTimer timer;
  bool made = false;

  explicit State(vulkan::Frames& device_frames) : frames(device_frames) {}
  int level_width(int level) const { return width >> level; }
  int level_height(int level) const { return height >> level; }
};

DeviceLevels::DeviceLevels(vulkan::Frames& frames, std::shared_ptr<const DeviceHeightImages> heights,
                           int sector_count, bake::Address address)
    : state_(std::make_unique<State>(frames)) {
  State& s = *state_;
  if (!heights || heights->owner != &frames || heights->heights == nullptr)
    throw vulkan::Error("DeviceLevels: the heights of a DeviceSim on the same Frames, alive, are needed");
  if (sector_count != 1 && sector_count != 4 && sector_count != 8)
    throw vulkan::Error("DeviceLevels: a cone map has 1, 4 or 8 sectors, not " +
                        std::to_string(sector_count));
  s.source = std::move(heights);
  s.width = int(s.source->heights->width());
  s.height = int(s.source->heights->height());
  s.count = bake::detail_level_count(s.width, s.height);
  s.sectors = sector_count;
  s.address = address;
  const Context& context = frames.context();
  s.timer = StageTimer(context);
  s.tops = Buffer(context, tops_bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                  VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
  if (s.count > 0) {
    const glm::ivec2 atlas = level_atlas_size(s.width, s.height, s.count);
    const int layers = cone_layer_count(sector_count, false);
    s.atlas_heights =
        Image(context, VK_FORMAT_R32G32B32A32_SFLOAT, std::uint32_t(atlas.x), std::uint32_t(atlas.y), 1,
              VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT,
              VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_VIEW_TYPE_2D);
    s.atlas_cones =
        Image(context, cone_format, std::uint32_t(atlas.x), std::uint32_t(atlas.y), std::uint32_t(layers),
              VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT,
              VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_VIEW_TYPE_2D_ARRAY);
    for (int level = 1; level <= s.count; ++level) {
      s.heights.emplace_back(context, VK_FORMAT_R32_SFLOAT, std::uint32_t(s.level_width(level)),
                             std::uint32_t(s.level_height(level)), 1,
                             VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT,
                             VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_VIEW_TYPE_2D);
    }
    context.submit_and_wait([&](VkCommandBuffer commands) {
      image_barrier(commands, s.atlas_heights.handle(), 1, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_GENERAL,
                    0, VK_ACCESS_SHADER_WRITE_BIT, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT,
                    VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT);
      image_barrier(commands, s.atlas_cones.handle(), std::uint32_t(layers), VK_IMAGE_LAYOUT_UNDEFINED,
                    VK_IMAGE_LAYOUT_GENERAL, 0, VK_ACCESS_TRANSFER_WRITE_BIT,
                    VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT);
      for (const Image& level : s.heights)
        image_barrier(commands, level.handle(), 1, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_GENERAL, 0,
                      VK_ACCESS_SHADER_WRITE_BIT, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT,
                      VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT);
      vkCmdFillBuffer(commands, s.tops.handle(), 0, VK_WHOLE_SIZE, 0x3f800000u);  // 1.0f: the relief's top
    });
    const ComputeKernel kernel(context, spirv_level_down_comp, level_down_bindings,
                               sizeof(gpu::LevelDownPush));
    for (int level = 1; level <= s.count; ++level) {
      ComputeKernel& down = s.down.emplace_back(kernel.sibling());
      down.bind_image(0, level == 1 ? s.source->heights->view() : s.heights[std::size_t(level - 2)].view());
      down.bind_image(1, s.atlas_heights.view());
      down.bind_image(2, s.heights[std::size_t(level - 1)].view());
      s.level_maps.push_back(std::make_shared<DeviceHeightImages>(
          DeviceHeightImages{&frames, &s.heights[std::size_t(level - 1)]}));
      s.cones.push_back(std::make_unique<DeviceCones>(frames, s.level_maps.back(), sector_count, address));
    }
  }
  s.map = std::make_shared<DeviceLevelImages>(DeviceLevelImages{&frames, &s.atlas_heights, &s.atlas_cones,
                                                                s.tops.handle(), s.width, s.height, s.count,
                                                                s.sectors, s.address == Address::wrap});
}

DeviceLevels::~DeviceLevels() {
  State& s = *state_;
  s.frames.wait_submitted();
  s.cones.clear();
  for (const std::shared_ptr<DeviceHeightImages>& level : s.level_maps) level->heights = nullptr;
  s.map->heights = s.map->cones =
      nullptr;  // (a MapSet may still name it: the renderer then refuses the frame)
}

std::shared_ptr<const DeviceLevelImages> DeviceLevels::maps() const { return state_->map; }

void DeviceLevels::make(const Budget& budget, const DeviceFirstPass& first_pass) {
  State& s = *state_;
  if (s.source->heights == nullptr)
    throw vulkan::Error("DeviceLevels::make: the DeviceSim whose heights it reads is gone");
  if (s.count == 0) return;
  const int slot = s.frames.slot();
  VkCommandBuffer commands = s.frames.begin();
  s.timer.begin(commands, slot);
  rewrite_barrier(commands);  // the frames before sampled the atlases and copied the tops
  for (int level = 1; level <= s.count; ++level) {
    gpu::LevelDownPush push{};
    push.fine_width = s.level_width(level - 1);
    push.fine_height = s.level_height(level - 1);
    const glm::ivec2 origin = level_atlas_origin(s.width, s.height, level);
    push.origin_x = origin.x;
    push.origin_y = origin.y;
    if (level >= 2) {
      const glm::ivec2 fine_origin = level_atlas_origin(s.width, s.height, level - 1);
      push.fine_origin_x = fine_origin.x;
      push.fine_origin_y = fine_origin.y;
    }
    push.from_level0 = level == 1 ? 1 : 0;
    s.down[std::size_t(level - 1)].record(
        commands, group_count(std::uint32_t(s.level_width(level)), CONE_TILE),
        group_count(std::uint32_t(s.level_height(level)), CONE_TILE), 1, &push);
    compute_barrier(commands);  // the next level reads this one's heights and moments
  }
  for (const std::unique_ptr<DeviceCones>& level : s.cones) level->bake(budget, first_pass);
  commands = s.frames.begin();  // the same recording
  // each level's cone image into its place in the atlas (in the transfer layouts, back to GENERAL
  // for the draw), and the top of its max pyramid into the tops
  const auto layers = std::uint32_t(cone_layer_count(s.sectors, false));
  const VkAccessFlags read = VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_TRANSFER_READ_BIT;
  const VkPipelineStageFlags readers = VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT;
  image_barrier(commands, s.atlas_cones.handle(), layers, VK_IMAGE_LAYOUT_GENERAL,
                VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 0, VK_ACCESS_TRANSFER_WRITE_BIT,
                VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT);
  for (int level = 1; level <= s.count; ++level) {
    const DeviceConeImage& parts = *s.cones[std::size_t(level - 1)]->map();
    const glm::ivec2 origin = level_atlas_origin(s.width, s.height, level);
    image_barrier(commands, parts.image->handle(), layers, VK_IMAGE_LAYOUT_GENERAL,
                  VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_ACCESS_TRANSFER_WRITE_BIT,
                  VK_ACCESS_TRANSFER_READ_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
                  VK_PIPELINE_STAGE_TRANSFER_BIT);
    VkImageCopy region{};
    region.srcSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, layers};
    region.dstSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, layers};
    region.dstOffset = {origin.x, origin.y, 0};
    region.extent = {std::uint32_t(s.level_width(level)), std::uint32_t(s.level_height(level)), 1};
    vkCmdCopyImage(commands, parts.image->handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                   s.atlas_cones.handle(), VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &region);
    image_barrier(commands, parts.image->handle(), layers, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                  VK_IMAGE_LAYOUT_GENERAL, VK_ACCESS_TRANSFER_READ_BIT, read, VK_PIPELINE_STAGE_TRANSFER_BIT,
                  readers);
    const VkBufferCopy top{parts.top_offset, VkDeviceSize(level - 1) * 4, 4};
    vkCmdCopyBuffer(commands, parts.pyramid, s.tops.handle(), 1, &top);
  }
  // the atlas for the frame's draw, the tops for its copy into the uniforms (and a read back)
  image_barrier(commands, s.atlas_cones.handle(), layers, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                VK_IMAGE_LAYOUT_GENERAL, VK_ACCESS_TRANSFER_WRITE_BIT, read, VK_PIPELINE_STAGE_TRANSFER_BIT,
                readers);
  VkMemoryBarrier barrier{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  barrier.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
  barrier.dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT;
  vkCmdPipelineBarrier(commands, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 1,
                       &barrier, 0, nullptr, 0, nullptr);
  s.timer.end(commands, slot);
  s.made = true;
}

BakeStats DeviceLevels::read_back(int level, std::vector<float>* heights, std::vector<float>* slopes,
                                  std::vector<float>* ratios, std::vector<float>* apex, float* top) {
  State& s = *state_;
  if (level < 1 || level > s.count)
    throw vulkan::Error("DeviceLevels::read_back: level " + std::to_string(level) + " of " +
                        std::to_string(s.count));
  if (!s.made) throw vulkan::Error("DeviceLevels::read_back: nothing was made");
  // the level's bake: its stats and the heights' check (this submits and waits)
  BakeStats stats = s.cones[std::size_t(level - 1)]->read_back(nullptr, nullptr);
  const int w = s.level_width(level), h = s.level_height(level);
  const auto texels = std::size_t(w) * std::size_t(h);
  const auto layers = std::uint32_t(cone_layer_count(s.sectors, false));
  const VkDeviceSize height_bytes = texels * 16, cone_bytes = texels * layers * cone_texel_bytes;
  const VkDeviceSize readback_bytes = height_bytes + cone_bytes + 4;  // and the level's top
  // made again for a larger level (the first read is level 1's, the largest)
  if (s.readback.handle() == VK_NULL_HANDLE || s.readback.size() < readback_bytes) {
    s.readback = Buffer(s.frames.context(), readback_bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                        VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
  }
  const glm::ivec2 origin = level_atlas_origin(s.width, s.height, level);
  const VkCommandBuffer commands = s.frames.begin();
  // both atlases in the transfer layout for the copies, then back in GENERAL for the draws
  const VkPipelineStageFlags writers = VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT;
  const VkPipelineStageFlags readers =
      VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT | VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT;
  for (const auto& [image, image_layers] :
       {std::pair{&s.atlas_heights, 1u}, std::pair{&s.atlas_cones, layers}})
    image_barrier(commands, image->handle(), image_layers, VK_IMAGE_LAYOUT_GENERAL,
                  VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                  VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT, VK_ACCESS_TRANSFER_READ_BIT,
                  writers, VK_PIPELINE_STAGE_TRANSFER_BIT);
  VkBufferImageCopy region{};
  region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
  region.imageOffset = {origin.x, origin.y, 0};
  region.imageExtent = {std::uint32_t(w), std::uint32_t(h), 1};
  vkCmdCopyImageToBuffer(commands, s.atlas_heights.handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                         s.readback.handle(), 1, &region);
  region.bufferOffset = height_bytes;
  region.imageSubresource.layerCount = layers;
  vkCmdCopyImageToBuffer(commands, s.atlas_cones.handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                         s.readback.handle(), 1, &region);
  for (const auto& [image, image_layers] :
       {std::pair{&s.atlas_heights, 1u}, std::pair{&s.atlas_cones, layers}})
    image_barrier(commands, image->handle(), image_layers, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                  VK_IMAGE_LAYOUT_GENERAL, VK_ACCESS_TRANSFER_READ_BIT,
                  VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
                  readers);
  const VkBufferCopy level_top{VkDeviceSize(level - 1) * 4, height_bytes + cone_bytes, 4};
  vkCmdCopyBuffer(commands, s.tops.handle(), s.readback.handle(), 1, &level_top);
  host_read_barrier(commands);
  s.frames.submit(true);

  const auto* bytes = static_cast<const std::byte*>(s.readback.mapped());
  const auto* values = reinterpret_cast<const float*>(bytes);
  if (heights) {
    heights->resize(texels);
    for (std::size_t t = 0; t < texels; ++t) (*heights)[t] = values[t * 4];
  }
  if (slopes) {
    slopes->resize(texels * 3);
    for (std::size_t t = 0; t < texels; ++t)
      for (std::size_t c = 0; c < 3; ++c) (*slopes)[t * 3 + c] = values[t * 4 + 1 + c];
  }
  const auto* cone_values = reinterpret_cast<const std::uint32_t*>(bytes + height_bytes);
  if (ratios) {
    ratios->resize(texels * std::size_t(s.sectors));
    for (int k = 0; k < s.sectors; ++k)
      for (std::size_t t = 0; t < texels; ++t)
        (*ratios)[t * std::size_t(s.sectors) + std::size_t(k)] =
            vulkan::decode_ratio(std::uint16_t(cone_values[std::size_t(k) * texels + t] & 0xffffu));
    double sum = 0.0;
    for (float ratio : *ratios) sum += ratio;
    stats.mean_ratio = ratios->empty() ? 0.0 : sum / double(ratios->size());
  }
  if (apex) {
    apex->resize(texels);
    for (std::size_t t = 0; t < texels; ++t)
      (*apex)[t] = vulkan::decode_apex(std::uint16_t(cone_values[t] >> 16));
  }
  if (top) std::memcpy(top, bytes + height_bytes + cone_bytes, 4);
  return stats;
}

int DeviceLevels::level_count() const { return state_->count; }
int DeviceLevels::sector_count() const { return state_->sectors; }
bake::Address DeviceLevels::address() const { return state_->address; }

double DeviceLevels::device_milliseconds() const {
  return state_->frames.finished_milliseconds(state_->timer);
}

}  // namespace displace::bake
