// bake/cone_bilinear_budgeted.cpp - the renderer's cone maps (bake_bilinear_cones' contract) within a
// frame budget, kept between frames (bake.h, BilinearBaker).
//
// Stage L (always completed, O(N)): per quadrant, a lower bound of the ratio from the far cells (lane
// sweeps of the cell maxima on the cell grid, lane_sweep.cpp's bilinear mode, for the 3 x 3 and 4 x 4
// boxes of cells next to the texel), the near cells (the slope over half-texel sub-cells, in 16 bits)
// and the Lipschitz constant of the bilinear surface (where the lanes start).
// Refinement (while the budget lasts): texels not certified within the tolerance against upper bounds
// (a centre-to-centre lane sweep, witnesses near the texel) get bake_bilinear_cones' own search,
// largest possible gain first; the larger lower bound is emitted.
// update() redoes stage L and keeps the searched ratios that cannot have changed.
// The one fact: every bound only falls under rounding, so the map is conservative at every budget.
//
// Proofs: docs/design/bakers.md#bakecone_bilinear_budgetedcpp-bilinearbakers-bounds
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "bake/apex_kernel.h"
#include "bake/bilinear_search.h"
#include "bake/budget_clock.h"
#include "bake/geometry.h"
#include "bake/lane_sweep.h"
#include "bake/work_span.h"

namespace displace::bake {
namespace {

constexpr float lane_lowest_ratio = 0.02f;  // stage L: the lowest lane of make_lane_plan (replaced below)
constexpr double lane_knee = 0.03;          // stage L: lanes 1.3x apart below this ratio, dense above
constexpr int stage_l_sweeps =
    1;  // stage L: sweeps of detail::lane_count lanes each (2: +33% time, +1% ratio)
constexpr int refine_chunk = 64;  // texels searched between two looks at the budget
constexpr int near_reach = 6;     // half texels of padding the near field reads past the map (even)
constexpr int near_band = 32;     // texel rows per band of sub-cells (a task's share), at most
constexpr int near_bands = 32;    // with many threads, bands a map is cut into at least (8 rows or more)
constexpr int split_threads = 8;  // stage L: threads from which it runs as for many (many_threads)
constexpr int apex_parts = 2;     // stage L's steps (run_stage_l_step): the apexes in 2 parts,
constexpr int near_parts = 4;     // the cells, two sweeps, the near field in 4 parts
constexpr int stage_l_steps = apex_parts + 3 + near_parts;
// each step's share of stage L's time, measured on a 512 x 512 ocean (one step per advance() call,
// medians of 15; the last near part includes the emission): for advance()'s `at_least`
constexpr double stage_l_step_share[stage_l_steps] = {0.028, 0.024, 0.066, 0.206, 0.194,
                                                      0.101, 0.098, 0.097, 0.186};
constexpr int witness_reach = 4;        // half texels: how far the upper bounds' near witnesses reach
constexpr int witness_pad = 6;          // half texels of witness rows past the map (even, > reach)
constexpr float witness_slack = 2e-7f;  // heights: a witness's rounding and its difference to H_c

// Made for a band of rows at a time (first_row on), so that a thread's planes stay O(W).
struct SubCells {
  int columns = 0, rows = 0;  // per plane
  int first_row = 0;          // Y of the planes' first row
  // Values from one row to the next: the columns rounded up to 64 bytes and 64 more, so that the
  // near field's 45 offsets (7 rows of 10 planes) fall in different cache sets. With the columns
  // alone a row of 4096 texels was 12 bytes past a multiple of 4 KiB, every row of every plane met
  // in the same few sets of L1, and the near field of a 4096 x 256 map took twice that of 1024 x 1024.
  std::size_t stride = 0;
  // [field][parity]: 0 max, 1 rise +u, 2 rise -u, 3 rise +v, 4 rise -v, in 16 bits (SubCellRowJob)
  std::vector<std::uint16_t> planes[5][2];
  const std::uint16_t* row(int field, int parity, int y) const {
    return planes[field][parity].data() + std::size_t(y - first_row) * stride;
  }
};

}  // namespace

struct BilinearBaker::State {
  int width = 0, height = 0, sector_count = 0;
  Address address = Address::wrap;
  bool has_frame = false;
  std::vector<float> heights;   // the last frame's
  std::vector<float> apex;      // H_c as emitted
  std::vector<float> stage_l;   // per texel and quadrant, stage L's ratios
  std::vector<float> searched;  // per texel and sector, the search's ratios (valid where searched_flag)
  std::vector<std::uint8_t> searched_flag;
  std::vector<int> queue;                // texels still to search, in order
  std::vector<std::uint8_t> queue_band;  // order_by_gain's scratch, kept between frames
  std::vector<int> queue_ordered;
  std::size_t next = 0;                   // queue position
  std::vector<std::uint8_t> uncertified;  // per texel, from the last emission: not certified, not searched
  long long uncertified_count = 0;        // of them
  bool queue_stale = false;      // the queue is still to be made from `uncertified` (when refinement runs)
  double emitted_sum = 0.0;      // of every ratio emitted (the stats' mean)
  std::vector<double> row_sums;  // emit_all's per row: the emitted ratios' sum
  std::vector<long long> row_flagged;  // and the uncertified texels
  // where stage L's last steps emit each row as they finish it (bake()), or null (emit_all later)
  float* emit_out = nullptr;
  float* emit_apex = nullptr;
  float tolerance = 0.25f;
  std::unique_ptr<detail::BilinearSearch> search;  // made on first use, kept for the next heights
  bool search_current = false;                     // search is for the current heights
  // stage L scratch, kept between frames
  std::vector<float> cell_max;
  std::vector<std::uint16_t> apex_bottom;
  // per sweep, quadrant and texel: the count of lanes that pass for the cells beyond the boxes
  // {0, 1, 2}^2 (passed) and {0, ..., 3}^2 (passed3)
  std::vector<std::uint8_t> passed[stage_l_sweeps][4], passed3[stage_l_sweeps][4];
  std::vector<std::uint32_t> upper_masks[4];                 // the upper bounds' centre sweep, per quadrant
  float lane_ratio[stage_l_sweeps][detail::lane_count + 1];  // per sweep: the ratio a count proves
  detail::LanePlan plan, upper_plan;
  std::vector<float> upper;   // per texel and quadrant: a certified upper bound of the best ratio
  bool upper_ready = false;   // upper holds this frame's bounds (else every bound is 1)
  std::vector<double> lanes;  // stage L's lane ratios (stage_l_sweeps x 32)
  std::vector<int> column_before, column_after;  // stage L: each column's neighbours, wrapped or clamped
  // stage L in steps: the next one (stage_l_steps: none under way) and what the steps hand on
  int stage_l_next = stage_l_steps;
  long long stage_l_work = 0;
  float lipschitz = 1.0f;
  alignas(64) std::uint16_t bonus[detail::lane_count], bonus3[detail::lane_count];
};

namespace {

using State = BilinearBaker::State;

using Clock = detail::BudgetClock;

void check_view(const State& state, HeightView heights, const ConeView& out, std::span<float> apex) {
  validate(heights, out);
  if (heights.width != state.width || heights.height != state.height ||
      out.sector_count != state.sector_count) {
    throw BakeError("bilinear baker: made for a " + std::to_string(state.width) + " x " +
                    std::to_string(state.height) + " map with " + std::to_string(state.sector_count) +
                    " sectors, given " + std::to_string(heights.width) + " x " +
                    std::to_string(heights.height) + " with " + std::to_string(out.sector_count));
  }
  if (apex.size() != std::size_t(state.width) * state.height) {
    throw BakeError("bilinear baker: the apex heights hold " + std::to_string(apex.size()) + " values for " +
                    std::to_string(std::size_t(state.width) * state.height) + " texels");
  }
}

// The smallest of a texel's four quadrant values (1 sector takes it; so do the certified bounds).
inline float lowest_of_four(const float* quadrant) {
  return std::min(std::min(quadrant[0], quadrant[1]), std::min(quadrant[2], quadrant[3]));
}

int wrap_index(int n, int count) {
  const int m = n % count;
  return m < 0 ? m + count : m;
}

// The cell maxima (cell n between texels n - 1 and n; wrap W x H, clamp (W + 1) x (H + 1)), and
// a ratio every texel's every sector is proven to hold, from the surface's Lipschitz constant: on a
// cell the bilinear patch's rate along u is largest on one of its two u edges (a difference of two
// texels times W), likewise along v, so |grad s| <= G_cell = sqrt((W du)^2 + (H dv)^2) there, and
// along any segment s rises at most G = max G_cell per unit of uv length. For p in Q_c, s(p) <= H_c
// (the apex is s's maximum over Q_c), so s(x) - H_c <= s(x) - s(p) <= G |x - p|: 1 / G holds from
// every p of Q_c in every direction. Returned rounded down (the float differences and squares
// within a relative 1e-5), 1 where the map is flat; `lowest` gets the smallest cell maximum.
float make_cells(State& state, float& lowest) {
  const bool wrap = state.address == Address::wrap;
  const int W = state.width, H = state.height;
  const int cells_u = wrap ? W : W + 1, cells_v = wrap ? H : H + 1;
  state.cell_max.resize(std::size_t(cells_u) * cells_v);
  auto texel = [&](int n, int count) { return wrap ? wrap_index(n, count) : std::clamp(n, 0, count - 1); };
  const float per_u = float(W), per_v = float(H);
  struct Found {
    float steepest_squared = 0.0f;
    float lowest = std::numeric_limits<float>::infinity();
  };
  const Found found = detail::parallel_reduce_region(
      "cells", tbb::blocked_range<int>(0, cells_v), Found{},
      [&](const tbb::blocked_range<int>& rows, Found partial) {
        float steepest = partial.steepest_squared, low = partial.lowest;
        for (int nv = rows.begin(); nv < rows.end(); ++nv) {
          const float* row0 = state.heights.data() + std::size_t(texel(nv - 1, H)) * W;
          const float* row1 = state.heights.data() + std::size_t(texel(nv, H)) * W;
          float* out = state.cell_max.data() + std::size_t(nv) * cells_u;
          auto cell = [&](int nu, int j0, int j1) {
            const float a = row0[j0], b = row0[j1], c = row1[j0], d = row1[j1];
            out[nu] = std::max(std::max(a, b), std::max(c, d));
            const float du = std::max(std::abs(b - a), std::abs(d - c)) * per_u;
            const float dv = std::max(std::abs(c - a), std::abs(d - b)) * per_v;
            steepest = std::max(steepest, du * du + dv * dv);
          };
          cell(0, texel(-1, W), texel(0, W));
          for (int nu = 1; nu < std::min(W, cells_u); ++nu) cell(nu, nu - 1, nu);  // both texels in the map
          for (int nu = std::max(1, W); nu < cells_u; ++nu) cell(nu, texel(nu - 1, W), texel(nu, W));
          for (int nu = 0; nu < cells_u; ++nu) low = std::min(low, out[nu]);
        }
        return Found{steepest, low};
      },
      [](Found a, const Found& b) {
        return Found{std::max(a.steepest_squared, b.steepest_squared), std::min(a.lowest, b.lowest)};
      });
  lowest = found.lowest;
  const float steepest_squared = found.steepest_squared;
  if (!(steepest_squared > 0.0f)) return 1.0f;
  return float(std::min(1.0, (1.0 - 1e-5) / std::sqrt(double(steepest_squared) * (1.0 + 1e-5))));
}

// The near field's data, on the half-texel grid: samples of s at texel-centre coordinates
// (X / 2, Y / 2) - texel centres, edge midpoints and corners, where s is the average of one, two
// or four texels - and per half-texel square ("sub-cell", lower corner (X, Y)) its maximum and the
// largest rates at which s rises along +u, -u, +v and -v over it. s is bilinear on a sub-cell (it
// lies in one cell), so its maximum is at a corner and its rate along u is largest on one of its two
// u edges, where it is the difference of two samples over half a texel. Computed in float and
// stored raised past their roundings (sample_slack): a sample is 1/4 of two float sums of two column
// sums of heights in [0, 1], within 2^-24 of s; a maximum is raised by top_slack, more than that
// and its own rounding; a rate is a rounded difference (2^-25) of two samples times 2 W or 2 H
// (relative 2^-24), raised by a relative 2^-20 and by rate_slack times 2 W (2 H). Sub-cells are
// split by the parity of X, so that texel j's sub-cell at a fixed offset is at a fixed index j + k
// in its plane: X = 2 k + parity - near_reach. Rows Y from -near_reach.
constexpr float top_slack = 2.4e-7f;  // heights: over a sample's error (2^-24) and the sum's rounding
constexpr double rate_slack = 4e-7;   // heights per half texel: two samples' errors and their difference's

// Sub-cell rows Y in [first_row, last_row) (within [-near_reach, 2 H + near_reach)), the rates in
// units of 1 / rate_scale (near_rate_scale).
void make_sub_cells(const State& state, int first_row, int last_row, float rate_scale, SubCells& cells) {
  const bool wrap = state.address == Address::wrap;
  const int level = detail::lane_sweep_best_level();
  const int W = state.width, H = state.height, pad = near_reach;
  cells.columns = std::max(W, detail::near_block) + pad;  // X from -pad to 2 W + pad - 1 (or on)
  cells.rows = last_row - first_row;
  cells.first_row = first_row;
  cells.stride = (std::size_t(cells.columns) + 31) / 32 * 32 + 32;
  for (auto& field : cells.planes)
    for (auto& plane : field) plane.resize(cells.stride * cells.rows);
  auto texel = [&](int n, int count) { return wrap ? wrap_index(n, count) : std::clamp(n, 0, count - 1); };
  // samples per parity: cells.columns + 1 of each (X up to 2 W + pad + 1, further on a map narrower
  // than a block); the column sums of texels m - pad / 2 for m in [0, samples + 1), wrapped or
  // clamped (an odd sample reads column sum k + 1: ASan found the read past the end on narrow maps)
  const int samples = cells.columns + 1, sums = std::max(W + pad + 2, samples + 1);
  thread_local std::vector<int> column;
  column.resize(sums);
  for (int m = 0; m < sums; ++m) column[m] = texel(m - pad / 2, W);
  const float per_u = float(2 * W), per_v = float(2 * H);  // 1 / (half a texel) in uv, exact
  const float slack_u = float(rate_slack * per_u * (1.0 + 1e-6)),
              slack_v = float(rate_slack * per_v * (1.0 + 1e-6));
  std::uint16_t* out[5][2];
  for (int f = 0; f < 5; ++f)
    for (int p = 0; p < 2; ++p) out[f][p] = cells.planes[f][p].data();
  thread_local std::vector<float> column_sum, rows[2][2];
  column_sum.resize(sums);
  // the samples of row Y: the texel rows on either side (the same row at a centre) summed per
  // column, then even X = 2 k - pad the column sum of texel k - pad / 2 halved and odd X the
  // average of two neighbouring column sums halved
  auto sample_row = [&](int Y, std::vector<float>* row) {
    const int i0 = Y >= 0 ? Y / 2 : -((1 - Y) / 2);
    const float* a = state.heights.data() + std::size_t(texel(i0, H)) * W;
    const float* b = state.heights.data() + std::size_t(texel(Y == 2 * i0 ? i0 : i0 + 1, H)) * W;
    // column m holds texel m - pad / 2: in place for m in [pad / 2, W + pad / 2), a loop that
    // vectorises; wrapped or clamped through the table at the ends
    const int inner_first = pad / 2, inner_last = std::min(sums, W + pad / 2);
    for (int m = 0; m < inner_first; ++m) column_sum[m] = a[column[m]] + b[column[m]];
    const float* a_in = a - pad / 2;
    const float* b_in = b - pad / 2;
    float* sum_out = column_sum.data();
    for (int m = inner_first; m < inner_last; ++m) sum_out[m] = a_in[m] + b_in[m];
    for (int m = inner_last; m < sums; ++m) column_sum[m] = a[column[m]] + b[column[m]];
    row[0].resize(samples);
    row[1].resize(samples);
    float* even = row[0].data();
    float* odd = row[1].data();
    for (int k = 0; k < samples; ++k) {
      even[k] = 0.25f * (column_sum[k] + column_sum[k]);
      odd[k] = 0.25f * (column_sum[k] + column_sum[k + 1]);
    }
  };
  int lower = 0;
  sample_row(first_row, rows[lower]);
  for (int Y = first_row; Y < last_row; ++Y) {
    sample_row(Y + 1, rows[1 - lower]);
    detail::SubCellRowJob job;
    job.even0 = rows[lower][0].data();
    job.odd0 = rows[lower][1].data();
    job.even1 = rows[1 - lower][0].data();
    job.odd1 = rows[1 - lower][1].data();
    job.count = cells.columns;
    job.per_u = per_u;
    job.per_v = per_v;
    job.slack_u = slack_u;
    job.slack_v = slack_v;
    job.top_slack = top_slack;
    job.rate_scale = rate_scale;
    for (int f = 0; f < 5; ++f)
      for (int p = 0; p < 2; ++p) job.out[f][p] = out[f][p] + std::size_t(Y - first_row) * cells.stride;
    switch (level) {
      case 0: detail::sub_cell_row_generic(job); break;
      case 3: detail::sub_cell_row_avx2(job); break;
      default: detail::sub_cell_row_avx512(job); break;
    }
    lower = 1 - lower;
  }
}

// The near bounds of texel row i, for quadrant q (0: +u +v, 1: -u +v, 2: -u -v, 3: +u -v), into
// near[j]: the quadrant's L-shaped region beyond Q_c within 2 texels (sub-cells at offsets (x, y) in
// [0, 5)^2 outside Q_c's own [0, 2)^2, counted from Q_c's first sub-cell towards the quadrant). Where
// the surface at x exceeds H_c, the segment from y (x's nearest point of Q_c) to x ends inside
// sub-cells whose maximum exceeds H_c after its last point at height H_c, so s(x) - H_c <= G |x - y|
// with G = sqrt(rise_u^2 + rise_v^2) over those sub-cells - rise_u only over the ones beyond Q_c's
// edge along u (a segment runs along u only there), rise_v likewise. Each sub-cell above H_c also
// bounds by its gap to Q_c over its height above H_c; the bound is the larger of the two (see the
// file comment), infinity where nothing in the region exceeds H_c.
// Where a quadrant's 45 sub-cells lie, fixed for a map: per offset its row (Y = 2 i + dy), its
// parity and index k0 in its planes, and 1 / (its gap to Q_c), in near_row_kernel's group order.
// The gap term in 16 bits: 1 / gap in units of 1 / gap_scale rounded up, gap_scale putting the
// largest 1 / gap (half a texel's) at 65535; then floor(rise * inverse_gap / 65536) + 1 (rise in
// units of 1 / 65535, rounded up) exceeds (top - apex) / gap in units of steep_unit =
// 65536 / (65535 gap_scale), rounded up.
struct NearPlan {
  struct Entry {
    int dy = 0, parity = 0, k0 = 0;
    int along_u = 1, along_v = 3;  // planes: rise +u (1) or -u (2), +v (3) or -v (4)
    std::uint16_t inverse_gap = 0;
  };
  Entry entries[45];
  int group_counts[detail::near_groups] = {};
  float steep_unit = 0.0f;
};

// The 16-bit unit of the sub-cells' rates (make_sub_cells): 65533 units reach past every rate a
// sub-cell can have, so that the stores (x 65533 / largest + 2, truncated) never clamp. A sub-cell's
// rate along u is the rate of s along u on one of its cell's u edges (a difference of two samples
// half a texel apart, times 2 W): at most W times the cell's largest texel difference along u,
// which make_cells' Lipschitz bound (its 1 / lipschitz) exceeds; add the samples' float errors
// (2^-24 each, times 2 W), the relative raise and the slack, and 1% on top.
float near_rate_scale(float lipschitz, int W, int H) {
  const double sides = double(std::max(W, H));
  const double slack = rate_slack * 2.0 * sides * (1.0 + 1e-6);
  const double largest = 1.01 / double(lipschitz) + 2.0 * slack + 8.0 * 0x1p-24 * sides + 1e-6;
  return float(65533.0 / largest);
}

NearPlan make_near_plan(int width, int height, int q) {
  const int su = q == 0 || q == 3 ? 1 : -1, sv = q <= 1 ? 1 : -1;
  NearPlan::Entry grouped[detail::near_groups][45];
  double inverse_gap[detail::near_groups][45] = {};
  NearPlan plan;
  for (int y = 0; y < 7; ++y)
    for (int x = 0; x < 7; ++x) {
      if (x < 2 && y < 2) continue;
      const bool box2 = x < 5 && y < 5, touching = x <= 2 && y <= 2;
      const int group = (box2 ? (touching ? 0 : 3) : 6) + (y < 2 ? 0 : x < 2 ? 1 : 2);  // beyond u, v, both
      NearPlan::Entry& entry = grouped[group][plan.group_counts[group]++];
      // sub-cell lower corner: X = 2 j - 1 + x (+u) or 2 j - x (-u); Y likewise
      entry.dy = sv > 0 ? y - 1 : -y;
      entry.parity = su > 0 ? (x + 1) & 1 : x & 1;
      // index of texel 0's sub-cell in its plane (X = 2 k + parity - near_reach)
      entry.k0 = su > 0 ? (x - 1 + near_reach - entry.parity) / 2 : (near_reach - x - entry.parity) / 2;
      entry.along_u = su > 0 ? 1 : 2;
      entry.along_v = sv > 0 ? 3 : 4;
      const double gap_u = std::max(0, x - 2) * 0.5 / width, gap_v = std::max(0, y - 2) * 0.5 / height;
      inverse_gap[group][plan.group_counts[group] - 1] =
          touching ? 0.0 : 1.0 / std::sqrt(gap_u * gap_u + gap_v * gap_v) * (1.0 + 1e-12);
    }
  // the largest 1 / gap is half a texel's, along the shorter texel side
  const double gap_scale = 65535.0 / (2.0 * std::max(width, height) * (1.0 + 1e-9));
  plan.steep_unit = detail::float_at_least(65536.0 / (65535.0 * gap_scale) * (1.0 + 1e-12));
  int count = 0;
  for (int g = 0; g < detail::near_groups; ++g)
    for (int n = 0; n < plan.group_counts[g]; ++n) {
      plan.entries[count] = grouped[g][n];
      plan.entries[count++].inverse_gap =
          std::uint16_t(std::ceil(inverse_gap[g][n] * gap_scale * (1.0 + 1e-12)));
    }
  return plan;
}

// The near bounds of texel row i, for quadrant q (0: +u +v, 1: -u +v, 2: -u -v, 3: +u -v), into
// near[j]: the quadrant's L-shaped region beyond Q_c within 2 texels (sub-cells at offsets (x, y) in
// [0, 5)^2 outside Q_c's own [0, 2)^2, counted from Q_c's first sub-cell towards the quadrant). Where
// the surface at x exceeds H_c, the segment from y (x's nearest point of Q_c) to x ends inside
// sub-cells whose maximum exceeds H_c after its last point at height H_c, so s(x) - H_c <= G |x - y|
// with G = sqrt(rise_u^2 + rise_v^2) over those sub-cells - rise_u only over the ones beyond Q_c's
// edge along u (a segment runs along u only there), rise_v likewise. Each sub-cell above H_c also
// bounds by its gap to Q_c over its height above H_c; the bound is the larger of the two (see the
// file comment), infinity where nothing in the region exceeds H_c. The plan is make_near_plan's for q.
void near_row(const SubCells& cells, const NearPlan& plan, const std::uint16_t* apex, float rate_unit,
              int width, int i, float* near, float* slope3) {
  detail::NearOffset offsets[45];
  for (int n = 0; n < 45; ++n) {
    const NearPlan::Entry& entry = plan.entries[n];
    const int Y = 2 * i + entry.dy;
    offsets[n].top = cells.row(0, entry.parity, Y) + entry.k0;
    offsets[n].along_u = cells.row(entry.along_u, entry.parity, Y) + entry.k0;
    offsets[n].along_v = cells.row(entry.along_v, entry.parity, Y) + entry.k0;
    offsets[n].inverse_gap = entry.inverse_gap;
  }
  detail::NearRowJob job;
  std::copy(std::begin(plan.group_counts), std::end(plan.group_counts), job.group_counts);
  job.offsets = offsets;
  job.apex = apex;
  job.rate_unit = rate_unit;
  job.steep_unit = plan.steep_unit;
  job.width = width;
  job.near = near;
  job.slope3 = slope3;
  switch (detail::lane_sweep_best_level()) {
    case 0: detail::near_row_generic(job); break;
    case 3: detail::near_row_avx2(job); break;
    default: detail::near_row_avx512(job); break;
  }
}

// Whether stage L runs as for many threads: each quadrant's sweep in two strips and the near field
// in 32 bands or more (the same bits for more work), where the arena has split_threads or
// more, and while its work and span are recorded (which predicts such a machine).
bool many_threads() {
  return tbb::this_task_arena::max_concurrency() >= split_threads ||
         detail::work_span_active.load(std::memory_order_relaxed);
}

// The near field's band of rows: near_band, or with many threads fewer rows on a map of fewer than
// 32 bands of them, so that 16 threads have two bands each (each band makes its own sub-cells: 6
// rows more than its 2 x rows of them).
int near_band_rows(int height) {
  return many_threads() ? std::clamp((height + near_bands - 1) / near_bands, 8, near_band) : near_band;
}

// Stage L over the whole map (apexes, lane sweeps, near bounds; stage_l gets the quadrant ratios), in
// steps that BilinearBaker::advance spreads over calls and bake() runs all at once: the apexes, in
// apex_parts parts of the rows; the cells, the Lipschitz bound and the lanes; the sweeps of
// quadrants 0 and 1, then of 2 and 3 (two at a time, in parallel); the near field and the last step
// that joins it all, in near_parts parts of the rows. A step reads only the heights copied at the
// start and what the steps before it wrote into the state, so any spread gives bit for bit the same map.
int near_part_first_row(int height, int part) {
  const int bands = (height + near_band - 1) / near_band;
  return std::min(height, bands * part / near_parts * near_band);
}

void emit_rows(State& state, int first_row, int last_row, float* out, float* apex);

// stage L's apexes (exactly bake_bilinear_cones'), and floor(apex * 65535) a little below: part
// `step` of apex_parts of the rows (with `merged`, the rest of them)
void stage_l_apexes(State& state, int step, bool merged) {
  const int W = state.width, H = state.height;
  const bool wrap = state.address == Address::wrap;
  const std::size_t texels = std::size_t(W) * H;
  const int level = detail::lane_sweep_best_level();
  if (step == 0) {
    state.apex.resize(texels);
    state.apex_bottom.resize(texels);
    // the neighbouring columns of every column (wrapped or clamped)
    state.column_before.resize(W);
    state.column_after.resize(W);
    for (int j = 0; j < W; ++j) {
      state.column_before[j] = wrap ? wrap_index(j - 1, W) : std::max(j - 1, 0);
      state.column_after[j] = wrap ? wrap_index(j + 1, W) : std::min(j + 1, W - 1);
    }
  }
  const std::vector<int>& before = state.column_before;
  const std::vector<int>& after = state.column_after;
  const HeightView view{state.heights.data(), W, H};
  const int block_texels = detail::apex_block_texels(level);
  const int first = int(std::int64_t(H) * step / apex_parts),
            last = merged ? H : int(std::int64_t(H) * (step + 1) / apex_parts);
  const tbb::blocked_range<int> part_rows(first, last);
  detail::parallel_for_region("apexes", part_rows, [&](const tbb::blocked_range<int>& rows) {
    for (int i = rows.begin(); i < rows.end(); ++i) {
      const int up = wrap ? wrap_index(i + 1, H) : std::min(i + 1, H - 1),
                down = wrap ? wrap_index(i - 1, H) : std::max(i - 1, 0);
      const float* const rows3[3] = {view.data + std::size_t(down) * W, view.data + std::size_t(i) * W,
                                     view.data + std::size_t(up) * W};
      float* apex_row = state.apex.data() + std::size_t(i) * W;
      std::uint16_t* bottom_row = state.apex_bottom.data() + std::size_t(i) * W;
      // bake_bilinear_cones' apex with its arithmetic, term for term: the largest of s at Q_c's
      // corners, edge midpoints and centre (0.25 (h11 + h1a + hb1 + hba) for a, b in {0, 1, 2}),
      // rounded up to float (to the next float's bits where the nearest is below)
      auto apex_at = [&](int j, int left, int right) {
        const int columns[3] = {left, j, right};
        double h[3][3];
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) h[r][c] = rows3[r][columns[c]];
        const double highest = detail::highest_sample(h);
        const float nearest = float(highest);
        std::uint32_t bits;
        std::memcpy(&bits, &nearest, sizeof bits);
        bits += double(nearest) < highest ? 1u : 0u;
        float apex;
        std::memcpy(&apex, &bits, sizeof apex);
        apex_row[j] = apex;
        const int floor_scaled = int(apex * float(detail::height_scale) - 0x1p-7f);
        bottom_row[j] = std::uint16_t(std::clamp(floor_scaled, 0, 65535));
      };
      apex_at(0, before[0], after[0]);
      // the columns whose neighbours lie in the row: a vector of texels at a time, the same arithmetic
      const int blocks = std::max(W - 2, 0) / block_texels;
      switch (level) {
        case 0: detail::apex_blocks_generic(rows3, 1, blocks, apex_row, bottom_row); break;
        case 3: detail::apex_blocks_avx2(rows3, 1, blocks, apex_row, bottom_row); break;
        default: detail::apex_blocks_avx512(rows3, 1, blocks, apex_row, bottom_row); break;
      }
      int j = 1 + blocks * block_texels;
      for (; j + 1 < W; ++j) apex_at(j, j - 1, j + 1);
      if (W > 1) apex_at(W - 1, before[W - 1], after[W - 1]);
    }
  });
}

// stage L's cells, Lipschitz bound, lane plan and lanes
void stage_l_lanes(State& state) {
  const int W = state.width, H = state.height;
  const bool wrap = state.address == Address::wrap;
  const std::size_t texels = std::size_t(W) * H;
  const double t = 1.0 / double(std::max(W, H));
  float lowest_cell = 0.0f;
  state.lipschitz = make_cells(state, lowest_cell);
  const int cells_u = wrap ? W : W + 1, cells_v = wrap ? H : H + 1;
  detail::make_lane_plan(state.cell_max.data(), cells_u, cells_v, wrap, lane_lowest_ratio, true, false,
                         state.plan);
  // the lanes (of every sweep, interleaved): from the smallest ratio a map can have (one texel over
  // its height range, and never below the Lipschitz bound, which every texel holds anyway) to just
  // above 1, 1.3x apart below lane_knee and evenly geometric above
  double lanes[stage_l_sweeps * detail::lane_count];
  const double range = double(state.plan.highest) - double(lowest_cell);
  const double smallest = std::clamp(
      std::max(range > 0.0 ? double(state.plan.nearest) / range : lane_knee, double(state.lipschitz)),
      1.0 / 8192.0, 0.5);
  const int total = stage_l_sweeps * detail::lane_count;
  const int low = std::clamp(int(std::ceil(std::log(lane_knee / smallest) / std::log(1.3))), 0, 12);
  const double lowest = std::max(smallest, lane_knee / std::pow(1.3, low));
  for (int l = 0; l < total; ++l)
    lanes[l] =
        l <= low ? lowest * std::pow(1.3, l)
                 : lowest * std::pow(1.3, low) *
                       std::pow(1.0001 / (lowest * std::pow(1.3, low)), double(l - low) / (total - 1 - low));
  state.lanes.assign(lanes, lanes + total);
  double ratios[detail::lane_count];
  for (int l = 0; l < detail::lane_count; ++l) ratios[l] = lanes[stage_l_sweeps * l];
  detail::set_lane_ratios(state.plan, ratios);
  for (int l = 0; l < detail::lane_count; ++l) {
    // the bonus t / (2 r) of each lane, from a ratio at least the lane's, rounded down; for the
    // box {0, ..., 3}^2 the gap beyond its far faces is at least 1.5 texels more
    const double ratio_above = double(state.plan.lane_ratio[l + 1]) * (1.0 + 2e-5);
    state.bonus[l] = std::uint16_t(
        std::min(65535.0, std::floor(0.5 * t / ratio_above * detail::height_scale * (1.0 - 1e-9))));
    state.bonus3[l] = std::uint16_t(
        std::min(65535.0, std::floor(1.5 * t / ratio_above * detail::height_scale * (1.0 - 1e-9))));
  }
  for (int q = 0; q < 4; ++q) {
    state.passed[0][q].resize(texels);
    state.passed3[0][q].resize(texels);
  }
}

// stage L's lane sweeps: quadrants 0 and 1 (step 1), 2 and 3 (step 2; with `merged`, all four at step 1)
void stage_l_sweep_quadrants(State& state, int step, bool merged) {
  const int W = state.width, H = state.height;
  const std::size_t texels = std::size_t(W) * H;
  const int first_quadrant = 2 * (step - 1), quadrant_count = merged ? 4 - first_quadrant : 2;
  std::uint8_t* passed[4];
  std::uint8_t* passed3[4];
  for (int q = 0; q < 4; ++q) {
    passed[q] = state.passed[0][q].data();
    passed3[q] = state.passed3[0][q].data();
  }
  // each quadrant in two strips where there are threads for 8 sweeps (a quarter more work)
  const bool split = many_threads();
  state.stage_l_work += detail::sweep_bilinear_quadrants(state.plan, W, H, state.apex_bottom.data(),
                                                         state.bonus, passed, state.bonus3, passed3, -1, true,
                                                         first_quadrant, quadrant_count, split);
  if (first_quadrant + quadrant_count == 4) {
    std::copy(std::begin(state.plan.lane_ratio), std::end(state.plan.lane_ratio), state.lane_ratio[0]);
    state.upper_ready = false;
    state.stage_l.resize(texels * 4);
  }
}

// stage L's near field and the join of it all, row by row: part `part` of near_parts (with `merged`,
// the rest of them)
void stage_l_near(State& state, int part, bool merged) {
  const int W = state.width, H = state.height;
  const int level = detail::lane_sweep_best_level();
  const double t = 1.0 / double(std::max(W, H));
  const int first = near_part_first_row(H, part),
            last = near_part_first_row(H, merged ? near_parts : part + 1);
  const float highest = state.plan.highest;
  const NearPlan near_plans[4] = {make_near_plan(W, H, 0), make_near_plan(W, H, 1), make_near_plan(W, H, 2),
                                  make_near_plan(W, H, 3)};
  const float rate_scale = near_rate_scale(state.lipschitz, W, H);
  const float rate_unit = detail::float_at_least(1.0 / double(rate_scale));
  // in bands of texel rows, each with its own sub-cells: rows 2 i - near_reach to 2 i + near_reach
  const int band = near_band_rows(H);
  detail::parallel_for_region(
      "near field", tbb::blocked_range<int>(first, last, band), [&](const tbb::blocked_range<int>& rows) {
        thread_local std::vector<float> near[4], slope3[4];
        thread_local SubCells sub_cells;
        for (int q = 0; q < 4; ++q) {
          near[q].resize(W);
          slope3[q].resize(W);
        }
        make_sub_cells(state, 2 * rows.begin() - near_reach, 2 * (rows.end() - 1) + near_reach + 1,
                       rate_scale, sub_cells);
        detail::StageLCombineJob job;
        job.width = W;
        job.highest = highest;
        job.half_texel = 0.5 * t;
        job.lane_ratio = state.lane_ratio[0];
        job.lipschitz = state.lipschitz;
        for (int i = rows.begin(); i < rows.end(); ++i) {
          const std::size_t row = std::size_t(i) * W;
          for (int q = 0; q < 4; ++q) {
            near_row(sub_cells, near_plans[q], state.apex_bottom.data() + row, rate_unit, W, i,
                     near[q].data(), slope3[q].data());
            job.passed[q] = state.passed[0][q].data() + row;
            job.passed3[q] = state.passed3[0][q].data() + row;
            job.near[q] = near[q].data();
            job.slope3[q] = slope3[q].data();
          }
          job.apex = state.apex.data() + row;
          job.out = state.stage_l.data() + row * 4;
          switch (level) {
            case 0: detail::stage_l_combine_generic(job); break;
            case 3: detail::stage_l_combine_avx2(job); break;
            default: detail::stage_l_combine_avx512(job); break;
          }
          if (state.emit_out)
            emit_rows(state, i, i + 1, state.emit_out, state.emit_apex);  // while the row is in cache
        }
      });
  state.stage_l_work += (long long)(last - first) * W * 4;
}

// `merged`: the step and the ones of its kind after it at once (the apexes, the two sweeps, the near
// field's parts), as bake() runs them: fewer joins of the threads, the same bits.
void run_stage_l_step(State& state, int step, bool merged = false) {
  static_assert(stage_l_sweeps == 1, "the steps and stage_l_combine_kernel take one sweep's lanes");
  if (step < apex_parts) {
    stage_l_apexes(state, step, merged);
  } else if (step == apex_parts) {
    stage_l_lanes(state);
  } else if (step <= apex_parts + 2) {
    stage_l_sweep_quadrants(state, step - apex_parts, merged);
  } else {
    stage_l_near(state, step - apex_parts - 3, merged);
  }
}

// Whether a step has anything to do (the near field's last parts have no rows on a small map).
bool stage_l_step_works(const State& state, int step) {
  const int part = step - apex_parts - 3;
  return part < 0 || near_part_first_row(state.height, part) < near_part_first_row(state.height, part + 1);
}

// Every step at once; returns the work.
long long run_stage_l(State& state) {
  state.stage_l_work = 0;
  run_stage_l_step(state, 0, true);               // the apexes
  run_stage_l_step(state, apex_parts);            // the cells, the Lipschitz bound, the lanes
  run_stage_l_step(state, apex_parts + 1, true);  // the four sweeps
  run_stage_l_step(state, apex_parts + 3, true);  // the near field and the rest
  state.stage_l_next = stage_l_steps;
  return state.stage_l_work;
}

// The emitted ratios of texel t: stage L's quadrants spread to the sectors, and the search's where it
// ran; returns their sum.
template <int sectors>
float emit_texel_of(const State& state, std::size_t t, float* out) {
  const float* quadrant = state.stage_l.data() + t * 4;
  const bool searched = state.searched_flag[t] != 0;
  float sum = 0.0f;
  for (int k = 0; k < sectors; ++k) {
    const float from_l = sectors == 4   ? quadrant[k]
                         : sectors == 8 ? quadrant[k / 2]
                                        : lowest_of_four(quadrant);
    const float value = searched ? std::max(from_l, state.searched[t * sectors + k]) : from_l;
    out[t * sectors + k] = value;
    sum += value;
  }
  return sum;
}

float emit_texel(const State& state, std::size_t t, float* out) {
  switch (state.sector_count) {
    case 1: return emit_texel_of<1>(state, t, out);
    case 4: return emit_texel_of<4>(state, t, out);
    default: return emit_texel_of<8>(state, t, out);
  }
}

// Upper bounds from witnesses near the texel. For a surface point x with s(x) > H_c whose direction
// from some p in Q_c lies in quadrant q, every valid ratio r of q has s(x) <= H_c + |x - p| / r, so
// r <= |x - p| / (s(x) - H_c); p is taken as the point of Q_c nearest x among those that see x in
// q (per axis towards q, x at dX half texels from c's centre with dX >= -1: a gap of
// max(0, dX - 1) half texels). Points x: the half-texel samples of s (texel centres, edge midpoints,
// cell corners, exact averages of texels, rounded to float) within witness_reach half texels; with
// clamp only those inside [0, 1]^2. The sample's rounding and the float difference are covered by
// witness_slack, 1 / gap is rounded down and the bound up, so each is a real upper bound.
struct WitnessRows {
  int columns = 0, first_row = 0;
  std::vector<float> planes[2];  // [parity of X]: sample X at [(X + witness_pad) / 2]
  const float* row(int parity, int Y) const {
    return planes[parity].data() + std::size_t(Y - first_row) * columns;
  }
};

void make_witness_rows(const State& state, int first_row, int last_row, WitnessRows& rows) {
  const int W = state.width, H = state.height;
  const bool wrap = state.address == Address::wrap;
  rows.columns = W + witness_pad;  // X from -witness_pad to 2 W + witness_pad - 1
  rows.first_row = first_row;
  for (auto& plane : rows.planes) plane.resize(std::size_t(rows.columns) * (last_row - first_row));
  auto texel = [&](int n, int count) { return wrap ? wrap_index(n, count) : std::clamp(n, 0, count - 1); };
  auto half_floor = [](int X) { return X >= 0 ? X / 2 : -((1 - X) / 2); };
  constexpr float absent = -std::numeric_limits<float>::infinity();
  // per plane column: the texels on either side of its sample, or -1 outside [0, 1]^2 (clamp)
  thread_local std::vector<int> left[2], right[2];
  for (int parity = 0; parity < 2; ++parity) {
    left[parity].resize(rows.columns);
    right[parity].resize(rows.columns);
    for (int k = 0; k < rows.columns; ++k) {
      const int X = 2 * k + parity - witness_pad, j0 = half_floor(X), j1 = X == 2 * j0 ? j0 : j0 + 1;
      const bool outside = !wrap && (X < -1 || X > 2 * W - 1);
      left[parity][k] = outside ? -1 : texel(j0, W);
      right[parity][k] = outside ? -1 : texel(j1, W);
    }
  }
  for (int Y = first_row; Y < last_row; ++Y) {
    const int i0 = half_floor(Y), i1 = Y == 2 * i0 ? i0 : i0 + 1;
    const bool outside_v = !wrap && (Y < -1 || Y > 2 * H - 1);
    const float* a = state.heights.data() + std::size_t(texel(i0, H)) * W;
    const float* b = state.heights.data() + std::size_t(texel(i1, H)) * W;
    for (int parity = 0; parity < 2; ++parity) {
      float* out = rows.planes[parity].data() + std::size_t(Y - first_row) * rows.columns;
      const int* l = left[parity].data();
      const int* r = right[parity].data();
      for (int k = 0; k < rows.columns; ++k) {
        const int k0 = l[k], k1 = r[k];
        out[k] = outside_v || k0 < 0
                     ? absent
                     : float(0.25 * ((double(a[k0]) + double(a[k1])) + (double(b[k0]) + double(b[k1]))));
      }
    }
  }
}

long long witness_upper(State& state) {
  const int W = state.width, H = state.height;
  constexpr int side = witness_reach + 2;  // offsets -1 .. witness_reach per axis
  std::array<float, std::size_t(side) * side> inverse_gap{};
  for (int dy = -1; dy <= witness_reach; ++dy)
    for (int dx = -1; dx <= witness_reach; ++dx) {
      if (dx <= 1 && dy <= 1) continue;  // in Q_c: no higher than H_c
      const double gu = std::max(0, dx - 1) * 0.5 / W, gv = std::max(0, dy - 1) * 0.5 / H;
      inverse_gap[std::size_t(dy + 1) * side + dx + 1] =
          float(1.0 / std::sqrt(gu * gu + gv * gv) * (1.0 - 1e-6));
    }
  tbb::parallel_for(tbb::blocked_range<int>(0, H, near_band), [&](const tbb::blocked_range<int>& range) {
    thread_local WitnessRows rows;
    thread_local std::vector<float> steepest;
    make_witness_rows(state, 2 * range.begin() - witness_reach, 2 * (range.end() - 1) + witness_reach + 1,
                      rows);
    steepest.resize(W);
    float* steep = steepest.data();
    for (int i = range.begin(); i < range.end(); ++i) {
      const float* apex = state.apex.data() + std::size_t(i) * W;
      for (int q = 0; q < 4; ++q) {
        const int su = q == 0 || q == 3 ? 1 : -1, sv = q <= 1 ? 1 : -1;
        // the largest (s(x) - H_c) / |x - p| over the witnesses, rounded down
        std::fill(steepest.begin(), steepest.end(), 0.0f);
        for (int dy = -1; dy <= witness_reach; ++dy)
          for (int dx = -1; dx <= witness_reach; ++dx) {
            const float inverse = inverse_gap[std::size_t(dy + 1) * side + dx + 1];
            if (inverse == 0.0f) continue;
            // texel j's sample at X = 2 j + su dx
            const float* sample = rows.row(dx & 1, 2 * i + sv * dy) + (su * dx + witness_pad - (dx & 1)) / 2;
            for (int j = 0; j < W; ++j) {
              const float excess = (sample[j] - apex[j]) - witness_slack;
              steep[j] = steep[j] > excess * inverse ? steep[j] : excess * inverse;
            }
          }
        float* upper = state.upper.data() + std::size_t(i) * W * 4 + q;
        for (int j = 0; j < W; ++j)
          if (steep[j] > 0.0f)
            upper[std::size_t(j) * 4] =
                std::min(upper[std::size_t(j) * 4], float(1.0 / double(steep[j]) * (1.0 + 1e-5)));
      }
    }
  });
  return (long long)W * H * 4 * (side * side - 9);
}

// Certified upper bounds of the best ratio per texel and quadrant, for the tolerance.
long long ensure_upper(State& state) {
  if (state.upper_ready) return 0;
  const int W = state.width, H = state.height;
  const bool wrap = state.address == Address::wrap;
  const std::size_t texels = std::size_t(W) * H;
  const double* lanes = state.lanes.data();
  long long work = 0;
  // Upper bounds, for the tolerance (made when refinement first needs them): the centre-to-centre lane sweep
  // of the texels tested against the apexes. Where lane l fails, some texel centre q in the quadrant has h(q)
  // above the apex by more than lane l's cone from c allows (lane_sweep.cpp's bound, with the apex for h(c):
  // its rounding is the same), and q is a surface point that the contract's cone from p = c must clear, so
  // the best ratio is below lane_upper.
  detail::make_lane_plan(state.heights.data(), W, H, wrap, lane_lowest_ratio, true, false, state.upper_plan);
  state.upper_plan.bottom = state.apex_bottom;
  state.upper.assign(texels * 4, 1.0f);
  for (int sweep = 0; sweep < stage_l_sweeps; ++sweep) {  // the same lanes, the smaller bound
    double ratios[detail::lane_count];
    for (int l = 0; l < detail::lane_count; ++l) ratios[l] = lanes[stage_l_sweeps * l + sweep];
    detail::set_lane_ratios(state.upper_plan, ratios);
    std::uint32_t* masks[4];
    for (int q = 0; q < 4; ++q) {
      state.upper_masks[q].resize(texels);
      masks[q] = state.upper_masks[q].data();
    }
    work += detail::sweep_sectors(state.upper_plan, state.heights.data(), 4, masks, nullptr, nullptr).work;
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, texels, 4096), [&](const tbb::blocked_range<std::size_t>& range) {
          for (std::size_t n = range.begin(); n < range.end(); ++n)
            for (int q = 0; q < 4; ++q)
              state.upper[n * 4 + q] = std::min(
                  state.upper[n * 4 + q], state.upper_plan.lane_upper[detail::lanes_passed(masks[q][n])]);
        });
  }
  // and the witnesses near the texel
  work += witness_upper(state);
  state.upper_ready = true;
  return work;
}

// Within the tolerance of the best ratio the contract allows: against the certified upper bounds
// (1 and 4 sectors; an octant has none, so 8 sectors certify only what reaches the tolerance of 1).
// `upper` is the texel's four bounds, or none (all 1) before they are made.
template <int sectors>
inline bool certified_of(const float* quadrant, const float* upper, float keep) {
  const float lowest = lowest_of_four(quadrant);
  switch (sectors) {
    case 4: {
      bool all = true;
      for (int q = 0; q < 4; ++q) all &= !(quadrant[q] < keep * upper[q]);
      return all;
    }
    case 1: return lowest >= keep * lowest_of_four(upper);
    default: return lowest >= keep;
  }
}

constexpr float no_upper_bounds[4] = {1.0f, 1.0f, 1.0f, 1.0f};

bool certified(const State& state, std::size_t t) {
  const float keep = 1.0f - state.tolerance;
  const float* quadrant = state.stage_l.data() + t * 4;
  const float* upper = state.upper_ready ? state.upper.data() + t * 4 : no_upper_bounds;
  switch (state.sector_count) {
    case 4: return certified_of<4>(quadrant, upper, keep);
    case 1: return certified_of<1>(quadrant, upper, keep);
    default: return certified_of<8>(quadrant, upper, keep);
  }
}

// What a search of texel t could raise its ratios by at most: the sum over its quadrants of how far
// stage L's ratio lies below the certified bound (with 1 sector, the lowest quadrant below the
// lowest bound; 8 sectors order by their quadrants' bounds too, though an octant's best may exceed
// them - an order only, no claim).
float possible_gain(const State& state, std::size_t t) {
  const float* quadrant = state.stage_l.data() + t * 4;
  const float* upper = state.upper_ready ? state.upper.data() + t * 4 : no_upper_bounds;
  if (state.sector_count == 1) {
    const float lowest = lowest_of_four(quadrant);
    return std::max(0.0f, lowest_of_four(upper) - lowest);
  }
  float gain = 0.0f;
  for (int q = 0; q < 4; ++q) gain += std::max(0.0f, upper[q] - quadrant[q]);
  return gain;
}

// The queue's rest (from next) by possible gain, the largest first (gain_buckets bands of 1 /
// gain_buckets, the last holding everything from 1 on; texel order within a band): a budget that
// runs out has then searched the texels whose ratios can rise most. A stable counting sort, the
// same order every time. On the 256 ocean, a work limit of a tenth of an unlimited bake's now
// raises the mean ratio from 0.930 to 0.952 of the full bake's (0.941 in texel order, 0.948 in
// order of stage L's quotient to the bound); a fifth 0.951 -> 0.964.
constexpr int gain_buckets = 256;
void order_by_gain(State& state) {
  const std::size_t first = state.next, count = state.queue.size() - first;
  if (count < 2) return;
  std::vector<std::uint8_t>& bucket = state.queue_band;
  std::vector<int>& ordered = state.queue_ordered;
  bucket.resize(count);
  ordered.resize(count);
  std::size_t starts[gain_buckets + 1] = {};
  for (std::size_t n = 0; n < count; ++n) {
    const float gain = possible_gain(state, std::size_t(state.queue[first + n]));
    bucket[n] = std::uint8_t(gain_buckets - 1 - std::min(gain_buckets - 1, int(gain * gain_buckets)));
    ++starts[bucket[n] + 1];
  }
  for (int b = 0; b < gain_buckets; ++b) starts[b + 1] += starts[b];
  for (std::size_t n = 0; n < count; ++n) ordered[starts[bucket[n]]++] = state.queue[first + n];
  std::copy(ordered.begin(), ordered.end(), state.queue.begin() + std::ptrdiff_t(first));
}

// The texels to search, in order: neither searched nor certified.
void make_queue(State& state) {
  state.queue.clear();
  state.next = 0;
  state.queue_stale = false;
  const std::size_t texels = std::size_t(state.width) * state.height;
  for (std::size_t t = 0; t < texels; ++t)
    if (!state.searched_flag[t] && !certified(state, t)) state.queue.push_back(int(t));
  if (state.upper_ready) order_by_gain(state);  // else when refinement makes the bounds
}

// The same from the flags emit_all left (the tolerance and upper bounds unchanged since).
void make_queue_from_emission(State& state) {
  state.queue.clear();
  state.next = 0;
  state.queue_stale = false;
  const std::size_t texels = std::size_t(state.width) * state.height;
  const std::uint8_t* flags = state.uncertified.data();
  for (std::size_t t = 0; t < texels; ++t)
    if (flags[t]) state.queue.push_back(int(t));
}

// Searches queued texels while the budget lasts, writing their ratios to out.
long long run_refinement(State& state, Clock& clock, ConeView out, long long& refined,
                         const Progress& progress) {
  struct Finish {  // the call's last report, 1, however it ends
    const Progress& progress;
    ~Finish() {
      if (progress) progress(1.0);
    }
  } finish_report{progress};
  if (clock.exhausted()) return 0;
  if (state.queue_stale) make_queue_from_emission(state);  // made only when a search can run (not at 0 ms)
  if (state.next >= state.queue.size()) return 0;
  long long work = 0;
  if (!state.upper_ready) {  // certify with the upper bounds before searching: drop what they certify
    work += ensure_upper(state);
    std::size_t kept = state.next;
    for (std::size_t n = state.next; n < state.queue.size(); ++n)
      if (!certified(state, std::size_t(state.queue[n]))) state.queue[kept++] = state.queue[n];
    state.queue.resize(kept);
    if (state.next >= state.queue.size()) return work;
    order_by_gain(state);
  }
  const HeightView current{state.heights.data(), state.width, state.height};
  if (!state.search) {
    state.search = std::make_unique<detail::BilinearSearch>(current, state.address, state.sector_count,
                                                            BilinearConeSettings{}.slope_window);
  } else if (!state.search_current) {
    state.search->update(current);
  }
  state.search_current = true;
  const int sectors = state.sector_count;
  const std::size_t first_queued = state.next;
  // With a clock or a work limit, batches of 2 chunks, so that the budget is looked at often. An
  // unlimited budget looks at nothing between batches but the progress report, so a batch is a
  // share of the queue as large as the reports allow: with 2 chunks, one thread waited for the
  // other at every join (the searches differ in cost), 4% of the time in TBB and 4% in the kernel's
  // scheduler on the 512 ocean.
  const std::size_t two_chunks = std::size_t(refine_chunk) * 2;
  const std::size_t share = (state.queue.size() - first_queued) / max_progress_reports + 1;
  const std::size_t batch = clock.unlimited() ? std::max(two_chunks, share) : two_chunks;
  double next_report = 1.0 / max_progress_reports;
  while (state.next < state.queue.size() && !clock.exhausted()) {
    const std::size_t first = state.next, last = std::min(state.queue.size(), first + batch);
    struct Done {
      long long work = 0;
      double raised = 0.0;  // the emitted sum's change
    };
    const Done batch_done = tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(first, last, refine_chunk), Done{},
        [&](const tbb::blocked_range<std::size_t>& range, Done done) {
          for (std::size_t n = range.begin(); n < range.end(); ++n) {
            const int t = state.queue[n];
            float apex;
            done.work += state.search->texel(t / state.width, t % state.width, apex,
                                             state.searched.data() + std::size_t(t) * sectors);
            float before = 0.0f;
            for (int k = 0; k < sectors; ++k) before += out.data[std::size_t(t) * sectors + k];
            state.searched_flag[t] = 1;
            done.raised += double(emit_texel(state, std::size_t(t), out.data)) - double(before);
          }
          return done;
        },
        [](Done a, Done b) {
          return Done{a.work + b.work, a.raised + b.raised};
        });
    const long long batch_work = batch_done.work;
    state.emitted_sum += batch_done.raised;
    refined += (long long)(last - first);
    work += batch_work;
    clock.work += batch_work;
    state.next = last;
    const double done = double(state.next - first_queued) / double(state.queue.size() - first_queued);
    if (progress && done >= next_report && done < 1.0) {
      progress(done);
      next_report = done + 1.0 / max_progress_reports;
    }
  }
  return work;
}

// Texels still to search: the queue's rest, or the flags' count before the queue is made.
long long pending_of(const State& state) {
  return state.queue_stale ? state.uncertified_count : (long long)(state.queue.size() - state.next);
}

BakeStats finish(const State& state, const Clock& clock, long long work, long long refined) {
  BakeStats stats;
  stats.mode = Mode::bilinear_budgeted;
  stats.width = state.width;
  stats.height = state.height;
  stats.sector_count = state.sector_count;
  stats.texels_refined = refined;
  stats.texels_fallback = pending_of(state);
  stats.work = work;
  stats.milliseconds = clock.elapsed();
  const std::size_t values = std::size_t(state.width) * state.height * state.sector_count;
  stats.mean_ratio = values ? state.emitted_sum / double(values) : 0.0;
  return stats;
}

// One row of emit_all: texels [first, first + count) to the caller, their refinement flags, and the
// sum of their ratios. The sum runs in 16 float accumulators (value n of the row into n mod 16) added
// in a fixed order at the end, so that it vectorises and gives the same bits however the rows are
// split among threads; `searched` says whether any texel of the row has search ratios (without them
// a texel's ratios are stage L's spread to the sectors). Every emission follows a new stage L, whose
// upper bounds are made only when refinement first needs them, so the flags hold against none (1).
template <int sectors, bool searched>
double emit_row(State& state, std::size_t first, int count, float* out, float* apex, float keep,
                long long& flagged) {
  constexpr int accumulators = 16;
  float partial[accumulators] = {};
  const float* quadrants = state.stage_l.data() + first * 4;
  float* row_out = out + first * sectors;
  int j = 0;
  if constexpr (sectors == 4 && !searched) {
    // four texels (16 values) at a time: a copy and a sum into the same accumulators as the loop below
    typedef float Floats __attribute__((vector_size(64)));
    j = count / 4 * 4;
    std::memcpy(row_out, quadrants, sizeof(float) * 4 * std::size_t(j));
    Floats sums = {};
    for (int n = 0; n < 4 * j; n += 16) {
      Floats values;
      std::memcpy(&values, quadrants + n, sizeof values);
      sums += values;
    }
    std::memcpy(partial, &sums, sizeof partial);
  }
  for (; j < count; ++j) {
    if constexpr (searched) {
      partial[j % accumulators] += emit_texel_of<sectors>(state, first + std::size_t(j), out);
    } else {
      const float* quadrant = quadrants + std::size_t(j) * 4;
      for (int k = 0; k < sectors; ++k) {
        const float value = sectors == 4   ? quadrant[k]
                            : sectors == 8 ? quadrant[k / 2]
                                           : lowest_of_four(quadrant);
        row_out[std::size_t(j) * sectors + k] = value;
        partial[(j * sectors + k) % accumulators] += value;
      }
    }
  }
  std::uint8_t* flags = state.uncertified.data() + first;
  flagged = 0;
  for (j = 0; j < count; ++j) {
    const bool flag = (!searched || !state.searched_flag[first + std::size_t(j)]) &&
                      !certified_of<sectors>(quadrants + std::size_t(j) * 4, no_upper_bounds, keep);
    flags[j] = flag;
    flagged += flag;
  }
  std::memcpy(apex + first, state.apex.data() + first, sizeof(float) * std::size_t(count));
  double sum = 0.0;
  for (float value : partial) sum += double(value);
  return sum;
}

template <int sectors>
void emit_rows_of(State& state, int first_row, int last_row, float* out, float* apex) {
  const int W = state.width;
  const float keep = 1.0f - state.tolerance;
  for (int i = first_row; i < last_row; ++i) {
    const std::size_t first = std::size_t(i) * W;
    const bool any_searched = std::memchr(state.searched_flag.data() + first, 1, std::size_t(W)) != nullptr;
    long long flagged = 0;
    state.row_sums[std::size_t(i)] =
        any_searched ? emit_row<sectors, true>(state, first, W, out, apex, keep, flagged)
                     : emit_row<sectors, false>(state, first, W, out, apex, keep, flagged);
    state.row_flagged[std::size_t(i)] = flagged;
  }
}

void emit_rows(State& state, int first_row, int last_row, float* out, float* apex) {
  switch (state.sector_count) {
    case 1: emit_rows_of<1>(state, first_row, last_row, out, apex); break;
    case 4: emit_rows_of<4>(state, first_row, last_row, out, apex); break;
    default: emit_rows_of<8>(state, first_row, last_row, out, apex); break;
  }
}

// Before an emission: the flags and per-row sums sized, searched ratios cleared when `fresh` (a new
// stage L and nothing searched yet), the tolerance the flags use.
void prepare_emission(State& state, float tolerance, bool fresh) {
  const std::size_t texels = std::size_t(state.width) * state.height;
  if (fresh) state.searched_flag.assign(texels, 0);
  state.searched.resize(texels * state.sector_count);
  state.uncertified.resize(texels);
  state.row_sums.resize(std::size_t(state.height));
  state.row_flagged.resize(std::size_t(state.height));
  state.tolerance = tolerance;
}

// After every row is emitted: the stats' sum in row order (the same bits on every run, however the
// rows were split among threads or steps) and the count refinement will want.
void finish_emission(State& state) {
  double sum = 0.0;
  long long flagged = 0;
  for (int i = 0; i < state.height; ++i) {
    sum += state.row_sums[std::size_t(i)];
    flagged += state.row_flagged[std::size_t(i)];
  }
  state.emitted_sum = sum;
  state.uncertified_count = flagged;
  // the queue is made from the flags when refinement runs (at 0 ms it never does)
  state.queue.clear();
  state.next = 0;
  state.queue_stale = true;
}

// Every texel's ratios and apex to the caller, a row at a time, summing them and flagging the
// texels refinement will want (make_queue_from_emission); prepare_emission first.
void emit_all(State& state, ConeView out, std::span<float> apex) {
  tbb::parallel_for(tbb::blocked_range<int>(0, state.height, 8), [&](const tbb::blocked_range<int>& rows) {
    emit_rows(state, rows.begin(), rows.end(), out.data, apex.data());
  });
  finish_emission(state);
}

}  // namespace

BilinearBaker::BilinearBaker(int width, int height, int sector_count, Address address)
    : state_(std::make_unique<State>()) {
  if (width < 1 || height < 1 || width > max_map_side || height > max_map_side) {
    throw BakeError("bilinear baker: a " + std::to_string(width) + " x " + std::to_string(height) +
                    " map (each side must be 1 to " + std::to_string(max_map_side) + " texels)");
  }
  if (!is_valid_sector_count(sector_count)) {
    throw BakeError("bilinear baker: " + std::to_string(sector_count) + " sectors (use 1, 4 or 8)");
  }
  state_->width = width;
  state_->height = height;
  state_->sector_count = sector_count;
  state_->address = address;
}
BilinearBaker::~BilinearBaker() = default;
BilinearBaker::BilinearBaker(BilinearBaker&&) noexcept = default;
BilinearBaker& BilinearBaker::operator=(BilinearBaker&&) noexcept = default;

namespace {

void check_tolerance(const Budget& budget) {
  if (!(budget.tolerance >= 0.0f && budget.tolerance < max_tolerance)) {
    char text[96];
    std::snprintf(text, sizeof text, "bilinear baker: Budget::tolerance %g is outside [0, %g)",
                  double(budget.tolerance), double(max_tolerance));
    throw BakeError(text);
  }
}

// Per axis, the uv gap between Q_c = [c - 0.5, c + 0.5] and [first, last] (texel-centre coordinates),
// over the periodic images with wrap.
double axis_gap(double c, double first, double last, int count, bool wrap) {
  auto gap = [&](double shift) {
    return std::max({0.0, first + shift - (c + 0.5), (c - 0.5) - (last + shift)});
  };
  double best = gap(0.0);
  if (wrap) {
    if (last - first >= count) return 0.0;
    for (int k = -2; k <= 2; ++k) best = std::min(best, gap(double(k) * count));
  }
  return best / count;
}

}  // namespace

BakeStats BilinearBaker::bake(HeightView heights, const Budget& budget, ConeView out, std::span<float> apex) {
  State& state = *state_;
  check_view(state, heights, out, apex);
  check_tolerance(budget);
  Clock clock(budget);
  const std::size_t texels = std::size_t(state.width) * state.height;
  // the frame's heights, kept (in parallel: one thread's copy was a tenth of a 16-thread stage L)
  state.heights.resize(texels);
  detail::parallel_for_region("heights", tbb::blocked_range<std::size_t>(0, texels, std::size_t(1) << 15),
                              [&](const tbb::blocked_range<std::size_t>& range) {
                                std::memcpy(state.heights.data() + range.begin(),
                                            heights.data + range.begin(), sizeof(float) * range.size());
                              });
  state.has_frame = true;
  state.search_current = false;
  // stage L emits each row as the near field finishes it (the same bits as emit_all)
  prepare_emission(state, budget.tolerance, true);
  struct Emitting {  // the rows' target for this call only, however it ends
    State& state;
    Emitting(State& s, float* out, float* apex) : state(s) {
      state.emit_out = out;
      state.emit_apex = apex;
    }
    ~Emitting() { state.emit_out = state.emit_apex = nullptr; }
  };
  long long work = 0;
  {
    const Emitting emitting(state, out.data, apex.data());
    work = run_stage_l(state);
  }
  finish_emission(state);
  long long refined = 0;
  work += run_refinement(state, clock, out, refined, budget.progress);
  return finish(state, clock, work, refined);
}

BakeStats BilinearBaker::update(HeightView heights, std::span<const Rect> dirty, const Budget& budget,
                                ConeView out, std::span<float> apex) {
  State& state = *state_;
  // with a stage under way the heights held are not the emitted ones: nothing to compare against
  if (!state.has_frame || in_progress()) return bake(heights, budget, out, apex);
  check_view(state, heights, out, apex);
  check_tolerance(budget);
  Clock clock(budget);
  const int W = state.width, H = state.height;
  const bool wrap = state.address == Address::wrap;
  const std::size_t texels = std::size_t(W) * H;
  // heights may only have changed inside the dirty rectangles; the raised ones, per rectangle
  std::vector<std::uint8_t> inside(texels, 0);
  struct Raised {
    int i0, i1, j0, j1;
  };
  std::vector<Raised> raised;
  for (const Rect& rect : dirty) {
    if (rect.x0 < 0 || rect.y0 < 0 || rect.x1 > W || rect.y1 > H || rect.x0 > rect.x1 || rect.y0 > rect.y1) {
      throw BakeError("bilinear baker: dirty rectangle [" + std::to_string(rect.x0) + ", " +
                      std::to_string(rect.x1) + ") x [" + std::to_string(rect.y0) + ", " +
                      std::to_string(rect.y1) + ") is not inside the " + std::to_string(W) + " x " +
                      std::to_string(H) + " map");
    }
    Raised box{H, -1, W, -1};
    for (int i = rect.y0; i < rect.y1; ++i)
      for (int j = rect.x0; j < rect.x1; ++j) {
        const std::size_t t = std::size_t(i) * W + j;
        inside[t] = 1;
        if (heights.data[t] > state.heights[t]) {
          box.i0 = std::min(box.i0, i);
          box.i1 = std::max(box.i1, i);
          box.j0 = std::min(box.j0, j);
          box.j1 = std::max(box.j1, j);
        }
      }
    if (box.i1 >= 0) raised.push_back(box);
  }
  for (std::size_t t = 0; t < texels; ++t)
    if (!inside[t] && heights.data[t] != state.heights[t]) {
      throw BakeError("bilinear baker: texel (" + std::to_string(t / W) + ", " + std::to_string(t % W) +
                      ") changed outside the dirty rectangles");
    }
  const std::vector<float> old_apex = state.apex;
  state.heights.assign(heights.data, heights.data + texels);
  state.search_current = false;
  prepare_emission(state, budget.tolerance, false);
  long long work = run_stage_l(state);
  // the raised texels' cells lie within [i0 - 1, i1 + 1] x [j0 - 1, j1 + 1] (texel-centre
  // coordinates) and below the largest new height there
  std::vector<float> raised_top(raised.size());
  for (std::size_t r = 0; r < raised.size(); ++r) {
    float top = 0.0f;
    for (int i = raised[r].i0 - 1; i <= raised[r].i1 + 1; ++i)
      for (int j = raised[r].j0 - 1; j <= raised[r].j1 + 1; ++j) {
        const int y = wrap ? wrap_index(i, H) : std::clamp(i, 0, H - 1),
                  x = wrap ? wrap_index(j, W) : std::clamp(j, 0, W - 1);
        top = std::max(top, state.heights[std::size_t(y) * W + x]);
      }
    raised_top[r] = top;
  }
  const int sectors = state.sector_count;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, texels, 4096),
                    [&](const tbb::blocked_range<std::size_t>& range) {
                      for (std::size_t t = range.begin(); t < range.end(); ++t) {
                        if (!state.searched_flag[t]) continue;
                        if (state.apex[t] != old_apex[t]) {
                          state.searched_flag[t] = 0;
                          continue;
                        }
                        const int i = int(t / W), j = int(t % W);
                        const float* searched = state.searched.data() + t * sectors;
                        const float largest = *std::max_element(searched, searched + sectors);
                        for (std::size_t r = 0; r < raised.size() && state.searched_flag[t]; ++r) {
                          if (!(raised_top[r] > state.apex[t])) continue;
                          const double gu = axis_gap(j, raised[r].j0 - 1, raised[r].j1 + 1, W, wrap);
                          const double gv = axis_gap(i, raised[r].i0 - 1, raised[r].i1 + 1, H, wrap);
                          const double bound =
                              std::sqrt(gu * gu + gv * gv) / (double(raised_top[r]) - double(state.apex[t]));
                          if (bound * (1.0 - 1e-6) < double(largest))
                            state.searched_flag[t] = 0;  // may have dropped: search again
                        }
                      }
                    });
  emit_all(state, out, apex);
  long long refined = 0;
  work += run_refinement(state, clock, out, refined, budget.progress);
  return finish(state, clock, work, refined);
}

BakeStats BilinearBaker::refine(const Budget& budget, ConeView out, std::span<float> apex) {
  State& state = *state_;
  if (!state.has_frame) throw BakeError("bilinear baker: refine() before the first bake()");
  if (in_progress())
    throw BakeError("bilinear baker: refine() while a staged first stage is under way (advance() it)");
  check_view(state, {state.heights.data(), state.width, state.height}, out, apex);
  check_tolerance(budget);
  Clock clock(budget);
  if (budget.tolerance != state.tolerance) {
    state.tolerance = budget.tolerance;
    make_queue(state);
  }
  long long refined = 0;
  const long long work = run_refinement(state, clock, out, refined, budget.progress);
  return finish(state, clock, work, refined);
}

long long BilinearBaker::pending() const { return pending_of(*state_); }

void BilinearBaker::begin(HeightView heights) {
  State& state = *state_;
  validate_heights(heights, "a cone map");
  if (heights.width != state.width || heights.height != state.height) {
    throw BakeError("bilinear baker: made for a " + std::to_string(state.width) + " x " +
                    std::to_string(state.height) + " map, given " + std::to_string(heights.width) + " x " +
                    std::to_string(heights.height));
  }
  state.heights.assign(heights.data, heights.data + std::size_t(state.width) * state.height);
  state.search_current = false;
  state.stage_l_work = 0;
  state.stage_l_next = 0;
}

bool BilinearBaker::advance(const Budget& budget, ConeView out, std::span<float> apex, BakeStats& stats,
                            double at_least) {
  State& state = *state_;
  if (!in_progress()) throw BakeError("bilinear baker: advance() without begin()");
  check_view(state, {state.heights.data(), state.width, state.height}, out, apex);
  check_tolerance(budget);
  Clock clock(budget);
  // one step that does something, more until at_least is done, then more while the budget lasts
  bool worked = false;
  while (state.stage_l_next < stage_l_steps &&
         !(worked && first_stage_done() >= at_least * (1.0 - 1e-9) && clock.exhausted())) {
    const int step = state.stage_l_next++;
    if (!stage_l_step_works(state, step)) continue;
    run_stage_l_step(state, step);
    worked = true;
  }
  if (state.stage_l_next < stage_l_steps) return false;
  state.has_frame = true;
  prepare_emission(state, budget.tolerance, true);
  emit_all(state, out, apex);
  long long refined = 0;
  const long long work = state.stage_l_work + run_refinement(state, clock, out, refined, budget.progress);
  stats = finish(state, clock, work, refined);
  return true;
}

bool BilinearBaker::in_progress() const { return state_->stage_l_next < stage_l_steps; }

double BilinearBaker::first_stage_done() const {
  double done = 0.0;
  for (int step = 0; step < state_->stage_l_next; ++step) done += stage_l_step_share[step];
  return state_->stage_l_next >= stage_l_steps ? 1.0 : done;
}

int BilinearBaker::first_stage_steps() { return stage_l_steps; }

}  // namespace displace::bake
