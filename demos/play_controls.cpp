// demos/play_controls.cpp - the play window's controls applied to its scene and view.
#include "demos/play_controls.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

#include "demos/commands/settings.h"

namespace displace::app {
namespace {

constexpr float min_elevation = 0.02f;  // radians above the look-at point's horizon
constexpr float max_elevation = 1.5f;
static_assert(std::find(budget_levels.begin(), budget_levels.end(), interactive_budget_ms) !=
              budget_levels.end());

}  // namespace

render::View orbit_view(render::View view, const Controls& controls) {
  if (!controls.orbited) return view;
  render::Camera& camera = view.camera;
  const glm::vec3 offset = camera.eye - camera.look_at;
  const float distance = glm::length(offset) * controls.zoom;
  const float azimuth = std::atan2(offset.y, offset.x) + controls.yaw;
  const float elevation =
      std::clamp(std::asin(std::clamp(offset.z / glm::length(offset), -1.0f, 1.0f)) + controls.pitch,
                 min_elevation, max_elevation);
  camera.eye =
      camera.look_at + distance * glm::vec3(std::cos(elevation) * std::cos(azimuth),
                                            std::cos(elevation) * std::sin(azimuth), std::sin(elevation));
  return view;
}

std::vector<const render::MethodInfo*> play_methods(render::Surface surface) {
  std::vector<const render::MethodInfo*> usable;
  for (const render::MethodInfo& info : render::method_table()) {
    if (render::supports_surface(info.method, surface)) usable.push_back(&info);
  }
  return usable;
}

namespace {

const render::MethodInfo& next_method(render::Method current, int delta, render::Surface surface) {
  const std::vector<const render::MethodInfo*> usable = play_methods(surface);
  const auto at =
      std::find_if(usable.begin(), usable.end(), [&](auto* info) { return info->method == current; });
  const int count = int(usable.size());
  const int index = at == usable.end() ? 0 : int(at - usable.begin());
  return *usable[std::size_t(((index + delta) % count + count) % count)];
}

}  // namespace

bool apply_scene_keys(Controls& controls, pipeline::Scene& scene) {
  bool changed = false;
  if (controls.method_delta != 0) {
    scene.method = next_method(scene.method, controls.method_delta, scene.surface).method;
    controls.method_delta = 0;
    changed = true;
  }
  if (controls.steps_factor != 0) {
    const int steps = controls.steps_factor > 0 ? scene.steps * 2 : scene.steps / 2;
    scene.steps = std::clamp(steps, 1, max_play_steps);
    controls.steps_factor = 0;
    changed = true;
  }
  if (controls.budget_delta != 0) {
    const auto level = std::lower_bound(budget_levels.begin(), budget_levels.end(), scene.frame_ms);
    const int index = std::clamp(int(level - budget_levels.begin()) + controls.budget_delta, 0,
                                 int(budget_levels.size()) - 1);
    scene.frame_ms = budget_levels[std::size_t(index)];
    controls.budget_delta = 0;
    changed = true;
  }
  if (controls.lag_delta != 0) {
    scene.cone_lag_frames =
        std::clamp(scene.cone_lag_frames + controls.lag_delta, 0, pipeline::max_cone_lag_frames);
    controls.lag_delta = 0;
    changed = true;
  }
  return changed;
}

}  // namespace displace::app
