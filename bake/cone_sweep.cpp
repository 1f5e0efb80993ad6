// bake/cone_sweep.cpp - conservative quadrant cone ratios by grey-scale dilation sweeps (the budgeted
// baker's stage S).
//
// For a ratio r, "no blocker in the quadrant" means max over q of (h(q) - d(c, q) / r) <= h(c). With
// d replaced by the octagonal distance max(L-infinity, L1 / sqrt 2) - never above the Euclidean one,
// so the test stays conservative - the maximum splits into recurrences over the quadrant: a row ray,
// a column ray and a diagonal step for L-infinity, two unit steps for L1. One sweep over the map
// evaluates the test for every texel and every ratio of a fixed set of lanes at once; a texel's
// ratio is the largest lane that passes. Wrap is handled by starting the sweep `reach` texels beyond
// the map (on its periodic images), far enough that nothing further out can fail a lane.
#include <algorithm>
#include <cmath>
#include <vector>

#include "bake/sweep.h"

namespace displace::bake::detail {

namespace {

constexpr float absent = -1e30f;                // height of "nothing there"
constexpr float rounding_margin = 1.0f - 1e-4f;  // covers the rounding the recurrences accumulate
constexpr int rows_between_checks = 8;           // how often a sweep asks whether to stop

}  // namespace

std::array<float, sweep_lane_count> sweep_lanes(int band) {
  const float low = sweep_band_edges[band], high = sweep_band_edges[band + 1];
  std::array<float, sweep_lane_count> lanes;
  // the low band stops one step short of the high band's first lane
  const int steps = band + 1 < sweep_band_count ? sweep_lane_count : sweep_lane_count - 1;
  for (int l = 0; l < sweep_lane_count; ++l) lanes[l] = low * std::pow(high / low, float(l) / float(steps));
  return lanes;
}

DISPLACE_BAKE_SIMD_CLONES
void sweep_quadrant(const Grid& grid, const float* heights, float height_range, int quadrant, int band,
                    const std::function<bool()>& stop, float* out) {
  constexpr int L = sweep_lane_count;
  const int width = grid.width, height = grid.height;
  const bool wrap = grid.address == Address::wrap;
  const bool flip_x = quadrant == 1 || quadrant == 2, flip_y = quadrant >= 2;
  const std::array<float, L> lanes = sweep_lanes(band);
  alignas(64) float step_x[L], step_y[L], step_diagonal[L], step_l1_x[L], step_l1_y[L], lanes_margin[L];
  for (int l = 0; l < L; ++l) {
    lanes_margin[l] = lanes[l] * rounding_margin;
    step_x[l] = grid.inv_width / lanes[l];
    step_y[l] = grid.inv_height / lanes[l];
    step_diagonal[l] = std::min(step_x[l], step_y[l]);
    step_l1_x[l] = step_x[l] * 0.70710678f;
    step_l1_y[l] = step_y[l] * 0.70710678f;
  }
  // beyond reach texels no blocker can fail even the largest lane: it would need a gap above the range
  const int reach_x = wrap ? std::min(width, int(std::ceil(lanes[L - 1] * height_range * float(width))) + 1) : 0;
  const int reach_y = wrap ? std::min(height, int(std::ceil(lanes[L - 1] * height_range * float(height))) + 1) : 0;

  // the map seen from the quadrant: virtual (i, j) with blockers at larger i and j
  auto texel_index = [&](int vi, int vj) {
    const int i = vi % height, j = vj % width;
    return std::size_t(flip_y ? height - 1 - i : i) * width + (flip_x ? width - 1 - j : j);
  };
  auto height_at = [&](int vi, int vj) {
    if (!wrap && (vi >= height || vj >= width)) return absent;
    return heights[texel_index(vi, vj)];
  };

  // the row below (virtual i + 1), per column: column ray, L-infinity and L1 dilations
  std::vector<float> below_ray(std::size_t(width) * L, absent), below_inf(std::size_t(width) * L, absent),
      below_l1(std::size_t(width) * L, absent);
  std::vector<float> row_ray(below_ray.size()), row_inf(below_inf.size()), row_l1(below_l1.size());
  alignas(64) float ray_x[L], l1_right[L], nothing[L], passes[L];
  std::fill_n(nothing, L, absent);
  for (int vi = height - 1 + reach_y; vi >= 0; --vi) {
    if (vi % rows_between_checks == 0 && stop()) return;  // rows already swept keep their results
    std::fill_n(ray_x, L, absent);
    std::fill_n(l1_right, L, absent);
    const bool first_row = vi == height - 1 + reach_y;
    for (int vj = width - 1 + reach_x; vj >= 0; --vj) {
      const int column = vj % width;
      const float hc = height_at(vi, vj);
      const float h_right = height_at(vi, vj + 1);
      const float h_below = first_row ? absent : height_at(vi + 1, vj);
      const bool last_column = vj == width - 1 + reach_x;
      const float* b_ray = &below_ray[std::size_t(column) * L];
      const float* b_inf_right =
          first_row || (last_column && !wrap) ? nothing : &below_inf[std::size_t((vj + 1) % width) * L];
      const float* b_l1 = &below_l1[std::size_t(column) * L];
      float* r_ray = &row_ray[std::size_t(column) * L];
      float* r_inf = &row_inf[std::size_t(column) * L];
      float* r_l1 = &row_l1[std::size_t(column) * L];
      for (int l = 0; l < L; ++l) {
        ray_x[l] = std::max(h_right, ray_x[l]) - step_x[l];
        const float ray_y = std::max(h_below, b_ray[l]) - step_y[l];
        const float diagonal = b_inf_right[l] - step_diagonal[l];
        const float inf = std::max(std::max(hc, ray_x[l]), std::max(ray_y, diagonal));
        const float l1 = std::max(hc, std::max(l1_right[l] - step_l1_x[l], b_l1[l] - step_l1_y[l]));
        l1_right[l] = l1;
        r_ray[l] = ray_y;
        r_inf[l] = inf;
        r_l1[l] = l1;
        passes[l] = std::min(inf, l1) <= hc ? lanes_margin[l] : 0.0f;
      }
      if (vi < height && vj < width) {
        float& ratio = out[texel_index(vi, vj)];
        for (int l = 0; l < L; ++l) ratio = std::max(ratio, passes[l]);
      }
    }
    below_ray.swap(row_ray);
    below_inf.swap(row_inf);
    below_l1.swap(row_l1);
  }
}

}  // namespace displace::bake::detail
