// bake/cone_coarse_sweep.cpp - EXPERIMENTAL: quadrant cone ratios from dilation sweeps on a coarse
// grid of B x B cells (the budgeted baker's stage S moved to cell maxima), plus a near field.
//
// One fact matters: for a texel c at offset s (texels, from the cell corner that faces the
// quadrant) inside cell C, and a cell D at nominal offset (a, b) cells, every texel q of D in the
// quadrant has |q - c| >= oct(aP, bP) - oct(s) (oct = max(L-infinity, L1 / sqrt 2), a norm below
// the Euclidean one; P = the smallest cell width). So "ratio >= r against every far cell" holds when
// max over far D of (M(D) - oct(D - C) / r) + oct(s) / r <= h(c), and that maximum is a lattice
// dilation computed by recurrences (row ray, column ray, diagonal, L1 steps) for all lanes at once.
// The near cells (a <= 1 and b <= 1), where that bound is loosest, are left out of the sweep and
// bounded per texel: an exact scan of their texels, or the own cell exactly and the three others as
// boxes. Wrap: the sweep starts far enough beyond the map that nothing further can fail a lane.
// Between the last lane that passes and the first that fails, the dilation (a maximum of functions
// linear in 1 / r, so convex in 1 / r) lies below its chord, and the chord gives a ratio between lanes.
// Measured (docs/budgeted-speed.md): ~14 ms for 0.82 (B 4) and ~19 ms for 0.85 (B 2) on the 512 ocean.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <vector>

#include "bake/bake.h"
#include "bake/geometry.h"

namespace displace::bake {

namespace {

constexpr float absent = -1e30f;                 // height of "nothing there"
constexpr float rounding_margin = 1.0f - 1e-4f;  // covers the rounding the recurrences accumulate
constexpr float inv_sqrt2 = 0.70710678f;
constexpr float chord_slack = 1e-4f;  // height units kept below h(c) in the chord test, for rounding

struct Frame {  // one quadrant seen so that its blockers are at larger virtual (i, j)
  int width, height;
  bool flip_x, flip_y;
  std::size_t real(int vi, int vj) const {
    return std::size_t(flip_y ? height - 1 - vi : vi) * width + (flip_x ? width - 1 - vj : vj);
  }
};

template <int L>
[[gnu::always_inline]] inline void coarse_quadrant(const detail::Grid& grid, const float* heights, float height_max,
                                                   float height_range, int quadrant,
                                                   const CoarseSweepSettings& settings,
                                                   const std::array<float, L>& lanes,
                                                   const std::vector<float>& inverse_distance, float* ratio_out,
                                                   std::vector<float>& padded) {
  const int width = grid.width, height = grid.height, B = settings.cell_size;
  const bool wrap = grid.address == Address::wrap;
  const Frame frame{width, height, quadrant == 1 || quadrant == 2, quadrant >= 2};
  // heights in the virtual frame, padded by 2B texels right and below (wrap: periodic; clamp: below
  // every height) so that the near field reads them with no address arithmetic
  const int padded_width = width + 2 * B, padded_height = height + 2 * B;
  padded.resize(std::size_t(padded_width) * padded_height);
  for (int vi = 0; vi < padded_height; ++vi) {
    float* row = &padded[std::size_t(vi) * padded_width];
    if (!wrap && vi >= height) {
      std::fill_n(row, padded_width, -1.0f);
      continue;
    }
    const int i = frame.flip_y ? height - 1 - vi % height : vi % height;
    const float* source = heights + std::size_t(i) * width;
    if (frame.flip_x) {
      for (int vj = 0; vj < width; ++vj) row[vj] = source[width - 1 - vj];
    } else {
      std::copy_n(source, width, row);
    }
    for (int vj = width; vj < padded_width; ++vj) row[vj] = wrap ? row[vj % width] : -1.0f;
  }
  auto vh = [&](int vi, int vj) { return padded[std::size_t(vi) * padded_width + vj]; };

  // cell maxima (the last cell along an axis may be partial), two absent columns after each row
  const int cells_x = (width + B - 1) / B, cells_y = (height + B - 1) / B;
  const int pitch_x = wrap ? width - (cells_x - 1) * B : B, pitch_y = wrap ? height - (cells_y - 1) * B : B;
  const int max_stride = cells_x + 2;
  std::vector<float> cell_max(std::size_t(max_stride) * cells_y, absent);
  for (int vi = 0; vi < height; ++vi) {
    float* target = &cell_max[std::size_t(vi / B) * max_stride];
    for (int cx = 0; cx < cells_x; ++cx) {
      float m = target[cx];
      for (int vj = cx * B; vj < std::min(width, (cx + 1) * B); ++vj) m = std::max(m, vh(vi, vj));
      target[cx] = m;
    }
  }

  // per-lane steps of the nominal lattice, in height units
  const float cell_u = float(pitch_x) * grid.inv_width, cell_v = float(pitch_y) * grid.inv_height;
  alignas(64) float step_x[L], step_y[L], step_diagonal[L], step_l1_x[L], step_l1_y[L], inv_lane[L], passed[L];
  for (int l = 0; l < L; ++l) {
    step_x[l] = cell_u / lanes[l];
    step_y[l] = cell_v / lanes[l];
    step_diagonal[l] = std::min(step_x[l], step_y[l]);
    step_l1_x[l] = step_x[l] * inv_sqrt2;
    step_l1_y[l] = step_y[l] * inv_sqrt2;
    inv_lane[l] = 1.0f / lanes[l];
    passed[l] = lanes[l] * rounding_margin;
  }
  // warm-up: beyond reach cells the nominal distance exceeds the largest lane times the range plus
  // the largest per-texel correction, so no cell further out can fail a lane
  auto reach = [&](float cell_uv, float texel_uv) {
    return wrap ? int(std::ceil((lanes[L - 1] * height_range + 2.0f * float(B) * texel_uv) / cell_uv)) + 4 : 0;
  };
  const int reach_x = reach(cell_u, grid.inv_width), reach_y = reach(cell_v, grid.inv_height);
  const int columns = cells_x + reach_x + 3;
  std::vector<int> column_index(columns);  // lattice column -> stored column (clamp: beyond = absent pads)
  for (int vj = 0; vj < columns; ++vj) column_index[vj] = wrap ? vj % cells_x : std::min(vj, cells_x);

  // three rolling rows of (cells_x + 2) cells x L lanes: row ray, column ray, L-infinity, L1
  const std::size_t row_size = std::size_t(cells_x + 2) * L;
  std::vector<float> rows[3][4];
  for (auto& row : rows)
    for (auto& a : row) a.assign(row_size, absent);
  enum { ray_x = 0, ray_y = 1, inf = 2, l1 = 3 };
  // the cell row's far-field dilations per lane, per metric (a lane passes when either metric passes)
  std::vector<float> threshold_inf(std::size_t(cells_x) * L), threshold_l1(threshold_inf.size());
  // per-texel corrections L-infinity(s) and L1(s) / sqrt 2, s from the cell corner facing the
  // quadrant (the virtual low corner): each metric's triangle inequality
  std::vector<float> correction_inf(std::size_t(B) * B), correction_l1(std::size_t(B) * B);
  for (int sy = 0; sy < B; ++sy)
    for (int sx = 0; sx < B; ++sx) {
      const float x = float(sx) * grid.inv_width, y = float(sy) * grid.inv_height;
      correction_inf[std::size_t(sy) * B + sx] = std::max(x, y);
      correction_l1[std::size_t(sy) * B + sx] = (x + y) * inv_sqrt2;
    }
  const float nearest_far = std::min(float(pitch_x + 1) * grid.inv_width, float(pitch_y + 1) * grid.inv_height);
  std::vector<int> top_lane(width), sub_x(width), cell_of(width);
  for (int tj = 0; tj < width; ++tj) cell_of[tj] = tj / B, sub_x[tj] = tj % B;
  const std::vector<float> nothing_row(L, absent);
  const float* nothing = nothing_row.data();
  for (int vi = cells_y - 1 + reach_y; vi >= 0; --vi) {
    const int top_row = cells_y - 1 + reach_y;
    // rows below: clamp has nothing beyond the map; wrap's first rows read nothing below the start
    const bool has_below1 = wrap ? vi + 1 <= top_row : vi + 1 < cells_y;
    const bool has_below2 = wrap ? vi + 2 <= top_row : vi + 2 < cells_y;
    std::vector<float>* current = rows[vi % 3];
    std::vector<float>* below1 = rows[(vi + 1) % 3];
    std::vector<float>* below2 = rows[(vi + 2) % 3];
    auto cur = [&](int kind, int vj) { return &current[kind][std::size_t(column_index[vj]) * L]; };
    auto b1 = [&](int kind, int vj) -> const float* {
      return has_below1 ? &below1[kind][std::size_t(column_index[vj]) * L] : nothing;
    };
    auto b2 = [&](int kind, int vj) -> const float* {
      return has_below2 ? &below2[kind][std::size_t(column_index[vj]) * L] : nothing;
    };
    const bool absent_row = !wrap && vi >= cells_y;
    const float* max_row = &cell_max[std::size_t(vi % cells_y) * max_stride];
    for (int vj = cells_x - 1 + reach_x; vj >= 0; --vj) {
      const float m = absent_row ? absent : max_row[column_index[vj]];
      const bool last_column = vj == cells_x - 1 + reach_x;
      const float* right_ray = last_column && wrap ? nothing : cur(ray_x, vj + 1);
      const float* right_l1 = last_column && wrap ? nothing : cur(l1, vj + 1);
      const float* below_ray = b1(ray_y, vj);
      const float* below_l1 = b1(l1, vj);
      const float* diagonal = b1(inf, vj + 1);
      float* __restrict r_x = cur(ray_x, vj);
      float* __restrict r_y = cur(ray_y, vj);
      float* __restrict r_inf = cur(inf, vj);
      float* __restrict r_l1 = cur(l1, vj);
      alignas(64) float in_x[L], in_y[L], in_diagonal[L], in_l1_x[L], in_l1_y[L];
      std::copy_n(right_ray, L, in_x);
      std::copy_n(below_ray, L, in_y);
      std::copy_n(diagonal, L, in_diagonal);
      std::copy_n(right_l1, L, in_l1_x);
      std::copy_n(below_l1, L, in_l1_y);
      for (int l = 0; l < L; ++l) {
        const float x = std::max(m, in_x[l] - step_x[l]);
        const float y = std::max(m, in_y[l] - step_y[l]);
        r_x[l] = x;
        r_y[l] = y;
        r_inf[l] = std::max(std::max(x, y), in_diagonal[l] - step_diagonal[l]);
        r_l1[l] = std::max(m, std::max(in_l1_x[l] - step_l1_x[l], in_l1_y[l] - step_l1_y[l]));
      }
    }
    if (vi >= cells_y) continue;
    // far-field thresholds of this cell row (the near cells a <= 1 and b <= 1 left out)
    for (int cx = 0; cx < cells_x; ++cx) {
      const float* x0 = cur(ray_x, cx + 2);
      const float* x1 = b1(ray_x, cx + 2);
      const float* y0 = b2(ray_y, cx);
      const float* y1 = b2(ray_y, cx + 1);
      const float* diag2 = b2(inf, cx + 2);
      const float* l1_right = cur(l1, cx + 2);
      const float* l1_up = b2(l1, cx);
      float* t_inf = &threshold_inf[std::size_t(cx) * L];
      float* t_l1 = &threshold_l1[std::size_t(cx) * L];
      for (int l = 0; l < L; ++l) {
        const float g_inf = std::max(
            std::max(std::max(x0[l] - 2.0f * step_x[l], y0[l] - 2.0f * step_y[l]),
                     std::max(x1[l] - step_x[l] - step_diagonal[l], y1[l] - step_y[l] - step_diagonal[l])),
            diag2[l] - 2.0f * step_diagonal[l]);
        const float g_l1 = std::max(l1_right[l] - 2.0f * step_l1_x[l], l1_up[l] - 2.0f * step_l1_y[l]);
        t_inf[l] = g_inf;
        t_l1[l] = g_l1;
      }
    }
    // per texel: the largest lane that passes (pass 1, vectorised over lanes), then the chord to the
    // next lane (pass 2, vectorised over texels), or a bound from the nearest far texel
    const int row_end = std::min(height, (vi + 1) * B);
    for (int ti = vi * B; ti < row_end; ++ti) {
      const float* e_inf_row = &correction_inf[std::size_t(ti - vi * B) * B];
      const float* e_l1_row = &correction_l1[std::size_t(ti - vi * B) * B];
      const float* h_row = &padded[std::size_t(ti) * padded_width];
      for (int cx = 0; cx < cells_x; ++cx) {
        const float* t_inf = &threshold_inf[std::size_t(cx) * L];
        const float* t_l1 = &threshold_l1[std::size_t(cx) * L];
        for (int sx = 0, tj = cx * B; sx < B && tj < width; ++sx, ++tj) {
          const float hc = h_row[tj];
          const float e_inf = e_inf_row[sx], e_l1 = e_l1_row[sx];
          int top = 0;  // 1 + the largest lane that passes (an integer maximum vectorises)
          for (int l = 0; l < L; ++l)
            top = std::max(top, (t_inf[l] + e_inf * inv_lane[l] <= hc) | (t_l1[l] + e_l1 * inv_lane[l] <= hc) ? l + 1 : 0);
          top_lane[tj] = top;
        }
      }
      float* out_row = &ratio_out[std::size_t(ti) * width];
      for (int tj = 0; tj < width; ++tj) {
        const float hc = h_row[tj];
        const int top = top_lane[tj];
        const int sx = sub_x[tj];
        float best = passed[std::max(top - 1, 0)];
        if (settings.chord) {
          // G(u) = max over D of (M(D) - cost(D) u), u = 1 / r, is convex in u for each metric, so
          // below its chord between two lanes; where chord + e u <= h, every far blocker passes
          const int l = std::clamp(top - 1, 0, L - 2);
          const float u1 = inv_lane[l], u2 = inv_lane[l + 1];
          const float h_safe = hc - chord_slack;
          const std::size_t at = std::size_t(cell_of[tj]) * L + l;
          const float e_inf = e_inf_row[sx], e_l1 = e_l1_row[sx];
          const float f1_inf = threshold_inf[at] + e_inf * u1 - h_safe, f2_inf = threshold_inf[at + 1] + e_inf * u2 - h_safe;
          const float f1_l1 = threshold_l1[at] + e_l1 * u1 - h_safe, f2_l1 = threshold_l1[at + 1] + e_l1 * u2 - h_safe;
          // u where the chord crosses zero: u1 - (u1 - u2) f1 / (f1 - f2), valid when f1 <= 0 < f2
          const float u_inf = f1_inf <= 0.0f && f2_inf > f1_inf ? u1 + (u1 - u2) * f1_inf / (f2_inf - f1_inf) : u1;
          const float u_l1 = f1_l1 <= 0.0f && f2_l1 > f1_l1 ? u1 + (u1 - u2) * f1_l1 / (f2_l1 - f1_l1) : u1;
          const float chord = rounding_margin / std::min(u_inf, u_l1);
          best = top > 0 && top < L ? std::max(best, chord) : best;
        }
        const float fallback = height_max > hc ? detail::pair_ratio(nearest_far, height_max - hc) * rounding_margin : 1.0f;
        out_row[tj] = std::min(top == 0 ? fallback : best, 1.0f);
      }
    }
  }

  // near field in the virtual frame: blockers at offsets dx, dy >= 0 in cells (0..1, 0..1) of the
  // texel's, as slopes (gap / distance) with one division per texel and a margin for its rounding
  const int table_size = 2 * B + 1;  // inverse_distance[dy * table_size + dx], made outside the clones
  auto cell_width = [&](int c) { return c % cells_x == cells_x - 1 ? width - (cells_x - 1) * B : B; };
  auto cell_height = [&](int c) { return c % cells_y == cells_y - 1 ? height - (cells_y - 1) * B : B; };
  std::vector<int> gap_x(width), span_x(width);  // texels to the next cell, and to the one after
  std::vector<float> inverse_gap_x(width), right_max(width), up_max(width), diagonal_max(width), slope(width),
      inverse_diagonal(width);
  for (int tj = 0; tj < width; ++tj) {
    const int cx = tj / B;
    gap_x[tj] = cell_width(cx) - (tj - cx * B);
    span_x[tj] = gap_x[tj] + cell_width(cx + 1);
    inverse_gap_x[tj] = inverse_distance[gap_x[tj]];
  }
  constexpr float slope_margin = 1.0f - 1e-6f;
  for (int ti = 0; ti < height; ++ti) {
    const int cy = ti / B, sy = ti - cy * B;
    const int gap_y = cell_height(cy) - sy;
    const float* h_row = &padded[std::size_t(ti) * padded_width];
    std::fill(slope.begin(), slope.end(), 0.0f);
    auto scan = [&](int dy_end, const int* dx_limit, int dx_end) {
      for (int dy = 0; dy < dy_end; ++dy) {
        const float* q_row = &padded[std::size_t(ti + dy) * padded_width];
        for (int dx = dy == 0 ? 1 : 0; dx < dx_end; ++dx) {
          const float inverse = inverse_distance[std::size_t(dy) * table_size + dx];
          const float* q = q_row + dx;
          for (int tj = 0; tj < width; ++tj) {
            const float s = (q[tj] - h_row[tj]) * inverse;
            slope[tj] = dx < dx_limit[tj] ? std::max(slope[tj], s) : slope[tj];
          }
        }
      }
    };
    if (settings.near_field == NearField::scan) {
      scan(gap_y + cell_height(cy + 1), span_x.data(), 2 * B);
    } else {
      scan(gap_y, gap_x.data(), B);
      // the three neighbouring cells as boxes
      const bool up_exists = wrap || cy + 1 < cells_y;
      const float* max_row = &cell_max[std::size_t(cy) * max_stride];
      const float* up_row = &cell_max[std::size_t((cy + 1) % cells_y) * max_stride];
      const float inverse_up = inverse_distance[std::size_t(gap_y) * table_size];
      for (int cx = 0; cx < cells_x; ++cx) {
        const int right = wrap ? (cx + 1) % cells_x : cx + 1;  // clamp: the absent pad
        for (int tj = cx * B; tj < std::min(width, (cx + 1) * B); ++tj) {
          right_max[tj] = max_row[right];
          up_max[tj] = up_exists ? up_row[cx] : absent;
          diagonal_max[tj] = up_exists ? up_row[right] : absent;
          inverse_diagonal[tj] = inverse_distance[std::size_t(gap_y) * table_size + gap_x[tj]];
        }
      }
      for (int tj = 0; tj < width; ++tj) {
        const float hc = h_row[tj];
        const float s = std::max(std::max((right_max[tj] - hc) * inverse_gap_x[tj], (up_max[tj] - hc) * inverse_up),
                                 (diagonal_max[tj] - hc) * inverse_diagonal[tj]);
        slope[tj] = std::max(slope[tj], s);
      }
    }
    float* out_row = &ratio_out[std::size_t(ti) * width];
    for (int tj = 0; tj < width; ++tj)
      if (slope[tj] > 0.0f) out_row[tj] = std::min(out_row[tj], slope_margin / slope[tj]);
  }
}

template <int L>
std::array<float, L> make_lanes(float lowest) {
  std::array<float, L> lanes;
  for (int l = 0; l < L; ++l) lanes[l] = lowest * std::pow(1.0f / lowest, float(l) / float(L - 1));
  lanes[L - 1] = 1.0f;
  return lanes;
}

// the instruction-set clones of the per-quadrant work, one per lane count
#define DISPLACE_COARSE_QUADRANT(L)                                                                              \
  DISPLACE_BAKE_SIMD_CLONES void coarse_quadrant_##L(const detail::Grid& grid, const float* heights, float top, \
                                                     float range, int quadrant, const CoarseSweepSettings& s,  \
                                                     const std::array<float, L>& lanes,                        \
                                                     const std::vector<float>& table, float* out,              \
                                                     std::vector<float>& scratch) {                            \
    coarse_quadrant<L>(grid, heights, top, range, quadrant, s, lanes, table, out, scratch);                    \
  }
DISPLACE_COARSE_QUADRANT(16)
DISPLACE_COARSE_QUADRANT(24)
DISPLACE_COARSE_QUADRANT(32)
#undef DISPLACE_COARSE_QUADRANT

template <int L>
void bake_quadrants(const detail::Grid& grid, const float* heights, const CoarseSweepSettings& settings,
                    std::array<std::vector<float>, 4>& quadrant_ratio) {
  const std::size_t count = std::size_t(grid.width) * grid.height;
  const auto [low, high] = std::minmax_element(heights, heights + count);
  const std::array<float, L> lanes = make_lanes<L>(settings.lowest_lane);
  // inverse uv distances of the near offsets, made here (not in the instruction-set clones) so that
  // they round exactly as bake_exact's distances
  const int table_size = 2 * settings.cell_size + 1;
  std::vector<float> distance_table(std::size_t(table_size) * table_size);
  for (int dy = 0; dy < table_size; ++dy)
    for (int dx = 0; dx < table_size; ++dx)
      distance_table[std::size_t(dy) * table_size + dx] = dx + dy == 0 ? 0.0f : 1.0f / grid.distance(dx, dy);
  tbb::parallel_for(0, 4, [&](int quadrant) {
    std::vector<float> virtual_heights;
    quadrant_ratio[quadrant].resize(count);
    float* out = quadrant_ratio[quadrant].data();
    if constexpr (L == 16) coarse_quadrant_16(grid, heights, *high, *high - *low, quadrant, settings, lanes, distance_table, out, virtual_heights);
    if constexpr (L == 24) coarse_quadrant_24(grid, heights, *high, *high - *low, quadrant, settings, lanes, distance_table, out, virtual_heights);
    if constexpr (L == 32) coarse_quadrant_32(grid, heights, *high, *high - *low, quadrant, settings, lanes, distance_table, out, virtual_heights);
  });
}

}  // namespace

BakeStats bake_coarse_sweep(HeightView heights, Address address, const CoarseSweepSettings& settings, ConeView out) {
  const auto start = std::chrono::steady_clock::now();
  validate(heights, out);
  if (settings.cell_size < 2 || settings.cell_size > 32)
    throw BakeError("coarse sweep cell size must be in [2, 32]");
  if (!(settings.lowest_lane > 0.0f && settings.lowest_lane < 1.0f))
    throw BakeError("coarse sweep lowest lane must be in (0, 1)");
  const detail::Grid grid(heights.width, heights.height, out.sector_count, address);
  std::array<std::vector<float>, 4> quadrant_ratio;
  switch (settings.lane_count) {
    case 16: bake_quadrants<16>(grid, heights.data, settings, quadrant_ratio); break;
    case 24: bake_quadrants<24>(grid, heights.data, settings, quadrant_ratio); break;
    case 32: bake_quadrants<32>(grid, heights.data, settings, quadrant_ratio); break;
    default: throw BakeError("coarse sweep lane count must be 16, 24 or 32");
  }
  // back to the real frame: sector k of 4 is quadrant k, an octant takes its quadrant, one sector the min
  const int width = heights.width, height = heights.height, sectors = out.sector_count;
  double sum = 0.0;
  std::array<Frame, 4> frames;
  for (int q = 0; q < 4; ++q) frames[q] = {width, height, q == 1 || q == 2, q >= 2};
  std::vector<double> row_sums(height);
  tbb::parallel_for(tbb::blocked_range<int>(0, height, 16), [&](const tbb::blocked_range<int>& rows) {
    for (int i = rows.begin(); i < rows.end(); ++i) {
      double row_sum = 0.0;
      for (int j = 0; j < width; ++j) {
        float q[4];
        for (int k = 0; k < 4; ++k) {
          const int vi = frames[k].flip_y ? height - 1 - i : i, vj = frames[k].flip_x ? width - 1 - j : j;
          q[k] = quadrant_ratio[k][std::size_t(vi) * width + vj];
        }
        float* target = &out.data[(std::size_t(i) * width + j) * sectors];
        for (int k = 0; k < sectors; ++k) {
          target[k] = sectors == 1 ? std::min(std::min(q[0], q[1]), std::min(q[2], q[3])) : q[sectors == 4 ? k : k / 2];
          row_sum += target[k];
        }
      }
      row_sums[i] = row_sum;
    }
  });
  for (double s : row_sums) sum += s;
  BakeStats stats;
  stats.mode = Mode::budgeted;
  stats.width = width;
  stats.height = height;
  stats.sector_count = sectors;
  stats.mean_ratio = sum / (double(width) * height * sectors);
  stats.milliseconds = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return stats;
}

}  // namespace displace::bake
