// tests/render/level_checks.h - what the tests of the levels of detail share (tests/render/
// detail_levels_test.cpp: the CPU's chain; tests/pipeline/device_levels_test.cpp: the device's): a
// level of the chain as the map maker makes it, an unbounded view whose rays reach a few patches away,
// and the exact distance to a field's first crossing along a pixel's ray on the unbounded plane.
#pragma once

#include <cmath>
#include <cstddef>
#include <utility>

#include "bake/bake.h"
#include "render/render.h"

namespace displace::testing {

// Level `level` (0: the field) of `field`'s chain, as the map maker makes it.
inline render::HeightField level_of(const render::HeightField& field, int level) {
  render::HeightField below = field;
  for (int l = 1; l <= level; ++l) {
    render::HeightField coarse{below.width / 2, below.height / 2, {}};
    coarse.heights.resize(std::size_t(coarse.width) * std::size_t(coarse.height));
    bake::downsample_heights({below.heights.data(), below.width, below.height}, coarse.heights);
    below = std::move(coarse);
  }
  return below;
}

// An unbounded view looking down onto the plane at a slant (rays reach a few patches away).
inline render::View slanted_unbounded_view() {
  render::View view;
  view.unbounded = true;
  view.depth_scale = 0.08f;
  view.camera.eye = {0.3f, -0.3f, 0.6f};
  view.camera.look_at = {0.55f, 0.7f, -0.05f};
  view.camera.width = 56;
  view.camera.height = 44;
  return view;
}

// The world distance from the eye to the exact first crossing of the pixel's ray with `field`'s
// bilinear surface on the unbounded plane (render::first_crossing, wrap, no patch side to leave).
inline double exact_distance(const render::HeightField& field, const render::View& view, int px, int py) {
  const render::Ray ray = view.camera.pixel_ray(px + 0.5, py + 0.5);
  const glm::dvec3 eye = ray.origin, d = ray.direction;
  const glm::dvec3 entry = eye - (eye.z / d.z) * d;
  const double tile = view.tile, depth = view.depth_scale;
  // a whole number of periods over, so that first_crossing's patch [0, 1e9]^2 holds the whole ray
  constexpr double periods = 1000.0;
  const glm::dvec3 origin(entry.x * tile + periods, entry.y * tile + periods, 1.0);
  const glm::dvec3 direction(d.x * tile, d.y * tile, d.z / depth);
  const glm::dvec3 descent(direction.x / -direction.z, direction.y / -direction.z, -1.0);
  const double s = render::first_crossing(field, bake::Address::wrap, 1e9, origin, descent);
  const glm::dvec3 hit = origin + s * descent;
  const glm::dvec3 world((hit.x - periods) / tile, (hit.y - periods) / tile, (hit.z - 1.0) * depth);
  return glm::length(world - eye);
}

}  // namespace displace::testing
