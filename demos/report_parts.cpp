// demos/report_parts.cpp - the parts of `displace report` (demos/report_parts.h).
#include "demos/report_parts.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <limits>
#include <nlohmann/json.hpp>
#include <ostream>
#include <string>
#include <thread>
#include <vector>

#include "demos/cone_bake.h"
#include "demos/error.h"
#include "demos/frame_output.h"
#include "demos/heights.h"
#include "demos/text_file.h"
#include "pipeline/frame_pipeline.h"
#include "pipeline/maps.h"

namespace displace::app::report {
namespace {

constexpr double unlimited = std::numeric_limits<double>::infinity();

constexpr render::Method heatmap_methods[] = {
    render::Method::pom,    render::Method::relief, render::Method::interval, render::Method::sphere,
    render::Method::csm,    render::Method::acm4,   render::Method::acm8,     render::Method::relaxed,
    render::Method::maxmip, render::Method::qdm};

std::string number(double value) { return std::isfinite(value) ? fmt::format("{:g}", value) : "inf"; }

pipeline::Scene sized(pipeline::Scene scene, int side) {
  scene.camera.width = side;
  scene.camera.height = side;
  return scene;
}

// The scene's camera moved to `degrees` above the top plane, looking at the patch's centre from
// the -v side (the tile's centre when the texture repeats).
render::View at_elevation(render::View view, double degrees) {
  constexpr double distance = 1.2;  // world units from the eye to the patch's centre
  const double radians = degrees * 3.14159265358979323846 / 180.0;
  const float centre = 0.5f;
  view.camera.look_at = {centre, centre, 0.0f};
  view.camera.eye = {centre, float(centre - distance * std::cos(radians)),
                     float(distance * std::sin(radians))};
  view.camera.up = {0.0f, 0.0f, 1.0f};
  return view;
}

// The grazing part's view at `degrees`: at_elevation's eye, with two changes that keep a low view
// on the relief. (1) On a wrapped map the plane holds `tile` copies a side, scaled down so the
// relief keeps its slopes (depth_scale / tile): a ray entering the top plane at the near edge can
// cross the whole slab, depth / tan(elevation), before it leaves the patch (else, below a few
// degrees, the rays leave the patch above the crests and the reference hits nothing). (2) The
// vertical field of view narrows until the top plane's near edge is the image's bottom row, so
// the patch fills the image instead of a few rows of it (never wider than the scene's).
render::View grazing_view(render::View view, double degrees) {
  view = at_elevation(view, degrees);
  const double radians = degrees * 3.14159265358979323846 / 180.0;
  if (view.address == bake::Address::wrap) {
    const int copies = std::clamp(int(std::ceil(view.depth_scale / std::tan(radians))), 1, max_grazing_tile);
    view.tile = std::min(view.tile * copies, render::max_tile);
    view.depth_scale /= float(copies);
  }
  // the near edge's angle below the view's centre, in the image's vertical plane
  const glm::dvec3 eye(view.camera.eye), forward = glm::normalize(glm::dvec3(view.camera.look_at) - eye);
  const glm::dvec3 up = glm::normalize(glm::dvec3(0.0, 0.0, 1.0) - forward.z * forward);
  const glm::dvec3 to_edge = glm::dvec3(view.camera.look_at.x, 0.0, 0.0) - eye;
  const double half_fov = std::atan(std::abs(glm::dot(to_edge, up)) / glm::dot(to_edge, forward));
  view.camera.fov_y_degrees =
      std::min(view.camera.fov_y_degrees, float(2.0 * half_fov * 180.0 / 3.14159265358979323846));
  return view;
}

// Pixels where the reference hits the relief.
long long hit_count(const render::Frame& frame) {
  long long hits = 0;
  for (std::size_t p = 2; p < frame.uv.size(); p += 3) hits += frame.uv[p] > 0.5f;
  return hits;
}

}  // namespace

Plan make_plan(bool quick, int image_side) {
  Plan plan;
  plan.elevations = {0.5, 1, 2, 3, 5, 10, 20, 45, 80};
  plan.bake_steps = {4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128, 192, 256, 384, 512, 768, 1024};
  if (quick) {
    plan.elevations = {0.5, 2, 10, 45};  // the horizon band and the 45 degrees it is compared with
    plan.image_side = 128;
    plan.steps = {4, 16, 64, 256};
    plan.repeat = 1;
    plan.grazing_steps = {8, 32, 128, 512};
    plan.bake_budgets_ms = {0, 2, 8, unlimited};
    plan.bake_tolerances = {0.75f, 0.05f};
    plan.frame_map_size = 128;
    plan.frame_width = 128;
    plan.frame_height = 72;
    plan.frame_count = 24;
    plan.frame_budgets_ms = {33.3, 100, unlimited};
    plan.heatmap_steps = 64;
  } else {
    plan.steps = {4, 8, 16, 32, 64, 128, 256, 512, 1024};
    plan.grazing_steps = {4, 8, 16, 32, 64, 128, 256, 512, 1024};
    plan.bake_budgets_ms = {0, 1, 2, 4, 8, 16, 32, 64, unlimited};
    plan.bake_tolerances = {0.9f, 0.5f, 0.1f, 0.05f, 0.02f};
    plan.frame_budgets_ms = {33.3, 50, 66.7, 100, 150, unlimited};
  }
  if (image_side > 0) plan.image_side = image_side;
  plan.horizon_steps = pipeline::builtin_scene("water").steps;
  assert(std::find(plan.grazing_steps.begin(), plan.grazing_steps.end(), plan.horizon_steps) !=
         plan.grazing_steps.end());
  return plan;
}

// The scene the single-view parts (bake, heatmaps) use: the ocean when asked for, else the first.
const pipeline::Scene& main_scene(const std::vector<pipeline::Scene>& scenes) {
  for (const pipeline::Scene& scene : scenes) {
    if (scene.name == "ocean") return scene;
  }
  return scenes.front();
}

// ---- parts

void cost_part(render::Renderer& renderer, pipeline::MapMaker& maps,
               const std::vector<pipeline::Scene>& scenes, const Plan& plan,
               const std::filesystem::path& directory, std::ostream& out) {
  TextFile csv(directory / "cost.csv",
               "scene,method,steps,rmse,max_error,fraction_over_10,mean_fetches,p99_fetches,"
               "mean_iterations,median_ms");
  render::Frame frame;
  for (const pipeline::Scene& scene_settings : scenes) {
    const pipeline::Scene scene = sized(scene_settings, plan.image_side);
    load_scene(renderer, maps, scene);
    const render::Frame reference =
        pipeline::render_with_maps(renderer, maps, start_view(scene), {render::Method::reference, 1, 0});
    for (const render::MethodInfo& info : render::method_table()) {
      if (info.method == render::Method::reference ||
          !render::supports_surface(info.method, start_view(scene).surface)) {
        continue;
      }
      for (int steps : plan.steps) {
        const MethodRun run = measure_method(renderer, maps, start_view(scene), {info.method, steps, 8},
                                             plan.repeat, reference, frame);
        csv << fmt::format("{},{},{},{:.4f},{:.0f},{:.6f},{:.3f},{:.0f},{:.3f},{:.4f}\n", scene.name,
                           info.name, steps, run.error.rmse, run.error.max_error, run.error.fraction_over_10,
                           run.summary.mean_fetches, run.summary.p99_fetches, run.summary.mean_iterations,
                           run.median_ms);
        if (info.family == render::MethodFamily::surface) break;  // no steps to give: one row
      }
    }
    csv.save();
    out << fmt::format("  cost: {} done\n", scene.name) << std::flush;
  }
  csv.save();
}

void grazing_part(render::Renderer& renderer, pipeline::MapMaker& maps,
                  const std::vector<pipeline::Scene>& scenes, const Plan& plan,
                  const std::filesystem::path& directory, std::ostream& out) {
  TextFile csv(directory / "grazing.csv",
               "scene,elevation_deg,tile,fov_y_deg,reference_pixels,method,steps,rmse,fraction_over_10,"
               "mean_fetches,median_ms");
  render::Frame frame;
  for (const pipeline::Scene& scene_settings : scenes) {
    const pipeline::Scene scene = sized(scene_settings, plan.image_side);
    if (start_view(scene).surface != render::Surface::plane) {
      out << fmt::format("  grazing: {} skipped (only planes have an elevation)\n", scene.name);
      continue;
    }
    load_scene(renderer, maps, scene);
    for (double elevation : plan.elevations) {
      const render::View view = grazing_view(start_view(scene), elevation);
      const render::Frame reference =
          pipeline::render_with_maps(renderer, maps, view, {render::Method::reference, 1, 0});
      const long long reference_pixels = hit_count(reference);
      for (const render::MethodInfo& info : render::method_table()) {
        if (info.method == render::Method::reference) continue;
        for (int steps : plan.grazing_steps) {
          const MethodRun run =
              measure_method(renderer, maps, view, {info.method, steps, 8}, 1, reference, frame);
          csv << fmt::format("{},{:g},{},{:.5f},{},{},{},{:.4f},{:.6f},{:.3f},{:.4f}\n", scene.name,
                             elevation, view.tile, view.camera.fov_y_degrees, reference_pixels, info.name,
                             steps, run.error.rmse, run.error.fraction_over_10, run.summary.mean_fetches,
                             run.median_ms);
          if (info.family == render::MethodFamily::surface) break;  // no steps to give: one row
        }
      }
    }
    csv.save();
    out << fmt::format("  grazing: {} done\n", scene.name) << std::flush;
  }
  csv.save();
}

// acm4 from `cones` (4 sectors, bilinear) at the plan's step counts until rmse <= target: the
// first step count that reaches it, or the last one tried.
struct ConeRender {
  int steps = 0;
  MethodRun run;
  bool reached = false;
};
ConeRender acm4_until_target(render::Renderer& renderer, render::MapSet maps, const BakedCones& cones,
                             bake::Address address, const render::View& view, const render::Frame& reference,
                             const Plan& plan) {
  render::ConeMapView& slot = maps.cones[render::cone_slot(4)];
  slot = {4, address, cones.ratios, cones.apex, {}, pipeline::next_map_version(), 0, {}};
  renderer.set_maps(maps);
  ConeRender result;
  render::Frame frame;
  for (int steps : plan.bake_steps) {
    renderer.render(view, {render::Method::acm4, steps, 8}, frame);
    result.steps = steps;
    result.run = {render::compare(frame, reference), summarize(frame), frame.gpu_milliseconds};
    if (result.run.error.rmse <= sweep_target_rmse) {
      result.reached = true;
      break;
    }
  }
  return result;
}

void bake_part(render::Renderer& renderer, const pipeline::Scene& scene_settings, const Plan& plan,
               const std::filesystem::path& directory, std::ostream& out) {
  TextFile csv(directory / "bake.csv",
               "scene,cones,budget_ms,tolerance,bake_ms,mean_ratio,texels_refined,texels_fallback,"
               "acm4_steps,acm4_fetches,acm4_rmse,acm4_ms");
  const pipeline::Scene scene = sized(scene_settings, plan.image_side);
  const SceneHeights input = scene_heights(scene, scene.start);
  const bake::Address address = start_view(scene).address;
  render::MapSet maps;
  maps.width = input.width;
  maps.height = input.height;
  maps.heights = input.heights;
  maps.heights_version = pipeline::next_map_version();
  renderer.clear_albedo();
  renderer.set_maps(maps);
  // a low view (10 degrees), where the cones' tightness decides how many steps a ray takes
  const render::View view = start_view(scene).surface == render::Surface::plane
                                ? at_elevation(start_view(scene), bake_view_elevation)
                                : start_view(scene);
  const render::Frame reference = renderer.render(view, {render::Method::reference, 1, 0});

  struct Setting {
    double budget_ms;
    float tolerance;
  };
  std::vector<Setting> settings;
  for (double budget : plan.bake_budgets_ms) settings.push_back({budget, default_tolerance});
  for (float tolerance : plan.bake_tolerances) settings.push_back({unlimited, tolerance});
  // warm up (first-touch of the bakers' memory and thread pool)
  bake_bilinear(input.heights, input.width, input.height, 4, Baker::budgeted, address, 0.0);
  bake_cones(input.heights, input.width, input.height, 4, Baker::budgeted, address, 0.0);

  const auto row = [&](std::string_view kind, std::string_view budget, float tolerance,
                       const BakedCones& baked, const ConeRender* render) {
    csv << fmt::format("{},{},{},{:g},{:.3f},{:.5f},{},{}", scene.name, kind, budget, tolerance,
                       baked.stats.milliseconds, baked.stats.mean_ratio, baked.stats.texels_refined,
                       baked.stats.texels_fallback);
    if (render && render->reached) {
      csv << fmt::format(",{},{:.3f},{:.4f},{:.4f}\n", render->steps, render->run.summary.mean_fetches,
                         render->run.error.rmse, render->run.median_ms);
    } else if (render) {
      csv << fmt::format(",,,{:.4f},\n", render->run.error.rmse);  // not reached at the most steps
    } else {
      csv << ",,,,\n";
    }
  };
  for (const Setting& setting : settings) {
    const BakedCones center = bake_cones(input.heights, input.width, input.height, 4, Baker::budgeted,
                                         address, setting.budget_ms, setting.tolerance);
    row("center", number(setting.budget_ms), setting.tolerance, center, nullptr);
    const BakedCones bilinear = bake_bilinear(input.heights, input.width, input.height, 4, Baker::budgeted,
                                              address, setting.budget_ms, setting.tolerance);
    const ConeRender render = acm4_until_target(renderer, maps, bilinear, address, view, reference, plan);
    row("bilinear", number(setting.budget_ms), setting.tolerance, bilinear, &render);
  }
  // the exact bilinear map (bake_bilinear_cones): the tightest there is, at its price
  const BakedCones full =
      bake_bilinear(input.heights, input.width, input.height, 4, Baker::full, address, unlimited);
  const ConeRender render = acm4_until_target(renderer, maps, full, address, view, reference, plan);
  row("bilinear-full", "inf", 0.0f, full, &render);
  csv.save();
  out << fmt::format("  bake: {} done ({} x {} map)\n", scene.name, input.width, input.height) << std::flush;
}

void frame_part(render::Renderer& renderer, const Plan& plan, const std::filesystem::path& directory,
                std::ostream& out) {
  TextFile csv(directory / "frame.csv",
               "frame_budget_ms,frame,sim_ms,bake_ms,upload_ms,render_ms,frame_ms,bake_budget_ms,"
               "mean_ratio,pending,mean_fetches,rmse,fraction_over_10");
  render::Frame frame, reference;
  for (double budget : plan.frame_budgets_ms) {
    pipeline::Scene scene = pipeline::builtin_scene("water");
    scene.map_size = plan.frame_map_size;
    scene.camera.width = plan.frame_width;
    scene.camera.height = plan.frame_height;
    scene.frame_ms = budget;
    scene.bake_work = -1;
    pipeline::FramePipeline pipe(scene, renderer);
    for (long long index = 0; index < plan.frame_count; ++index) {
      render::View view = pipeline::scene_view(scene, pipeline::frame_time(scene, index));
      view.unbounded = false;  // on the patch, which the reference tessellates
      const pipeline::FrameRecord record = pipe.run(index, view, frame, render::output_all);
      // the reference of the same heights, foam and view: what the frame would show if exact
      renderer.render(view, {render::Method::reference, 1, 0}, reference,
                      render::output_color | render::output_uv);
      const render::ImageError error = render::compare(frame, reference);
      csv << fmt::format("{},{},{:.3f},{:.3f},{:.3f},{:.3f},{:.3f},{},{:.5f},{},{:.3f},{:.4f},{:.6f}\n",
                         number(budget), index, record.sim_ms, record.bake_ms, record.upload_ms,
                         record.render_ms, record.frame_ms, number(record.bake_budget_ms),
                         record.cones.mean_ratio, record.pending, summarize(frame).mean_fetches, error.rmse,
                         error.fraction_over_10);
    }
    csv.save();
    out << fmt::format("  frame: budget {} ms done\n", number(budget)) << std::flush;
  }
  csv.save();
}

void heatmap_part(render::Renderer& renderer, pipeline::MapMaker& maps, const pipeline::Scene& scene_settings,
                  const Plan& plan, const std::filesystem::path& directory, std::ostream& out) {
  TextFile csv(directory / "heatmaps.csv",
               "scene,method,steps,mean_iterations,max_iterations,mean_fetches,rmse,file");
  const pipeline::Scene scene = sized(scene_settings, plan.image_side);
  load_scene(renderer, maps, scene);
  const render::Frame reference =
      pipeline::render_with_maps(renderer, maps, start_view(scene), {render::Method::reference, 1, 0});
  render::Frame frame;
  std::vector<std::uint16_t> values;
  for (render::Method method : heatmap_methods) {
    if (!render::supports_surface(method, start_view(scene).surface)) continue;
    const MethodRun run = measure_method(renderer, maps, start_view(scene), {method, plan.heatmap_steps, 8},
                                         1, reference, frame);
    // iterations + 1 on the relief, 0 off it
    values.assign(frame.iterations.size(), 0);
    for (std::size_t p = 0; p < values.size(); ++p) {
      if (frame.uv[p * 3 + 2] >= 0.5f)
        values[p] = std::uint16_t(std::min(frame.iterations[p] + 1.0f, 65535.0f));
    }
    const std::string name = render::method_info(method).name;
    const std::string file = "heatmap_" + name + ".png";
    write_png_gray16(directory / file, frame.width, frame.height, values);
    csv << fmt::format("{},{},{},{:.3f},{:.0f},{:.3f},{:.4f},{}\n", scene.name, name, plan.heatmap_steps,
                       run.summary.mean_iterations, run.summary.max_iterations, run.summary.mean_fetches,
                       run.error.rmse, file);
  }
  csv.save();
  out << fmt::format("  heatmaps: {} done\n", scene.name) << std::flush;
}

}  // namespace displace::app::report
