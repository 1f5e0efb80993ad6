// pipeline/cone_bake.cpp - one cone map baked whole (pipeline/cone_bake.h).
#include "pipeline/cone_bake.h"

#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>

namespace displace::pipeline {
namespace {

using Clock = std::chrono::steady_clock;

double milliseconds_since(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

}  // namespace

const char* baker_name(Baker baker) {
  switch (baker) {
    case Baker::exact: return "exact";
    case Baker::original: return "original";
    case Baker::paper_adaptive: return "paper-adaptive";
    case Baker::budgeted: return "budgeted";
    case Baker::relaxed: return "relaxed";
    case Baker::full: return "full";
  }
  return "unknown";
}

std::optional<Baker> baker_named(std::string_view name) {
  for (const Baker baker :
       {Baker::exact, Baker::original, Baker::paper_adaptive, Baker::budgeted, Baker::relaxed, Baker::full}) {
    if (name == baker_name(baker)) return baker;
  }
  return std::nullopt;
}

BakedCones bake_cones(std::span<const float> heights, int width, int height, int sector_count, Baker baker,
                      bake::Address address, double budget_milliseconds, float tolerance,
                      const bake::Progress& progress) {
  if (baker == Baker::relaxed && sector_count != 1 && sector_count != 4) {
    throw std::invalid_argument("the relaxed baker supports 1 or 4 sectors, not " +
                                std::to_string(sector_count));
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
    case Baker::full: throw std::invalid_argument("the full baker bakes bilinear cones only");
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
    throw std::invalid_argument(std::string("bilinear cones bake with the budgeted or the full baker, not ") +
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

}  // namespace displace::pipeline
