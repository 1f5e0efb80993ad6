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

constexpr std::size_t level_texel_bytes = 16;  // the levels' height atlas: RGBA32F (pack_level)

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
  needs.levels = traces_levels(method, view);
  return needs;
}

bool traces_levels(Method method, const View& view) {
  const bool cone_method = method == Method::csm || method == Method::acm4 || method == Method::acm8 ||
                           method == Method::acm4_interval;
  return cone_method && view.unbounded && view.level != View::level_off;
}

namespace {

// How each map of a MapSet is brought up to date (take_maps).
struct MapCopies {
  Copy heights = Copy::none, foam = Copy::none;
  std::array<Copy, 3> cones{Copy::none, Copy::none, Copy::none};
  Copy pyramid = Copy::none, distance = Copy::none;
  Copy levels = Copy::none;  // none or whole: the chain changes as a whole
};

// The rectangles a copy writes: the dirty ones, the whole map, or none.
std::span<const bake::Rect> rects_of(Copy copy, std::span<const bake::Rect> dirty,
                                     std::span<const bake::Rect> whole_map) {
  return copy == Copy::rects ? dirty : (copy == Copy::whole ? whole_map : std::span<const bake::Rect>{});
}

// The cone maps' sizes and slots, checked before anything is made.
void validate_cone_sizes(const MapSet& maps) {
  const int width = maps.width, height = maps.height;
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
    if (given.device) continue;  // reshape_cones checks the DeviceCones
    if (given.ratios.size() != texels * std::size_t(given.sector_count) || given.apex.size() != texels ||
        !(given.relaxed.empty() || given.relaxed.size() == texels)) {
      throw RenderError(std::string("maps: the ") + name + " does not match the " + size_text(width, height) +
                        " heights (ratios, apex heights and relaxed ratios are per texel)");
    }
    check_rects(given.dirty, width, height, name);
  }
}

// The levels of detail: a chain the heights' sides halve into, with cone maps of one sector count.
void validate_levels(const MapSet& maps) {
  const int count = maps.level_count;
  if (count == 0 || maps.device_levels) return;  // a DeviceLevels': checked against it (reshape_levels)
  if (count < 0 || count > bake::max_detail_levels || maps.device_heights ||
      (maps.width >> count) << count != maps.width || (maps.height >> count) << count != maps.height ||
      (maps.width >> count) < 1 || (maps.height >> count) < 1 ||
      !bake::is_valid_sector_count(maps.level_sectors)) {
    throw RenderError("maps: " + std::to_string(count) + " levels of detail of " +
                      size_text(maps.width, maps.height) + " heights: at most " +
                      std::to_string(bake::max_detail_levels) +
                      " halvings of both sides, with cone maps of 1, 4 or 8 sectors, of heights on the host");
  }
  for (int level = 1; level <= count; ++level) {
    const MapSet::Level& given = maps.levels[std::size_t(level - 1)];
    const std::size_t texels = std::size_t(maps.width >> level) * std::size_t(maps.height >> level);
    if (given.heights.size() != texels || given.apex.size() != texels ||
        given.ratios.size() != texels * std::size_t(maps.level_sectors) ||
        (!given.slopes.empty() && given.slopes.size() != texels * 3)) {
      throw RenderError(
          "maps: level of detail " + std::to_string(level) + " must hold " +
          size_text(maps.width >> level, maps.height >> level) +
          " heights, apex heights and ratios per sector (and three slope moments a texel, or none)");
    }
  }
}

// Every map's size against the heights' and the device's limits; returns the max pyramid's bytes
// (header and values; 0 without one).
VkDeviceSize validate_map_sizes(const MapSet& maps, const DeviceInfo& device) {
  const int width = maps.width, height = maps.height;
  if (width < 1 || height < 1 || width > max_map_side || height > max_map_side ||
      (!maps.device_heights && maps.heights.size() != std::size_t(width) * std::size_t(height))) {
    throw RenderError("MapSet::width and MapSet::height must be between 1 and " +
                      std::to_string(max_map_side) + " texels, with one height per texel (got " +
                      size_text(width, height) + " and " + std::to_string(maps.heights.size()) + " heights)");
  }
  check_rects(maps.heights_dirty, width, height, "heights");
  if (!maps.foam.empty() && maps.foam.size() != std::size_t(width) * std::size_t(height)) {
    throw RenderError("maps: foam coverage must hold one value per texel of the " + size_text(width, height) +
                      " heights");
  }
  validate_cone_sizes(maps);
  validate_levels(maps);
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
    if (pyramid_bytes > device.max_storage_buffer_range) {
      throw RenderError("the max pyramid of a " + size_text(width, height) + " map needs " +
                        std::to_string(pyramid_bytes) + " bytes, more than this device's " +
                        std::to_string(device.max_storage_buffer_range) + "-byte storage buffers");
    }
  }
  const DistanceMapView& distance_view = maps.distance;
  if (distance_view.width != 0) {
    const int limit = device.max_image_dimension_3d;
    if (distance_view.width < 1 || distance_view.height < 1 || distance_view.depth < 1 ||
        distance_view.width > limit || distance_view.height > limit || distance_view.depth > limit ||
        distance_view.values.size() != std::size_t(distance_view.width) * std::size_t(distance_view.height) *
                                           std::size_t(distance_view.depth)) {
      throw RenderError("maps: the distance map must have 1 to " + std::to_string(limit) +
                        " voxels a side (this device's 3D images) and one value per voxel");
    }
  }
  return pyramid_bytes;
}

// Device images of the right shape, made again only when the shape changed; the first map made
// again waits for the frames in flight (once per take_maps).
struct Reshaper {
  Renderer::Impl& impl;
  bool drained = false;

  void drain_once() {
    if (drained) return;
    impl.drain();  // an earlier frame, or copies recorded for this one, may still use the old image
    drained = true;
  }
  // whether `map` is to be made again at this shape (its image is then still to be made)
  bool reshape(DeviceMap& map, int w, int h, int layers) {
    if (map.image.handle() && map.width == w && map.height == h && map.layers == layers) return false;
    if (map.image.handle() || map.buffer.handle()) drain_once();
    map.held = false;
    map.width = w;
    map.height = h;
    map.layers = layers;
    return true;
  }
  // a map's image: written by the host where the device shares its memory, else copied into
  void make_image(DeviceMap& map, VkFormat format, int w, int h, int layers, VkImageViewType view_type) {
    const auto image_width = std::uint32_t(w), image_height = std::uint32_t(h),
               image_layers = std::uint32_t(layers);
    Context& context = impl.context;
    map.general = false;
    map.image = impl.host_written_maps && context.host_images(format, image_width, image_height, image_layers)
                    ? Image::host_written(context, format, image_width, image_height, image_layers, view_type)
                    : Image();
    map.host_written = map.image.handle() != VK_NULL_HANDLE;
    if (!map.host_written) {
      map.image = Image(context, format, image_width, image_height, image_layers,
                        VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT,
                        VK_IMAGE_ASPECT_COLOR_BIT, view_type);
    }
  }
};

// heights and foam: what changes, and their images
void reshape_values(Reshaper& reshaper, const MapSet& maps, MapCopies& copies) {
  Renderer::Impl& impl = reshaper.impl;
  const int width = maps.width, height = maps.height;
  impl.device_heights = maps.device_heights;
  if (const DeviceHeightImages* device = maps.device_heights.get()) {
    if (device->owner != &impl.frames || device->heights == nullptr ||
        int(device->heights->width()) != width || int(device->heights->height()) != height) {
      impl.device_heights = nullptr;
      throw RenderError("maps: device_heights needs a DeviceSim of this renderer, alive, of " +
                        size_text(width, height) + " texels");
    }
    copies.heights = Copy::none;
    copies.foam = Copy::none;
    impl.foam.held = false;
    return;
  }
  copies.heights = copy_kind(impl.heights, impl.heights.width == width && impl.heights.height == height,
                             maps.heights_version, maps.heights_dirty_since, maps.heights_dirty.size());
  if (reshaper.reshape(impl.heights, width, height, 1))
    reshaper.make_image(impl.heights, VK_FORMAT_R32_SFLOAT, width, height, 1, VK_IMAGE_VIEW_TYPE_2D);
  DeviceMap& foam = impl.foam;
  if (!maps.foam.empty()) {
    copies.foam = copy_kind(foam, foam.width == width && foam.height == height, maps.foam_version, 0, 0);
    if (reshaper.reshape(foam, width, height, 1))
      reshaper.make_image(foam, VK_FORMAT_R32_SFLOAT, width, height, 1, VK_IMAGE_VIEW_TYPE_2D);
  } else {
    foam.held = false;
  }
}

// the cone maps: what changes, and their images (one layer per sector, and more: cone_layer_count)
void reshape_cones(Reshaper& reshaper, const MapSet& maps, MapCopies& copies) {
  const int width = maps.width, height = maps.height;
  for (std::size_t index = 0; index < reshaper.impl.cones.size(); ++index) {
    const ConeMapView& view = maps.cones[index];
    DeviceMap& map = reshaper.impl.cones[index];
    reshaper.impl.device_cones[index] = nullptr;
    if (view.sector_count == 0) {
      map.held = false;
      continue;
    }
    if (const DeviceConeImage* device = view.device.get()) {  // nothing to upload, the host's map is stale
      if (device->owner != &reshaper.impl.frames || device->image == nullptr || device->width != width ||
          device->height != height || device->sectors != view.sector_count) {
        throw RenderError(
            "maps: cones[" + std::to_string(index) + "].device needs a " + std::to_string(view.sector_count) +
            "-sector DeviceCones of this renderer, alive, of " + size_text(width, height) + " texels");
      }
      reshaper.impl.device_cones[index] = view.device;
      copies.cones[index] = Copy::none;
      map.held = false;
      continue;
    }
    const bool relaxed = !view.relaxed.empty();
    const int layers = cone_layer_count(view.sector_count, relaxed);
    const bool same = map.width == width && map.height == height && map.layers == layers &&
                      map.sectors == view.sector_count && map.relaxed == relaxed &&
                      map.address == view.address;
    copies.cones[index] = copy_kind(map, same, view.version, view.dirty_since, view.dirty.size());
    if (reshaper.reshape(map, width, height, layers)) {
      reshaper.make_image(map, cone_format, width, height, layers, VK_IMAGE_VIEW_TYPE_2D_ARRAY);
    }
    if (copies.cones[index] == Copy::whole) map.held = false;
    map.sectors = view.sector_count;
    map.relaxed = relaxed;
    map.address = view.address;
  }
}

// the levels of detail: what changes, and their atlases
void reshape_levels(Reshaper& reshaper, const MapSet& maps, MapCopies& copies) {
  Renderer::Impl& impl = reshaper.impl;
  DeviceMap& heights = impl.level_heights;
  DeviceMap& cones = impl.level_cones;
  impl.device_levels = nullptr;
  if (maps.level_count == 0) {
    heights.held = false;
    cones.held = false;
    impl.level_count = 0;
    return;
  }
  if (const DeviceLevelImages* device =
          maps.device_levels.get()) {  // nothing to upload, the host's are stale
    if (!maps.device_heights || device->owner != &impl.frames || device->heights == nullptr ||
        device->width != maps.width || device->height != maps.height || device->count != maps.level_count ||
        device->sectors != maps.level_sectors ||
        device->wrap != (maps.level_address == bake::Address::wrap)) {
      throw RenderError(
          "maps: device_levels needs device_heights and a DeviceLevels of this renderer, alive, of " +
          size_text(maps.width, maps.height) + " heights, with its level count, sector count and address");
    }
    heights.held = false;
    cones.held = false;
    copies.levels = Copy::none;
    impl.level_count = maps.level_count;
    impl.device_levels = maps.device_levels;
    return;
  }
  const glm::ivec2 atlas = level_atlas_size(maps.width, maps.height, maps.level_count);
  const int width = atlas.x, rows = atlas.y;
  const int layers = cone_layer_count(maps.level_sectors, false);
  const bool same = heights.width == width && heights.height == rows && cones.layers == layers &&
                    cones.sectors == maps.level_sectors && cones.address == maps.level_address &&
                    impl.level_count == maps.level_count;
  copies.levels = copy_kind(heights, same, maps.levels_version, 0, 0);
  if (reshaper.reshape(heights, width, rows, 1))
    reshaper.make_image(heights, VK_FORMAT_R32G32B32A32_SFLOAT, width, rows, 1, VK_IMAGE_VIEW_TYPE_2D);
  if (reshaper.reshape(cones, width, rows, layers))
    reshaper.make_image(cones, cone_format, width, rows, layers, VK_IMAGE_VIEW_TYPE_2D_ARRAY);
  if (copies.levels == Copy::whole) {
    heights.held = false;
    cones.held = false;
  }
  cones.sectors = maps.level_sectors;
  cones.address = maps.level_address;
  impl.level_count = maps.level_count;
}

// the max pyramid's buffer and the distance map's 3D image: what changes, and their memory
void reshape_pyramid_and_distance(Reshaper& reshaper, const MapSet& maps, VkDeviceSize pyramid_bytes,
                                  MapCopies& copies) {
  Renderer::Impl& impl = reshaper.impl;
  DeviceMap& max_pyramid = impl.max_pyramid;
  if (maps.max_pyramid.pyramid) {
    const int bytes = int(std::min<VkDeviceSize>(pyramid_bytes, 0x7fffffff));
    const bool same = max_pyramid.width == bytes && max_pyramid.address == maps.max_pyramid.address;
    copies.pyramid = copy_kind(max_pyramid, same, maps.max_pyramid.version, 0, 0);
    if (max_pyramid.width != bytes || !max_pyramid.buffer.handle()) {
      if (max_pyramid.buffer.handle()) reshaper.drain_once();
      max_pyramid.buffer = Buffer(impl.context, pyramid_bytes,
                                  VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                  VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
      max_pyramid.width = bytes;
      max_pyramid.held = false;
      copies.pyramid = Copy::whole;
    }
    max_pyramid.address = maps.max_pyramid.address;
  } else {
    max_pyramid.held = false;
  }
  const DistanceMapView& distance_view = maps.distance;
  DeviceMap& distance = impl.distance;
  if (distance_view.width != 0) {
    const bool same = distance.width == distance_view.width && distance.height == distance_view.height &&
                      distance.layers == distance_view.depth && distance.address == distance_view.address;
    copies.distance = copy_kind(distance, same, distance_view.version, 0, 0);
    if (reshaper.reshape(distance, distance_view.width, distance_view.height, distance_view.depth)) {
      distance.image = Image(impl.context, VK_FORMAT_R32_SFLOAT, std::uint32_t(distance_view.width),
                             std::uint32_t(distance_view.height), std::uint32_t(distance_view.depth),
                             VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT,
                             VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_VIEW_TYPE_3D);
    }
    distance.address = distance_view.address;
  } else {
    distance.held = false;
  }
}

// The staging bytes the copies need, and whether a host-written map changes (the host then waits
// for the frames that may read it).
VkDeviceSize staging_bytes(const Renderer::Impl& impl, const MapSet& maps, const MapCopies& copies,
                           VkDeviceSize pyramid_bytes, std::span<const bake::Rect> whole_map,
                           bool& host_writes) {
  VkDeviceSize bytes = 0;
  host_writes = false;
  if (impl.heights.host_written) {
    host_writes |= copies.heights != Copy::none;
  } else {
    for (const bake::Rect& rect : rects_of(copies.heights, maps.heights_dirty, whole_map))
      bytes += align_up(rect_texels(rect) * 4);
  }
  if (impl.foam.host_written) {
    host_writes |= copies.foam != Copy::none;
  } else if (copies.foam != Copy::none) {
    bytes += align_up(std::size_t(maps.width) * std::size_t(maps.height) * 4);
  }
  for (std::size_t index = 0; index < impl.cones.size(); ++index) {
    if (impl.cones[index].host_written) {
      host_writes |= copies.cones[index] != Copy::none;
      continue;
    }
    for (const bake::Rect& rect : rects_of(copies.cones[index], maps.cones[index].dirty, whole_map)) {
      bytes += align_up(rect_texels(rect) * cone_texel_bytes * VkDeviceSize(impl.cones[index].layers));
    }
  }
  if (copies.pyramid != Copy::none) bytes += align_up(pyramid_bytes);
  if (copies.distance != Copy::none) bytes += align_up(maps.distance.values.size() * sizeof(float));
  if (copies.levels != Copy::none) {
    host_writes |= impl.level_heights.host_written || impl.level_cones.host_written;
    for (int level = 1; level <= maps.level_count; ++level) {
      const VkDeviceSize texels = VkDeviceSize(maps.width >> level) * VkDeviceSize(maps.height >> level);
      if (!impl.level_heights.host_written) bytes += align_up(texels * level_texel_bytes);
      if (!impl.level_cones.host_written)
        bytes += align_up(texels * cone_texel_bytes * VkDeviceSize(impl.level_cones.layers));
    }
  }
  return bytes;
}

// Where this take_maps' copies go: the current slot's staging and command buffer.
struct Upload {
  FrameSlot* frame_slot = nullptr;
  std::byte* staging = nullptr;
  VkCommandBuffer commands = VK_NULL_HANDLE;
  int width = 0;  // of the maps
  std::span<const bake::Rect> whole_map;
  std::vector<VkBufferImageCopy>& regions;  // Renderer::Impl::copy_regions, reused

  VkDeviceSize reserve(VkDeviceSize size) {
    const VkDeviceSize offset = frame_slot->staging_used;
    frame_slot->staging_used += align_up(size);
    return offset;
  }
  // a host-written image made this time: to GENERAL layout before the frame's shaders read it (the
  // host's writes before the submission are visible to it without a barrier of their own)
  void to_general(DeviceMap& map, std::uint32_t layers) const {
    if (map.general) return;
    image_barrier(commands, map.image.handle(), layers, VK_IMAGE_LAYOUT_PREINITIALIZED,
                  VK_IMAGE_LAYOUT_GENERAL, VK_ACCESS_HOST_WRITE_BIT, VK_ACCESS_SHADER_READ_BIT,
                  VK_PIPELINE_STAGE_HOST_BIT,
                  VK_PIPELINE_STAGE_VERTEX_SHADER_BIT | VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT);
    map.general = true;
  }
  // the regions gathered, copied into `map` between its barriers
  void copy_regions_into(DeviceMap& map, std::uint32_t layers, bool fresh) const {
    to_transfer(commands, map, layers, fresh);
    if (!regions.empty()) {
      vkCmdCopyBufferToImage(commands, frame_slot->staging.handle(), map.image.handle(),
                             VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, std::uint32_t(regions.size()),
                             regions.data());
    }
    to_shader(commands, map, layers);
  }
};

VkBufferImageCopy rect_region(VkDeviceSize offset, const bake::Rect& rect, std::uint32_t layers) {
  VkBufferImageCopy region{};
  region.bufferOffset = offset;
  region.bufferRowLength = std::uint32_t(rect.x1 - rect.x0);
  region.bufferImageHeight = std::uint32_t(rect.y1 - rect.y0);
  region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, layers};
  region.imageOffset = {rect.x0, rect.y0, 0};
  region.imageExtent = {std::uint32_t(rect.x1 - rect.x0), std::uint32_t(rect.y1 - rect.y0), 1};
  return region;
}

// heights and foam: one R32F value per texel in [0, 1]
void upload_values(Upload& upload, DeviceMap& map, Copy copy, std::span<const float> values,
                   std::span<const bake::Rect> dirty, std::uint64_t version, const char* what) {
  if (copy == Copy::none) return;
  const bool fresh = !map.held;
  map.held = false;
  if (map.host_written) {
    for (const bake::Rect& rect : rects_of(copy, dirty, upload.whole_map)) {
      if (rect_texels(rect) == 0) continue;
      if (!detail::pack_heights(values, upload.width, rect, texel_of(map, rect.x0, rect.y0, 4),
                                map.image.row_pitch() / 4)) {
        throw RenderError(std::string("maps: ") + what + " must be finite and in [0, 1]");
      }
    }
    upload.to_general(map, 1);
    map.held = true;
    map.version = version;
    return;
  }
  upload.regions.clear();
  for (const bake::Rect& rect : rects_of(copy, dirty, upload.whole_map)) {
    if (rect_texels(rect) == 0) continue;
    const VkDeviceSize offset = upload.reserve(rect_texels(rect) * 4);
    if (!detail::pack_heights(values, upload.width, rect, reinterpret_cast<float*>(upload.staging + offset),
                              std::size_t(rect.x1 - rect.x0))) {
      throw RenderError(std::string("maps: ") + what + " must be finite and in [0, 1]");
    }
    upload.regions.push_back(rect_region(offset, rect, 1));
  }
  upload.copy_regions_into(map, 1, fresh);
  map.held = true;
  map.version = version;
}

// a cone map: every layer of a rectangle in one region (layer after layer in the staging)
void upload_cones(Upload& upload, DeviceMap& map, Copy copy, const ConeMapView& view) {
  if (copy == Copy::none) return;
  const bool fresh = !map.held;
  map.held = false;
  auto invalid = [&] {  // made only when thrown: a frame builds no strings
    return RenderError(
        "maps: the " + std::to_string(view.sector_count) +
        "-sector cone map holds a negative or non-finite ratio or an apex height outside [0, 1]");
  };
  if (map.host_written) {
    for (const bake::Rect& rect : rects_of(copy, view.dirty, upload.whole_map)) {
      if (rect_texels(rect) == 0) continue;
      auto* origin = reinterpret_cast<std::uint16_t*>(texel_of(map, rect.x0, rect.y0, cone_texel_bytes));
      if (!detail::pack_cones(view, upload.width, rect, origin, map.image.row_pitch() / 2,
                              map.image.layer_pitch() / 2)) {
        throw invalid();
      }
    }
    upload.to_general(map, std::uint32_t(map.layers));
    map.held = true;
    map.version = view.version;
    return;
  }
  upload.regions.clear();
  for (const bake::Rect& rect : rects_of(copy, view.dirty, upload.whole_map)) {
    if (rect_texels(rect) == 0) continue;
    const VkDeviceSize offset =
        upload.reserve(rect_texels(rect) * cone_texel_bytes * VkDeviceSize(map.layers));
    if (!detail::pack_cones(view, upload.width, rect,
                            reinterpret_cast<std::uint16_t*>(upload.staging + offset),
                            std::size_t(rect.x1 - rect.x0) * 2, std::size_t(rect_texels(rect)) * 2)) {
      throw invalid();
    }
    upload.regions.push_back(rect_region(offset, rect, std::uint32_t(map.layers)));
  }
  upload.copy_regions_into(map, std::uint32_t(map.layers), fresh);
  map.held = true;
  map.version = view.version;
}

// One level's texels as the height atlas holds them (RGBA32F): the height, then its slope moments
// (MapSet::Level::slopes; zeros without them). False for a height outside [0, 1] or a moment that
// is not finite.
bool pack_level(const MapSet::Level& level, int width, int height, float* out, std::size_t row_floats) {
  bool valid = true;
  for (int y = 0; y < height; ++y) {
    float* to = out + std::size_t(y) * row_floats;
    for (int x = 0; x < width; ++x, to += 4) {
      const std::size_t texel = std::size_t(y) * std::size_t(width) + std::size_t(x);
      const float h = level.heights[texel];
      valid &= h >= 0.0f && h <= 1.0f;  // false for NaN
      to[0] = h;
      for (int c = 0; c < 3; ++c) {
        const float m = level.slopes.empty() ? 0.0f : level.slopes[texel * 3 + std::size_t(c)];
        valid &= std::isfinite(m);
        to[1 + c] = m;
      }
    }
  }
  return valid;
}

// the levels of detail: each level's heights, then each level's cones, packed into its rows of the
// atlases
void upload_levels(Upload& upload, DeviceMap& heights, DeviceMap& cones, const MapSet& maps,
                   std::array<float, bake::max_detail_levels>& tops) {
  const bool fresh_heights = !heights.held, fresh_cones = !cones.held;
  heights.held = false;
  cones.held = false;
  const auto layers = std::uint32_t(cones.layers);
  auto level_rect = [&](int level) { return bake::Rect{0, 0, maps.width >> level, maps.height >> level}; };
  auto atlas_rect = [&](int level) {
    const glm::ivec2 origin = level_atlas_origin(maps.width, maps.height, level);
    return bake::Rect{origin.x, origin.y, origin.x + (maps.width >> level),
                      origin.y + (maps.height >> level)};
  };
  upload.regions.clear();
  for (int level = 1; level <= maps.level_count; ++level) {
    const MapSet::Level& given = maps.levels[std::size_t(level - 1)];
    const bake::Rect rect = level_rect(level);
    bool valid = true;
    if (heights.host_written) {
      valid = pack_level(given, rect.x1, rect.y1,
                         texel_of(heights, atlas_rect(level).x0, atlas_rect(level).y0, level_texel_bytes),
                         heights.image.row_pitch() / 4);
    } else {
      const VkDeviceSize offset = upload.reserve(rect_texels(rect) * level_texel_bytes);
      valid = pack_level(given, rect.x1, rect.y1, reinterpret_cast<float*>(upload.staging + offset),
                         std::size_t(rect.x1) * 4);
      upload.regions.push_back(rect_region(offset, atlas_rect(level), 1));
    }
    if (!valid) {
      throw RenderError("maps: the heights of level of detail " + std::to_string(level) +
                        " must be finite and in [0, 1], and its slope moments finite");
    }
    const std::span<const float> values = given.heights;
    tops[std::size_t(level - 1)] = *std::max_element(values.begin(), values.end());
  }
  if (heights.host_written) {
    upload.to_general(heights, 1);
  } else {
    upload.copy_regions_into(heights, 1, fresh_heights);
  }
  upload.regions.clear();
  for (int level = 1; level <= maps.level_count; ++level) {
    const MapSet::Level& given = maps.levels[std::size_t(level - 1)];
    ConeMapView view;
    view.sector_count = maps.level_sectors;
    view.address = maps.level_address;
    view.ratios = given.ratios;
    view.apex = given.apex;
    const bake::Rect rect = level_rect(level);
    bool valid = true;
    if (cones.host_written) {
      auto* origin = reinterpret_cast<std::uint16_t*>(
          texel_of(cones, atlas_rect(level).x0, atlas_rect(level).y0, cone_texel_bytes));
      valid = detail::pack_cones(view, rect.x1, rect, origin, cones.image.row_pitch() / 2,
                                 cones.image.layer_pitch() / 2);
    } else {
      const VkDeviceSize offset = upload.reserve(rect_texels(rect) * cone_texel_bytes * layers);
      valid =
          detail::pack_cones(view, rect.x1, rect, reinterpret_cast<std::uint16_t*>(upload.staging + offset),
                             std::size_t(rect.x1) * 2, std::size_t(rect_texels(rect)) * 2);
      upload.regions.push_back(rect_region(offset, atlas_rect(level), layers));
    }
    if (!valid) {
      throw RenderError("maps: the cone map of level of detail " + std::to_string(level) +
                        " holds a negative or non-finite ratio or an apex height outside [0, 1]");
    }
  }
  if (cones.host_written) {
    upload.to_general(cones, layers);
  } else {
    upload.copy_regions_into(cones, layers, fresh_cones);
  }
  heights.held = cones.held = true;
  heights.version = cones.version = maps.levels_version;
}

// the max pyramid: header and values, as the shader reads them at BINDING_MAX_PYRAMID
void upload_pyramid(Upload& upload, DeviceMap& max_pyramid, const MaxPyramidView& view,
                    VkDeviceSize pyramid_bytes) {
  const bake::DualMaxPyramid* pyramid = view.pyramid;
  max_pyramid.held = false;
  const VkDeviceSize offset = upload.reserve(pyramid_bytes);
  gpu::MaxPyramidHeader header{};
  const std::size_t levels = pyramid->widths.size();
  header.shape = glm::ivec4(int(levels), pyramid->origin, 0, 0);
  for (std::size_t level = 0; level < levels; ++level) {
    header.levels[level] =
        glm::ivec4(int(pyramid->offsets[level]), pyramid->widths[level], pyramid->heights[level], 0);
  }
  std::memcpy(upload.staging + offset, &header, sizeof header);
  std::memcpy(upload.staging + offset + sizeof header, pyramid->values.data(),
              pyramid->values.size() * sizeof(float));
  const VkCommandBuffer commands = upload.commands;
  VkBufferMemoryBarrier barrier{VK_STRUCTURE_TYPE_BUFFER_MEMORY_BARRIER};
  barrier.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  barrier.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  barrier.buffer = max_pyramid.buffer.handle();
  barrier.size = VK_WHOLE_SIZE;
  barrier.dstAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
  vkCmdPipelineBarrier(commands, VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 0,
                       nullptr, 1, &barrier, 0, nullptr);
  const VkBufferCopy region{offset, 0, pyramid_bytes};
  vkCmdCopyBuffer(commands, upload.frame_slot->staging.handle(), max_pyramid.buffer.handle(), 1, &region);
  barrier.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
  barrier.dstAccessMask = VK_ACCESS_SHADER_READ_BIT;
  vkCmdPipelineBarrier(commands, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT, 0, 0,
                       nullptr, 1, &barrier, 0, nullptr);
  max_pyramid.held = true;
  max_pyramid.version = view.version;
}

// the distance map (3D)
void upload_distance(Upload& upload, DeviceMap& distance, const DistanceMapView& view) {
  const bool fresh = !distance.held;
  distance.held = false;
  const VkDeviceSize offset = upload.reserve(view.values.size() * sizeof(float));
  float* out = reinterpret_cast<float*>(upload.staging + offset);
  bool valid = true;
  for (std::size_t v = 0; v < view.values.size(); ++v) {
    const float value = view.values[v];
    valid &= value >= 0.0f && value <= 1e30f;
    out[v] = value;
  }
  if (!valid) throw RenderError("maps: the distance map holds a negative or non-finite distance");
  to_transfer(upload.commands, distance, 1, fresh);
  VkBufferImageCopy region{};
  region.bufferOffset = offset;
  region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
  region.imageExtent = {std::uint32_t(view.width), std::uint32_t(view.height), std::uint32_t(view.depth)};
  vkCmdCopyBufferToImage(upload.commands, upload.frame_slot->staging.handle(), distance.image.handle(),
                         VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &region);
  to_shader(upload.commands, distance, 1);
  distance.held = true;
  distance.version = view.version;
}

}  // namespace

void Renderer::Impl::take_maps(const MapSet& maps) {
  const VkDeviceSize pyramid_bytes = validate_map_sizes(maps, context.info());
  check_map_memory(maps);

  // what changes, and device images of the right shape (made again only when the shape changed)
  Reshaper reshaper{*this};
  map_width = maps.width;
  map_height = maps.height;
  MapCopies copies;
  reshape_values(reshaper, maps, copies);
  reshape_cones(reshaper, maps, copies);
  reshape_pyramid_and_distance(reshaper, maps, pyramid_bytes, copies);
  reshape_levels(reshaper, maps, copies);

  // staging bytes, then room in the current slot's part of the ring
  const bake::Rect whole{0, 0, maps.width, maps.height};
  const std::span<const bake::Rect> whole_map(&whole, 1);
  bool host_writes = false;  // a host-written map changes: wait for the frames that may read it
  const VkDeviceSize bytes = staging_bytes(*this, maps, copies, pyramid_bytes, whole_map, host_writes);
  if (bytes == 0 && !host_writes) return;
  if (host_writes) frames.wait_submitted();
  FrameSlot* frame_slot = &begin_slot();
  if (bytes > 0 && frame_slot->staging_used + bytes > frame_slot->staging.size()) {
    if (frame_slot->staging_used > 0) {  // copies already recorded read the old buffer: send them first
      submit_slot(true);
      frame_slot = &begin_slot();
    }
    frame_slot->staging = Buffer(context, bytes, VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                                 VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
  }

  // pack and record the copies
  Upload upload{frame_slot,     static_cast<std::byte*>(frame_slot->staging.mapped()),
                frames.begin(), maps.width,
                whole_map,      copy_regions};
  upload_values(upload, heights, copies.heights, maps.heights, maps.heights_dirty, maps.heights_version,
                "heights");
  upload_values(upload, foam, copies.foam, maps.foam, {}, maps.foam_version, "foam coverage");
  for (std::size_t index = 0; index < cones.size(); ++index)
    upload_cones(upload, cones[index], copies.cones[index], maps.cones[index]);
  if (copies.pyramid != Copy::none) upload_pyramid(upload, max_pyramid, maps.max_pyramid, pyramid_bytes);
  if (copies.distance != Copy::none) upload_distance(upload, distance, maps.distance);
  if (copies.levels != Copy::none) upload_levels(upload, level_heights, level_cones, maps, level_tops);
}

int Renderer::Impl::traced_levels(const View& view, const MethodInfo& info) const {
  if (!traces_levels(info.method, view) || level_count == 0) return 0;
  if (device_levels) {
    return device_levels->sectors == info.cone_sectors && device_levels->wrap ? level_count : 0;
  }
  if (device_heights || !level_heights.held || !level_cones.held ||
      level_cones.sectors != info.cone_sectors || level_cones.address != bake::Address::wrap)
    return 0;
  return level_count;
}

void Renderer::Impl::check_device_maps_alive() const {
  if (device_heights && device_heights->heights == nullptr)
    throw RenderError("render: the DeviceSim whose heights the maps name is gone");
  for (const std::shared_ptr<const DeviceConeImage>& device : device_cones) {
    if (device && device->image == nullptr)
      throw RenderError("render: the DeviceCones whose cone map the maps name is gone");
  }
  if (device_levels && device_levels->heights == nullptr)
    throw RenderError("render: the DeviceLevels whose levels the maps name is gone");
}

void Renderer::Impl::require_maps(const MapNeeds& needs, const MethodInfo& info) const {
  const std::string method = std::string("MethodSettings::method ") + info.name;
  if (!heights.held && !device_heights)
    throw RenderError("render: no height map was given (Renderer::set_maps)");
  check_device_maps_alive();
  if (needs.cone_sectors > 0 && device_cones[std::size_t(cone_slot(needs.cone_sectors))]) {
    const DeviceConeImage& device = *device_cones[std::size_t(cone_slot(needs.cone_sectors))];
    const std::string wanted = std::to_string(needs.cone_sectors) + "-sector cone map";
    if (needs.relaxed)
      throw RenderError(method + " needs the " + wanted + " with its relaxed ratios; DeviceCones makes none");
    const bake::Address baked = device.wrap ? bake::Address::wrap : bake::Address::clamp;
    if (baked != needs.cone_address) {
      throw RenderError(method + " needs a " + wanted + " baked with address " +
                        address_name(needs.cone_address) + "; the DeviceCones bakes with " +
                        address_name(baked));
    }
  } else if (needs.cone_sectors > 0) {
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
