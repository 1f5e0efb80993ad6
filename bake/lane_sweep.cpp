// bake/lane_sweep.cpp - stage L of the budgeted baker: conservative quadrant (or octant) cone ratios
// for every texel from four (or eight) dilation sweeps, each testing 32 ratio lanes at once in
// 16-bit integers.
//
// The one fact: texel c's ratio in a quadrant is at least r when the dilation E_r(c) = max over
// blockers q != c of (h(q) - d(c, q) / r) is at most h(c). With d a chamfer distance (paths of moves
// that stay in the quadrant, fitted to the map's aspect, never longer than the straight line), E_r
// obeys a recurrence, so one pass over the map tests every texel for 32 lanes. Blockers are rounded
// up, the tested texel and every step down, so a passing lane is a proven lower bound (emitted
// times 1 - 1e-5), and a failing lane bounds the exact ratio from above (make_lane_plan).
//
// Proofs (moves, octants, rounding, wrap): docs/design/bakers.md#bakelane_sweepcpp-the-lane-sweeps
#include "bake/lane_sweep.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <new>
#include <stdexcept>
#include <string>
#include <vector>

#include "bake/geometry.h"
#include "bake/work_span.h"

namespace displace::bake::detail {

LaneSweepTotals LaneSweepTotals::add(LaneSweepTotals a, const LaneSweepTotals& b) {
  a.ratio_sum += b.ratio_sum;
  a.pending += b.pending;
  a.work += b.work;
  return a;
}

std::size_t lane_sweep_scratch(LaneSweepJob& job) {
  job.depth = std::max(2, job.column_count > 0 ? job.column_first + job.column_count - 1 : 1);
  job.padding = std::max(2, job.row_first + job.row_count - 1);
  return std::size_t(job.depth) * (std::size_t(job.width) + std::size_t(job.padding)) * lane_count;
}

LaneFloor lane_floor(const LanePlan& plan, const float* heights, std::size_t n, int sector, int sectors) {
  // the window: two texels each way along the shorter side (a brick's mortar at 2048 x 2048 needs
  // them) and as far in uv along the longer one
  constexpr int floor_reach = 2;
  const int width = plan.width, height = plan.height;
  const int reach_x =
      width > height ? int(std::ceil(double(floor_reach + 1) * width / height)) - 1 : floor_reach;
  const int reach_y =
      height > width ? int(std::ceil(double(floor_reach + 1) * height / width)) - 1 : floor_reach;
  const int i = int(n / std::size_t(width)), j = int(n % std::size_t(width));
  const float h = heights[n];
  const Grid grid(width, height, sectors, plan.wrap ? Address::wrap : Address::clamp);
  // the sector's quadrant of offsets (all four for one sector)
  const int quadrant = sectors == 4 ? sector : sectors == 8 ? sector / 2 : -1;
  const int x_first = quadrant == 0 || quadrant == 3 ? 0 : -reach_x,
            x_last = quadrant == 1 || quadrant == 2 ? 0 : reach_x;
  const int y_first = quadrant == 0 || quadrant == 1 ? 0 : -reach_y, y_last = quadrant >= 2 ? 0 : reach_y;
  LaneFloor result;
  float nearest_blocker = 1.0f;  // the window's exact ratio, with the exact baker's arithmetic
  for (int dy = y_first; dy <= y_last; ++dy)
    for (int dx = x_first; dx <= x_last; ++dx) {
      if ((dx == 0 && dy == 0) || !(point_sectors(grid, dx, dy) >> sector & 1u)) continue;
      int y = i + dy, x = j + dx;
      if (!plan.wrap && (y < 0 || y >= height || x < 0 || x >= width)) continue;
      y = (y % height + height) % height;
      x = (x % width + width) % width;
      const float other = heights[std::size_t(y) * width + x];
      if (other > h)
        nearest_blocker = std::min(nearest_blocker, pair_ratio(grid.distance(dx, dy), other - h));
    }
  result.upper = nearest_blocker;
  // every other texel is at least reach_x + 1 texels away along u or reach_y + 1 along v
  const float nearest_outside =
      std::min(float(reach_x + 1) / float(width), float(reach_y + 1) / float(height));
  const float further = h < plan.highest ? nearest_outside / (plan.highest - h) * (1.0f - 1e-5f) : 1.0f;
  result.floor = std::min({nearest_blocker, further, 1.0f});
  return result;
}

int lane_sweep_level_for(const char* setting, int cpu_level) {
  if (!setting || !*setting) return cpu_level;
  const std::string word = setting;
  const int asked = word == "avx512" ? 4 : word == "avx2" ? 3 : word == "generic" ? 0 : -1;
  if (asked < 0) {
    throw std::invalid_argument("DISPLACE_BAKE_ISA must be avx512, avx2 or generic, not '" + word + "'");
  }
  return std::min(asked, cpu_level);
}

int lane_sweep_best_level() {
#if defined(DISPLACE_LANE_SWEEP_X86)
  static const int cpu = __builtin_cpu_supports("x86-64-v4")   ? 4
                         : __builtin_cpu_supports("x86-64-v3") ? 3
                                                               : 0;
#else
  static const int cpu = 0;
#endif
  static const int level = lane_sweep_level_for(std::getenv("DISPLACE_BAKE_ISA"), cpu);
  return level;
}

#if !defined(DISPLACE_LANE_SWEEP_X86)
void near_row_avx2(const NearRowJob& job) { near_row_generic(job); }
void near_row_avx512(const NearRowJob& job) { near_row_generic(job); }
void stage_l_combine_avx2(const StageLCombineJob& job) { stage_l_combine_generic(job); }
void sub_cell_row_avx2(const SubCellRowJob& job) { sub_cell_row_generic(job); }
void sub_cell_row_avx512(const SubCellRowJob& job) { sub_cell_row_generic(job); }
void stage_l_combine_avx512(const StageLCombineJob& job) { stage_l_combine_generic(job); }
void apex_blocks_avx2(const float* const (&rows)[3], int first, int blocks, float* apex,
                      std::uint16_t* bottom) {
  apex_blocks_generic(rows, first, 2 * blocks, apex, bottom);
}
void apex_blocks_avx512(const float* const (&rows)[3], int first, int blocks, float* apex,
                        std::uint16_t* bottom) {
  apex_blocks_generic(rows, first, 4 * blocks, apex, bottom);
}
void lane_sweep_avx2(LaneSweepJob& job) { lane_sweep_generic(job); }
void lane_sweep_avx512(LaneSweepJob& job) { lane_sweep_generic(job); }
void lane_emit_avx2(LaneEmitJob& job, std::size_t first, std::size_t last) {
  lane_emit_generic(job, first, last);
}
void lane_emit_avx512(LaneEmitJob& job, std::size_t first, std::size_t last) {
  lane_emit_generic(job, first, last);
}
#endif

namespace {

// A chamfer move (da, db) and the row of steps it uses.
struct ChamferMove {
  int index, da, db;
};

// The plan's moves by angle from the v axis - (1, 0), (column_reach, 1) .. (2, 1), (1, 1) ..
// (1, row_reach), (0, 1) - and their uv lengths.
// (a fixed array: planned every frame, never allocated)
struct ChamferMoves {
  std::array<ChamferMove, lane_move_limit> move;
  std::size_t count = 0;
  void push_back(const ChamferMove& m) { move[count++] = m; }
  const ChamferMove* begin() const { return move.data(); }
  const ChamferMove* end() const { return move.data() + count; }
  std::size_t size() const { return count; }
  const ChamferMove& operator[](std::size_t m) const { return move[m]; }
};

ChamferMoves chamfer_moves(const LanePlan& plan, double (&length)[lane_move_limit]) {
  ChamferMoves moves;
  moves.push_back({lane_move_row, 1, 0});
  for (int k = plan.column_reach; k >= 2; --k) moves.push_back({lane_move_column + k - 2, k, 1});
  for (int k = 1; k <= plan.row_reach; ++k) moves.push_back({lane_move_row + k, 1, k});
  moves.push_back({lane_move_carry, 0, 1});
  for (const ChamferMove& move : moves)
    length[move.index] = std::hypot(double(move.db) / plan.width, double(move.da) / plan.height);
  return moves;
}

}  // namespace

void AlignedScratch::Free::operator()(std::uint16_t* p) const {
  ::operator delete[](p, std::align_val_t(64));
}

std::uint16_t* AlignedScratch::get(std::size_t values) {
  if (values > size_ || !data_) {
    data_.reset(static_cast<std::uint16_t*>(
        ::operator new[](std::max<std::size_t>(values, 1) * sizeof(std::uint16_t), std::align_val_t(64))));
    size_ = values;
  }
  return data_.get();
}

void set_lane_ratios(LanePlan& plan, const double (&ratios)[lane_count]) {
  double length[lane_move_limit] = {};
  const ChamferMoves moves = chamfer_moves(plan, length);
  const double scale = plan.scale;
  double slope[lane_count];
  plan.lane_ratio[0] = 0.0f;
  for (int l = 0; l < lane_count; ++l) {
    slope[l] = 1.0 / ratios[l];
    // emitted a little below the lane, for the rounding of the exact baker's own division
    plan.lane_ratio[l + 1] = float(std::min(1.0, ratios[l] * (1.0 - 1e-5)));
  }
  std::fill(std::begin(plan.steps), std::end(plan.steps), std::uint16_t(0));
  for (const ChamferMove& move : moves)
    for (int l = 0; l < lane_count; ++l) {
      const double step = std::floor(scale * length[move.index] * slope[l] * height_scale);
      plan.steps[move.index * lane_count + l] = std::uint16_t(std::min(step, height_scale));
    }

  // Upper bounds. Lane l (ratio r) fails when some path P of moves from a real blocker q has
  // top(q) - (sum of its steps) > bottom(c), so top(q) - sum >= bottom(c) + 1. A move of uv length
  // len costs scale * len * 65535 / r less the fraction its rounding dropped, and that fraction is at
  // most lambda * len * M (M = the larger side; lambda the largest dropped fraction per texel of
  // length over the moves, per lane); P is no shorter than the straight line (length d); top is at
  // most 65535 h + 1.016 and bottom at least 65535 h - 1.016. Together, with d >= 1 / M:
  // gap > d * (scale / r - (lambda + 1.032) * M / 65535), so the exact ratio is below the inverse of
  // that bracket when it is positive. (Such a q is within uv distance 1 whenever the bound is below
  // 1, so the exact baker counts it.) A move whose step is the whole height range leaves nothing
  // behind it, so it is on no failing path and does not count.
  const double sides = double(std::max(plan.width, plan.height));
  for (int p = 0; p < lane_count; ++p) {
    double lambda = 0.0;
    for (const ChamferMove& move : moves) {
      const double exact_step = scale * length[move.index] * slope[p] * height_scale;
      if (exact_step >= height_scale) continue;  // such a move leaves 0: it is on no failing path
      const double dropped = exact_step - double(plan.steps[move.index * lane_count + p]);
      lambda = std::max(lambda, dropped / (length[move.index] * sides));
    }
    const double bracket = scale * slope[p] - (lambda + 1.032) * sides / height_scale;
    plan.lane_upper[p] = bracket > 0.0 ? float(std::min(1.0, (1.0 + 1e-5) / bracket)) : 1.0f;
  }
  plan.lane_upper[lane_count] = 1.0f;
}

void make_lane_plan(const float* heights, int width, int height, bool wrap, float lowest_ratio, bool knights,
                    bool octants, LanePlan& plan) {
  plan.width = width;
  plan.height = height;
  plan.wrap = wrap;
  const std::size_t count = std::size_t(width) * height;
  plan.top.resize(count);
  plan.bottom.resize(count);
  // h * 65535 in float is within 2^-8 of the real product (below 2^16 a float's unit in the last
  // place is 2^-7), so moving it by 2^-7 before truncating rounds the right way; top and bottom are
  // within 1.016 of 65535 h
  std::uint16_t* top = plan.top.data();
  std::uint16_t* bottom = plan.bottom.data();
  // the extremes as bit patterns: for heights in [0, 1] (with -0 masked to 0) their order is the
  // floats' order, and the integer loop vectorises
  struct Extremes {
    std::int32_t low = 0x7fffffff, high = 0;
  };
  const Extremes extremes = parallel_reduce_region(
      "lane plan", tbb::blocked_range<std::size_t>(0, count, 1 << 13), Extremes{},
      [&](const tbb::blocked_range<std::size_t>& range, Extremes found) {
        for (std::size_t n = range.begin(); n < range.end(); ++n) {
          const float scaled = heights[n] * float(height_scale);
          const int up = int(scaled + 0x1p-7f) + 1, down = int(scaled - 0x1p-7f);
          top[n] = std::uint16_t(up < 65535 ? up : 65535);
          bottom[n] = std::uint16_t(down > 0 ? down : 0);
          std::int32_t bits;
          std::memcpy(&bits, &heights[n], sizeof bits);
          bits &= 0x7fffffff;
          found.low = bits < found.low ? bits : found.low;
          found.high = bits > found.high ? bits : found.high;
        }
        return found;
      },
      [](Extremes a, const Extremes& b) {
        a.low = std::min(a.low, b.low);
        a.high = std::max(a.high, b.high);
        return a;
      });
  float lowest_height;
  std::memcpy(&plan.highest, &extremes.high, sizeof(float));
  std::memcpy(&lowest_height, &extremes.low, sizeof(float));
  plan.nearest = 1.0f / float(std::max(width, height));

  // The moves, fitted to the aspect (see the header comment): row moves (1, 0 .. row_reach) and
  // column moves (2 .. column_reach, 1), each reach the smallest that keeps the last move within
  // 2% (in tangent) of the square map's atan(1 / 2) of its axis. Octants where the diagonal that
  // separates them is a move.
  const double aspect = double(width) / double(height);
  constexpr double widest_tangent = 0.51;  // tan of the widest angle wanted between neighbouring moves
  auto reach_for = [&](double stretch) {
    return knights ? std::clamp(int(std::ceil(stretch / widest_tangent)), 1, lane_reach_limit) : 1;
  };
  plan.row_reach = reach_for(aspect);
  plan.column_reach = reach_for(1.0 / aspect);
  plan.octant_split = 0;
  if (octants && width == height)
    plan.octant_split = 1;
  else if (octants && knights && width % height == 0 && width / height <= plan.row_reach)
    plan.octant_split = width / height;
  else if (octants && knights && height % width == 0 && height / width <= plan.column_reach)
    plan.octant_split = height / width;

  // the chamfer scale: the cosine of half the widest angle (in uv) between neighbouring moves
  double length[lane_move_limit] = {};
  const ChamferMoves moves = chamfer_moves(plan, length);
  double scale = 1.0;
  for (std::size_t m = 1; m < moves.size(); ++m) {
    auto angle = [&](const ChamferMove& move) {  // from the v axis
      return std::atan2(double(move.db) / width, double(move.da) / height);
    };
    scale = std::min(scale, std::cos(0.5 * (angle(moves[m]) - angle(moves[m - 1]))));
  }
  plan.scale = scale * (1.0 - 1e-9);

  // Lanes reach up to just above 1 (so that passing the top lane proves a ratio of 1 after
  // rounding) and down to the smallest ratio any texel can have - the nearest texel over the largest
  // gap - but no higher than lowest_ratio. Below a knee they are 1.28x apart, which still certifies
  // every texel within 0.75 of exact (the upper bounds below); above it they are as close as the
  // certified bound needs, since the large ratios are the ones that decide how far a ray steps. A
  // lane r that fails bounds the exact ratio by r / (scale - loss r), loss growing with the larger
  // side M (the rounding of heights and steps against the shortest move, 1 / M): near 1 on a large
  // map the lanes must stay closer, lower down they may spread, and the lowest lanes give way to
  // the upper ones where there are not enough.
  const double range = double(plan.highest) - double(lowest_height);
  const double smallest_ratio =
      range > 0.0 ? std::clamp(double(plan.nearest) / range, 1.0 / 8192.0, double(lowest_ratio))
                  : double(lowest_ratio);
  const double highest_lane = 1.0001, knee = 0.05, low_spacing = 1.28, certified = 0.77;
  const double worst_loss = 2.032 * double(std::max(width, height)) / height_scale;  // see the upper bounds
  // the spacing below lane r that still certifies `certified`
  auto spacing_below = [&](double r) { return std::max(1.05, (scale - worst_loss * r) / certified); };
  int top_lanes = 0;  // the upper lanes needed to reach the knee at that spacing
  for (double r = highest_lane; r > knee && top_lanes < lane_count - 1; r /= spacing_below(r)) ++top_lanes;
  const int low_lanes = std::clamp(int(std::ceil(std::log(knee / smallest_ratio) / std::log(low_spacing))), 0,
                                   std::max(0, std::min(lane_count / 2, lane_count - 1 - top_lanes)));
  top_lanes = lane_count - 1 - low_lanes;
  // The upper lanes take the steps that spacing allows made `closer` times smaller (in log), as many
  // as reach down to the knee lane, the top of the lower ones, when there are more lanes than
  // needed (never wider than allowed: closer >= 1); the lower ones go on from where they end.
  const double knee_target =
      std::max(smallest_ratio, knee / std::pow(low_spacing, low_lanes)) * std::pow(low_spacing, low_lanes);
  double steps_needed = 0.0;  // at spacing_below, with the fraction of the last
  for (double r = highest_lane; steps_needed < lane_count;) {
    const double spacing = spacing_below(r);
    if (r / spacing <= knee_target) {
      steps_needed += std::log(r / knee_target) / std::log(spacing);
      break;
    }
    r /= spacing;
    steps_needed += 1.0;
  }
  const double closer = steps_needed > 0.0 ? std::max(1.0, top_lanes / steps_needed) : 1.0;
  double ratios[lane_count];
  ratios[lane_count - 1] = highest_lane;
  for (int l = lane_count - 1; l > 0; --l)
    ratios[l - 1] = l > low_lanes ? ratios[l] / std::pow(spacing_below(ratios[l]), 1.0 / closer)
                                  : ratios[l] / low_spacing;
  set_lane_ratios(plan, ratios);
}

LaneSweepTotals sweep_sectors(const LanePlan& plan, const float* heights, int sectors,
                              std::uint32_t* const masks[], float* out4, const std::uint8_t* pending_count,
                              const LaneSweepOptions& options) {
  const int level = options.level < 0 ? lane_sweep_best_level() : options.level;
  const bool octants = sectors == 8;
  if (octants && plan.octant_split == 0) throw std::logic_error("lane plan without octants");
  const int jobs = octants ? 8 : 4;
  const bool tall = plan.height > plan.width;
  long long works[8] = {};
  tbb::parallel_for(0, jobs, [&](int n) {
    const int quadrant = octants ? n / 2 : n;
    // quadrant q holds the blockers of sector q: 0 = +u +v, 1 = -u +v, 2 = -u -v, 3 = +u -v
    LaneSweepJob job;
    job.flip_x = quadrant == 1 || quadrant == 2;
    job.flip_y = quadrant >= 2;
    job.carry = true;
    job.row_first = 0;
    job.row_count = plan.row_reach + 1;
    job.column_first = 2;
    job.column_count = plan.column_reach - 1;
    // an octant: the moves from (1, 0) to the diagonal move without the carry (the half next to
    // the v axis), or from the diagonal move to (0, 1) with it (the half next to the u axis)
    const bool next_to_v = n % 2 == 1;
    const int split = plan.octant_split;
    if (octants && next_to_v) {
      job.carry = false;
      job.row_count = tall ? 1 : split + 1;
      if (tall) job.column_first = split, job.column_count = plan.column_reach - split + 1;
    } else if (octants) {
      job.row_first = tall ? 1 : split;
      job.row_count = plan.row_reach - job.row_first + 1;
      job.column_count = tall ? split - 1 : 0;
    }
    // sectors go round from +u: in quadrant q the octant next to the u axis is 2q for even q
    const int sector = !octants ? quadrant : 2 * quadrant + (next_to_v == (quadrant % 2 == 0) ? 1 : 0);
    job.width = plan.width;
    job.height = plan.height;
    LaneScratch& kept = plan.scratch[std::size_t(n)];
    kept.row_sums.assign(std::size_t(job.height / 2 + 2), 0);
    job.wrap = plan.wrap;
    job.top = plan.top.data();
    job.bottom = plan.bottom.data();
    job.steps = plan.steps;
    job.scratch = kept.rows.get(lane_sweep_scratch(job));
    job.row_sums = kept.row_sums.data();
    job.masks = masks[sector];
    job.stop_early = options.stop_early;
    switch (level) {
      case 0: lane_sweep_generic(job); break;
      case 3: lane_sweep_avx2(job); break;
      default: lane_sweep_avx512(job); break;
    }
    works[n] = job.work;
  });
  LaneSweepTotals totals;
  for (long long w : works) totals.work += w;
  if (!out4) return totals;
  if (sectors != 4) throw std::logic_error("the lane sweep writes 4-sector output only");

  // the 4-sector output, all four quadrants of a texel together
  const std::size_t count = std::size_t(plan.width) * plan.height;
  const LaneSweepTotals sums = tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, (count + 15) / 16, 256), LaneSweepTotals{},
      [&](const tbb::blocked_range<std::size_t>& blocks, LaneSweepTotals partial) {
        LaneEmitJob emit;
        for (int q = 0; q < 4; ++q) emit.masks[q] = masks[q];
        emit.plan = &plan;
        emit.heights = heights;
        emit.out = out4;
        emit.lane_ratio = plan.lane_ratio;
        emit.pending_count = pending_count;
        emit.floor_keep = options.floor_keep;
        const std::size_t first = blocks.begin() * 16, last = std::min(count, blocks.end() * 16);
        switch (level) {
          case 0: lane_emit_generic(emit, first, last); break;
          case 3: lane_emit_avx2(emit, first, last); break;
          default: lane_emit_avx512(emit, first, last); break;
        }
        partial.ratio_sum += emit.ratio_sum;
        partial.pending += emit.pending;
        return partial;
      },
      LaneSweepTotals::add);
  totals.ratio_sum = sums.ratio_sum;
  totals.pending = sums.pending;
  return totals;
}

namespace {

// The bilinear sweeps of one call of sweep_bilinear_quadrants: its arguments, a quadrant's job, and
// the two ways to run the quadrants (each whole, or each in two strips on two threads).
struct QuadrantSweeps {
  const LanePlan& cells;
  int width, height;
  const std::uint16_t* texel_bottom;
  const std::uint16_t* bonus;
  std::uint8_t* const* passed;
  const std::uint16_t* bonus3;
  std::uint8_t* const* passed3;
  int level;
  bool stop_early;

  void run(LaneSweepJob& job) const {
    switch (level) {
      case 0: lane_sweep_generic(job); break;
      case 3: lane_sweep_avx2(job); break;
      default: lane_sweep_avx512(job); break;
    }
  }

  // quadrant q's job with the buffers of scratch slot `slot` (their contents as they are)
  LaneSweepJob job_for(int quadrant, int slot) const {
    LaneScratch& kept = cells.scratch[std::size_t(slot)];
    LaneSweepJob job;
    job.width = cells.width;
    job.height = cells.height;
    job.carry = true;
    job.row_first = 0;
    job.row_count = cells.row_reach + 1;
    job.column_first = 2;
    job.column_count = cells.column_reach - 1;
    job.scratch = kept.rows.get(lane_sweep_scratch(job));
    job.bilinear_scratch = kept.bilinear.get(bilinear_sweep_scratch(job.width, width));
    job.wrap = cells.wrap;
    job.flip_x = quadrant == 1 || quadrant == 2;
    job.flip_y = quadrant >= 2;
    job.top = cells.top.data();
    job.steps = cells.steps;
    job.passed = passed[quadrant];
    job.bilinear = true;
    job.texel_width = width;
    job.texel_height = height;
    // with wrap, a flipped axis sees cell n' between its local texels n' and n' + 1: one before the
    // convention's (see LaneSweepJob)
    job.cell_offset_x = cells.wrap && job.flip_x ? -1 : 0;
    job.cell_offset_y = cells.wrap && job.flip_y ? -1 : 0;
    job.texel_bottom = texel_bottom;
    job.bonus = bonus;
    job.passed3 = passed3[quadrant];
    job.bonus3 = bonus3;
    job.stop_early = stop_early;
    return job;
  }

  // a quadrant's whole sweep in one task, in slot q
  long long whole(int quadrant) const {
    LaneScratch& kept = cells.scratch[std::size_t(quadrant)];
    LaneSweepJob job = job_for(quadrant, quadrant);
    kept.row_sums.assign(std::size_t(job.height / 2 + 2), 0);
    job.row_sums = kept.row_sums.data();
    // the first lap's first three rows read rows not swept yet, and the second lap never stops
    // before they are tested again: theirs are always left to it, and as many more as it took the
    // last time (a map's next frame is much like it)
    job.skip_tests = std::max(3, kept.second_lap_rows);
    run(job);
    kept.second_lap_rows = job.second_lap_rows;
    return job.work;
  }

  // Each quadrant's rows in two strips, A = steps [0, half) and B = [half, H), in slots q and
  // q + 4. First passes, all in parallel: A as the first lap begins, B from nothing below its first
  // row, each keeping its rows' sums. Second passes, in parallel: B again from A's last rows (A's
  // buffers) until its rows meet its first pass's - then the rest of them stand, as the second lap's
  // stop test argues - and, with wrap, A's second lap from B's last rows (B's buffers) until it
  // meets A's first pass. Both meeting, every row holds what the whole sweep gives (the same least
  // solution of the rows' recurrence); where either does not, the quadrant is swept whole again.
  long long split(int first_quadrant, int quadrant_count) const {
    const bool wrap = cells.wrap;
    const int H = cells.height, half = (H + 1) / 2;
    long long works[4][2] = {};
    int skipped[4][2] = {}, swept[4][2] = {};
    bool met[4][2] = {};
    auto strip = [&](int n, int& quadrant, bool& second) {
      quadrant = first_quadrant + n / 2;
      second = n % 2 == 1;
    };
    parallel_for_each_region("sweeps: first passes", 0, 2 * quadrant_count, [&](int n) {
      int quadrant;
      bool second;
      strip(n, quadrant, second);
      LaneScratch& kept = cells.scratch[std::size_t(quadrant + (second ? 4 : 0))];
      LaneSweepJob job = job_for(quadrant, quadrant + (second ? 4 : 0));
      job.split = true;
      job.fresh = true;
      job.first_step = second ? half : 0;
      job.last_step = second ? H : half;
      const int rows = job.last_step - job.first_step;
      // box tests left to the second pass: the first three rows read rows not swept yet (with clamp,
      // A's read nothing, truly), and as many more as the second pass took the last time
      const int skip = wrap || second ? std::min(rows, std::max(3, kept.second_lap_rows)) : 0;
      job.skip_until = job.first_step + skip;
      kept.row_sums.assign(std::size_t(rows), 0);
      job.record_sums = kept.row_sums.data();
      job.sums_count = rows;
      run(job);
      works[quadrant][second] = job.work;
      skipped[quadrant][second] = skip;
    });
    parallel_for_each_region("sweeps: second passes", 0, 2 * quadrant_count, [&](int n) {
      int quadrant;
      bool second;
      strip(n, quadrant, second);
      if (!second && !wrap) {  // with clamp, A's first pass is the sweep's
        met[quadrant][0] = true;
        return;
      }
      // B goes on from A's buffers, A's second lap from B's; each against its own first pass
      const int own = quadrant + (second ? 4 : 0), other = quadrant + (second ? 0 : 4);
      LaneSweepJob job = job_for(quadrant, other);
      job.split = true;
      job.fresh = false;
      job.first_step = second ? half : H;
      job.last_step = second ? H : H + half;
      job.compare_sums = cells.scratch[std::size_t(own)].row_sums.data();
      job.sums_count = job.last_step - job.first_step;
      job.compare_skip = skipped[quadrant][second];
      run(job);
      works[quadrant][second] += job.work;
      // with clamp, B running to the map's end without meeting its first pass is the sweep itself
      met[quadrant][second] = job.converged || !wrap;
      swept[quadrant][second] = job.split_rows;
    });
    long long work = 0;
    int unmet[4], unmet_count = 0;
    for (int quadrant = first_quadrant; quadrant < first_quadrant + quadrant_count; ++quadrant) {
      work += works[quadrant][0] + works[quadrant][1];
      for (int part = 0; part < 2; ++part)
        cells.scratch[std::size_t(quadrant + 4 * part)].second_lap_rows = swept[quadrant][part];
      if (!met[quadrant][0] || !met[quadrant][1]) unmet[unmet_count++] = quadrant;
    }
    if (unmet_count > 0) {
      long long again[4] = {};
      parallel_for_each_region("sweeps: whole again", 0, unmet_count,
                               [&](int n) { again[n] = whole(unmet[n]); });
      for (int n = 0; n < unmet_count; ++n) work += again[n];
    }
    return work;
  }
};

}  // namespace

long long sweep_bilinear_quadrants(const LanePlan& cells, int width, int height,
                                   const std::uint16_t* texel_bottom, const std::uint16_t* bonus,
                                   std::uint8_t* const passed[4], const std::uint16_t* bonus3,
                                   std::uint8_t* const passed3[4], int level, bool stop_early,
                                   int first_quadrant, int quadrant_count, bool split) {
  const QuadrantSweeps sweeps{cells,        width,   height,
                              texel_bottom, bonus,   passed,
                              bonus3,       passed3, level < 0 ? lane_sweep_best_level() : level,
                              stop_early};
  // a strip's second pass stops after depth + 3 equal rows (the kernel's stop test), and with wrap
  // A's must read B's last depth rows: strips shorter than twice that would rarely meet
  const int H = cells.height, depth = std::max(2, cells.column_reach);
  if (split && stop_early && H >= split_sweep_rows && H / 2 >= 2 * (depth + 3))
    return sweeps.split(first_quadrant, quadrant_count);
  long long works[4] = {};
  parallel_for_each_region("sweeps", first_quadrant, first_quadrant + quadrant_count,
                           [&](int quadrant) { works[quadrant] = sweeps.whole(quadrant); });
  return works[0] + works[1] + works[2] + works[3];
}

}  // namespace displace::bake::detail
