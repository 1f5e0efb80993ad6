#include "render/pass_rows.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "render/shaders/config.h"

namespace displace::render::detail {

namespace {

void add_row(RowRange& range, int row) {  // rows come in increasing order
  if (range.empty()) range.begin = row;
  range.end = row + 1;
}

}  // namespace

// The shader (choose_level) takes the pixel's unnormalised ray t = corner + x along_x + y along_y
// (x, y its centre), d = t / |t|, and
//   detail = log2(eye.z / -d.z * |along_y| / |t| * texels_per_unit) + A log2(-1 / d.z) + B
//          = C + A log2|t| - (1 + A) log2(-t.z),   C = log2(eye.z |along_y| texels_per_unit) + B,
// level floor(detail) clamped to [0, levels]: level 0 where detail < 1. Along a row -t.z is linear
// in x (its extremes at the row's ends) and |t| the root of a quadratic (least at its vertex, most at
// an end), so the row's detail lies between the bounds below. The shader sums t in float from the
// uniforms' float vectors: -t.z is widened by eight roundings of its terms' magnitudes, |t| by a
// relative 1e-6, the detail by 1e-3 (its logarithms and products in float).
PassRows level_pass_rows(const Camera& camera, int levels, int pinned, double texels_per_unit) {
  const Camera::PixelRays exact = camera.pixel_rays();
  const glm::dvec3 corner(glm::vec3(exact.corner)), along_x(glm::vec3(exact.along_x)),
      along_y(glm::vec3(exact.along_y));
  const double eye_z = double(camera.eye.z);
  const double anisotropy = LEVEL_ANISOTROPY;
  const double detail_margin = 1e-3, length_margin = 1e-6, rounding = 8.0 * std::ldexp(1.0, -24);
  const double c = eye_z > 0.0 ? std::log2(eye_z * glm::length(along_y) * texels_per_unit) + LEVEL_BIAS : 0.0;
  const double x0 = 0.5, x1 = double(camera.width) - 0.5;
  PassRows rows;
  for (int row = 0; row < camera.height; ++row) {
    const double y = double(row) + 0.5;
    const glm::dvec3 base = corner + y * along_y;
    const double error = rounding * (std::abs(corner.z) + x1 * std::abs(along_x.z) + y * std::abs(along_y.z));
    const double down0 = -(base.z + x0 * along_x.z), down1 = -(base.z + x1 * along_x.z);
    const double down_lo = std::min(down0, down1) - error, down_hi = std::max(down0, down1) + error;
    const bool sky = eye_z <= 0.0 || down_lo <= 0.0;  // a pixel may see the sky (d.z >= 0)
    const bool plane = eye_z > 0.0 && down_hi > 0.0;  // a pixel may see the plane
    if (sky) add_row(levels > 0 ? rows.sky : rows.level_zero, row);
    if (!plane) continue;
    bool level_zero = false, coarser = false;
    if (levels <= 0 || pinned == 0) {
      level_zero = true;
    } else if (pinned > 0) {
      coarser = true;
    } else {
      const double along = glm::dot(along_x, along_x);
      const double vertex = std::clamp(-glm::dot(base, along_x) / along, x0, x1);
      const double length_lo = glm::length(base + vertex * along_x) * (1.0 - length_margin);
      const double length_hi = std::max(glm::length(base + x0 * along_x), glm::length(base + x1 * along_x)) *
                               (1.0 + length_margin);
      const double detail_lo =
          c + anisotropy * std::log2(length_lo) - (1.0 + anisotropy) * std::log2(down_hi);
      level_zero = detail_lo - detail_margin < 1.0;
      // a row that reaches the horizon has pixels of every detail above its least
      coarser = down_lo <= 0.0 || c + anisotropy * std::log2(length_hi) -
                                          (1.0 + anisotropy) * std::log2(down_lo) + detail_margin >=
                                      1.0;
    }
    if (level_zero) add_row(rows.level_zero, row);
    if (coarser) add_row(rows.coarser, row);
  }
  return rows;
}

}  // namespace displace::render::detail
