// bake/cone_relaxed.cpp - relaxed cone maps (Policarpo & Oliveira, "Relaxed Cone Stepping for
// Relief Mapping", GPU Gems 3), for 1 and 4 sectors.
//
// A relaxed cone may contain relief, as long as a viewing ray inside it crosses the height field at
// most once: a renderer that steps to the cone's edge then lands at most one crossing past the first
// hit, which a binary search finds. As in their preprocessing, for texel c and every other texel d
// we follow the ray from the top of c's axis, (c, 1), through the surface point (d, h(d)) and on
// until it leaves the bilinear relief at E (found exactly, cell by cell, not by marching); the cone must not
// contain E, so its ratio is at most |E - c| / (h(E) - h(c)) when E lies above c. Because E is beyond d and
// no higher than d, that bound is never below d's pair ratio: the max pyramid search of the exact baker
// prunes the texels d (search.h), and a relaxed ratio is never below the conservative one.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>

#include "bake/progress.h"
#include "bake/search.h"

namespace displace::bake {

namespace {

struct Surface {
  const float* heights;
  int width, height;
  Address address;

  double texel(int i, int j) const {
    if (address == Address::wrap) {
      i = ((i % height) + height) % height;
      j = ((j % width) + width) % width;
    } else {
      i = std::clamp(i, 0, height - 1);
      j = std::clamp(j, 0, width - 1);
    }
    return heights[std::size_t(i) * width + j];
  }
};

// The ray (x, y, z) = (x0 + s dx, y0 + s dy, 1 - drop s), s >= 1, starts on the surface at s = 1 (a
// texel centre). Returns the first s > 1 where the bilinear surface is at or below the ray (the
// exit), or a value >= s_stop when the ray stays inside until s_stop. Exact per bilinear cell: along
// a line the bilinear patch is a quadratic in s. Texel (i, j) sits at (j, i).
double exit_parameter(const Surface& surface, double x0, double y0, double dx, double dy, double drop,
                      double s_stop, long long& work) {
  double s = 1.0;
  // the cell the ray enters just after s (a direction with 0 components stays on the cell edge)
  const double eps = 1e-9;
  while (s < s_stop) {
    const double px = x0 + (s + eps) * dx, py = y0 + (s + eps) * dy;
    if (surface.address == Address::clamp &&
        (px < 0.0 || py < 0.0 || px > surface.width - 1.0 || py > surface.height - 1.0))
      return s;  // off the map: nothing there
    const int j = int(std::floor(px)), i = int(std::floor(py));
    // parameter where the ray leaves this cell
    double s_end = s_stop;
    if (dx > 0) s_end = std::min(s_end, (j + 1 - x0) / dx);
    if (dx < 0) s_end = std::min(s_end, (j - x0) / dx);
    if (dy > 0) s_end = std::min(s_end, (i + 1 - y0) / dy);
    if (dy < 0) s_end = std::min(s_end, (i - y0) / dy);
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
    const double probe = std::min(s_end, s + 1e-6 * (s_end - s) + 1e-12);
    if (f(probe) <= 0.0) return s;  // leaves right away
    for (int n = 0; n < root_count; ++n)
      if (roots[n] > s && roots[n] <= s_end) return roots[n];
    if (f(s_end) <= 0.0) return s_end;
    s = s_end;
  }
  return s_stop;
}

}  // namespace

BakeStats bake_relaxed(HeightView heights, Address address, ConeView out, const Progress& progress) {
  validate(heights, out);
  if (out.sector_count != 1 && out.sector_count != 4)
    throw BakeError("relaxed cone maps support 1 or 4 sectors, not " + std::to_string(out.sector_count));
  const auto start = std::chrono::steady_clock::now();
  const detail::Grid grid(heights.width, heights.height, out.sector_count, address);
  const detail::Pyramid pyramid = detail::make_pyramid(heights);
  const detail::SearchContext context{grid, pyramid};
  const std::vector<detail::Node> roots = detail::root_nodes(context);
  const Surface surface{heights.data, heights.width, heights.height, address};
  const int sectors = out.sector_count;
  std::atomic<long long> total_work{0};
  detail::RowProgress rows_done(progress, heights.height);

  tbb::parallel_for(tbb::blocked_range<int>(0, heights.height), [&](const tbb::blocked_range<int>& rows) {
    long long work = 0;
    for (int i = rows.begin(); i < rows.end(); ++i) {
      for (int j = 0; j < heights.width; ++j) {
        const std::size_t t = std::size_t(i) * heights.width + j;
        const float hc = heights.data[t];
        // exit point of the ray from (c, 1) through (d, hq), d at texel offset (dx, dy)
        const detail::LeafRatio leaf = [&](int dx, int dy, float hq) {
          const float pair = detail::pair_ratio(grid.distance(dx, dy), hq - hc);
          if (!(hq < 1.0f)) return pair;         // a horizontal ray along the top leaves at once
          const double drop = 1.0 - double(hq);  // ray height lost per unit of the c -> d offset
          const double s_stop = (1.0 - double(hc)) / drop;
          const double s = exit_parameter(surface, j, i, dx, dy, drop, s_stop, work);
          if (s >= s_stop) return 1.0f;  // inside until below the apex: no constraint
          const double z = 1.0 - drop * s;
          const double u = s * dx * grid.inv_width, v = s * dy * grid.inv_height;
          return float(std::min(1.0, std::sqrt(u * u + v * v) / (z - double(hc))));
        };
        float* best = out.data + t * sectors;
        std::fill_n(best, sectors, 1.0f);
        work += detail::search_texel_leaves(context, i, j, hc, roots, 1.0f, best, nullptr, &leaf);
      }
      rows_done.row_done();
    }
    total_work += work;
  });
  rows_done.finish();

  return detail::whole_map_stats(Mode::exact, heights, sectors, total_work, start, out.data);
}

}  // namespace displace::bake
