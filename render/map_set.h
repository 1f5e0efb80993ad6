// render/map_set.h - the maps a frame samples, as the caller hands them to the renderer: heights,
// cone maps, the max pyramid, the distance map, the levels of detail, foam and albedo (views of the
// caller's memory, versioned, with the rectangles that changed), and which maps a method needs on a
// view (map_needs). The renderer uploads them and never bakes; pipeline/maps.h makes them.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "bake/bake.h"
#include "render/view.h"
#include "vulkan/device_info.h"

namespace displace::render {}  // namespace displace::render

// Maps a compute stage wrote on the renderer's own device (Renderer::frames()), named by the stage
// that made them (sim::DeviceSim::maps, bake::DeviceCones::map, bake::DeviceLevels::maps): the
// renderer samples them where they are. Opaque; a frame that samples maps whose stage is gone fails
// with a RenderError.
namespace displace::vulkan {
struct DeviceHeightImages;
struct DeviceConeImage;
struct DeviceLevelImages;
}  // namespace displace::vulkan

namespace displace::render {

using vulkan::DeviceConeImage;
using vulkan::DeviceHeightImages;
using vulkan::DeviceLevelImages;

// A height field on the CPU (the reference tracers' input and what map makers read).
struct HeightField {
  int width = 0;
  int height = 0;
  std::vector<float> heights;  // [0, 1], row-major, bake conventions
};

// An RGBA8 image, row-major, row 0 at v = 0 (like the heights).
struct Albedo {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> rgba;
};

// ---- Maps: made by the caller (bake/), handed to the renderer, which uploads them and never bakes.
//
// Every map is a view of memory the caller owns, valid for the call that hands it over (set_maps
// copies what changed). Versions: a map's `version` changes whenever its content does, and names
// that content for every map handed to this renderer (pipeline::MapMaker draws them from one
// process-wide counter); `dirty` lists the texel rectangles ([x0, x1) x [y0, y1)) that changed since
// version `dirty_since` (empty: all of it). The renderer copies only those rectangles when it holds
// version `dirty_since` of that map at the same size, and the whole map otherwise; a map whose
// version it already holds is not copied at all.

// The bilinear-surface cone map of bake::BilinearBaker / bake_bilinear_cones (apex heights with
// ratios for 1, 4 or 8 sectors), plus bake::bake_relaxed's 1-sector relaxed ratios for relaxed
// cone stepping (1 sector only).
struct ConeMapView {
  int sector_count = 0;  // 0: not given
  bake::Address address = bake::Address::wrap;
  std::span<const float> ratios;   // W x H x sector_count, interleaved (bake::ConeView)
  std::span<const float> apex;     // W x H
  std::span<const float> relaxed;  // W x H, or empty
  std::uint64_t version = 0;
  std::uint64_t dirty_since = 0;
  std::span<const bake::Rect> dirty;
  // Or the cones a DeviceCones of this renderer made (its sector count and address; ratios, apex and
  // relaxed then stay empty).
  std::shared_ptr<const DeviceConeImage> device = nullptr;
};

// bake::build_dual_max_pyramid's pyramid of the heights (maxmip, qdm).
struct MaxPyramidView {
  const bake::DualMaxPyramid* pyramid = nullptr;  // nullptr: not given
  bake::Address address = bake::Address::wrap;
  std::uint64_t version = 0;
};

// bake::bake_distance_map's distance map (sphere tracing); its size need not be the height map's.
struct DistanceMapView {
  int width = 0, height = 0, depth = 0;  // 0: not given
  bake::Address address = bake::Address::wrap;
  std::span<const float> values;  // W x H x D, bake::DistanceView's layout
  std::uint64_t version = 0;
};

inline constexpr int max_map_side =
    vulkan::max_map_side;  // texels, MapSet::width and height (and Albedo's pixels)

struct MapSet {
  int width = 0, height = 0;       // of the height map and of every cone map
  std::span<const float> heights;  // W x H in [0, 1], bake conventions; every method reads them
  std::uint64_t heights_version = 0;
  std::uint64_t heights_dirty_since = 0;
  std::span<const bake::Rect> heights_dirty;
  std::array<ConeMapView, 3> cones;  // by cone_slot(sector_count): 1, 4 and 8 sectors
  MaxPyramidView max_pyramid;
  DistanceMapView distance;
  // foam coverage in [0, 1] per texel, for the water material (empty: none), with its version
  std::span<const float> foam;
  std::uint64_t foam_version = 0;
  // Or the heights, and the foam where it makes any, a DeviceSim of this renderer made (`heights` and
  // `foam` then stay empty; width and height are the DeviceSim's).
  std::shared_ptr<const DeviceHeightImages> device_heights = nullptr;
  // Levels of detail (bake::downsample_heights; optional: without them every view traces level 0):
  // levels[l - 1] is level l = 1 .. level_count, (width >> l) x (height >> l) texels, its heights and
  // the bilinear cone map of `level_sectors` sectors baked for them with `level_address`. The chain
  // changes as a whole: a new `levels_version` copies every level.
  int level_count = 0;  // 0 .. bake::max_detail_levels
  int level_sectors = 0;
  bake::Address level_address = bake::Address::wrap;
  // Or the levels a DeviceLevels of this renderer makes (with device_heights): the count, sectors and
  // address must be its own, and `levels` stays empty.
  std::shared_ptr<const DeviceLevelImages> device_levels = nullptr;
  struct Level {
    std::span<const float> heights;  // (W >> l) x (H >> l)
    std::span<const float> ratios;   // (W >> l) x (H >> l) x level_sectors, interleaved
    std::span<const float> apex;     // (W >> l) x (H >> l)
    // (W >> l) x (H >> l) x 3 (optional, water's shading): bake::downsample_moments' means of level
    // 0's gradient moments over each texel's footprint; empty: the level is shaded as if smooth
    std::span<const float> slopes;
  };
  std::array<Level, bake::max_detail_levels> levels{};
  std::uint64_t levels_version = 0;
};
int cone_slot(int sector_count);  // 0, 1, 2 for 1, 4, 8 sectors

// What a method reads for a view, from the method table: the renderer refuses a frame whose maps
// are missing (naming the map), and map makers (pipeline/maps.h) bake exactly this.
struct MapNeeds {
  int cone_sectors = 0;                              // 0: no cone map
  bool relaxed = false;                              // the cone map's relaxed layer
  bake::Address cone_address = bake::Address::wrap;  // wrap on quadrics (u closes around the axis)
  bool max_pyramid = false;
  bool distance = false;
  bake::Address address = bake::Address::wrap;  // of the pyramid and the distance map: the view's
  // the levels of detail with their cone maps of cone_sectors (MapSet::levels): an unbounded view of
  // csm, acm4, acm8 or acm4-interval whose View::level is not level_off
  bool levels = false;
};
MapNeeds map_needs(Method method, const View& view);
// Whether a method traces levels of detail on a view (map_needs' `levels`).
bool traces_levels(Method method, const View& view);

}  // namespace displace::render
