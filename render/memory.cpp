// render/memory.cpp - the memory guards: what the renderer allocates, estimated before it does, and
// the check that refuses work that cannot fit (render.h, "Memory guards").
//
// The one fact to know: the estimates follow the renderer's own allocations byte for byte where the
// bytes are known (targets, readback buffers, map images, staging, the plane reference's
// tessellation) and bound them from above where they are not (a mesh reference, capped at
// max_mesh_reference_vertices). Vulkan may round an allocation up to its alignment; the guard is
// about gigabytes, not those few bytes.
#include <algorithm>
#include <cinttypes>
#include <cstdio>
#include <string>

#include "render/renderer_impl.h"
#include "render/shaders/config.h"

namespace displace::render {
namespace {

// bytes per pixel of each render target and readback (renderer_impl.h's formats)
constexpr std::uint64_t color_bytes = 4;     // RGBA8
constexpr std::uint64_t hit_bytes = 16;      // RGBA32F: u, v, hit, depth
constexpr std::uint64_t counters_bytes = 8;  // RG32F: iterations, fetches
constexpr std::uint64_t depth_bytes = 4;     // D32F
// bytes per texel of each map on the device
constexpr std::uint64_t height_texel_bytes = 4;                     // R32F
constexpr std::uint64_t cone_layer_texel_bytes = cone_texel_bytes;  // RG16UI: (ratio, apex) per layer
constexpr std::uint64_t plane_vertex_bytes = 8;                     // (u, v) floats
constexpr std::uint64_t triangle_bytes = 12;                        // three 32-bit indices
// a mesh reference's triangles per vertex at most (n^2 triangles over (n + 1)(n + 2) / 2 vertices)
constexpr std::uint64_t mesh_triangles_per_vertex = 2;

std::string size_text(std::uint64_t width, std::uint64_t height) {
  return std::to_string(width) + " x " + std::to_string(height);
}

std::uint64_t pixels_of(int width, int height) {
  return std::uint64_t(std::max(width, 0)) * std::uint64_t(std::max(height, 0));
}

const char* pool_name(MemoryKind kind, const MemoryLimits& limits) {
  if (limits.device.empty() || limits.device_is_host || kind == MemoryKind::host) return "host memory";
  return kind == MemoryKind::device_local || limits.shared_heap ? "device memory"
                                                                : "host-visible device memory";
}

// The bytes behind one item of frame_memory: the reference's tessellation on the plane.
struct PlaneTessellation {
  std::uint64_t vertices = 0, triangles = 0;
};
PlaneTessellation plane_tessellation(int map_width, int map_height, int tile) {
  const std::uint64_t columns = std::uint64_t(map_width) * std::uint64_t(tile) + 2;
  const std::uint64_t rows = std::uint64_t(map_height) * std::uint64_t(tile) + 2;
  return {columns * rows, (columns - 1) * (rows - 1) * 2};
}

// Bytes as text with `decimals` more digits than usual, so that two amounts that differ can be told apart.
std::string amount(std::uint64_t bytes, int decimals) {
  char text[40];
  if (bytes >= 1000000000ull) {
    std::snprintf(text, sizeof text, "%.*f GB", (bytes >= 10000000000ull ? 1 : 2) + decimals,
                  double(bytes) / 1e9);
  } else if (bytes >= 1000000ull) {
    std::snprintf(text, sizeof text, "%.*f MB", decimals, double(bytes) / 1e6);
  } else {
    std::snprintf(text, sizeof text, "%.*f kB", decimals, double(bytes) / 1e3);
  }
  return text;
}

}  // namespace

std::string memory_text(std::uint64_t bytes) { return amount(bytes, 0); }

void check_memory(std::span<const Allocation> allocations, const MemoryLimits& limits) {
  const std::string limited = limits.limited_by.empty() ? std::string() : " (" + limits.limited_by + ")";
  // each Vulkan allocation on its own
  for (const Allocation& allocation : allocations) {
    if (allocation.kind == MemoryKind::host || limits.max_allocation == 0) continue;
    if (allocation.bytes > limits.max_allocation) {
      int decimals = 0;  // enough to tell the two apart
      while (decimals < 3 && amount(allocation.bytes, decimals) == amount(limits.max_allocation, decimals))
        ++decimals;
      throw RenderError(allocation.what + " needs one allocation of " + amount(allocation.bytes, decimals) +
                        "; " + limits.device + " allows at most " + amount(limits.max_allocation, decimals) +
                        " in one: lower " + allocation.lower);
    }
  }

  // the sums, per memory the allocations come from
  struct Pool {
    std::uint64_t available = 0;
    std::uint64_t needed = 0;
    const Allocation* largest = nullptr;
  };
  const bool one_pool = limits.device.empty() || limits.device_is_host;
  Pool host{limits.host}, device{limits.device_local}, host_visible{limits.host_visible};
  for (const Allocation& allocation : allocations) {
    Pool& pool = one_pool || allocation.kind == MemoryKind::host                     ? host
                 : allocation.kind == MemoryKind::device_local || limits.shared_heap ? device
                                                                                     : host_visible;
    pool.needed += allocation.bytes;
    if (!pool.largest || allocation.bytes > pool.largest->bytes) pool.largest = &allocation;
  }
  for (const Pool* pool : {&host, &device, &host_visible}) {
    if (pool->needed <= pool->available) continue;
    const Allocation& largest = *pool->largest;
    const bool alone = largest.bytes == pool->needed;
    const bool lowered = pool == &host && !limited.empty();
    throw RenderError(largest.what + " needs " + memory_text(largest.bytes) +
                      (alone ? std::string() : " (" + memory_text(pool->needed) + " with the rest)") +
                      " of " + pool_name(largest.kind, limits) + "; " + memory_text(pool->available) +
                      (pool == &host ? " is available" : " is all " + limits.device + " has") +
                      (lowered ? limited : std::string()) + ": lower " + largest.lower);
  }
}

void add_target_memory(std::vector<Allocation>& list, int width, int height) {
  const std::uint64_t pixels = pixels_of(width, height);
  const std::string frame = " of a " + size_text(std::uint64_t(width), std::uint64_t(height)) + " frame";
  list.push_back(
      {"the colour target" + frame, pixels * color_bytes, MemoryKind::device_local, lower_frame_size});
  list.push_back({"the hit target" + frame, pixels * hit_bytes, MemoryKind::device_local, lower_frame_size});
  list.push_back(
      {"the counter target" + frame, pixels * counters_bytes, MemoryKind::device_local, lower_frame_size});
  list.push_back(
      {"the depth buffer" + frame, pixels * depth_bytes, MemoryKind::device_local, lower_frame_size});
}

void add_readback_memory(std::vector<Allocation>& list, int width, int height, unsigned outputs) {
  const std::uint64_t pixels = pixels_of(width, height);
  const std::string frame = " of a " + size_text(std::uint64_t(width), std::uint64_t(height)) + " frame";
  if (outputs & output_color) {
    list.push_back(
        {"the colour readback" + frame, pixels * color_bytes, MemoryKind::host_visible, lower_frame_size});
  }
  if (outputs & (output_uv | output_depth)) {
    list.push_back(
        {"the hit readback" + frame, pixels * hit_bytes, MemoryKind::host_visible, lower_frame_size});
  }
  if (outputs & (output_iterations | output_fetches)) {
    list.push_back({"the counter readback" + frame, pixels * counters_bytes, MemoryKind::host_visible,
                    lower_frame_size});
  }
}

void add_frame_vector_memory(std::vector<Allocation>& list, int width, int height, unsigned outputs) {
  const std::uint64_t pixels = pixels_of(width, height);
  // Frame's vectors: colour 4 bytes, uv 3 floats, depth, iterations and fetches 1 float each
  std::uint64_t bytes = 0;
  if (outputs & output_color) bytes += pixels * color_bytes;
  if (outputs & output_uv) bytes += pixels * 12;
  if (outputs & output_depth) bytes += pixels * 4;
  if (outputs & output_iterations) bytes += pixels * 4;
  if (outputs & output_fetches) bytes += pixels * 4;
  if (bytes == 0) return;
  list.push_back(
      {"the pixels read back from a " + size_text(std::uint64_t(width), std::uint64_t(height)) + " frame",
       bytes, MemoryKind::host, lower_frame_size});
}

void add_reference_memory(std::vector<Allocation>& list, const View& view, int map_width, int map_height) {
  if (view.surface == Surface::mesh) {
    // at most max_mesh_reference_vertices (mesh_reference's cap), whatever the mesh and map
    const std::uint64_t vertices = std::uint64_t(max_mesh_reference_vertices);
    const std::uint64_t vertex_bytes = vertices * sizeof(MeshVertex);
    const std::uint64_t index_bytes = vertices * mesh_triangles_per_vertex * triangle_bytes;
    list.push_back({"the reference's tessellation of the mesh", vertex_bytes + index_bytes, MemoryKind::host,
                    lower_map_size});
    list.push_back({"the reference's vertex buffer", vertex_bytes, MemoryKind::host_visible, lower_map_size});
    list.push_back({"the reference's index buffer", index_bytes, MemoryKind::host_visible, lower_map_size});
    return;
  }
  const PlaneTessellation mesh = plane_tessellation(map_width, map_height, view.tile);
  const std::string what = "the reference's tessellation of a " +
                           size_text(std::uint64_t(map_width), std::uint64_t(map_height)) + " map" +
                           (view.tile > 1 ? " tiled " + std::to_string(view.tile) + " times" : std::string());
  const std::string lower = view.tile > 1 ? lower_tile_or_map_size : lower_map_size;
  if (mesh.vertices > std::uint64_t(UINT32_MAX)) {
    throw RenderError(what + " would have " + std::to_string(mesh.vertices) +
                      " vertices, more than 32-bit indices address: lower " + lower);
  }
  const std::uint64_t vertex_bytes = mesh.vertices * plane_vertex_bytes,
                      index_bytes = mesh.triangles * triangle_bytes;
  list.push_back({what, vertex_bytes + index_bytes, MemoryKind::host, lower});
  list.push_back({"the vertex buffer of " + what, vertex_bytes, MemoryKind::host_visible, lower});
  list.push_back({"the index buffer of " + what, index_bytes, MemoryKind::host_visible, lower});
}

std::vector<Allocation> map_memory(const MapShape& shape) {
  std::vector<Allocation> list;
  const std::uint64_t texels = pixels_of(shape.width, shape.height);
  const std::string map =
      " of a " + size_text(std::uint64_t(shape.width), std::uint64_t(shape.height)) + " map";
  std::uint64_t staging = 0;
  auto add = [&](std::string what, std::uint64_t bytes) {
    list.push_back({std::move(what), bytes, MemoryKind::device_local, lower_map_size});
    staging += bytes;
  };
  add("the height image" + map, texels * height_texel_bytes);
  if (shape.foam) add("the foam image" + map, texels * height_texel_bytes);
  if (shape.cone_sectors > 0) {
    const std::uint64_t layers = std::uint64_t(cone_layer_count(shape.cone_sectors, shape.relaxed));
    add("the " + std::to_string(shape.cone_sectors) + "-sector cone image" + map,
        texels * layers * cone_layer_texel_bytes);
  }
  if (shape.max_pyramid_values > 0) {
    add("the max pyramid" + map, sizeof(gpu::MaxPyramidHeader) + shape.max_pyramid_values * sizeof(float));
  }
  if (shape.distance_depth > 0) {
    add("the distance map" + map, pixels_of(shape.distance_width, shape.distance_height) *
                                      std::uint64_t(shape.distance_depth) * sizeof(float));
  }
  if (shape.level_count > 0) {  // the atlases of levels 1 .. L (config.h)
    const glm::ivec2 size = level_atlas_size(shape.width, shape.height, shape.level_count);
    const std::uint64_t atlas = pixels_of(size.x, size.y);
    add("the levels of detail's height atlas" + map, atlas * 4 * height_texel_bytes);  // RGBA32F
    add("the levels of detail's cone atlas" + map,
        atlas * std::uint64_t(cone_layer_count(std::max(shape.level_sectors, 1), false)) *
            cone_layer_texel_bytes);
  }
  list.push_back({"the staging of the maps" + map, staging, MemoryKind::host_visible, lower_map_size});
  return list;
}

std::vector<Allocation> frame_memory(const View& view, const MethodSettings& method, int map_width,
                                     int map_height, unsigned outputs, bool with_reference) {
  std::vector<Allocation> list;
  const int width = view.camera.width, height = view.camera.height;
  add_target_memory(list, width, height);
  const int frames = with_reference ? 2 : 1;  // each in its own frame slot, with its own readback
  for (int frame = 0; frame < frames; ++frame) {
    add_readback_memory(list, width, height, outputs);
    add_frame_vector_memory(list, width, height, outputs);
  }
  if (method.method == Method::reference || with_reference)
    add_reference_memory(list, view, map_width, map_height);
  return list;
}

void Renderer::Impl::check_frame_memory(const View& view, const MethodInfo& info, const Frame& frame,
                                        unsigned outputs) const {
  // what this frame makes that is not made yet (nothing, once a size has been rendered)
  const int width = view.camera.width, height = view.camera.height;
  const std::size_t pixels = std::size_t(pixels_of(width, height));
  const bool new_targets = targets.width != width || targets.height != height;
  const FrameSlot& next = slots[std::size_t(frames.slot())];
  const bool same_readback = next.readback_width == width && next.readback_height == height;
  unsigned new_readback = 0;
  if ((outputs & output_color) && !(same_readback && next.color_readback.handle()))
    new_readback |= output_color;
  if ((outputs & (output_uv | output_depth)) && !(same_readback && next.hit_readback.handle()))
    new_readback |= output_uv;
  if ((outputs & (output_iterations | output_fetches)) &&
      !(same_readback && next.counters_readback.handle())) {
    new_readback |= output_iterations;
  }
  unsigned growing = 0;  // outputs whose vector in the caller's Frame grows
  if ((outputs & output_color) && frame.color.capacity() < pixels * 4) growing |= output_color;
  if ((outputs & output_uv) && frame.uv.capacity() < pixels * 3) growing |= output_uv;
  if ((outputs & output_depth) && frame.depth.capacity() < pixels) growing |= output_depth;
  if ((outputs & output_iterations) && frame.iterations.capacity() < pixels) growing |= output_iterations;
  if ((outputs & output_fetches) && frame.fetches.capacity() < pixels) growing |= output_fetches;
  bool new_reference = false;
  if (info.family == MethodFamily::reference) {
    const std::array<int, 3> key{view.tile, map_width, map_height};
    new_reference = view.surface == Surface::mesh
                        ? mesh_reference_key != key || !mesh_reference_vertices.handle()
                        : reference_key != key || !reference_vertices.handle();
  }
  if (!new_targets && new_readback == 0 && growing == 0 && !new_reference) return;

  std::vector<Allocation> needed;
  if (new_targets) add_target_memory(needed, width, height);
  add_readback_memory(needed, width, height, new_readback);
  add_frame_vector_memory(needed, width, height, growing);
  if (new_reference) add_reference_memory(needed, view, map_width, map_height);
  check_memory(needed, memory_limits());
}

void Renderer::Impl::check_map_memory(const MapSet& maps) const {
  // only when a map is made again (a new shape); the staging of a whole upload comes with it
  MapShape shape;
  shape.width = maps.width;
  shape.height = maps.height;
  shape.foam = !maps.foam.empty();
  bool reshaped =
      heights.width != maps.width || heights.height != maps.height || !heights.image.handle() ||
      (shape.foam && (foam.width != maps.width || foam.height != maps.height || !foam.image.handle()));
  for (std::size_t index = 0; index < maps.cones.size(); ++index) {
    const ConeMapView& view = maps.cones[index];
    if (view.sector_count == 0 || view.device) continue;  // a DeviceCones' image: made with it
    const DeviceMap& held = cones[index];
    const int layers = cone_layer_count(view.sector_count, !view.relaxed.empty());
    reshaped |= held.width != maps.width || held.height != maps.height || held.layers != layers ||
                !held.image.handle();
    if (view.sector_count > shape.cone_sectors) {  // the largest cone map stands for them all
      shape.cone_sectors = view.sector_count;
      shape.relaxed = !view.relaxed.empty();
    }
  }
  if (maps.max_pyramid.pyramid) {
    shape.max_pyramid_values = maps.max_pyramid.pyramid->values.size();
    reshaped |= !max_pyramid.buffer.handle();
  }
  if (maps.distance.width != 0) {
    shape.distance_width = maps.distance.width;
    shape.distance_height = maps.distance.height;
    shape.distance_depth = maps.distance.depth;
    reshaped |= distance.width != maps.distance.width || distance.height != maps.distance.height ||
                distance.layers != maps.distance.depth || !distance.image.handle();
  }
  if (maps.level_count > 0 && !maps.device_levels) {  // a DeviceLevels' atlases are made with it
    shape.level_count = maps.level_count;
    shape.level_sectors = maps.level_sectors;
    reshaped |= level_heights.width != level_atlas_size(maps.width, maps.height, maps.level_count).x ||
                level_heights.height != maps.height / 2 || level_count != maps.level_count ||
                level_cones.layers != cone_layer_count(maps.level_sectors, false) ||
                !level_heights.image.handle();
  }
  if (!reshaped) return;
  std::vector<Allocation> needed = map_memory(shape);
  for (std::size_t index = 0; index < maps.cones.size(); ++index) {  // the other cone maps
    const ConeMapView& view = maps.cones[index];
    if (view.sector_count == 0 || view.device || view.sector_count == shape.cone_sectors) continue;
    const std::uint64_t bytes = pixels_of(maps.width, maps.height) *
                                std::uint64_t(cone_layer_count(view.sector_count, !view.relaxed.empty())) *
                                cone_layer_texel_bytes;
    needed.push_back({"the " + std::to_string(view.sector_count) + "-sector cone image", bytes,
                      MemoryKind::device_local, lower_map_size});
    for (Allocation& allocation : needed) {
      if (allocation.kind == MemoryKind::host_visible)
        allocation.bytes += bytes;  // the staging carries it too
    }
  }
  check_memory(needed, memory_limits());
}

}  // namespace displace::render
