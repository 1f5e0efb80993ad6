// bake/cone_relaxed.cpp - relaxed cone maps (Policarpo & Oliveira, "Relaxed Cone Stepping for
// Relief Mapping", GPU Gems 3), for 1 and 4 sectors: bake_relaxed_reference's map, bit for bit,
// from a search that follows the rays of far fewer blockers.
//
// The one fact: a blocker d's relaxed value V(c, d) is never below its pair ratio (relaxed_ray.h),
// so only a d whose pair ratio is below the ratio found so far can lower it. Per texel and sector,
// the blockers that limited the texel's left and upper neighbours give a first ratio; then rings of
// offsets are scanned, nearest first (a chunk of 8 texels whose maximum cannot lower the ratio is
// skipped whole), and the ray of each candidate is followed where the scan finds it, only until its
// ray point's own ratio reaches the ratio found (or not at all when the ray provably stays inside
// its first cell and the ray point there already has that ratio). The search ends at the first ring whose
// nearest offset could not lower the ratio even at the map's maximum height. Every test compares
// monotone float formulas with a margin over their rounding, so none drops a blocker whose value
// is below the ratio found. The proof is in docs/design/bakers.md, "Relaxed cones".
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/partitioner.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <string>
#include <vector>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "bake/progress.h"
#include "bake/relaxed_ray.h"
#include "bake/relaxed_search.h"

namespace displace::bake {

namespace {

using detail::Grid;

constexpr int rows_per_band = 8;  // rows a thread bakes in order (at most, and at least half as many)
constexpr int chunk_texels = 8;   // texels in a chunk of a row or column whose maximum the scan tests first
// Relative margins of the squared float comparisons below. With u = 2^-24: d2 = x * x + y * y is
// the float whose root pair_ratio takes; if d2 >= fl(fl(gap * gap) * fl(fl(best * best) * (1 +
// scan_margin))), then d2 >= gap^2 best^2 (1 + 1e-5) (1 - u)^4 (1 - 6e-8), so fl(sqrt(d2)) >= gap
// best (1 + 4.6e-6) and fl(fl(sqrt(d2)) / gap) >= best (1 + 4.6e-6) (1 - u) > best: the float pair
// ratio is >= best.
constexpr float scan_margin = 1e-5f;

struct Offset {
  int dx = 0, dy = 0;
};

// The maxima of aligned chunks: of row i's texels [b * 8, b * 8 + 8) at rows[i * row_chunks + b], of
// column j's texels [b * 8, b * 8 + 8) at columns[b * W + j] (the last chunk may be shorter).
struct ChunkMaxima {
  int row_chunks = 0;
  std::vector<float> rows, columns;
};

ChunkMaxima chunk_maxima(HeightView heights) {
  ChunkMaxima maxima;
  const int w = heights.width, h = heights.height;
  maxima.row_chunks = (w + chunk_texels - 1) / chunk_texels;
  maxima.rows.assign(std::size_t(h) * maxima.row_chunks, 0.0f);
  maxima.columns.assign(std::size_t((h + chunk_texels - 1) / chunk_texels) * w, 0.0f);
  for (int i = 0; i < h; ++i)
    for (int j = 0; j < w; ++j) {
      const float value = heights.data[std::size_t(i) * w + j];
      float& row = maxima.rows[std::size_t(i) * maxima.row_chunks + j / chunk_texels];
      float& column = maxima.columns[std::size_t(i / chunk_texels) * w + j];
      row = std::max(row, value);
      column = std::max(column, value);
    }
  return maxima;
}

// The offsets one search looks at: dx in [min_dx, max_dx], dy in [min_dy, max_dy] - a closed
// quadrant (the sector of a 4-sector map) or everything, cut to the map with clamp.
struct Window {
  int min_dx, max_dx, min_dy, max_dy;
};

// Half extents (texels) of the rectangle of ring r: the same uv reach along u and v.
struct Extents {
  int x = 0, y = 0;
};
Extents ring_extents(const Grid& grid, int r) {
  if (grid.width == grid.height) return {r, r};
  if (grid.width > grid.height) return {int((long long)r * grid.width / grid.height), r};
  return {r, int((long long)r * grid.height / grid.width)};
}

// One texel's search in one sector: its ratio so far and the offset that set it.
struct SectorSearch {
  SectorSearch(int i, int j, float h, long long& work_done) : ci(i), cj(j), hc(h), work(work_done) {}

  int ci, cj;
  float hc;
  long long& work;
  float best = 1.0f;
  Offset bound_by;
  float scan_limit = 1.0f + scan_margin;       // best^2 (1 + scan_margin)
  double limit2 = detail::ratio_limit2(1.0f);  // of best, for the ray walk's give-up test

  void lower(float value, Offset by) {
    best = value;
    bound_by = by;
    scan_limit = value * value * (1.0f + scan_margin);
    limit2 = detail::ratio_limit2(value);
  }
  // Whether a texel at squared uv distance d2 (float products) and height hq may have a pair ratio
  // below best: false only when its float pair ratio is at least best, as the margin covers the
  // rounding of d2, of these products and of the pair ratio's root and quotient. Branch free.
  bool may_lower(float d2, float hq) const {
    const float gap = std::max(hq - hc, 0.0f);
    return d2 < gap * gap * scan_limit;
  }
};

// Bit q = (dx < 0) + 2 (dy < 0) of texel d's byte: no corner of the cell that a ray leaving d with
// offset signs q enters first (the cell the ray walk of relaxed_ray.h picks: the + side along a 0
// component) is below d, and that cell is on the map. A ray through d then stays inside the relief
// in that cell: the bilinear surface there is never below d's height and the ray descends from it.
std::vector<std::uint8_t> flat_ahead(HeightView heights, Address address) {
  const int w = heights.width, h = heights.height;
  std::vector<std::uint8_t> bits(std::size_t(w) * h, 0);
  const auto at = [&](int i, int j, float& value) {
    if (address == Address::clamp && (unsigned(i) >= unsigned(h) || unsigned(j) >= unsigned(w))) return false;
    value = heights.data[std::size_t(((i % h) + h) % h) * w + ((j % w) + w) % w];
    return true;
  };
  for (int i = 0; i < h; ++i)
    for (int j = 0; j < w; ++j) {
      const float* p = heights.data + std::size_t(i) * w + j;
      const float hd = *p;
      if (i > 0 && i + 1 < h && j > 0 && j + 1 < w) {  // inside: the eight neighbours without addressing
        const float* up = p - w;
        const float* down = p + w;
        const bool left = p[-1] >= hd, right = p[1] >= hd, above = up[0] >= hd, below = down[0] >= hd;
        bits[std::size_t(i) * w + j] =
            std::uint8_t(int(right && below && down[1] >= hd) | int(left && below && down[-1] >= hd) << 1 |
                         int(right && above && up[1] >= hd) << 2 | int(left && above && up[-1] >= hd) << 3);
        continue;
      }
      for (int q = 0; q < 4; ++q) {
        const int sx = q & 1 ? -1 : 1, sy = q & 2 ? -1 : 1;
        float a = 0, b = 0, c = 0;
        if (at(i, j + sx, a) && at(i + sy, j, b) && at(i + sy, j + sx, c) && a >= hd && b >= hd && c >= hd)
          bits[std::size_t(i) * w + j] |= std::uint8_t(1u << q);
      }
    }
  return bits;
}

// Texel d's entry q (q as in flat_ahead) of four floats: relaxed_ray.h's first_cell_rise of the
// cell a ray with offset signs q enters first after d; +inf where that cell is off the map (clamp).
std::vector<float> first_cell_rises(HeightView heights, Address address) {
  const int w = heights.width, h = heights.height;
  std::vector<float> rises(std::size_t(w) * h * 4, std::numeric_limits<float>::infinity());
  const auto at = [&](int i, int j, double& value) {
    if (address == Address::clamp && (unsigned(i) >= unsigned(h) || unsigned(j) >= unsigned(w))) return false;
    value = heights.data[std::size_t(((i % h) + h) % h) * w + ((j % w) + w) % w];
    return true;
  };
  const auto rows = [&](int i) {
    for (int j = 0; j < w; ++j) {
      const float* p = heights.data + std::size_t(i) * w + j;
      const double h0 = *p;
      float* out = &rises[(std::size_t(i) * w + j) * 4];
      if (i > 0 && i + 1 < h && j > 0 && j + 1 < w) {  // inside: the eight neighbours without addressing
        const float* up = p - w;
        const float* down = p + w;
        const auto rise = [h0](double hx, double hy, double hxy) {
          return float(detail::first_cell_rise(h0, hx, hy, hxy));
        };
        out[0] = rise(p[1], down[0], down[1]);
        out[1] = rise(p[-1], down[0], down[-1]);
        out[2] = rise(p[1], up[0], up[1]);
        out[3] = rise(p[-1], up[0], up[-1]);
        continue;
      }
      for (int q = 0; q < 4; ++q) {
        const int sx = q & 1 ? -1 : 1, sy = q & 2 ? -1 : 1;
        double hx = 0, hy = 0, hxy = 0;
        if (!at(i, j + sx, hx) || !at(i + sy, j, hy) || !at(i + sy, j + sx, hxy)) continue;
        out[q] = float(detail::first_cell_rise(h0, hx, hy, hxy));
      }
    }
  };
  tbb::parallel_for(tbb::blocked_range<int>(0, h, 32), [&](const tbb::blocked_range<int>& band) {
    for (int i = band.begin(); i < band.end(); ++i) rows(i);
  });
  return rises;
}

struct RingSearch {
  const Grid& grid;
  const detail::RelaxedSurface& surface;
  const ChunkMaxima& maxima;
  const std::uint8_t* ahead;  // flat_ahead()
  const float* rises;         // first_cell_rises()
  float map_max;              // the highest texel of the map
  std::size_t texel_count;    // of the map (a chunk's vector loads stay inside it)

  // Whether blocker d, texel (i, j) at offset (dx, dy) with height hq, is proven unable to lower
  // best without following its ray: its first cell does not drop (ahead), or the ray descends
  // faster than that cell rises (rises, with a margin over the walk's own rounding:
  // docs/design/bakers.md), so the ray stays inside the relief up to that cell's end s1 (the walk
  // of relaxed_ray.h finds no exit there and would go on from s1), and the ray point's ratio at s1
  // is already >= best; it never decreases along the ray, so neither the exit's ratio nor V can be
  // below best. s1 is the walk's own first-cell end, (n + 1) / n for the larger n of |dx|, |dy|.
  // length2 = offset_length2(grid, dx, dy).
  bool stays_inside(const SectorSearch& t, int i, int j, int dx, int dy, float hq, double length2) const {
    const int q = int(dx < 0) + 2 * int(dy < 0);
    if (!(hq < 1.0f)) return false;
    const int steps = std::max(std::abs(dx), std::abs(dy));
    if (steps >= surface.first_end_count) return false;
    if (!(ahead[std::size_t(i) * grid.width + j] >> q & 1)) {
      // (the float rise is within 1.2e-7 of the double one: the margin, at least 10^-6, covers it)
      const double rise = rises[(std::size_t(i) * grid.width + j) * 4 + q];
      if (!detail::leaves_no_exit_in_first_cell(1.0 - double(hq), steps, rise)) return false;
    }
    return detail::ray_point_at_least(length2, t.limit2, 1.0 - double(hq), t.hc, surface.first_ends[steps]);
  }

  int wrap_row(int i) const {
    return unsigned(i) < unsigned(grid.height) ? i : ((i % grid.height) + grid.height) % grid.height;
  }
  int wrap_column(int j) const {
    return unsigned(j) < unsigned(grid.width) ? j : ((j % grid.width) + grid.width) % grid.width;
  }

#if defined(__SSE2__)
  // Bits n < count of the chunk's texels that may lower best, four at a time: heights[n] at offset
  // `first` + n along the chunk (uv `inv` a texel) and `across2` squared uv across it - may_lower's
  // float operations on each lane (x * x + across2, then gap * gap * scan_limit).
  static unsigned candidates(const SectorSearch& t, const float* heights, int first, float inv, float across2,
                             int count) {
    const __m128 scale = _mm_set1_ps(inv), across = _mm_set1_ps(across2), hcs = _mm_set1_ps(t.hc);
    const __m128 limit = _mm_set1_ps(t.scan_limit), zero = _mm_setzero_ps();
    unsigned mask = 0;
    for (int half = 0; half < 2; ++half) {
      const __m128 x = _mm_mul_ps(
          _mm_cvtepi32_ps(_mm_add_epi32(_mm_set1_epi32(first + 4 * half), _mm_set_epi32(3, 2, 1, 0))), scale);
      const __m128 d2 = _mm_add_ps(_mm_mul_ps(x, x), across);
      const __m128 gap = _mm_max_ps(_mm_sub_ps(_mm_loadu_ps(heights + 4 * half), hcs), zero);
      mask |= unsigned(_mm_movemask_ps(_mm_cmplt_ps(d2, _mm_mul_ps(_mm_mul_ps(gap, gap), limit))))
              << (4 * half);
    }
    return mask & ((1u << count) - 1);
  }
#endif

  // The offsets (dx, dy), dx in [x0, x1], chunk by chunk: a chunk whose maximum at its nearest
  // offset cannot lower best holds no texel that can (the float products are monotone).
  void scan_row(SectorSearch& t, int dy, int x0, int x1) const {
    const int i = wrap_row(t.ci + dy);
    const float* row = surface.heights + std::size_t(i) * grid.width;
    const float* row_maxima = maxima.rows.data() + std::size_t(i) * maxima.row_chunks;
    const float y = float(dy) * grid.inv_height, y2 = y * y;
    for (int dx = x0; dx <= x1;) {
      const unsigned j = unsigned(wrap_column(t.cj + dx)), chunk = j / chunk_texels;
      const int count = std::min(x1 - dx + 1, std::min(int(chunk + 1) * chunk_texels, grid.width) - int(j));
      const float nearest = float(detail::interval_gap(dx, dx + count - 1)) * grid.inv_width;
      if (t.may_lower(nearest * nearest + y2, row_maxima[chunk])) row_chunk(t, i, row, j, dx, dy, y2, count);
      dx += count;
    }
  }

  // The texels of a chunk of row i that passed: offsets dx .. dx + count - 1, texels j .. j + count - 1.
  [[gnu::noinline]] void row_chunk(SectorSearch& t, int i, const float* row, unsigned j, int dx, int dy,
                                   float y2, int count) const {
#if defined(__SSE2__)
    if (std::size_t(i) * grid.width + j + chunk_texels <= texel_count) {
      // the chunk's texel tests at once (the same float operations as may_lower's); a texel that
      // a ratio lowered meanwhile would drop is evaluated anyway, and evaluate drops it exactly
      for (unsigned mask = candidates(t, row + j, dx, grid.inv_width, y2, count); mask != 0;
           mask &= mask - 1) {
        const int n = __builtin_ctz(mask);
        evaluate(t, i, int(j) + n, dx + n, dy, row[j + n]);
      }
      return;
    }
#endif
    for (int n = 0; n < count; ++n) {
      const float x = float(dx + n) * grid.inv_width, d2 = x * x + y2;
      if (t.may_lower(d2, row[j + n])) evaluate(t, i, int(j) + n, dx + n, dy, row[j + n]);
    }
  }

  // The offsets (dx, dy), dy in [y0, y1], chunk by chunk.
  void scan_column(SectorSearch& t, int dx, int y0, int y1) const {
    const int j = wrap_column(t.cj + dx);
    const float x = float(dx) * grid.inv_width, x2 = x * x;
    for (int dy = y0; dy <= y1;) {
      const unsigned i = unsigned(wrap_row(t.ci + dy)), chunk = i / chunk_texels;
      const int count = std::min(y1 - dy + 1, std::min(int(chunk + 1) * chunk_texels, grid.height) - int(i));
      const float nearest = float(detail::interval_gap(dy, dy + count - 1)) * grid.inv_height;
      if (t.may_lower(nearest * nearest + x2, maxima.columns[std::size_t(chunk) * grid.width + j])) {
#if defined(__SSE2__)
        // as scan_row's chunks, the heights gathered from the column (the missing ones at 0)
        const float* column = surface.heights + std::size_t(i) * grid.width + j;
        const std::size_t stride = std::size_t(grid.width);
        float gathered[chunk_texels] = {};
        for (int n = 0; n < count; ++n) gathered[n] = column[std::size_t(n) * stride];
        // (x2 + y * y there: the same float as y * y + x2)
        for (unsigned mask = candidates(t, gathered, dy, grid.inv_height, x2, count); mask != 0;
             mask &= mask - 1) {
          const int n = __builtin_ctz(mask);
          evaluate(t, int(i) + n, j, dx, dy + n, gathered[n]);
        }
#else
        for (int n = 0; n < count; ++n) {
          const float hq = surface.heights[std::size_t(i + n) * grid.width + j];
          const float y = float(dy + n) * grid.inv_height, d2 = x2 + y * y;
          if (t.may_lower(d2, hq)) evaluate(t, int(i) + n, j, dx, dy + n, hq);
        }
#endif
      }
      dy += count;
    }
  }

  // Follows the ray through the blocker at (dx, dy), texel (i, j), height hq > hc, when its pair
  // ratio is below best and stays_inside does not settle it, only as far as it can lower best.
  void evaluate(SectorSearch& t, int i, int j, int dx, int dy, float hq) const {
    const double length2 = detail::offset_length2(grid, dx, dy);
    if (stays_inside(t, i, j, dx, dy, hq, length2)) return;
    const float pair = detail::pair_ratio(grid.distance(dx, dy), hq - t.hc);
    if (!(pair < t.best)) return;
    ++t.work;
    const float value = detail::relaxed_value(surface, grid, t.ci, t.cj, t.hc, dx, dy, hq, pair, t.best,
                                              length2, t.limit2, t.work);
    if (value < t.best) t.lower(value, {dx, dy});
  }

  // A first ratio from a blocker that limited a neighbour (any real offset in the window will do).
  void seed(SectorSearch& t, const Window& window, Offset offset) const {
    if ((offset.dx == 0 && offset.dy == 0) || offset.dx < window.min_dx || offset.dx > window.max_dx ||
        offset.dy < window.min_dy || offset.dy > window.max_dy)
      return;
    const int i = wrap_row(t.ci + offset.dy), j = wrap_column(t.cj + offset.dx);
    const float hq = surface.heights[std::size_t(i) * grid.width + j];
    if (hq > t.hc) evaluate(t, i, j, offset.dx, offset.dy, hq);
  }

  // Rings of offsets in the window, nearest first, until no offset outside those done has a pair
  // ratio below best even at the map's maximum height.
  void search_rings(SectorSearch& t, const Window& window) const {
    Extents inner;  // done: the window's offsets within +-inner.x, +-inner.y
    for (int r = 1;; ++r) {
      // the squared uv distance of the nearest offset left (the float whose root its distance takes),
      // tested at the map's maximum height as a chunk is
      float reach2 = std::numeric_limits<float>::infinity();
      if (window.max_dx > inner.x || window.min_dx < -inner.x) {
        const float x = float(inner.x + 1) * grid.inv_width;
        reach2 = x * x;
      }
      if (window.max_dy > inner.y || window.min_dy < -inner.y) {
        const float y = float(inner.y + 1) * grid.inv_height;
        reach2 = std::min(reach2, y * y);
      }
      if (!t.may_lower(reach2, map_max)) return;
      const Extents outer = ring_extents(grid, r);
      const int x0 = std::max(-outer.x, window.min_dx), x1 = std::min(outer.x, window.max_dx);
      const int y0 = std::max(-inner.y, window.min_dy), y1 = std::min(inner.y, window.max_dy);
      // the rows above and below the rectangle done, whole; then the columns beside it
      for (int dy = std::max(-outer.y, window.min_dy); dy < y0; ++dy) scan_row(t, dy, x0, x1);
      for (int dy = y1 + 1; dy <= std::min(outer.y, window.max_dy); ++dy) scan_row(t, dy, x0, x1);
      for (int dx = x0; dx < std::max(-inner.x, window.min_dx); ++dx) scan_column(t, dx, y0, y1);
      for (int dx = std::min(inner.x, window.max_dx) + 1; dx <= x1; ++dx) scan_column(t, dx, y0, y1);
      inner = outer;
    }
  }

  // best[k] = texel (ci, cj)'s relaxed ratio in sector k, bound_by[k] the offset that set it ((0, 0):
  // none). left and above (or null) hold those of texels (ci, cj - 1) and (ci - 1, cj): their
  // blockers are tried first.
  void texel(int ci, int cj, const Offset* left, const Offset* above, float* best, Offset* bound_by,
             long long& work) const {
    const float hc = surface.heights[std::size_t(ci) * grid.width + cj];
    const bool clamp = grid.address == Address::clamp;
    constexpr int far = std::numeric_limits<int>::max() / 4;  // no end: every periodic image (wrap)
    const Window map{clamp ? -cj : -far, clamp ? grid.width - 1 - cj : far, clamp ? -ci : -far,
                     clamp ? grid.height - 1 - ci : far};
    for (int k = 0; k < grid.sector_count; ++k) {
      // sector k of 4 is the closed quadrant k (bake.h): dx >= 0 for k = 0, 3, dy >= 0 for k = 0, 1
      Window window = map;
      if (grid.sector_count == 4) {
        if (k == 0 || k == 3)
          window.min_dx = std::max(window.min_dx, 0);
        else
          window.max_dx = std::min(window.max_dx, 0);
        if (k <= 1)
          window.min_dy = std::max(window.min_dy, 0);
        else
          window.max_dy = std::min(window.max_dy, 0);
      }
      SectorSearch t(ci, cj, hc, work);
      if (map_max > hc) {
        if (left && (left[k].dx != 0 || left[k].dy != 0)) seed(t, window, {left[k].dx - 1, left[k].dy});
        if (above && (above[k].dx != 0 || above[k].dy != 0)) seed(t, window, {above[k].dx, above[k].dy - 1});
        search_rings(t, window);
      }
      best[k] = t.best;
      bound_by[k] = t.bound_by;
    }
  }
};

}  // namespace

namespace detail {

CellLows make_cell_lows(const float* heights, int width, int height, Address address) {
  CellLows lows;
  const bool wrap = address == Address::wrap;
  int columns = wrap ? width : width - 1, rows = wrap ? height : height - 1;
  if (columns < 1 || rows < 1) return lows;
  std::vector<float> level(std::size_t(columns) * rows);
  for (int i = 0; i < rows; ++i) {
    const float* row0 = heights + std::size_t(i) * width;
    const float* row1 = heights + std::size_t(i + 1 < height ? i + 1 : 0) * width;
    for (int j = 0; j < columns; ++j) {
      const int next = j + 1 < width ? j + 1 : 0;
      level[std::size_t(i) * columns + j] =
          std::min(std::min(row0[j], row0[next]), std::min(row1[j], row1[next]));
    }
  }
  for (;;) {
    lows.columns.push_back(columns);
    lows.rows.push_back(rows);
    lows.lowest.push_back(std::move(level));
    ++lows.levels;
    if (columns == 1 && rows == 1) break;
    const std::vector<float>& below = lows.lowest.back();
    const int up_columns = (columns + 1) / 2, up_rows = (rows + 1) / 2;
    level.assign(std::size_t(up_columns) * up_rows, 0.0f);
    for (int i = 0; i < up_rows; ++i)
      for (int j = 0; j < up_columns; ++j) {
        float value = below[std::size_t(2 * i) * columns + 2 * j];
        if (2 * j + 1 < columns) value = std::min(value, below[std::size_t(2 * i) * columns + 2 * j + 1]);
        if (2 * i + 1 < rows) {
          value = std::min(value, below[std::size_t(2 * i + 1) * columns + 2 * j]);
          if (2 * j + 1 < columns)
            value = std::min(value, below[std::size_t(2 * i + 1) * columns + 2 * j + 1]);
        }
        level[std::size_t(i) * up_columns + j] = value;
      }
    columns = up_columns;
    rows = up_rows;
  }
  return lows;
}

struct RelaxedSearch::Impl {
  Impl(HeightView map, Address address, int sector_count)
      : heights(map),
        grid(map.width, map.height, sector_count, address),
        first_ends(std::size_t(std::max(map.width, map.height)) + 1),
        maxima(chunk_maxima(map)),
        ahead(flat_ahead(map, address)),
        rises(first_cell_rises(map, address)),
        lows(make_cell_lows(map.data, map.width, map.height, address)) {
    for (std::size_t n = 1; n < first_ends.size(); ++n) first_ends[n] = double(n + 1) / double(n);
  }

  HeightView heights;
  Grid grid;
  std::vector<double> first_ends;
  ChunkMaxima maxima;
  std::vector<std::uint8_t> ahead;
  std::vector<float> rises;
  CellLows lows;
  RelaxedSurface surface{heights.data,      heights.width,          heights.height, grid.address,
                         first_ends.data(), int(first_ends.size()), &lows};
  float map_max = *std::max_element(heights.data, heights.data + std::size_t(heights.width) * heights.height);
  RingSearch search{grid,
                    surface,
                    maxima,
                    ahead.data(),
                    rises.data(),
                    map_max,
                    std::size_t(heights.width) * heights.height};
};

RelaxedSearch::RelaxedSearch(HeightView heights, Address address, int sector_count)
    : impl_(std::make_unique<Impl>(heights, address, sector_count)) {}
RelaxedSearch::~RelaxedSearch() = default;

namespace {

// Texels [first, last) of row i into `out`; above: the offsets that limited row i - 1's texels, or
// null; bound_by receives this row's, from texel `first` on.
void relax_texels(const RingSearch& search, int i, int first, int last, const Offset* above, Offset* bound_by,
                  float* out, long long& work) {
  const int sectors = search.grid.sector_count;
  for (int j = first; j < last; ++j) {
    const std::size_t at = std::size_t(j - first) * sectors;
    search.texel(i, j, j > first ? &bound_by[at - sectors] : nullptr, above ? &above[at] : nullptr,
                 out + (std::size_t(i) * search.grid.width + j) * sectors, &bound_by[at], work);
  }
}

}  // namespace

long long RelaxedSearch::rows(int first, int last, float* out) const {
  const Impl& m = *impl_;
  long long work = 0;
  // the offsets that limited the previous row's texels and this row's
  std::vector<Offset> previous(std::size_t(m.grid.width) * m.grid.sector_count), current(previous.size());
  for (int i = first; i < last; ++i) {
    relax_texels(m.search, i, 0, m.grid.width, i > first ? previous.data() : nullptr, current.data(), out,
                 work);
    std::swap(previous, current);
  }
  return work;
}

long long RelaxedSearch::texels(int row, int first, int last, float* out) const {
  const Impl& m = *impl_;
  long long work = 0;
  std::vector<Offset> bound_by(std::size_t(std::max(last - first, 0)) * m.grid.sector_count);
  relax_texels(m.search, row, first, last, nullptr, bound_by.data(), out, work);
  return work;
}

}  // namespace detail

BakeStats bake_relaxed(HeightView heights, Address address, ConeView out, const Progress& progress) {
  validate(heights, out);
  if (out.sector_count != 1 && out.sector_count != 4)
    throw BakeError("relaxed cone maps support 1 or 4 sectors, not " + std::to_string(out.sector_count));
  const auto start = std::chrono::steady_clock::now();
  const detail::RelaxedSearch search(heights, address, out.sector_count);
  std::atomic<long long> total_work{0};
  detail::RowProgress rows_done(progress, heights.height);
  // bands of rows, each on one thread from top to bottom, so that a row's texels find the blockers of
  // the row above
  tbb::parallel_for(
      tbb::blocked_range<int>(0, heights.height, rows_per_band),
      [&](const tbb::blocked_range<int>& band) {
        total_work += search.rows(band.begin(), band.end(), out.data);
        for (int i = band.begin(); i < band.end(); ++i) rows_done.row_done();
      },
      tbb::simple_partitioner());
  rows_done.finish();
  return detail::whole_map_stats(Mode::exact, heights, out.sector_count, total_work, start, out.data);
}

}  // namespace displace::bake
