// render/map_upload.cpp - maps handed over by the caller (MapSet) to device images and buffers that
// are kept between frames.
//
// Per map: validate what changed (sizes, then the values while they are packed) -> check that what
// is made again fits (memory.cpp) -> make the device image again only if its shape changed -> pack
// the changed rectangles into the current slot's part of the staging ring -> record the copies (with
// layout barriers) into the slot's command buffer, which the frame then submits with its draw. A copy
// overwrites an image an earlier frame may still read: the barrier before it waits for the fragment
// and vertex shaders of every earlier submission on the queue, so one image per map is enough.
// Where the device is the CPU driver (lavapipe; Context::host_images), heights,
// foam and cone maps skip the staging and the device copy: they are linear images the host packs
// its rectangles into directly, after waiting for the frames in flight (which may read them), and
// shaders read them in GENERAL layout. On lavapipe that copy was a second pass over the bytes on the
// device's one queue thread: BM_UploadMaps/512/whole 1.74 ms staged, 0.85 ms host-written (one
// run), the 512 water frame's render 1 ms shorter.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>

#include "render/map_pack.h"
#include "render/renderer_impl.h"
#include "render/shaders/config.h"

namespace displace::render {
namespace {

constexpr VkDeviceSize staging_alignment = 16;  // bytes; a multiple of every texel size copied

VkDeviceSize align_up(VkDeviceSize bytes) {
  return (bytes + staging_alignment - 1) / staging_alignment * staging_alignment;
}

const char* address_name(bake::Address address) { return address == bake::Address::wrap ? "wrap" : "clamp"; }

std::string size_text(int width, int height) { return std::to_string(width) + "x" + std::to_string(height); }

// How a map is brought up to date.
enum class Copy { none, rects, whole };

// A map of `version` with `dirty` rectangles, against what the device holds.
Copy copy_kind(const DeviceMap& held, bool same_shape, std::uint64_t version, std::uint64_t dirty_since,
               std::size_t dirty_count) {
  if (!held.held || !same_shape) return Copy::whole;
  if (version == held.version) return Copy::none;
  if (dirty_since == held.version && dirty_count > 0) return Copy::rects;
  return Copy::whole;
}

void check_rects(std::span<const bake::Rect> rects, int width, int height, const char* map) {
  for (const bake::Rect& rect : rects) {
    if (rect.x0 < 0 || rect.y0 < 0 || rect.x1 > width || rect.y1 > height || rect.x0 > rect.x1 ||
        rect.y0 > rect.y1) {
      throw RenderError(std::string(map) + ": a dirty rectangle [" + std::to_string(rect.x0) + ", " +
                        std::to_string(rect.x1) + ") x [" + std::to_string(rect.y0) + ", " +
                        std::to_string(rect.y1) + ") lies outside the " + size_text(width, height) + " map");
    }
  }
}

VkDeviceSize rect_texels(const bake::Rect& rect) {
  return VkDeviceSize(rect.x1 - rect.x0) * VkDeviceSize(rect.y1 - rect.y0);
}

// A host-written image's float at texel (x, y) of layer 0.
float* texel_of(const DeviceMap& map, int x, int y, std::size_t texel_bytes) {
  return reinterpret_cast<float*>(map.image.mapped() + VkDeviceSize(y) * map.image.row_pitch() +
                                  VkDeviceSize(x) * texel_bytes);
}

void to_transfer(VkCommandBuffer commands, const DeviceMap& map, std::uint32_t layers, bool fresh) {
  image_barrier(commands, map.image.handle(), layers,
                fresh ? VK_IMAGE_LAYOUT_UNDEFINED : VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL,
                VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 0, VK_ACCESS_TRANSFER_WRITE_BIT,
                VK_PIPELINE_STAGE_VERTEX_SHADER_BIT | VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT,
                VK_PIPELINE_STAGE_TRANSFER_BIT);
}

void to_shader(VkCommandBuffer commands, const DeviceMap& map, std::uint32_t layers) {
  image_barrier(commands, map.image.handle(), layers, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, VK_ACCESS_TRANSFER_WRITE_BIT,
                VK_ACCESS_SHADER_READ_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
                VK_PIPELINE_STAGE_VERTEX_SHADER_BIT | VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT);
}

}  // namespace

int cone_slot(int sector_count) {
  switch (sector_count) {
    case 1: return 0;
    case 4: return 1;
    case 8: return 2;
    default: throw RenderError("a cone map has 1, 4 or 8 sectors, not " + std::to_string(sector_count));
  }
}

MapNeeds map_needs(Method method, const View& view) {
  const MethodInfo& info = method_info(method);
  MapNeeds needs;
  needs.cone_sectors = info.cone_sectors;
  needs.relaxed = info.relaxed_cones;
  // u closes around a quadric's axis: its cones are baked with wrap (conservative for a clamped v)
  needs.cone_address = is_quadric(view.surface) ? bake::Address::wrap : view.address;
  needs.max_pyramid = info.family == MethodFamily::pyramid;
  needs.distance = info.family == MethodFamily::distance;
  needs.address = view.address;
  return needs;
}

void Renderer::Impl::take_maps(const MapSet& maps) {
  // validate the sizes
  const int width = maps.width, height = maps.height;
  if (width < 1 || height < 1 || width > max_map_side || height > max_map_side ||
      maps.heights.size() != std::size_t(width) * std::size_t(height)) {
    throw RenderError(
        "maps: the height map must be between 1x1 and 16384x16384 texels with one height per texel (got " +
        size_text(width, height) + " and " + std::to_string(maps.heights.size()) + " heights)");
  }
  check_rects(maps.heights_dirty, width, height, "heights");
  if (!maps.foam.empty() && maps.foam.size() != std::size_t(width) * std::size_t(height)) {
    throw RenderError("maps: foam coverage must hold one value per texel of the " + size_text(width, height) +
                      " heights");
  }
  const std::size_t texels = std::size_t(width) * std::size_t(height);
  for (std::size_t index = 0; index < maps.cones.size(); ++index) {
    const ConeMapView& given = maps.cones[index];
    if (given.sector_count == 0) continue;
    // the map's name, for the errors only (a checked frame allocates nothing)
    const char* const name = given.sector_count == 1   ? "1-sector cone map"
                             : given.sector_count == 4 ? "4-sector cone map"
                                                       : "8-sector cone map";
    if (cone_slot(given.sector_count) != int(index)) {
      throw RenderError(std::string("maps: the ") + name + " belongs in cones[" +
                        std::to_string(cone_slot(given.sector_count)) + "]");
    }
    if (given.ratios.size() != texels * std::size_t(given.sector_count) || given.apex.size() != texels ||
        !(given.relaxed.empty() || given.relaxed.size() == texels)) {
      throw RenderError(std::string("maps: the ") + name + " does not match the " + size_text(width, height) +
                        " heights (ratios, apex heights and relaxed ratios are per texel)");
    }
    check_rects(given.dirty, width, height, name);
  }
  const bake::DualMaxPyramid* pyramid = maps.max_pyramid.pyramid;
  VkDeviceSize pyramid_bytes = 0;
  if (pyramid) {
    const std::size_t levels = pyramid->widths.size();
    if (levels == 0 || levels > MAX_PYRAMID_LEVELS || pyramid->heights.size() != levels ||
        pyramid->offsets.size() != levels ||
        pyramid->origin != (maps.max_pyramid.address == bake::Address::clamp ? -1 : 0)) {
      throw RenderError(
          "maps: the max pyramid is not one of bake::build_dual_max_pyramid with its address mode");
    }
    pyramid_bytes = sizeof(gpu::MaxPyramidHeader) + pyramid->values.size() * sizeof(float);
    if (pyramid_bytes > context.info().max_storage_buffer_range) {
      throw RenderError("the max pyramid of a " + size_text(width, height) + " map needs " +
                        std::to_string(pyramid_bytes) + " bytes, more than this device's " +
                        std::to_string(context.info().max_storage_buffer_range) + "-byte storage buffers");
    }
  }
  const DistanceMapView& distance_view = maps.distance;
  if (distance_view.width != 0) {
    const int limit = context.info().max_image_dimension_3d;
    if (distance_view.width < 1 || distance_view.height < 1 || distance_view.depth < 1 ||
        distance_view.width > limit || distance_view.height > limit || distance_view.depth > limit ||
        distance_view.values.size() != std::size_t(distance_view.width) * std::size_t(distance_view.height) *
                                           std::size_t(distance_view.depth)) {
      throw RenderError("maps: the distance map must have 1 to " + std::to_string(limit) +
                        " voxels a side (this device's 3D images) and one value per voxel");
    }
  }

  check_map_memory(maps);

  // what changes, and device images of the right shape (made again only when the shape changed)
  bool drained = false;
  auto reshape = [&](DeviceMap& map, int w, int h, int layers) {
    if (map.image.handle() && map.width == w && map.height == h && map.layers == layers) return false;
    if (!drained && (map.image.handle() || map.buffer.handle())) {
      drain();  // an earlier frame, or copies recorded for this one, may still use the old image
      drained = true;
    }
    map.held = false;
    map.width = w;
    map.height = h;
    map.layers = layers;
    return true;
  };
  map_width = width;
  map_height = height;

  const Copy heights_copy =
      copy_kind(heights, heights.width == width && heights.height == height, maps.heights_version,
                maps.heights_dirty_since, maps.heights_dirty.size());
  // a map's image: written by the host where the device shares its memory, else copied into
  auto make_image = [&](DeviceMap& map, VkFormat format, int w, int h, int layers,
                        VkImageViewType view_type) {
    const auto image_width = std::uint32_t(w), image_height = std::uint32_t(h),
               image_layers = std::uint32_t(layers);
    map.general = false;
    map.image = host_written_maps && context.host_images(format, image_width, image_height, image_layers)
                    ? Image::host_written(context, format, image_width, image_height, image_layers, view_type)
                    : Image();
    map.host_written = map.image.handle() != VK_NULL_HANDLE;
    if (!map.host_written) {
      map.image = Image(context, format, image_width, image_height, image_layers,
                        VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT,
                        VK_IMAGE_ASPECT_COLOR_BIT, view_type);
    }
  };
  if (reshape(heights, width, height, 1))
    make_image(heights, VK_FORMAT_R32_SFLOAT, width, height, 1, VK_IMAGE_VIEW_TYPE_2D);
  Copy foam_copy = Copy::none;
  if (!maps.foam.empty()) {
    foam_copy = copy_kind(foam, foam.width == width && foam.height == height, maps.foam_version, 0, 0);
    if (reshape(foam, width, height, 1))
      make_image(foam, VK_FORMAT_R32_SFLOAT, width, height, 1, VK_IMAGE_VIEW_TYPE_2D);
  } else {
    foam.held = false;
  }
  std::array<Copy, 3> cone_copies{Copy::none, Copy::none, Copy::none};
  for (std::size_t index = 0; index < cones.size(); ++index) {
    const ConeMapView& view = maps.cones[index];
    DeviceMap& map = cones[index];
    if (view.sector_count == 0) {
      map.held = false;
      continue;
    }
    const bool relaxed = !view.relaxed.empty();
    const int layers = cone_layer_count(view.sector_count, relaxed);
    const bool same = map.width == width && map.height == height && map.layers == layers &&
                      map.sectors == view.sector_count && map.relaxed == relaxed &&
                      map.address == view.address;
    cone_copies[index] = copy_kind(map, same, view.version, view.dirty_since, view.dirty.size());
    if (reshape(map, width, height, layers)) {
      make_image(map, cone_format, width, height, layers, VK_IMAGE_VIEW_TYPE_2D_ARRAY);
    }
    if (cone_copies[index] == Copy::whole) map.held = false;
    map.sectors = view.sector_count;
    map.relaxed = relaxed;
    map.address = view.address;
  }
  Copy pyramid_copy = Copy::none;
  if (pyramid) {
    const int bytes = int(std::min<VkDeviceSize>(pyramid_bytes, 0x7fffffff));
    const bool same = max_pyramid.width == bytes && max_pyramid.address == maps.max_pyramid.address;
    pyramid_copy = copy_kind(max_pyramid, same, maps.max_pyramid.version, 0, 0);
    if (max_pyramid.width != bytes || !max_pyramid.buffer.handle()) {
      if (!drained && max_pyramid.buffer.handle()) {
        drain();
        drained = true;
      }
      max_pyramid.buffer = Buffer(context, pyramid_bytes,
                                  VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                  VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
      max_pyramid.width = bytes;
      max_pyramid.held = false;
      pyramid_copy = Copy::whole;
    }
    max_pyramid.address = maps.max_pyramid.address;
  } else {
    max_pyramid.held = false;
  }
  Copy distance_copy = Copy::none;
  if (distance_view.width != 0) {
    const bool same = distance.width == distance_view.width && distance.height == distance_view.height &&
                      distance.layers == distance_view.depth && distance.address == distance_view.address;
    distance_copy = copy_kind(distance, same, distance_view.version, 0, 0);
    if (reshape(distance, distance_view.width, distance_view.height, distance_view.depth)) {
      distance.image = Image(context, VK_FORMAT_R32_SFLOAT, std::uint32_t(distance_view.width),
                             std::uint32_t(distance_view.height), std::uint32_t(distance_view.depth),
                             VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT,
                             VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_VIEW_TYPE_3D);
    }
    distance.address = distance_view.address;
  } else {
    distance.held = false;
  }

  // the whole map as one rectangle
  const bake::Rect whole{0, 0, width, height};
  const std::span<const bake::Rect> whole_map(&whole, 1);
  auto rects_of = [&](Copy copy, std::span<const bake::Rect> dirty) {
    return copy == Copy::rects ? dirty : (copy == Copy::whole ? whole_map : std::span<const bake::Rect>{});
  };

  // staging bytes, then room in the current slot's part of the ring
  VkDeviceSize bytes = 0;
  bool host_writes = false;  // a host-written map changes: wait for the frames that may read it
  if (heights.host_written) {
    host_writes |= heights_copy != Copy::none;
  } else {
    for (const bake::Rect& rect : rects_of(heights_copy, maps.heights_dirty))
      bytes += align_up(rect_texels(rect) * 4);
  }
  if (foam.host_written) {
    host_writes |= foam_copy != Copy::none;
  } else if (foam_copy != Copy::none) {
    bytes += align_up(texels * 4);
  }
  for (std::size_t index = 0; index < cones.size(); ++index) {
    if (cones[index].host_written) {
      host_writes |= cone_copies[index] != Copy::none;
      continue;
    }
    for (const bake::Rect& rect : rects_of(cone_copies[index], maps.cones[index].dirty)) {
      bytes += align_up(rect_texels(rect) * cone_texel_bytes * VkDeviceSize(cones[index].layers));
    }
  }
  if (pyramid_copy != Copy::none) bytes += align_up(pyramid_bytes);
  if (distance_copy != Copy::none) bytes += align_up(distance_view.values.size() * sizeof(float));
  if (bytes == 0 && !host_writes) return;
  if (host_writes) wait_submitted();
  FrameSlot* frame_slot = &begin_slot();
  if (bytes > 0 && frame_slot->staging_used + bytes > frame_slot->staging.size()) {
    if (frame_slot->staging_used > 0) {  // copies already recorded read the old buffer: send them first
      submit_slot(true);
      frame_slot = &begin_slot();
    }
    frame_slot->staging = Buffer(context, bytes, VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                                 VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
  }
  auto* staging = static_cast<std::byte*>(frame_slot->staging.mapped());
  const VkCommandBuffer commands = frame_slot->commands;
  auto reserve = [&](VkDeviceSize size) {
    const VkDeviceSize offset = frame_slot->staging_used;
    frame_slot->staging_used += align_up(size);
    return offset;
  };
  std::vector<VkBufferImageCopy>& regions = copy_regions;
  // a host-written image made this time: to GENERAL layout before the frame's shaders read it (the
  // host's writes before the submission are visible to it without a barrier of their own)
  auto to_general = [&](DeviceMap& map, std::uint32_t layers) {
    if (map.general) return;
    image_barrier(commands, map.image.handle(), layers, VK_IMAGE_LAYOUT_PREINITIALIZED,
                  VK_IMAGE_LAYOUT_GENERAL, VK_ACCESS_HOST_WRITE_BIT, VK_ACCESS_SHADER_READ_BIT,
                  VK_PIPELINE_STAGE_HOST_BIT,
                  VK_PIPELINE_STAGE_VERTEX_SHADER_BIT | VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT);
    map.general = true;
  };

  // heights and foam: one R32F value per texel in [0, 1]
  auto upload_values = [&](DeviceMap& map, Copy copy, std::span<const float> values,
                           std::span<const bake::Rect> dirty, std::uint64_t version, const char* what) {
    if (copy == Copy::none) return;
    const bool fresh = !map.held;
    map.held = false;
    if (map.host_written) {
      for (const bake::Rect& rect : rects_of(copy, dirty)) {
        if (rect_texels(rect) == 0) continue;
        if (!detail::pack_heights(values, width, rect, texel_of(map, rect.x0, rect.y0, 4),
                                  map.image.row_pitch() / 4)) {
          throw RenderError(std::string("maps: ") + what + " must be finite and in [0, 1]");
        }
      }
      to_general(map, 1);
      map.held = true;
      map.version = version;
      return;
    }
    regions.clear();
    for (const bake::Rect& rect : rects_of(copy, dirty)) {
      if (rect_texels(rect) == 0) continue;
      const VkDeviceSize offset = reserve(rect_texels(rect) * 4);
      if (!detail::pack_heights(values, width, rect, reinterpret_cast<float*>(staging + offset),
                                std::size_t(rect.x1 - rect.x0))) {
        throw RenderError(std::string("maps: ") + what + " must be finite and in [0, 1]");
      }
      VkBufferImageCopy region{};
      region.bufferOffset = offset;
      region.bufferRowLength = std::uint32_t(rect.x1 - rect.x0);
      region.bufferImageHeight = std::uint32_t(rect.y1 - rect.y0);
      region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
      region.imageOffset = {rect.x0, rect.y0, 0};
      region.imageExtent = {std::uint32_t(rect.x1 - rect.x0), std::uint32_t(rect.y1 - rect.y0), 1};
      regions.push_back(region);
    }
    to_transfer(commands, map, 1, fresh);
    if (!regions.empty()) {
      vkCmdCopyBufferToImage(commands, frame_slot->staging.handle(), map.image.handle(),
                             VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, std::uint32_t(regions.size()),
                             regions.data());
    }
    to_shader(commands, map, 1);
    map.held = true;
    map.version = version;
  };
  upload_values(heights, heights_copy, maps.heights, maps.heights_dirty, maps.heights_version, "heights");
  upload_values(foam, foam_copy, maps.foam, {}, maps.foam_version, "foam coverage");

  // cone maps: every layer of a rectangle in one region (layer after layer in the staging)
  for (std::size_t index = 0; index < cones.size(); ++index) {
    if (cone_copies[index] == Copy::none) continue;
    DeviceMap& map = cones[index];
    const ConeMapView& view = maps.cones[index];
    const bool fresh = !map.held;
    map.held = false;
    auto invalid = [&] {  // made only when thrown: a frame builds no strings
      return RenderError(
          "maps: the " + std::to_string(view.sector_count) +
          "-sector cone map holds a negative or non-finite ratio or an apex height outside [0, 1]");
    };
    if (map.host_written) {
      for (const bake::Rect& rect : rects_of(cone_copies[index], view.dirty)) {
        if (rect_texels(rect) == 0) continue;
        auto* origin = reinterpret_cast<std::uint16_t*>(texel_of(map, rect.x0, rect.y0, cone_texel_bytes));
        if (!detail::pack_cones(view, width, rect, origin, map.image.row_pitch() / 2,
                                map.image.layer_pitch() / 2)) {
          throw invalid();
        }
      }
      to_general(map, std::uint32_t(map.layers));
      map.held = true;
      map.version = view.version;
      continue;
    }
    regions.clear();
    for (const bake::Rect& rect : rects_of(cone_copies[index], view.dirty)) {
      if (rect_texels(rect) == 0) continue;
      const VkDeviceSize offset = reserve(rect_texels(rect) * cone_texel_bytes * VkDeviceSize(map.layers));
      if (!detail::pack_cones(view, width, rect, reinterpret_cast<std::uint16_t*>(staging + offset),
                              std::size_t(rect.x1 - rect.x0) * 2, std::size_t(rect_texels(rect)) * 2)) {
        throw invalid();
      }
      VkBufferImageCopy region{};
      region.bufferOffset = offset;
      region.bufferRowLength = std::uint32_t(rect.x1 - rect.x0);
      region.bufferImageHeight = std::uint32_t(rect.y1 - rect.y0);
      region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, std::uint32_t(map.layers)};
      region.imageOffset = {rect.x0, rect.y0, 0};
      region.imageExtent = {std::uint32_t(rect.x1 - rect.x0), std::uint32_t(rect.y1 - rect.y0), 1};
      regions.push_back(region);
    }
    to_transfer(commands, map, std::uint32_t(map.layers), fresh);
    if (!regions.empty()) {
      vkCmdCopyBufferToImage(commands, frame_slot->staging.handle(), map.image.handle(),
                             VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, std::uint32_t(regions.size()),
                             regions.data());
    }
    to_shader(commands, map, std::uint32_t(map.layers));
    map.held = true;
    map.version = view.version;
  }

  // the max pyramid: header and values, as the shader reads them at BINDING_MAX_PYRAMID
  if (pyramid_copy != Copy::none) {
    max_pyramid.held = false;
    const VkDeviceSize offset = reserve(pyramid_bytes);
    gpu::MaxPyramidHeader header{};
    const std::size_t levels = pyramid->widths.size();
    header.shape = glm::ivec4(int(levels), pyramid->origin, 0, 0);
    for (std::size_t level = 0; level < levels; ++level) {
      header.levels[level] =
          glm::ivec4(int(pyramid->offsets[level]), pyramid->widths[level], pyramid->heights[level], 0);
    }
    std::memcpy(staging + offset, &header, sizeof header);
    std::memcpy(staging + offset + sizeof header, pyramid->values.data(),
                pyramid->values.size() * sizeof(float));
    VkBufferMemoryBarrier barrier{VK_STRUCTURE_TYPE_BUFFER_MEMORY_BARRIER};
    barrier.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    barrier.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    barrier.buffer = max_pyramid.buffer.handle();
    barrier.size = VK_WHOLE_SIZE;
    barrier.dstAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
    vkCmdPipelineBarrier(commands, VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, 0,
                         0, nullptr, 1, &barrier, 0, nullptr);
    const VkBufferCopy region{offset, 0, pyramid_bytes};
    vkCmdCopyBuffer(commands, frame_slot->staging.handle(), max_pyramid.buffer.handle(), 1, &region);
    barrier.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
    barrier.dstAccessMask = VK_ACCESS_SHADER_READ_BIT;
    vkCmdPipelineBarrier(commands, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT, 0,
                         0, nullptr, 1, &barrier, 0, nullptr);
    max_pyramid.held = true;
    max_pyramid.version = maps.max_pyramid.version;
  }

  // the distance map (3D)
  if (distance_copy != Copy::none) {
    const bool fresh = !distance.held;
    distance.held = false;
    const VkDeviceSize offset = reserve(distance_view.values.size() * sizeof(float));
    float* out = reinterpret_cast<float*>(staging + offset);
    bool valid = true;
    for (std::size_t v = 0; v < distance_view.values.size(); ++v) {
      const float value = distance_view.values[v];
      valid &= value >= 0.0f && value <= 1e30f;
      out[v] = value;
    }
    if (!valid) throw RenderError("maps: the distance map holds a negative or non-finite distance");
    to_transfer(commands, distance, 1, fresh);
    VkBufferImageCopy region{};
    region.bufferOffset = offset;
    region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    region.imageExtent = {std::uint32_t(distance_view.width), std::uint32_t(distance_view.height),
                          std::uint32_t(distance_view.depth)};
    vkCmdCopyBufferToImage(commands, frame_slot->staging.handle(), distance.image.handle(),
                           VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &region);
    to_shader(commands, distance, 1);
    distance.held = true;
    distance.version = distance_view.version;
  }
}

void Renderer::Impl::require_maps(const MapNeeds& needs, const MethodInfo& info) const {
  const std::string method = std::string("--method ") + info.name;
  if (!heights.held) throw RenderError("render: no height map was given (Renderer::set_maps)");
  if (needs.cone_sectors > 0) {
    const DeviceMap& map = cones[std::size_t(cone_slot(needs.cone_sectors))];
    const std::string wanted = std::to_string(needs.cone_sectors) + "-sector cone map";
    if (!map.held)
      throw RenderError(method + " needs a " + wanted + " (bake::BilinearBaker); none was given");
    if (needs.relaxed && !map.relaxed) {
      throw RenderError(method + " needs the " + wanted +
                        " with its relaxed ratios (bake::bake_relaxed); they were not given");
    }
    if (map.address != needs.cone_address) {
      throw RenderError(method + " needs a " + wanted + " baked with address " +
                        address_name(needs.cone_address) + "; the one given was baked with " +
                        address_name(map.address));
    }
  }
  if (needs.max_pyramid) {
    if (!max_pyramid.held)
      throw RenderError(method +
                        " needs the dual max pyramid (bake::build_dual_max_pyramid); none was given");
    if (max_pyramid.address != needs.address) {
      throw RenderError(method + " needs the max pyramid built with address " + address_name(needs.address) +
                        "; the one given was built with " + address_name(max_pyramid.address));
    }
  }
  if (needs.distance) {
    if (!distance.held)
      throw RenderError(method + " needs a distance map (bake::bake_distance_map); none was given");
    if (distance.address != needs.address) {
      throw RenderError(method + " needs a distance map baked with address " + address_name(needs.address) +
                        "; the one given was baked with " + address_name(distance.address));
    }
  }
}

}  // namespace displace::render
