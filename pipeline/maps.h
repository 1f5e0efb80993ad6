// pipeline/maps.h - the maps the renderer's methods read, baked from one height field on demand
// (bake/) and handed over as a render::MapSet: the one place that bakes for the renderer, shared by
// the CLI, the tests and the frame pipeline.
//
// Conventions: maps are made the first time a method needs them (render::map_needs) and kept, with
// their version, until the heights change; new heights bump every version and drop what was baked
// for the old ones. Cone maps come from bake::BilinearBaker within the cone budget (conservative at
// any budget: a starved bake costs cone steps, never a wrong hit); one BilinearBaker per sector
// count is kept between height fields of the same size.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "bake/bake.h"
#include "render/render.h"

namespace displace::pipeline {

// The distance map of sphere tracing (bake_distance_map): the height map's uv resolution up to
// distance_max_side voxels a side (and the device's 3D limit), distance_slices voxels along h. A
// coarser map costs sphere steps, never accuracy: the cell walk finishes every ray exactly. Measured
// (fetches per pixel once converged): 64 slices instead of 16, and the full uv resolution instead of
// half, each save 6-23% on the ocean, grazing and deep views; 512 x 512 x 64 R32F is 67 MB and bakes
// in about 0.27 s on 2 cores.
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

class MapMaker {
 public:
  // max_3d_side: the device's largest 3D image side (render::DeviceInfo::max_image_dimension_3d).
  explicit MapMaker(int max_3d_side = distance_max_side);
  ~MapMaker();
  MapMaker(MapMaker&&) noexcept;
  MapMaker& operator=(MapMaker&&) noexcept;

  // New heights (validated as the bakers do; throws bake::BakeError). `dirty`: the rectangles that
  // changed since the last heights of the same size (empty: all of it), passed on to the renderer.
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
  // Statistics of the last cone bake per sector count (cone_slot order); sector_count 0 when none.
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
