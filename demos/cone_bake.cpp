// demos/cone_bake.cpp - whole cone maps for the bake and demo commands (demos/cone_bake.h).
#include "demos/cone_bake.h"

#include <chrono>
#include <cmath>
#include <nlohmann/json.hpp>

#include "demos/error.h"
#include "pipeline/maps.h"
#include "render/device.h"

namespace displace::app {
namespace {

using Clock = std::chrono::steady_clock;

double milliseconds_since(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

}  // namespace

BakedCones bake_cones(std::span<const float> heights, int width, int height, int sector_count, Baker baker,
                      bake::Address address, double budget_milliseconds, float tolerance,
                      const bake::Progress& progress) {
  if (baker == Baker::relaxed && sector_count != 1 && sector_count != 4) {
    throw usage_error("the relaxed baker supports 1 or 4 sectors, not " + std::to_string(sector_count));
  }
  BakedCones baked;
  baked.ratios.assign(std::size_t(width) * std::size_t(height) * std::size_t(sector_count), 0.0f);
  const bake::HeightView view{heights.data(), width, height};
  const bake::ConeView cones{baked.ratios.data(), width, height, sector_count};

  const auto start = Clock::now();
  switch (baker) {
    case Baker::exact: baked.stats = bake::bake_exact(view, address, cones, progress); break;
    case Baker::original: baked.stats = bake::bake_original(view, address, cones, progress); break;
    case Baker::paper_adaptive:
      baked.stats = bake::bake_paper_adaptive(view, address, bake::PaperAdaptiveSettings{}, cones);
      break;
    case Baker::budgeted: {
      bake::Budget budget;
      budget.milliseconds = budget_milliseconds;
      budget.tolerance = tolerance;
      baked.stats = bake::bake_budgeted(view, address, budget, cones);
      break;
    }
    case Baker::relaxed: baked.stats = bake::bake_relaxed(view, address, cones, progress); break;
    case Baker::full: throw usage_error("--mode full bakes bilinear cones only (--cones bilinear)");
  }
  const double elapsed = milliseconds_since(start);
  if (!(baked.stats.milliseconds > 0.0) || !std::isfinite(baked.stats.milliseconds)) {
    baked.stats.milliseconds = elapsed;
  }
  baked.stats.width = width;
  baked.stats.height = height;
  baked.stats.sector_count = sector_count;
  return baked;
}

BakedCones bake_bilinear(std::span<const float> heights, int width, int height, int sector_count, Baker baker,
                         bake::Address address, double budget_milliseconds, float tolerance,
                         const bake::Progress& progress) {
  if (baker != Baker::budgeted && baker != Baker::full) {
    throw usage_error(std::string("bilinear cones bake with the budgeted or the full baker, not ") +
                      baker_name(baker));
  }
  BakedCones baked;
  const std::size_t texels = std::size_t(width) * std::size_t(height);
  baked.ratios.assign(texels * std::size_t(sector_count), 0.0f);
  baked.apex.assign(texels, 0.0f);
  const bake::HeightView view{heights.data(), width, height};
  const bake::ConeView cones{baked.ratios.data(), width, height, sector_count};
  if (baker == Baker::full) {
    bake::BilinearConeSettings settings;
    settings.progress = progress;
    baked.stats = bake::bake_bilinear_cones(view, address, cones, baked.apex, settings);
  } else {
    bake::Budget budget;
    budget.milliseconds = budget_milliseconds;
    budget.tolerance = tolerance;
    budget.progress = progress;
    bake::BilinearBaker bilinear_baker(width, height, sector_count, address);
    baked.stats = bilinear_baker.bake(view, budget, cones, baked.apex);
  }
  return baked;
}

BakedCones bake_bilinear_on_device(render::Renderer& renderer, std::span<const float> heights, int width,
                                   int height, int sector_count, Baker baker, bake::Address address,
                                   double budget_milliseconds, const render::DeviceFirstPass& first_pass) {
  if (baker != Baker::budgeted && baker != Baker::full) {
    throw usage_error(std::string("bilinear cones bake with the budgeted or the full baker, not ") +
                      baker_name(baker));
  }
  const auto start = std::chrono::steady_clock::now();
  render::DeviceCones cones(renderer, bake::HeightView{heights.data(), width, height}, sector_count, address);
  bake::Budget budget;  // the full baker: unlimited
  if (baker == Baker::budgeted) budget.milliseconds = budget_milliseconds;
  cones.bake(pipeline::device_cone_budget(budget, first_pass));
  BakedCones baked;
  const render::DeviceConeStats device_stats = cones.read_back(&baked.ratios, &baked.apex);
  baked.stats.mode = bake::Mode::bilinear;
  baked.stats.width = width;
  baked.stats.height = height;
  baked.stats.sector_count = sector_count;
  baked.stats.texels_refined = device_stats.texels_refined;
  baked.stats.milliseconds =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  double sum = 0.0;
  for (float ratio : baked.ratios) sum += double(ratio);
  baked.stats.mean_ratio = baked.ratios.empty() ? 0.0 : sum / double(baked.ratios.size());
  return baked;
}

std::string stats_json(const bake::BakeStats& stats, Baker baker, bake::Address address, ConeKind kind) {
  const auto finite = [](double value) { return std::isfinite(value) ? value : 0.0; };
  const nlohmann::ordered_json line = {
      {"mode", baker_name(baker)},
      {"cones", cone_kind_name(kind)},
      {"width", stats.width},
      {"height", stats.height},
      {"sectors", stats.sector_count},
      {"address", address_name(address)},
      {"bake_ms", finite(stats.milliseconds)},
      {"texels_refined", stats.texels_refined},
      {"texels_fallback", stats.texels_fallback},
      {"blocker_tests", stats.work},
      {"mean_ratio", finite(stats.mean_ratio)},
  };
  return line.dump();
}

}  // namespace displace::app
