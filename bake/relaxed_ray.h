// bake/relaxed_ray.h - the ray of a relaxed cone's definition (internal to bake/): from the top of a
// texel's axis through a blocker's surface point and on until it leaves the bilinear relief. Both
// relaxed bakers (cone_relaxed.cpp, cone_relaxed_reference.cpp) evaluate a blocker with this one code,
// so that a value they both compute is the same float.
//
// The one fact: relaxed_value() returns V(c, d) = max(pair ratio, ratio of the exit point), and when
// it is given a threshold it stops following the ray as soon as V is proven >= threshold (it then
// returns a value >= threshold). V never drops below the pair ratio, and the ratio of a point on the
// ray never decreases along it, in floats too: every operation in it is monotone.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>

#include "bake/geometry.h"

namespace displace::bake::detail {

// The bilinear surface of a height map, periodic (wrap) or ending at the texel centres (clamp; the
// walk stops there). Texel (i, j) sits at (x, y) = (j, i).
struct RelaxedSurface {
  const float* heights;
  int width, height;
  Address address;
  // first_ends[n] = (n + 1) / n (n >= 1), rounded as a division rounds, for n < first_end_count:
  // where the ray leaves its first cell along an axis (exit_parameter); optional
  const double* first_ends = nullptr;
  int first_end_count = 0;

  double texel(int i, int j) const {
    if (address == Address::wrap) {
      if (unsigned(i) >= unsigned(height)) i = ((i % height) + height) % height;
      if (unsigned(j) >= unsigned(width)) j = ((j % width) + width) % width;
    } else {
      i = std::clamp(i, 0, height - 1);
      j = std::clamp(j, 0, width - 1);
    }
    return heights[std::size_t(i) * width + j];
  }
};

// The ray (x, y, z) = (x0 + s dx, y0 + s dy, 1 - drop s), s >= 1, starts on the surface at s = 1 (a
// texel centre). Returns the first s > 1 where the bilinear surface is at or below the ray (the
// exit), or a value >= s_stop when the ray stays inside until s_stop, or s_stop when it is still
// inside at the start of a cell past the first at an s where give_up(s) is true. Exact per bilinear
// cell: along a line the bilinear patch is a quadratic in s. `work` counts the cells visited.
template <typename GiveUp>
double exit_parameter(const RelaxedSurface& surface, double x0, double y0, double dx, double dy, double drop,
                      double s_stop, const GiveUp& give_up, long long& work) {
  double s = 1.0;
  // the cell the ray enters just after s (a direction with 0 components stays on the cell edge)
  const double eps = 1e-9;
  while (s < s_stop) {
    if (s > 1.0 && give_up(s)) return s_stop;
    const double px = x0 + (s + eps) * dx, py = y0 + (s + eps) * dy;
    if (surface.address == Address::clamp &&
        (px < 0.0 || py < 0.0 || px > surface.width - 1.0 || py > surface.height - 1.0))
      return s;  // off the map: nothing there
    const int j = int(std::floor(px)), i = int(std::floor(py));
    // parameter where the ray leaves this cell
    double s_end = s_stop;
    const int steps_x = int(std::fabs(dx)), steps_y = int(std::fabs(dy));
    if (s == 1.0 && steps_x < surface.first_end_count && steps_y < surface.first_end_count) {
      // the first cell: the divisions below are (|dx| + 1) / |dx| and (|dy| + 1) / |dy| there
      if (dx != 0) s_end = std::min(s_end, surface.first_ends[steps_x]);
      if (dy != 0) s_end = std::min(s_end, surface.first_ends[steps_y]);
    } else {
      if (dx > 0) s_end = std::min(s_end, (j + 1 - x0) / dx);
      if (dx < 0) s_end = std::min(s_end, (j - x0) / dx);
      if (dy > 0) s_end = std::min(s_end, (i + 1 - y0) / dy);
      if (dy < 0) s_end = std::min(s_end, (i - y0) / dy);
    }
    ++work;
    // f(s) = bilinear - z as a quadratic a s^2 + b s + c, with tx = x0 - j + s dx, ty = y0 - i + s dy
    const double h00 = surface.texel(i, j), h01 = surface.texel(i, j + 1);
    const double h10 = surface.texel(i + 1, j), h11 = surface.texel(i + 1, j + 1);
    const double ax = x0 - j, ay = y0 - i;
    // bilinear = h00 + (h01 - h00) tx + (h10 - h00) ty + k tx ty,  k = h00 - h01 - h10 + h11
    const double k = h00 - h01 - h10 + h11;
    const double qa = k * dx * dy;
    const double qb = (h01 - h00) * dx + (h10 - h00) * dy + k * (ax * dy + ay * dx) + drop;
    const double qc = h00 + (h01 - h00) * ax + (h10 - h00) * ay + k * ax * ay - 1.0;
    auto f = [&](double t) { return (qa * t + qb) * t + qc; };
    // first t in (s, s_end] with f(t) <= 0; f(s) >= 0 holds (inside, or on the surface at the start)
    const double probe = std::min(s_end, s + 1e-6 * (s_end - s) + 1e-12);
    if (f(probe) <= 0.0) return s;  // leaves right away
    double roots[2];
    int root_count = 0;
    if (std::fabs(qa) < 1e-15) {
      if (qb != 0.0) roots[root_count++] = -qc / qb;
    } else {
      const double disc = qb * qb - 4.0 * qa * qc;
      if (disc >= 0.0) {
        const double r = std::sqrt(disc);
        const double q = -0.5 * (qb + (qb >= 0 ? r : -r));
        roots[root_count++] = q / qa;
        if (q != 0.0) roots[root_count++] = qc / q;
      }
    }
    if (root_count == 2 && roots[1] < roots[0]) std::swap(roots[0], roots[1]);
    for (int n = 0; n < root_count; ++n)
      if (roots[n] > s && roots[n] <= s_end) return roots[n];
    if (f(s_end) <= 0.0) return s_end;
    s = s_end;
  }
  return s_stop;
}

// The ratio of the ray point at parameter s < s_stop, for the offset (dx, dy) (texels) of texel c
// at height hc; never decreasing in s.
inline float ray_point_ratio(const Grid& grid, int dx, int dy, double drop, float hc, double s) {
  const double z = 1.0 - drop * s;
  const double u = s * dx * grid.inv_width, v = s * dy * grid.inv_height;
  return float(std::min(1.0, std::sqrt(u * u + v * v) / (z - double(hc))));
}

// The relaxed value V(c, d) of blocker d at texel offset (dx, dy) from texel c = (ci, cj), with
// heights hq > hc: the ray from (c, 1) through (d, hq) leaves the relief at E, and V is E's ratio
// |E - c| / (h(E) - hc) (1 when E is not above c), never below the pair ratio `pair`. With
// threshold <= 1, a blocker whose V is proven >= threshold may return any value >= threshold
// (the ray is not followed further); pass a threshold above 1 for the exact V.
inline float relaxed_value(const RelaxedSurface& surface, const Grid& grid, int ci, int cj, float hc, int dx,
                           int dy, float hq, float pair, float threshold, long long& work) {
  if (!(hq < 1.0f)) return pair;         // a horizontal ray along the top leaves at once
  const double drop = 1.0 - double(hq);  // ray height lost per unit of the c -> d offset
  const double s_stop = (1.0 - double(hc)) / drop;
  // past the first cell: where the ray point's ratio reaches the threshold (solved in doubles once,
  // then checked in floats), or infinity
  double s_give_up = threshold <= 1.0f ? -1.0 : std::numeric_limits<double>::infinity();
  const auto give_up = [&](double s) {
    if (s_give_up < 0.0) {
      s_give_up = std::numeric_limits<double>::infinity();
      const double u = double(dx) * grid.inv_width, v = double(dy) * grid.inv_height;
      const double length = std::sqrt(u * u + v * v);
      double at = double(threshold) * (1.0 - double(hc)) / (length + double(threshold) * drop);
      for (int tries = 0; tries < 4 && at < s_stop; ++tries, at *= 1.0 + 1e-9)
        if (ray_point_ratio(grid, dx, dy, drop, hc, at) >= threshold) {
          s_give_up = at;
          break;
        }
    }
    return s >= s_give_up;
  };
  const double s = exit_parameter(surface, cj, ci, dx, dy, drop, s_stop, give_up, work);
  if (s >= s_stop) return 1.0f;  // inside until below the apex (or given up): no constraint
  return std::max(pair, ray_point_ratio(grid, dx, dy, drop, hc, s));
}

}  // namespace displace::bake::detail
