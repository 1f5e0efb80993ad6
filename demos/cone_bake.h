// demos/cone_bake.h - one cone map baked whole for `displace bake` and `displace demo`: centre cones
// with one of the centre bakers, or the renderer's bilinear cones with their apex heights.
#pragma once

#include <span>
#include <string>
#include <vector>

#include "bake/bake.h"
#include "demos/cone_export.h"
#include "render/device.h"
#include "render/render.h"

namespace displace::app {

struct BakedCones {
  std::vector<float> ratios;  // interleaved, width * height * sector_count
  std::vector<float> apex;    // bilinear cones: width * height apex heights; center cones: empty
  bake::BakeStats stats;
};
// Center cones (between texel centres) with one of the center bakers. `progress` hears from the
// slow ones (exact, original, relaxed).
BakedCones bake_cones(std::span<const float> heights, int width, int height, int sector_count, Baker baker,
                      bake::Address address, double budget_milliseconds, float tolerance = 0.25f,
                      const bake::Progress& progress = {});
// Bilinear cones on `renderer`'s device (render::DeviceCones, the same contract), with the frame
// pipeline's rule (pipeline::device_cone_budget): Baker::full and a budgeted bake without a budget
// search every texel to the cells, a budgeted bake with a budget (a dispatch cannot stop when it runs
// out) makes the first pass only, of the shape `first_pass` says. Stats: mode bilinear, texels refined, wall
// milliseconds, mean ratio.
BakedCones bake_bilinear_on_device(render::Renderer& renderer, std::span<const float> heights, int width,
                                   int height, int sector_count, Baker baker, bake::Address address,
                                   double budget_milliseconds,
                                   const render::DeviceFirstPass& first_pass = {});
// Bilinear cones (bake::bake_bilinear_cones' contract) with their apex heights: Baker::full bakes
// them whole, Baker::budgeted with bake::BilinearBaker within the budget (0 allowed); `progress`
// goes to either.
BakedCones bake_bilinear(std::span<const float> heights, int width, int height, int sector_count, Baker baker,
                         bake::Address address, double budget_milliseconds, float tolerance = 0.25f,
                         const bake::Progress& progress = {});

// The --stats JSON line (no trailing newline).
std::string stats_json(const bake::BakeStats& stats, Baker baker, bake::Address address,
                       ConeKind kind = ConeKind::center);

}  // namespace displace::app
