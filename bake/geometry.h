// bake/geometry.h - the geometry every baker shares (internal to bake/).
//
// One fact matters here: every baker computes distances and ratios with the SAME floating-point
// formulas, and those formulas are monotone (a smaller texel offset or a larger height gap never
// gives a larger ratio, even after rounding). That is what lets a bound computed from a pyramid
// node be compared bit-for-bit with the exact ratio of any texel inside the node.
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "bake/bake.h"

namespace displace::bake::detail {

// The smallest float at least x, and the largest float at most max(0, x): a double bound kept as a
// float on its safe side.
inline float float_at_least(double x) {
  float rounded = float(x);
  if (double(rounded) < x) rounded = std::nextafter(rounded, std::numeric_limits<float>::infinity());
  return rounded;
}
inline float float_at_most(double x) {
  if (!(x > 0.0)) return 0.0f;
  float rounded = float(x);
  if (double(rounded) > x) rounded = std::nextafter(rounded, 0.0f);
  return rounded;
}

// uv geometry of a W x H map. Directions are tested on the integer vector (dx * H, dy * W), which
// points the same way as the uv offset (dx / W, dy / H), so sector tests are exact.
struct Grid {
  int width = 0;
  int height = 0;
  float inv_width = 0.0f;   // uv per texel along u
  float inv_height = 0.0f;  // uv per texel along v
  int sector_count = 1;
  Address address = Address::wrap;

  Grid(int w, int h, int sectors, Address addr)
      : width(w),
        height(h),
        inv_width(1.0f / float(w)),
        inv_height(1.0f / float(h)),
        sector_count(sectors),
        address(addr) {}

  // uv distance of a texel offset; monotone in |dx| and |dy|.
  float distance(int dx, int dy) const {
    const float x = float(dx) * inv_width;
    const float y = float(dy) * inv_height;
    return std::sqrt(x * x + y * y);
  }
};

// The cone ratio one blocker imposes; monotone increasing in distance, decreasing in gap (> 0).
inline float pair_ratio(float distance, float gap) { return distance / gap; }

using SectorMask = std::uint32_t;

// Sectors (bit k = sector k) whose closed wedge contains the direction of the texel offset (dx, dy) != 0.
inline SectorMask point_sectors(const Grid& grid, int dx, int dy) {
  if (grid.sector_count == 1) return 1u;
  const std::int64_t x = std::int64_t(dx) * grid.height;
  const std::int64_t y = std::int64_t(dy) * grid.width;
  SectorMask mask = 0;
  if (grid.sector_count == 4) {
    if (x >= 0 && y >= 0) mask |= 1u << 0;
    if (x <= 0 && y >= 0) mask |= 1u << 1;
    if (x <= 0 && y <= 0) mask |= 1u << 2;
    if (x >= 0 && y <= 0) mask |= 1u << 3;
    return mask;
  }
  const std::int64_t ax = x < 0 ? -x : x;
  const std::int64_t ay = y < 0 ? -y : y;
  if (x >= 0 && y >= 0 && ay <= ax) mask |= 1u << 0;
  if (x >= 0 && y >= 0 && ax <= ay) mask |= 1u << 1;
  if (x <= 0 && y >= 0 && ax <= ay) mask |= 1u << 2;
  if (x <= 0 && y >= 0 && ay <= ax) mask |= 1u << 3;
  if (x <= 0 && y <= 0 && ay <= ax) mask |= 1u << 4;
  if (x <= 0 && y <= 0 && ax <= ay) mask |= 1u << 5;
  if (x >= 0 && y <= 0 && ax <= ay) mask |= 1u << 6;
  if (x >= 0 && y <= 0 && ay <= ax) mask |= 1u << 7;
  return mask;
}

// Sectors whose closed wedge meets the rectangle of texel offsets [x0, x1] x [y0, y1] (taken as a
// continuous rectangle, so the answer is a superset of the sectors of the texels inside).
inline SectorMask rect_sectors(const Grid& grid, int x0, int x1, int y0, int y1) {
  if (grid.sector_count == 1) return 1u;
  const std::int64_t X0 = std::int64_t(x0) * grid.height, X1 = std::int64_t(x1) * grid.height;
  const std::int64_t Y0 = std::int64_t(y0) * grid.width, Y1 = std::int64_t(y1) * grid.width;
  SectorMask mask = 0;
  if (grid.sector_count == 4) {
    if (X1 >= 0 && Y1 >= 0) mask |= 1u << 0;
    if (X0 <= 0 && Y1 >= 0) mask |= 1u << 1;
    if (X0 <= 0 && Y0 <= 0) mask |= 1u << 2;
    if (X1 >= 0 && Y0 <= 0) mask |= 1u << 3;
    return mask;
  }
  // For each octant pick the rectangle point closest to satisfying its diagonal constraint.
  if (X1 >= 0 && Y1 >= 0 && std::max<std::int64_t>(Y0, 0) <= X1) mask |= 1u << 0;
  if (X1 >= 0 && Y1 >= 0 && std::max<std::int64_t>(X0, 0) <= Y1) mask |= 1u << 1;
  if (X0 <= 0 && Y1 >= 0 && -std::min<std::int64_t>(X1, 0) <= Y1) mask |= 1u << 2;
  if (X0 <= 0 && Y1 >= 0 && std::max<std::int64_t>(Y0, 0) <= -X0) mask |= 1u << 3;
  if (X0 <= 0 && Y0 <= 0 && -std::min<std::int64_t>(Y1, 0) <= -X0) mask |= 1u << 4;
  if (X0 <= 0 && Y0 <= 0 && -std::min<std::int64_t>(X1, 0) <= -Y0) mask |= 1u << 5;
  if (X1 >= 0 && Y0 <= 0 && std::max<std::int64_t>(X0, 0) <= -Y0) mask |= 1u << 6;
  if (X1 >= 0 && Y0 <= 0 && -std::min<std::int64_t>(Y1, 0) <= X1) mask |= 1u << 7;
  return mask;
}

// Texel gap between 0 and the integer interval [a, b] (0 when it contains 0).
inline int interval_gap(int a, int b) { return a > 0 ? a : (b < 0 ? -b : 0); }

// Floor division for possibly negative numerators.
inline int floor_div(int a, int b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }

// The max pyramid seen as a periodic (wrap) or bounded (clamp) plane of blocks. A block at level L
// has an "unrolled" index n along each axis: tile floor(n / count) and in-tile index n mod count;
// it covers texels [tile * size + b * 2^L, tile * size + min((b + 1) * 2^L, size) - 1].
struct Pyramid {
  MaxPyramid max;
  int levels = 0;

  int count_x(int level) const { return max.widths[level]; }
  int count_y(int level) const { return max.heights[level]; }
  float value(int level, int by, int bx) const {
    return max.levels[level][std::size_t(by) * max.widths[level] + bx];
  }
};

// Inclusive texel range of unrolled block n at `level` along an axis of `size` texels.
inline void block_range(int n, int level, int count, int size, int& first, int& last) {
  const int tile = floor_div(n, count);
  const int b = n - tile * count;
  first = tile * size + (b << level);
  last = tile * size + std::min((b + 1) << level, size) - 1;
}

// Mean of `count` ratios (BakeStats::mean_ratio).
inline double mean_of(const float* data, std::size_t count) {
  double sum = 0.0;
  for (std::size_t i = 0; i < count; ++i) sum += data[i];
  return count ? sum / double(count) : 0.0;
}

// The stats of a bake that computed every texel of `out` (a W x H map, `sectors` ratios each),
// started at `start`.
inline BakeStats whole_map_stats(Mode mode, HeightView heights, int sectors, long long work,
                                 std::chrono::steady_clock::time_point start, const float* out) {
  BakeStats stats;
  stats.mode = mode;
  stats.width = heights.width;
  stats.height = heights.height;
  stats.sector_count = sectors;
  stats.texels_refined = (long long)heights.width * heights.height;
  stats.work = work;
  stats.milliseconds =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  stats.mean_ratio = mean_of(out, std::size_t(heights.width) * heights.height * sectors);
  return stats;
}

}  // namespace displace::bake::detail
