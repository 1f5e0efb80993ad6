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
#include <vector>

#include "bake/geometry.h"

namespace displace::bake::detail {

// The lowest corner of every cell (the square between four texel centres; with clamp only those on
// the map, where the walk stays) and of aligned blocks of 2^L x 2^L cells, L < levels (cut at the
// map's end, so that a block never crosses a wrap seam): the walk jumps over a block whose lowest
// corner is above the ray where it enters the block.
struct CellLows {
  int levels = 0;
  std::vector<int> columns, rows;          // blocks per row and per column, per level
  std::vector<std::vector<float>> lowest;  // per level, row-major
  float at(int level, int i, int j) const { return lowest[level][std::size_t(i) * columns[level] + j]; }
};
CellLows make_cell_lows(const float* heights, int width, int height, Address address);  // cone_relaxed.cpp

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
  const CellLows* lows = nullptr;  // optional: block jumps (make_cell_lows of these heights)

  // texel index a (of n along an axis) under the address mode
  int address_texel(int a, int n) const {
    if (unsigned(a) < unsigned(n)) return a;
    return address == Address::wrap ? ((a % n) + n) % n : std::clamp(a, 0, n - 1);
  }
  // The corners h00 = (i, j), h01 = (i, j + 1), h10 = (i + 1, j), h11 = (i + 1, j + 1) of cell (i, j).
  void corners(int i, int j, double& h00, double& h01, double& h10, double& h11) const {
    const float* row0 = heights + std::size_t(address_texel(i, height)) * width;
    const float* row1 = heights + std::size_t(address_texel(i + 1, height)) * width;
    const int j0 = address_texel(j, width), j1 = address_texel(j + 1, width);
    h00 = row0[j0];
    h01 = row0[j1];
    h10 = row1[j0];
    h11 = row1[j1];
  }
};

// floor(x) for |x| < 2^31, without SSE4.1's rounding instruction (the baseline x86-64 target has none)
inline int floor_to_int(double x) {
  const int t = int(x);
  return t - int(double(t) > x);
}

// The ray (x, y, z) = (x0 + s dx, y0 + s dy, 1 - drop s), s >= 1, starts on the surface at s = 1 (a
// texel centre). Returns the first s > 1 where the bilinear surface is at or below the ray (the
// exit), or a value >= s_stop when the ray stays inside until s_stop, or s_stop when it is still
// inside at the start of a cell past the first at an s where give_up(s) is true. Exact per bilinear
// cell: along a line the bilinear patch is a quadratic in s. `work` counts the cells visited.
template <typename GiveUp>
[[gnu::always_inline]] inline double exit_parameter(const RelaxedSurface& surface, double x0, double y0,
                                                    double dx, double dy, double drop, double s_stop,
                                                    const GiveUp& give_up, long long& work) {
  double s = 1.0;
  // the cell the ray enters just after s (a direction with 0 components stays on the cell edge)
  const double eps = 1e-9;
  while (s < s_stop) {
    if (s > 1.0 && give_up(s)) return s_stop;
    const double px = x0 + (s + eps) * dx, py = y0 + (s + eps) * dy;
    if (surface.address == Address::clamp &&
        (px < 0.0 || py < 0.0 || px > surface.width - 1.0 || py > surface.height - 1.0))
      return s;  // off the map: nothing there
    const int j = floor_to_int(px), i = floor_to_int(py);
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
    double h00, h01, h10, h11;
    surface.corners(i, j, h00, h01, h10, h11);
    // The bilinear surface in the cell is never below its lowest corner, and the ray only descends:
    // when that corner is above the ray where it enters the cell, the ray stays inside the whole cell
    // (flat tops and plateaus). In the first cell the ray starts on its blocker's corner, at z =
    // 1 - drop = h(d) exactly, and is below it for every s > 1: inside when no corner is lower. Later,
    // z = 1 - drop s is within 1e-15 of its rounded value: the margin covers it.
    const double lowest = std::min(std::min(h00, h01), std::min(h10, h11));
    if (s == 1.0) {
      if (lowest >= 1.0 - drop) {
        s = s_end;
        continue;
      }
    } else if (const double z = 1.0 - drop * s + 1e-12; lowest > z) {
      // and the largest aligned block around the cell whose lowest corner is above the ray there
      const CellLows* lows = surface.lows;
      const int iw = surface.address_texel(i, surface.height), jw = surface.address_texel(j, surface.width);
      int level = 0;
      if (lows && iw < lows->rows[0] && jw < lows->columns[0])
        while (level + 1 < lows->levels && lows->at(level + 1, iw >> (level + 1), jw >> (level + 1)) > z)
          ++level;
      if (level > 0) {
        // the block's edges where the ray is (the walk's x and y: unwrapped), cut at the map's end
        const int row0 = iw >> level << level, column0 = jw >> level << level;
        const int row1 = std::min(row0 + (1 << level), lows->rows[0]);
        const int column1 = std::min(column0 + (1 << level), lows->columns[0]);
        const double x_low = j - jw + column0, x_high = j - jw + column1;
        const double y_low = i - iw + row0, y_high = i - iw + row1;
        double s_block = s_stop;
        if (dx > 0) s_block = std::min(s_block, (x_high - x0) / dx);
        if (dx < 0) s_block = std::min(s_block, (x_low - x0) / dx);
        if (dy > 0) s_block = std::min(s_block, (y_high - y0) / dy);
        if (dy < 0) s_block = std::min(s_block, (y_low - y0) / dy);
        s = std::max(s_block, s_end);  // (the same formulas as s_end's with edges no nearer: never less)
      } else {
        s = s_end;
      }
      continue;
    }
    // f(s) = bilinear - z as a quadratic a s^2 + b s + c, with tx = x0 - j + s dx, ty = y0 - i + s dy
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
    // f > 0 at probe and at s_end: it has a root in (s, s_end] only if it is convex with its vertex
    // there and not above 0 at it; otherwise the ray stays inside the cell (no roots to solve)
    if (f(s_end) > 0.0) {
      if (!(qa > 0.0)) {
        s = s_end;
        continue;
      }
      const double vertex = -qb / (2.0 * qa);
      if (!(vertex > s && vertex < s_end) || f(vertex) > 0.0) {
        s = s_end;
        continue;
      }
    }
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

// Whether ray_point_ratio(grid, dx, dy, drop, hc, s) >= threshold (threshold <= 1) is proven, on
// squares: length2 = |(dx / W, dy / H)|^2 and limit2 = threshold^2 (1 + 1e-6) in doubles. The
// relative margin covers the roundings of ray_point_ratio's doubles and of its float; a ray point at
// or below hc's height (z <= hc: at or past s_stop) counts as proven, its exit's V being 1.
inline bool ray_point_at_least(double length2, double limit2, double drop, float hc, double s) {
  const double gap = 1.0 - drop * s - double(hc);
  return gap <= 0.0 || s * s * length2 >= gap * gap * limit2;
}
inline double offset_length2(const Grid& grid, int dx, int dy) {
  const double u = double(dx) * grid.inv_width, v = double(dy) * grid.inv_height;
  return u * u + v * v;
}
inline double ratio_limit2(float threshold) { return double(threshold) * double(threshold) * (1.0 + 1e-6); }

// A ray leaving blocker d's top descends `drop` = 1 - h(d) per unit of its parameter s, n texels
// along its larger offset component. first_cell_rise is how fast (height per texel along that
// component) it must descend to stay inside the cell it enters first, whose corners are h0 = h(d),
// hx and hy (d's neighbours in that cell along x and y) and hxy: at t texels along the larger
// component and b t (0 <= b <= 1) along the other, surface minus ray is t (g + k b t), k = h0 - hx -
// hy + hxy, g = hx - h0 + b (hy - h0) + D for a descent D (x the larger; hx and hy swap otherwise),
// positive on (0, 1] when g and g + k b are, both linear in b. leaves_no_exit_in_first_cell adds a
// margin of 10^-6 (1 + n^2) over the rounding of exit_parameter's own quadratic in that cell (terms
// up to about 28 n^2, its first probe 10^-6 cell in): when it holds, exit_parameter finds no exit
// before the cell's end. Proof: docs/design/bakers.md, "Relaxed cones".
inline double first_cell_rise(double h0, double hx, double hy, double hxy) {
  return std::max(std::max(h0 - hx, h0 - hy), std::max(2.0 * h0 - hx - hy, h0 - hxy));
}
inline bool leaves_no_exit_in_first_cell(double drop, int n, double rise) {
  const double steps = double(n);
  return drop >= (rise + 1e-6 * (1.0 + steps * steps)) * steps;
}

// The relaxed value V(c, d) of blocker d at texel offset (dx, dy) from texel c = (ci, cj), with
// heights hq > hc: the ray from (c, 1) through (d, hq) leaves the relief at E, and V is E's ratio
// |E - c| / (h(E) - hc) (1 when E is not above c), never below the pair ratio `pair`. With
// threshold <= 1, a blocker whose V is proven >= threshold may return any value >= threshold
// (the ray is not followed further); pass a threshold above 1 for the exact V.
// length2 = offset_length2(grid, dx, dy) and limit2 = ratio_limit2(threshold), as the caller has them.
inline float relaxed_value(const RelaxedSurface& surface, const Grid& grid, int ci, int cj, float hc, int dx,
                           int dy, float hq, float pair, float threshold, double length2, double limit2,
                           long long& work) {
  if (!(hq < 1.0f)) return pair;         // a horizontal ray along the top leaves at once
  const double drop = 1.0 - double(hq);  // ray height lost per unit of the c -> d offset
  const double s_stop = (1.0 - double(hc)) / drop;
  // past the first cell: given up where the ray point's own ratio reaches the threshold (it never
  // decreases along the ray, so the exit's cannot be below it); never with a threshold above 1
  const auto give_up = [&](double s) {
    return threshold <= 1.0f && ray_point_at_least(length2, limit2, drop, hc, s);
  };
  const double s = exit_parameter(surface, cj, ci, dx, dy, drop, s_stop, give_up, work);
  if (s >= s_stop) return 1.0f;  // inside until below the apex (or given up): no constraint
  return std::max(pair, ray_point_ratio(grid, dx, dy, drop, hc, s));
}
inline float relaxed_value(const RelaxedSurface& surface, const Grid& grid, int ci, int cj, float hc, int dx,
                           int dy, float hq, float pair, float threshold, long long& work) {
  return relaxed_value(surface, grid, ci, cj, hc, dx, dy, hq, pair, threshold, offset_length2(grid, dx, dy),
                       ratio_limit2(threshold), work);
}

}  // namespace displace::bake::detail
