// render/memory.h - the memory guards: what the renderer will allocate for a frame and its maps,
// estimated before it does, against what the machine has, so that work that cannot fit is refused
// with one line (what needs how much, what there is, what to lower) instead of running out of memory
// mid-way (render/memory.cpp).
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "render/view.h"
#include "vulkan/device_info.h"

namespace displace::render {

// The renderer checks itself: set_maps before it makes device maps and staging, render before it
// makes targets, readback buffers, the reference's tessellation or grows the caller's Frame. A
// caller can ask the same estimates up front (map_memory, frame_memory) and add its own (a bake's
// working memory) to refuse before any work starts.

enum class MemoryKind {
  device_local,  // device images and buffers (Vulkan, one allocation each)
  host_visible,  // staging, readback and vertex buffers the CPU writes or reads (Vulkan, one allocation each)
  host,          // ordinary process memory: vectors, bakes
};

struct Allocation {
  std::string what;  // the item, with its size: "the hit target of a 16384 x 16384 frame"
  std::uint64_t bytes = 0;
  MemoryKind kind = MemoryKind::host;
  std::string lower;  // what to lower when it does not fit: one of the lower_* names below
};

// Allocation::lower as render/ writes it: the fields of its own types, never a front end's flags (a
// CLI that shows the message maps each name to its flag: lower_frame_size to its image size flag).
inline constexpr const char* lower_frame_size = "Camera::width x Camera::height";
inline constexpr const char* lower_map_size = "MapSet::width x MapSet::height";
inline constexpr const char* lower_tile_or_map_size = "View::tile or MapSet::width x MapSet::height";

// What the machine offers (vulkan/device_info.h).
using vulkan::host_memory_limits;
using vulkan::MemoryLimits;

// Throws RenderError when `allocations` do not fit `limits`: one Vulkan allocation above the
// device's largest, or a sum above the memory it comes from. The message names the largest item of
// what does not fit, the bytes needed and available, and what to lower.
void check_memory(std::span<const Allocation> allocations, const MemoryLimits& limits);

// The shape of the maps handed to set_maps (MapSet's sizes; 0 sectors or depth: not given).
struct MapShape {
  int width = 0, height = 0;
  int cone_sectors = 0;
  bool relaxed = false;
  int level_count = 0;  // levels of detail (MapSet::level_count), with cone maps of level_sectors
  int level_sectors = 0;
  std::uint64_t max_pyramid_values = 0;  // floats of bake::DualMaxPyramid::values; 0: none
  int distance_width = 0, distance_height = 0, distance_depth = 0;
  bool foam = false;
};
// What set_maps allocates for maps of this shape given for the first time: device images and
// buffers, and the staging that carries them.
std::vector<Allocation> map_memory(const MapShape& shape);

// What render() allocates for its first frame of this view and method on a map_width x map_height
// map: the render targets, a readback buffer per output read back, the caller's Frame vectors, and
// for the reference its tessellation (on the CPU, then in buffers). `with_reference`: a frame of the
// reference follows (a comparison with the reference), in the other frame slot: its readback, Frame and
// tessellation too. Throws RenderError when the reference's tessellation would have more vertices
// than 32-bit indices address.
std::vector<Allocation> frame_memory(const View& view, const MethodSettings& method, int map_width,
                                     int map_height, unsigned outputs = output_all,
                                     bool with_reference = false);

// Bytes as text: "812 MB", "4.3 GB" (decimal units).
std::string memory_text(std::uint64_t bytes);

}  // namespace displace::render
