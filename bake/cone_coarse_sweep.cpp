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

float octagonal(float x, float y) { return std::max(std::max(x, y), (x + y) * inv_sqrt2); }

struct Frame {  // one quadrant seen so that its blockers are at larger virtual (i, j)
  int width, height;
  bool flip_x, flip_y;
  std::size_t real(int vi, int vj) const {
    return std::size_t(flip_y ? height - 1 - vi : vi) * width + (flip_x ? width - 1 - vj : vj);
  }
};

template <int L>
void coarse_quadrant(const detail::Grid& grid, const float* heights, float height_max, float height_range,
                     int quadrant, const CoarseSweepSettings& settings, const std::array<float, L>& lanes,
                     float* ratio_out /* virtual frame */, std::vector<float>& virtual_heights) {
  const int width = grid.width, height = grid.height, B = settings.cell_size;
  const bool wrap = grid.address == Address::wrap;
  const Frame frame{width, height, quadrant == 1 || quadrant == 2, quadrant >= 2};
  // heights in the virtual frame
  virtual_heights.resize(std::size_t(width) * height);
  float* vh = virtual_heights.data();
  for (int vi = 0; vi < height; ++vi)
    for (int vj = 0; vj < width; ++vj) vh[std::size_t(vi) * width + vj] = heights[frame.real(vi, vj)];

  // cell maxima; the last cell along an axis may be partial
  const int cells_x = (width + B - 1) / B, cells_y = (height + B - 1) / B;
  const int pitch_x = wrap ? width - (cells_x - 1) * B : B, pitch_y = wrap ? height - (cells_y - 1) * B : B;
  std::vector<float> cell_max(std::size_t(cells_x) * cells_y, 0.0f);
  for (int vi = 0; vi < height; ++vi)
    for (int vj = 0; vj < width; ++vj) {
      float& m = cell_max[std::size_t(vi / B) * cells_x + vj / B];
      m = std::max(m, vh[std::size_t(vi) * width + vj]);
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
  // warm-up: nominal distance beyond reach cells exceeds the largest lane times the range plus the
  // largest per-texel correction, so no cell further out can fail a lane
  auto reach = [&](float cell_uv, float texel_uv) {
    return wrap ? int(std::ceil((lanes[L - 1] * height_range + 2.0f * float(B) * texel_uv) / cell_uv)) + 4 : 0;
  };
  const int reach_x = reach(cell_u, grid.inv_width), reach_y = reach(cell_v, grid.inv_height);
  auto max_at = [&](int ci, int cj) {
    if (!wrap && (ci >= cells_y || cj >= cells_x)) return absent;
    return cell_max[std::size_t(ci % cells_y) * cells_x + cj % cells_x];
  };

  // three rolling rows of (cells_x + 2) cells x L lanes: row ray, column ray, L-infinity, L1
  const std::size_t row_size = std::size_t(cells_x + 2) * L;
  std::vector<float> rows[3][4];
  for (auto& row : rows)
    for (auto& a : row) a.assign(row_size, absent);
  enum { ray_x = 0, ray_y = 1, inf = 2, l1 = 3 };
  auto at = [&](int vi, int kind, int vj) -> float* {
    const int c = wrap ? vj % cells_x : vj;  // clamp: columns cells_x, cells_x + 1 stay absent
    return &rows[vi % 3][kind][std::size_t(c) * L];
  };
  std::vector<float> threshold(std::size_t(cells_x) * L);  // the row's min(G_inf, G_l1)
  // per-texel correction oct(s) with s from the corner facing the quadrant (virtual low corner)
  std::vector<float> correction(std::size_t(B) * B);
  for (int sy = 0; sy < B; ++sy)
    for (int sx = 0; sx < B; ++sx)
      correction[std::size_t(sy) * B + sx] = octagonal(float(sx) * grid.inv_width, float(sy) * grid.inv_height);
  const float nearest_far = std::min(float(pitch_x + 1) * grid.inv_width, float(pitch_y + 1) * grid.inv_height);

  const std::vector<float> nothing_row(L, absent);
  const float* nothing = nothing_row.data();
  for (int vi = cells_y - 1 + reach_y; vi >= 0; --vi) {
    const bool first_row = vi == cells_y - 1 + reach_y;
    // clamp rows beyond the map are absent; wrap's first row reads nothing below it
    auto row_below = [&](int offset, int kind, int vj) -> const float* {
      if (wrap ? (first_row || (offset == 2 && vi + 1 == cells_y - 1 + reach_y)) : vi + offset >= cells_y)
        return nothing;
      return at(vi + offset, kind, vj);
    };
    for (int vj = cells_x - 1 + reach_x; vj >= 0; --vj) {
      const float m = max_at(vi, vj);
      const bool last_column = vj == cells_x - 1 + reach_x;
      const float* right_ray = last_column && wrap ? nothing : at(vi, ray_x, vj + 1);
      const float* right_l1 = last_column && wrap ? nothing : at(vi, l1, vj + 1);
      const float* below_ray = row_below(1, ray_y, vj);
      const float* below_l1 = row_below(1, l1, vj);
      const float* diagonal = row_below(1, inf, vj + 1);
      float* r_x = at(vi, ray_x, vj);
      float* r_y = at(vi, ray_y, vj);
      float* r_inf = at(vi, inf, vj);
      float* r_l1 = at(vi, l1, vj);
      alignas(64) float new_x[L], new_l1[L];
      for (int l = 0; l < L; ++l) {
        new_x[l] = std::max(m, right_ray[l] - step_x[l]);
        r_y[l] = std::max(m, below_ray[l] - step_y[l]);
        r_inf[l] = std::max(std::max(new_x[l], r_y[l]), diagonal[l] - step_diagonal[l]);
        new_l1[l] = std::max(m, std::max(right_l1[l] - step_l1_x[l], below_l1[l] - step_l1_y[l]));
      }
      std::copy_n(new_x, L, r_x);
      std::copy_n(new_l1, L, r_l1);
    }
    if (vi >= cells_y) continue;
    // far-field thresholds of this cell row (near cells a <= 1 and b <= 1 left out)
    for (int cx = 0; cx < cells_x; ++cx) {
      const float* x0 = at(vi, ray_x, cx + 2);
      const float* x1 = row_below(1, ray_x, cx + 2);
      const float* y0 = row_below(2, ray_y, cx);
      const float* y1 = row_below(2, ray_y, cx + 1);
      const float* diag2 = row_below(2, inf, cx + 2);
      const float* l1_right = at(vi, l1, cx + 2);
      const float* l1_up = row_below(2, l1, cx);
      float* t = &threshold[std::size_t(cx) * L];
      for (int l = 0; l < L; ++l) {
        const float g_inf = std::max(
            std::max(std::max(x0[l] - 2.0f * step_x[l], y0[l] - 2.0f * step_y[l]),
                     std::max(x1[l] - step_x[l] - step_diagonal[l], y1[l] - step_y[l] - step_diagonal[l])),
            diag2[l] - 2.0f * step_diagonal[l]);
        const float g_l1 = std::max(l1_right[l] - 2.0f * step_l1_x[l], l1_up[l] - 2.0f * step_l1_y[l]);
        t[l] = std::min(g_inf, g_l1);
      }
    }
    // per texel: the largest lane that passes, or a bound from the nearest far texel
    const int row_end = std::min(height, (vi + 1) * B);
    for (int ti = vi * B; ti < row_end; ++ti)
      for (int tj = 0; tj < width; ++tj) {
        const float hc = vh[std::size_t(ti) * width + tj];
        const float e = correction[std::size_t(ti - vi * B) * B + (tj % B)];
        const float* t = &threshold[std::size_t(tj / B) * L];
        float best = 0.0f;
        for (int l = 0; l < L; ++l) best = std::max(best, t[l] + e * inv_lane[l] <= hc ? passed[l] : 0.0f);
        if (best == 0.0f) best = height_max > hc ? detail::pair_ratio(nearest_far, height_max - hc) * rounding_margin : 1.0f;
        ratio_out[std::size_t(ti) * width + tj] = std::min(best, 1.0f);
      }
  }

  // near field in the virtual frame: blockers at offsets dx, dy >= 0 inside cells (0..1, 0..1)
  const int cw_last = width - (cells_x - 1) * B, ch_last = height - (cells_y - 1) * B;
  auto cell_width = [&](int c) { return c % cells_x == cells_x - 1 ? cw_last : B; };
  auto cell_height = [&](int c) { return c % cells_y == cells_y - 1 ? ch_last : B; };
  for (int ti = 0; ti < height; ++ti) {
    const int cy = ti / B, sy = ti - cy * B;
    for (int tj = 0; tj < width; ++tj) {
      const int cx = tj / B, sx = tj - cx * B;
      const float hc = vh[std::size_t(ti) * width + tj];
      const int gap_x = cell_width(cx) - sx, gap_y = cell_height(cy) - sy;  // texels to the next cell
      float best = ratio_out[std::size_t(ti) * width + tj];
      auto blocker = [&](int dx, int dy) {
        int qi = ti + dy, qj = tj + dx;
        if (wrap) qi %= height, qj %= width;
        else if (qi >= height || qj >= width) return;
        const float hq = vh[std::size_t(qi) * width + qj];
        if (hq > hc) best = std::min(best, detail::pair_ratio(grid.distance(dx, dy), hq - hc));
      };
      if (settings.near_field == NearField::scan) {
        const int span_x = gap_x + cell_width(cx + 1), span_y = gap_y + cell_height(cy + 1);
        for (int dy = 0; dy < span_y; ++dy)
          for (int dx = dy == 0 ? 1 : 0; dx < span_x; ++dx) blocker(dx, dy);
      } else {
        for (int dy = 0; dy < gap_y; ++dy)
          for (int dx = dy == 0 ? 1 : 0; dx < gap_x; ++dx) blocker(dx, dy);
        auto box = [&](int ox, int oy, int dx, int dy) {
          const float mb = max_at(cy + oy, cx + ox);
          if (mb > hc) best = std::min(best, detail::pair_ratio(grid.distance(dx, dy), mb - hc));
        };
        box(1, 0, gap_x, 0);
        box(0, 1, 0, gap_y);
        box(1, 1, gap_x, gap_y);
      }
      ratio_out[std::size_t(ti) * width + tj] = best;
    }
  }
}

template <int L>
std::array<float, L> make_lanes(float lowest) {
  std::array<float, L> lanes;
  for (int l = 0; l < L; ++l) lanes[l] = lowest * std::pow(1.0f / lowest, float(l) / float(L - 1));
  lanes[L - 1] = 1.0f;
  return lanes;
}

template <int L>
void bake_quadrants(const detail::Grid& grid, const float* heights, const CoarseSweepSettings& settings,
                    std::array<std::vector<float>, 4>& quadrant_ratio) {
  const std::size_t count = std::size_t(grid.width) * grid.height;
  const auto [low, high] = std::minmax_element(heights, heights + count);
  const std::array<float, L> lanes = make_lanes<L>(settings.lowest_lane);
  tbb::parallel_for(0, 4, [&](int quadrant) {
    std::vector<float> virtual_heights;
    quadrant_ratio[quadrant].resize(count);
    coarse_quadrant<L>(grid, heights, *high, *high - *low, quadrant, settings, lanes, quadrant_ratio[quadrant].data(),
                       virtual_heights);
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
