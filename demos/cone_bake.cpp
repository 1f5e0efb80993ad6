// demos/cone_bake.cpp - the device's whole cone maps and the stats line (demos/cone_bake.h).
#include "demos/cone_bake.h"

#include <chrono>
#include <cmath>
#include <nlohmann/json.hpp>

#include "bake/device/device_cones.h"
#include "demos/error.h"
#include "pipeline/maps.h"
#include "sim/device/device_sim.h"

namespace displace::app {

BakedCones bake_bilinear_on_device(render::Renderer& renderer, std::span<const float> heights, int width,
                                   int height, int sector_count, Baker baker, bake::Address address,
                                   double budget_milliseconds, const bake::DeviceFirstPass& first_pass) {
  if (baker != Baker::budgeted && baker != Baker::full) {
    throw usage_error(std::string("bilinear cones bake with the budgeted or the full baker, not ") +
                      baker_name(baker));
  }
  const auto start = std::chrono::steady_clock::now();
  bake::DeviceCones cones(renderer.frames(), bake::HeightView{heights.data(), width, height}, sector_count,
                          address);
  bake::Budget budget;  // the full baker: unlimited
  if (baker == Baker::budgeted) budget.milliseconds = budget_milliseconds;
  cones.bake(budget, first_pass);
  BakedCones baked;
  baked.stats = cones.read_back(&baked.ratios, &baked.apex);
  baked.stats.mode = bake::Mode::bilinear;
  baked.stats.milliseconds =  // the command's wall time, as the CPU bakers report theirs
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
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
