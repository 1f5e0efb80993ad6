// pipeline/maps.h - the one map maker: heights -> the maps the renderer's methods read (bake/),
// handed over as a render::MapSet. The CLI's one-off renders, the tests and the frame pipeline all
// make their maps here; "who makes the maps" is this one choice, as pipeline/height_source.h's
// HeightSource is "who makes the heights".
//
// Conventions: maps are made the first time a method needs them (render::map_needs) and kept, with
// their version, for as long as the heights keep theirs; new heights bump every version and drop what
// was baked for the old ones. Cone maps come from bake::BilinearBaker within the cone budget
// (conservative at any budget: a starved bake costs cone steps, never a wrong hit); heights that
// changed only in their dirty rectangles since those the baker holds are updated there
// (BilinearBaker::update), not baked whole, and so are the levels of detail's cones.
//
// Two ways in. One-off: set_heights() then maps(needs) (slot 0, the cone budget of set_cone_budget).
// Per frame: make(slot, heights, needs, schedule) with the frame's heights, its cone budget and how
// cones carry over between frames (ConeSchedule: refinement of unchanged heights, lagged maps).
// State kept between frames, and MapHeights as the seam: docs/design/pipeline.md#pipelinemapsh-the-map-maker
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "bake/bake.h"
#include "bake/device/device_cones.h"
#include "render/render.h"
#include "sim/device/device_sim.h"

namespace displace::pipeline {

// The distance map of sphere tracing (bake_distance_map): the height map's uv resolution up to
// distance_max_side voxels a side (and the device's 3D limit), distance_slices voxels along h. A
// coarser map costs sphere steps, never accuracy: the cell walk finishes every ray exactly. Measured
// (fetches per pixel once converged): 64 slices instead of 16, and the full uv resolution instead of
// half, each save 6-23% on the ocean, grazing and deep views; 512 x 512 x 64 R32F is 67 MB.
inline constexpr int distance_slices = 64;     // voxels along h
inline constexpr int distance_max_side = 512;  // voxels along u and v at most

// The distance map of sphere tracing for `heights`, sized by the constants above and the device's
// 3D limit (`max_3d_side`), baked into `out` (its buffer reused).
struct DistanceMap {
  int width = 0, height = 0, depth = 0;
  std::vector<float> values;  // bake::DistanceView's layout
};
void bake_distance(bake::HeightView heights, bake::Address address, int max_3d_side, DistanceMap& out);

// A fresh map version: one process-wide counter, so that versions name content across map makers
// and frame pipelines that share a renderer.
std::uint64_t next_map_version();

// One frame's heights as make() reads them: views that must stay valid while the returned set is used
// (the set views the heights and the foam).
struct MapHeights {
  std::span<const float> heights;  // width x height in [0, 1], bake conventions
  int width = 0, height = 0;
  std::uint64_t version = 0;  // names the content (next_map_version): equal versions, equal heights
  // the rectangles that changed since version `dirty_since` (empty: all of it), for the renderer's
  // copy and the cone baker's update
  std::uint64_t dirty_since = 0;
  std::span<const bake::Rect> dirty;
  std::span<const float> foam;  // the source's foam coverage, passed on (empty: none)
  std::uint64_t foam_version = 0;
};

// A height field's MapHeights (no dirty rectangles, no foam), viewing `field`.
MapHeights map_heights(const render::HeightField& field, std::uint64_t version);

// How make() bakes a frame's cone map.
struct ConeSchedule {
  bake::Budget budget;  // the cone bake's budget for this frame
  // Heights the slot already holds a cone map for (or copied one from another slot): refine it
  // further within the budget, from where the baker stopped last (real time on a static source).
  bool refine = false;
  // > 0: lagged cone maps (moving heights, no relaxed layer; frame_pipeline.h): the baker's first
  // stage runs in steps on the heights of the frame it began on, an even share of it a frame over
  // at most lag_frames + 1 frames and more while the budget lasts, and each frame is served the map
  // made last with every apex raised by bake::raise_apexes for its own heights (bake::LaggedCones,
  // bake/lagged.h). The first map is made whole.
  int lag_frames = 0;
  long long frame_index = 0;  // the frame the heights belong to (a lagged map's age)
};

// What make() did.
struct MapStats {
  bake::BakeStats cones;        // the cone map served (sector_count 0: none)
  long long pending = 0;        // texels the cone baker would still refine
  long long cone_lag = 0;       // frames since the heights the served cone map was made from (lagged maps)
  float cone_lift = 0.0f;       // how far its apexes were raised for these heights
  bool cones_updated = false;   // the cone map was updated where the heights' dirty rectangles say
  bool levels_updated = false;  // and so were the levels of detail's cones
};

class MapMaker {
 public:
  // max_3d_side: the device's largest 3D image side (render::DeviceInfo::max_image_dimension_3d).
  // frames_in_flight: the slots make() may fill (at least 1), each with maps of its own.
  explicit MapMaker(int max_3d_side = distance_max_side, int frames_in_flight = 1);
  ~MapMaker();
  MapMaker(MapMaker&&) noexcept;
  MapMaker& operator=(MapMaker&&) noexcept;

  // ---- per frame
  // Makes what `needs` lists for `heights` into `slot` (0 .. frames_in_flight - 1): a map the slot
  // holds for these heights (version and address) is kept - refined with schedule.refine - one
  // another slot holds is copied, and the rest is baked (cones within schedule.budget). Fills
  // `stats`. The set views the slot's memory and `heights`, and holds until the next make() into the
  // slot; another slot's set may be read (uploaded) meanwhile, but make() is never called twice at once.
  const render::MapSet& make(int slot, const MapHeights& heights, const render::MapNeeds& needs,
                             const ConeSchedule& schedule, MapStats& stats);
  // The set the last make() into `slot` returned (empty before the first).
  const render::MapSet& made(int slot) const;
  // Makes the cone baker for heights of this size now instead of at the first make().
  void reserve(const render::MapNeeds& needs, int width, int height);

  // ---- one-off (slot 0)
  // New heights (validated as the bakers do; throws bake::BakeError). `dirty`: the rectangles that
  // changed since the last heights of the same size (empty: all of it), passed on to the renderer
  // and, where the cone baker holds those last heights, to its update().
  void set_heights(const render::HeightField& field, std::span<const bake::Rect> dirty = {});
  void set_heights(render::HeightField&& field, std::span<const bake::Rect> dirty = {});
  // The cone budget of the next cone bakes (unlimited by default).
  void set_cone_budget(const bake::Budget& budget);

  // Bakes what `needs` lists and is not made yet for these heights; the returned set views this
  // object's memory (valid until the next call) and holds every map made so far.
  const render::MapSet& maps(const render::MapNeeds& needs);
  const render::MapSet& maps_for(render::Method method, const render::View& view) {
    return maps(render::map_needs(method, view));
  }

  const render::HeightField& heights() const;
  // Statistics of slot 0's last cone bake per sector count (cone_slot order); sector_count 0 when none.
  const bake::BakeStats& cone_stats(int sector_count) const;

  struct State;

 private:
  std::unique_ptr<State> state_;
};

// Makes the maps `method` needs for `view`, hands them to `renderer` and renders: the usual way a
// one-off picture is made (the CLI's render and sweep, the tests).
render::Frame render_with_maps(render::Renderer& renderer, MapMaker& maps, const render::View& view,
                               const render::MethodSettings& method, unsigned outputs = render::output_all);

}  // namespace displace::pipeline
