// demos/report_parts.h - the parts of `displace report` (demos/commands/report.cpp), each a function
// that measures one thing and writes one table:
//   cost      every method at every step count per scene: rmse against the reference, fetches
//             per pixel and device milliseconds                                     cost.csv
//   grazing   the same on each plane scene seen from 0.5 to 80 degrees above it     grazing.csv
//             (low views see a wrapped map tiled and framed so the patch fills the image)
//   bake      the budgeted bakers at several budgets and tolerances: bake ms against mean ratio,
//             and for the bilinear (renderable) maps the acm4 steps and fetches that then reach
//             rmse <= target                                                        bake.csv
//   frame     the frame pipeline's water scene at several frame budgets: each frame's error
//             against the reference rendered from the same heights, and the stage split   frame.csv
//   heatmaps  iterations per pixel of the searching methods on one view   heatmap_*.png, heatmaps.csv
//
// The one fact to know: every number comes from a render compared with the exact reference of the
// same heights and view (render::compare, 8-bit units), so a method's curve is its error, not its
// agreement with another method.
#pragma once

#include <filesystem>
#include <ostream>
#include <vector>

#include "pipeline/maps.h"
#include "pipeline/scene.h"
#include "render/render.h"

namespace displace::app::report {

// What each part renders and bakes; quick: the same figures from fewer, smaller runs.
struct Plan {
  int image_side = 256;            // pixels a side of the cost, grazing and heatmap renders
  std::vector<int> steps;          // cost: step counts per method
  int repeat = 3;                  // cost: renders per row (median device time)
  std::vector<double> elevations;  // grazing: degrees above the plane
  std::vector<int> grazing_steps;
  int horizon_steps = 32;  // grazing: the horizon band's figure, at the sea scenes' step count (one of
                           // grazing_steps)
  std::vector<double> bake_budgets_ms;  // at the default tolerance
  std::vector<float> bake_tolerances;   // with an unlimited budget
  std::vector<int> bake_steps;          // acm4 step counts tried, in order, until rmse <= target
  int frame_map_size = 256;
  int frame_width = 256, frame_height = 144;
  long long frame_count = 240;
  std::vector<double> frame_budgets_ms;
  int heatmap_steps = 64;
};

Plan make_plan(bool quick, int image_side);

constexpr float default_tolerance = 0.25f;    // bake::Budget's default
constexpr double bake_view_elevation = 10.0;  // degrees: the bake part's view of the plane
constexpr int max_grazing_tile = 8;  // copies a side of a wrapped map in a grazing view (the reference
                                     // tessellates 8 x 8 maps: 0.6 GB for 256 x 256 texels)

// The scene the single-view parts (bake, heatmaps) use: the ocean when asked for, else the first.
const pipeline::Scene& main_scene(const std::vector<pipeline::Scene>& scenes);

void cost_part(render::Renderer& renderer, pipeline::MapMaker& maps,
               const std::vector<pipeline::Scene>& scenes, const Plan& plan,
               const std::filesystem::path& directory, std::ostream& out);
void grazing_part(render::Renderer& renderer, pipeline::MapMaker& maps,
                  const std::vector<pipeline::Scene>& scenes, const Plan& plan,
                  const std::filesystem::path& directory, std::ostream& out);
void bake_part(render::Renderer& renderer, const pipeline::Scene& scene, const Plan& plan,
               const std::filesystem::path& directory, std::ostream& out);
void frame_part(render::Renderer& renderer, const Plan& plan, const std::filesystem::path& directory,
                std::ostream& out);
void heatmap_part(render::Renderer& renderer, pipeline::MapMaker& maps, const pipeline::Scene& scene,
                  const Plan& plan, const std::filesystem::path& directory, std::ostream& out);

}  // namespace displace::app::report
