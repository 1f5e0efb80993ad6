// bake/cone_budgeted.cpp - the product baker: conservative at every budget, certified, incremental.
//
// The one fact: every ratio it emits is a lower bound of the exact one, whatever the budget: stage
// L's passing lanes are proven bounds (lane_sweep.cpp), and the refinement stages emit minima of pair
// ratios of real texels and of bounds (distance to a pyramid block) / (block max - texel height),
// never above the pair ratio of any texel inside the block (geometry.h).
//
// Stage L (bake(), always completed, O(N)): the lane sweeps, which also certify each texel's slack.
// Then, while the budget lasts, for texels whose slack is below 1 - tolerance: stage A (8 x 8 groups,
// one pyramid traversal each), stage B (a branch and bound per texel). Incremental update: stage 0
// for changed groups, exact repair where heights rose, unless a new stage L costs less.
//
// Stages: docs/design/bakers.md#bakecone_budgetedcpp-the-product-bakers-stages
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>

#include "bake/budget_clock.h"
#include "bake/lane_sweep.h"
#include "bake/search.h"
#include "displace/simd_clones.h"

namespace displace::bake {

namespace {

using detail::Grid;
using detail::Node;
using detail::Pyramid;
using detail::SearchContext;
using detail::SectorMask;

constexpr int group_level = 3;  // groups are 2^3 x 2^3 texels
constexpr int group_size = 1 << group_level;
constexpr int open_factor = 2;  // a block is opened while its gap to the group (texels) < factor * size
constexpr float lane_lowest_ratio = 0.02f;  // stage L: the lowest lane is at most this
constexpr bool lane_knights = true;         // stage L: chamfer with knight moves (see lane_sweep.cpp)

struct Candidate {
  int x0, x1, y0, y1;  // unrolled texel coordinates, inclusive
  float max;           // block max height
  float group_bound;   // lower bound for every texel of the group
  Node node;
};

struct GroupRect {
  int i0, i1, j0, j1;  // inclusive texel rows and columns
};

GroupRect group_rect(const Grid& grid, int group) {
  const int groups_x = (grid.width + group_size - 1) / group_size;
  const int gi = group / groups_x, gj = group % groups_x;
  return {gi * group_size, std::min(grid.height, (gi + 1) * group_size) - 1, gj * group_size,
          std::min(grid.width, (gj + 1) * group_size) - 1};
}

int group_count(const Grid& grid) {
  return ((grid.width + group_size - 1) / group_size) * ((grid.height + group_size - 1) / group_size);
}

// One traversal of the pyramid for a group: every block that could hold a blocker for some texel of
// the group ends up as a candidate, either opened down to a texel or kept whole when far enough.
long long collect_candidates(const SearchContext& context, const GroupRect& g, float group_min,
                             std::span<const Node> roots, std::vector<Candidate>& out) {
  const Grid& grid = context.grid;
  const Pyramid& pyramid = context.pyramid;
  long long work = 0;
  out.clear();
  std::vector<Node> stack(roots.begin(), roots.end());
  while (!stack.empty()) {
    const Node node = stack.back();
    stack.pop_back();
    ++work;
    const int count_x = pyramid.count_x(node.level), count_y = pyramid.count_y(node.level);
    const int tile_x = detail::floor_div(node.nx, count_x), tile_y = detail::floor_div(node.ny, count_y);
    const int bx = node.nx - tile_x * count_x, by = node.ny - tile_y * count_y;
    const float block_max = pyramid.value(node.level, by, bx);
    if (!(block_max > group_min)) continue;
    int x0, x1, y0, y1;
    detail::block_range(node.nx, node.level, count_x, grid.width, x0, x1);
    detail::block_range(node.ny, node.level, count_y, grid.height, y0, y1);
    // offsets q - c over every texel c of the group
    const int gap_x = detail::interval_gap(x0 - g.j1, x1 - g.j0);
    const int gap_y = detail::interval_gap(y0 - g.i1, y1 - g.i0);
    const float bound = detail::pair_ratio(grid.distance(gap_x, gap_y), block_max - group_min);
    if (!(bound < 1.0f)) continue;  // cannot beat the clamp
    if (node.level > 0 && std::max(gap_x, gap_y) < open_factor * (1 << node.level)) {
      const int level = node.level - 1;
      const int child_count_x = pyramid.count_x(level), child_count_y = pyramid.count_y(level);
      for (int dy = 0; dy < 2 && 2 * by + dy < child_count_y; ++dy)
        for (int dx = 0; dx < 2 && 2 * bx + dx < child_count_x; ++dx)
          stack.push_back(
              {level, tile_x * child_count_x + 2 * bx + dx, tile_y * child_count_y + 2 * by + dy});
      continue;
    }
    out.push_back({x0, x1, y0, y1, block_max, bound, node});
  }
  std::sort(out.begin(), out.end(),
            [](const Candidate& a, const Candidate& b) { return a.group_bound < b.group_bound; });
  return work;
}

// Scans a group's candidates for one texel. exact_best receives the pair-ratio minimum over the
// candidate texels, coarse the minimum of the block bounds. Returns the work done.
long long scan_candidates(const Grid& grid, std::span<const Candidate> candidates, int ci, int cj, float hc,
                          float* exact_best, float* coarse) {
  const int sectors = grid.sector_count;
  float largest = 1.0f;
  long long work = 0;
  for (const Candidate& c : candidates) {
    if (!(c.group_bound < largest)) break;
    ++work;
    if (!(c.max > hc)) continue;
    const int x0 = c.x0 - cj, x1 = c.x1 - cj, y0 = c.y0 - ci, y1 = c.y1 - ci;
    const float ratio = detail::pair_ratio(
        grid.distance(detail::interval_gap(x0, x1), detail::interval_gap(y0, y1)), c.max - hc);
    const bool texel = c.node.level == 0;
    const SectorMask mask =
        texel ? detail::point_sectors(grid, x0, y0) : detail::rect_sectors(grid, x0, x1, y0, y1);
    float* target = texel ? exact_best : coarse;
    bool lowered = false;
    for (int k = 0; k < sectors; ++k)
      if ((mask >> k & 1u) && ratio < target[k]) {
        target[k] = ratio;
        lowered = true;
      }
    if (lowered) {
      largest = 0.0f;
      for (int k = 0; k < sectors; ++k) largest = std::max(largest, std::min(exact_best[k], coarse[k]));
    }
  }
  return work;
}

}  // namespace

struct BudgetedBaker::State {
  Grid grid;
  std::vector<float> heights;
  Pyramid pyramid;
  std::vector<Node> roots;
  // per texel: emitted ratio / best known upper bound of the exact ratio (1 = known exact); the
  // texel is refined while its slack is below 1 - tolerance
  std::vector<float> slack;
  std::vector<float> group_slack;         // smallest slack of each group
  std::vector<std::uint8_t> group_stage;  // 0: only the O(N) floor so far, 1: stage A done
  // stage 0, per level L >= 1: the max over the level-L blocks that a quadrant of directions from a
  // texel can reach inside its 3 x 3 level-L neighbourhood (quadrant q = sector q of 4), and per
  // column / row the inverse of the distance a texel must travel, in each direction, to leave its
  // level-(L-1) neighbourhood
  std::vector<std::array<std::vector<float>, 4>> quadrant_max;
  std::vector<std::array<std::vector<float>, 2>> inverse_exit_x;  // [level][0: towards +u, 1: -u][column]
  std::vector<std::array<std::vector<float>, 2>> inverse_exit_y;  // [level][0: towards +v, 1: -v][row]
  // per texel and sector: the smallest pair ratio of a real blocker found so far (an upper bound of
  // the exact ratio, 1 when none), which starts stage B's search with a tight bound
  std::vector<float> upper;
  int cursor = 0;  // next group the refinement looks at
  // stage L: the lane plan of the current heights and, per quadrant and texel, the lane count
  detail::LanePlan lanes;
  std::vector<std::uint32_t> lane_masks;
  bool search_ready = false;  // pyramid, roots and stage 0's tables match the heights
  bool slack_stale = false;   // slack and group_slack still to be derived from lane_masks
  State(int w, int h, int sectors, Address address) : grid(w, h, sectors, address) {}
};

namespace {

// Stage 0, the O(N) floor that every call completes whatever the budget: the eight neighbours
// exactly, and for every level L one bound for all texels between the level-(L-1) and level-L
// 3 x 3 block neighbourhoods: (smallest distance to leave the inner one) / (largest height in the
// outer one - texel height). Every texel other than c lies in one of these rings (or beyond uv
// distance 1, where it cannot matter), so the result is conservative; coarse, but never zero.
// Inverse distances to leave the level-(level - 1) neighbourhood along one axis, per texel index.
// Blocks are unrolled like the pyramid (the last block of a tile may be partial); with clamp there is
// nothing beyond the map, so that side's inverse is 0 (no blocker).
void exit_inverses(const Grid& grid, int level, int size, bool along_u,
                   std::array<std::vector<float>, 2>& out) {
  const int fine = level - 1;
  const int count = (size + (1 << fine) - 1) >> fine;
  const bool wrap = grid.address == Address::wrap;
  out[0].assign(size, 0.0f);
  out[1].assign(size, 0.0f);
  for (int x = 0; x < size; ++x) {
    const int b = x >> fine;
    int first, last;
    if (wrap || b + 1 < count) {
      detail::block_range(b + 1, fine, count, size, first, last);
      const int exit = last + 1 - x;
      out[0][x] = 1.0f / (along_u ? grid.distance(exit, 0) : grid.distance(0, exit));
    }
    if (wrap || b - 1 >= 0) {
      detail::block_range(b - 1, fine, count, size, first, last);
      const int exit = x - (first - 1);
      out[1][x] = 1.0f / (along_u ? grid.distance(exit, 0) : grid.distance(0, exit));
    }
  }
}

void prepare_stage0(BudgetedBaker::State& state) {
  const Grid& grid = state.grid;
  const Pyramid& pyramid = state.pyramid;
  const bool wrap = grid.address == Address::wrap;
  state.quadrant_max.resize(pyramid.levels);
  state.inverse_exit_x.resize(pyramid.levels);
  state.inverse_exit_y.resize(pyramid.levels);
  for (int level = 1; level < pyramid.levels; ++level) {
    exit_inverses(grid, level, grid.width, true, state.inverse_exit_x[level]);
    exit_inverses(grid, level, grid.height, false, state.inverse_exit_y[level]);
    const int cx = pyramid.count_x(level), cy = pyramid.count_y(level);
    const std::vector<float>& blocks = pyramid.max.levels[level];
    // separable: the max with the next block along u (towards +u and towards -u), then along v; a
    // missing neighbour (clamp) is the block itself, which changes no maximum
    std::array<std::vector<float>, 2> along_u;
    for (int side = 0; side < 2; ++side) {
      along_u[side].resize(blocks.size());
      for (int by = 0; by < cy; ++by) {
        const float* row = &blocks[std::size_t(by) * cx];
        float* target = &along_u[side][std::size_t(by) * cx];
        for (int bx = 0; bx < cx; ++bx) {
          int other = side == 0 ? bx + 1 : bx - 1;
          if (other < 0 || other >= cx) other = wrap ? (other + cx) % cx : bx;
          target[bx] = std::max(row[bx], row[other]);
        }
      }
    }
    constexpr int u_side[4] = {0, 1, 1, 0}, v_step[4] = {1, 1, -1, -1};  // quadrant q: +u/-u, +v/-v
    for (int q = 0; q < 4; ++q) {
      const std::vector<float>& source = along_u[u_side[q]];
      std::vector<float>& quadrant = state.quadrant_max[level][q];
      quadrant.resize(blocks.size());
      for (int by = 0; by < cy; ++by) {
        int other = by + v_step[q];
        if (other < 0 || other >= cy) other = wrap ? (other + cy) % cy : by;
        const float* row = &source[std::size_t(by) * cx];
        const float* other_row = &source[std::size_t(other) * cx];
        float* target = &quadrant[std::size_t(by) * cx];
        for (int bx = 0; bx < cx; ++bx) target[bx] = std::max(row[bx], other_row[bx]);
      }
    }
  }
}

// Stage 0 over texel rows [i0, i1] and columns [j0, j1] (inclusive), a row at a time so that the
// column loops vectorise. Works with slopes (gap / distance) and divides once per sector, with a
// margin that covers the rounding of that reciprocal, so the ratios stay below exact bit for bit.
DISPLACE_SIMD_CLONES
void stage0_rect(BudgetedBaker::State& state, int i0, int i1, int j0, int j1, float* out) {
  const Grid& grid = state.grid;
  const Pyramid& pyramid = state.pyramid;
  const int sectors = grid.sector_count;
  const int width = grid.width, height = grid.height;
  const bool wrap = grid.address == Address::wrap;
  constexpr float margin = 1.0f - 1e-6f;
  const int span = j1 - j0 + 1;
  std::vector<float> slope(std::size_t(sectors) * span), ring(4 * std::size_t(span)), neighbour_row(span);
  for (int i = i0; i <= i1; ++i) {
    const float* h = &state.heights[std::size_t(i) * width + j0];
    // rings: per quadrant, the largest slope from the texel to the highest block it can reach in the
    // ring between its level-(L-1) and level-L neighbourhoods
    std::fill(ring.begin(), ring.end(), 0.0f);
    float* ring0 = &ring[0];
    float* ring1 = &ring[std::size_t(span)];
    float* ring2 = &ring[2 * std::size_t(span)];
    float* ring3 = &ring[3 * std::size_t(span)];
    for (int level = 1; level < pyramid.levels; ++level) {
      const std::size_t row_offset = std::size_t(i >> level) * pyramid.count_x(level);
      const float* top0 = &state.quadrant_max[level][0][row_offset];
      const float* top1 = &state.quadrant_max[level][1][row_offset];
      const float* top2 = &state.quadrant_max[level][2][row_offset];
      const float* top3 = &state.quadrant_max[level][3][row_offset];
      const float* exit_plus = &state.inverse_exit_x[level][0][j0];
      const float* exit_minus = &state.inverse_exit_x[level][1][j0];
      const float down = state.inverse_exit_y[level][0][i], up = state.inverse_exit_y[level][1][i];
      for (int block_start = 0; block_start < span;) {  // one block of constant maxima at a time
        const int block = (j0 + block_start) >> level;
        const int block_end = std::min(span, ((block + 1) << level) - j0);
        const float t0 = top0[block], t1 = top1[block], t2 = top2[block], t3 = top3[block];
        for (int n = block_start; n < block_end; ++n) {  // quadrants 0..3: (+u,+v) (-u,+v) (-u,-v) (+u,-v)
          ring0[n] = std::max(ring0[n], (t0 - h[n]) * std::max(exit_plus[n], down));
          ring1[n] = std::max(ring1[n], (t1 - h[n]) * std::max(exit_minus[n], down));
          ring2[n] = std::max(ring2[n], (t2 - h[n]) * std::max(exit_minus[n], up));
          ring3[n] = std::max(ring3[n], (t3 - h[n]) * std::max(exit_plus[n], up));
        }
        block_start = block_end;
      }
    }
    // a sector takes the quadrant that contains it (n = 8) or all four (n = 1)
    for (int k = 0; k < sectors; ++k) {
      float* sector_slope = &slope[std::size_t(k) * span];
      if (sectors == 1) {
        for (int n = 0; n < span; ++n)
          sector_slope[n] =
              std::max(std::max(ring[n], ring[span + n]), std::max(ring[2 * span + n], ring[3 * span + n]));
      } else {
        const int q = sectors == 4 ? k : k / 2;
        std::copy_n(&ring[std::size_t(q) * span], span, sector_slope);
      }
    }
    // the eight neighbours, exactly
    for (int dy = -1; dy <= 1; ++dy) {
      int qi = i + dy;
      if (wrap) qi = (qi + height) % height;
      if (qi < 0 || qi >= height) continue;  // clamp: absent
      const float* row = &state.heights[std::size_t(qi) * width];
      for (int dx = -1; dx <= 1; ++dx) {
        if (dx == 0 && dy == 0) continue;
        const float inverse = 1.0f / grid.distance(dx, dy);
        const SectorMask mask = detail::point_sectors(grid, dx, dy);
        // the texels whose neighbour lies inside the map, then the (at most two) edge texels
        const int inner_begin = std::max(0, -(j0 + dx)), inner_end = std::min(span, width - j0 - dx);
        const float* neighbour = row + j0 + dx;
        for (int n = inner_begin; n < inner_end; ++n) neighbour_row[n] = (neighbour[n] - h[n]) * inverse;
        for (int n = 0; n < span; ++n) {
          if (n >= inner_begin && n < inner_end) {
            n = inner_end - 1;
            continue;
          }
          const int qj = j0 + n + dx;
          neighbour_row[n] = wrap ? (row[(qj + width) % width] - h[n]) * inverse : 0.0f;  // clamp: absent
        }
        for (int k = 0; k < sectors; ++k) {
          if (!(mask >> k & 1u)) continue;
          float* sector_slope = &slope[std::size_t(k) * span];
          for (int n = 0; n < span; ++n) sector_slope[n] = std::max(sector_slope[n], neighbour_row[n]);
        }
      }
    }
    for (int n = 0; n < span; ++n) {
      const std::size_t t = std::size_t(i) * width + j0 + n;
      for (int k = 0; k < sectors; ++k) {
        const float sector_slope = slope[std::size_t(k) * span + n];
        out[t * sectors + k] = sector_slope > 1.0f ? margin / sector_slope : 1.0f;
      }
      state.slack[t] = 0.0f;
    }
  }
}

void stage0_group(BudgetedBaker::State& state, int group, float* out) {
  const GroupRect g = group_rect(state.grid, group);
  stage0_rect(state, g.i0, g.i1, g.j0, g.j1, out);
  state.group_stage[group] = 0;
  state.group_slack[group] = 0.0f;
}

// Stage A for one group: tightens the stage-0 ratios (out holds them) with the group's candidates
// and records how loose each texel may still be.
long long fallback_group(BudgetedBaker::State& state, int group, float* out,
                         std::vector<Candidate>& candidates) {
  const Grid& grid = state.grid;
  const int sectors = grid.sector_count;
  const SearchContext context{grid, state.pyramid};
  const GroupRect g = group_rect(grid, group);
  float group_min = 1.0f;
  for (int i = g.i0; i <= g.i1; ++i)
    for (int j = g.j0; j <= g.j1; ++j)
      group_min = std::min(group_min, state.heights[std::size_t(i) * grid.width + j]);
  long long work = collect_candidates(context, g, group_min, state.roots, candidates);
  float group_slack = 1.0f;
  float exact_best[8], coarse[8];
  for (int i = g.i0; i <= g.i1; ++i)
    for (int j = g.j0; j <= g.j1; ++j) {
      const std::size_t t = std::size_t(i) * grid.width + j;
      std::fill_n(exact_best, sectors, 1.0f);
      std::fill_n(coarse, sectors, 1.0f);
      work += scan_candidates(grid, candidates, i, j, state.heights[t], exact_best, coarse);
      float slack = 1.0f;
      for (int k = 0; k < sectors; ++k) {
        // both this and the stage-0 value below are lower bounds: keep the larger
        float& ratio = out[t * sectors + k];
        ratio = std::max(ratio, std::min(exact_best[k], coarse[k]));
        slack = std::min(slack, ratio / exact_best[k]);
      }
      std::copy_n(exact_best, sectors, &state.upper[t * sectors]);
      state.slack[t] = slack;
      group_slack = std::min(group_slack, slack);
    }
  state.group_slack[group] = group_slack;
  state.group_stage[group] = 1;
  return work;
}

// Stage B for one group: refines its pending texels with a branch and bound over the whole pyramid
// that leaves a block unopened once its bound is within the tolerance of the best blocker found.
long long refine_group(BudgetedBaker::State& state, int group, float keep, float* out, long long& refined) {
  const Grid& grid = state.grid;
  const int sectors = grid.sector_count;
  const SearchContext context{grid, state.pyramid};
  const GroupRect g = group_rect(grid, group);
  long long work = 0;
  float exact_best[8], floor[8];
  for (int i = g.i0; i <= g.i1; ++i)
    for (int j = g.j0; j <= g.j1; ++j) {
      const std::size_t t = std::size_t(i) * grid.width + j;
      if (!(state.slack[t] < keep)) continue;
      const float hc = state.heights[t];
      std::copy_n(&state.upper[t * sectors], sectors, exact_best);
      std::fill_n(floor, sectors, 1.0f);
      work += detail::search_texel_within(context, i, j, hc, state.roots, keep, exact_best, floor);
      std::copy_n(exact_best, sectors, &state.upper[t * sectors]);
      float slack = 1.0f;
      for (int k = 0; k < sectors; ++k) {
        // both this and what out held (stage L's floor) are lower bounds: keep the larger
        float& ratio = out[t * sectors + k];
        ratio = std::max(ratio, std::min(exact_best[k], floor[k]));
        slack = std::min(slack, ratio / exact_best[k]);
      }
      // within the tolerance by construction; the division above can round just below keep
      state.slack[t] = std::max(slack, keep);
      ++refined;
    }
  float group_slack = 1.0f;
  for (int i = g.i0; i <= g.i1; ++i)
    for (int j = g.j0; j <= g.j1; ++j)
      group_slack = std::min(group_slack, state.slack[std::size_t(i) * grid.width + j]);
  state.group_slack[group] = group_slack;
  return work;
}

}  // namespace

BudgetedBaker::BudgetedBaker(int width, int height, int sector_count, Address address) {
  if (width <= 0 || height <= 0) throw BakeError("budgeted baker needs a non-empty map");
  if (!is_valid_sector_count(sector_count))
    throw BakeError("sector count " + std::to_string(sector_count) + " is not supported (use 1, 4 or 8)");
  state_ = std::make_unique<State>(width, height, sector_count, address);
}
BudgetedBaker::~BudgetedBaker() = default;
BudgetedBaker::BudgetedBaker(BudgetedBaker&&) noexcept = default;
BudgetedBaker& BudgetedBaker::operator=(BudgetedBaker&&) noexcept = default;

namespace {
void ensure_slack(BudgetedBaker::State& state);
}  // namespace

long long BudgetedBaker::pending(float tolerance) const {
  if (state_->heights.empty()) return 0;
  ensure_slack(*state_);
  long long count = 0;
  for (float slack : state_->slack) count += slack < 1.0f - tolerance;
  return count;
}

namespace {

void check_view(const BudgetedBaker::State& state, HeightView heights, const ConeView& out) {
  validate(heights, out);
  if (heights.width != state.grid.width || heights.height != state.grid.height ||
      out.sector_count != state.grid.sector_count) {
    throw BakeError("budgeted baker was made for a different map size or sector count");
  }
}

// The pyramid, its roots and stage 0's tables for state.heights, and per-texel upper bounds (1 where
// none is known): what stages 0, A and B and the incremental update need. A bake() that stage L
// finishes never builds them.
void ensure_search_state(BudgetedBaker::State& state) {
  if (!state.search_ready) {
    state.pyramid = detail::make_pyramid({state.heights.data(), state.grid.width, state.grid.height});
    const SearchContext context{state.grid, state.pyramid};
    state.roots = detail::root_nodes(context);
    prepare_stage0(state);
    state.search_ready = true;
  }
  if (state.upper.size() != state.heights.size() * state.grid.sector_count)
    state.upper.assign(state.heights.size() * state.grid.sector_count, 1.0f);
}

void set_heights(BudgetedBaker::State& state, HeightView heights) {
  state.heights.assign(heights.data, heights.data + std::size_t(heights.width) * heights.height);
  state.search_ready = false;
  ensure_search_state(state);
}

float keep_of(const Budget& budget) {
  if (!(budget.tolerance >= 0.0f && budget.tolerance < max_tolerance)) {
    char text[64];
    std::snprintf(text, sizeof text, "Budget::tolerance must be in [0, %g)", double(max_tolerance));
    throw BakeError(text);
  }
  return 1.0f - budget.tolerance;
}

// Advances groups in cursor order while the budget lasts: first stage A for every group that only
// has the stage-0 floor, then stage B for groups with texels looser than the tolerance.
void run_refinement(BudgetedBaker::State& state, detail::BudgetClock& clock, float keep, float* out,
                    long long& refined) {
  const int groups = group_count(state.grid);
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<int> order;
    for (int n = 0; n < groups; ++n) {
      const int group = (state.cursor + n) % groups;
      const bool wanted = pass == 0 ? state.group_stage[group] == 0
                                    : state.group_stage[group] == 1 && state.group_slack[group] < keep;
      if (wanted) order.push_back(group);
    }
    if (order.empty()) continue;
    std::atomic<long long> refined_total{0};
    std::atomic<int> last_started{-1};
    tbb::parallel_for(tbb::blocked_range<int>(0, int(order.size()), 1),
                      [&](const tbb::blocked_range<int>& range) {
                        std::vector<Candidate> candidates;
                        long long local_refined = 0;
                        for (int n = range.begin(); n < range.end(); ++n) {
                          if (clock.exhausted()) break;
                          int seen = last_started.load();
                          while (seen < n && !last_started.compare_exchange_weak(seen, n)) {
                          }
                          clock.work += pass == 0 ? fallback_group(state, order[n], out, candidates)
                                                  : refine_group(state, order[n], keep, out, local_refined);
                        }
                        refined_total += local_refined;
                      });
    refined += refined_total;
    // continue after the furthest group started; groups skipped before it stay pending
    if (last_started >= 0) state.cursor = (order[last_started] + 1) % groups;
    if (clock.exhausted()) return;
  }
}

// Stage L, the floor that bake() always completes: the lane sweeps of lane_sweep.cpp over the whole
// map, one per quadrant (8 sectors where one side of the map is a multiple of the other: one per
// octant). A texel's ratio in a sector is the largest lane that passes (one sector takes the
// smallest quadrant's; 8 sectors on other maps their quadrant's); below the lowest lane, the exact
// ratio over a window around it (5 x 5 on a square map) against a bound for everything further
// (lane_floor). The first lane that fails - or below the
// lowest lane a blocking neighbour - bounds the exact ratio from above, which gives the texel's
// slack (ensure_slack); 8 sectors from quadrants have none, so the refinement stages take them.
// ratio_sum: of every emitted ratio; pending: texel sectors whose slack may be below keep, 0
// exactly when no texel's is
using StageTotals = detail::LaneSweepTotals;

// Stage L sweeps octants (8 planes of lane masks) for 8 sectors where the lane plan has them, else
// quadrants.
int swept_planes(const BudgetedBaker::State& state) {
  return state.grid.sector_count == 8 && state.lanes.octant_split > 0 ? 8 : 4;
}

// Slack of texel t from its planes' lane counts: the emitted ratio's share of the certified upper
// bound of the exact one. 8 sectors from quadrant planes: a quadrant bounds neither of its octants.
float texel_slack(const BudgetedBaker::State& state, int planes, std::size_t t, const int* c) {
  const detail::LanePlan& plan = state.lanes;
  const int sectors = state.grid.sector_count;
  if (sectors == 8 && planes == 4) return 0.0f;
  float slack = 1.0f, smallest = 1.0f, lowest_upper = 1.0f;
  for (int k = 0; k < planes; ++k) {
    float ratio = plan.lane_ratio[c[k]], upper = plan.lane_upper[c[k]];
    if (c[k] == 0) {  // below the lowest lane: the neighbours' floor, and their real blockers bound it
      const detail::LaneFloor floor = detail::lane_floor(plan, state.heights.data(), t, k, planes);
      ratio = floor.floor;
      upper = std::min(upper, floor.upper);
    }
    slack = std::min(slack, ratio / upper);
    smallest = std::min(smallest, ratio);
    lowest_upper = std::min(lowest_upper, upper);
  }
  // one sector: the smallest quadrant's ratio, below the smallest bound
  return std::min(1.0f, sectors == 1 ? smallest / lowest_upper : slack);
}

StageTotals run_stage_l(BudgetedBaker::State& state, float keep, detail::BudgetClock& clock, float* out) {
  const Grid& grid = state.grid;
  const int width = grid.width, height = grid.height, sectors = grid.sector_count;
  const std::size_t count = state.heights.size();
  detail::LanePlan& plan = state.lanes;
  detail::make_lane_plan(state.heights.data(), width, height, grid.address == Address::wrap,
                         lane_lowest_ratio, lane_knights, sectors == 8, plan);
  const int planes = swept_planes(state);
  state.lane_masks.resize(planes * count);
  std::uint32_t* masks[8];
  for (int k = 0; k < planes; ++k) masks[k] = &state.lane_masks[k * count];
  // lane counts that may leave a sector looser than keep (below the lowest lane the floor decides,
  // against its certified bound, as texel_slack does)
  std::uint8_t pending_count[detail::lane_count + 1];
  for (int p = 0; p <= detail::lane_count; ++p)
    pending_count[p] = !(p > 0 && plan.lane_ratio[p] / plan.lane_upper[p] >= keep);
  detail::LaneSweepOptions options;
  options.floor_keep = keep;
  const detail::LaneSweepTotals swept = detail::sweep_sectors(
      plan, state.heights.data(), planes, masks, sectors == 4 ? out : nullptr, pending_count, options);
  clock.work += swept.work;
  state.slack_stale = true;
  state.cursor = 0;
  if (sectors == 4) return swept;

  // 1 sector (the smallest quadrant) or 8 (octants, or where there are none their quadrants)
  const StageTotals totals = tbb::parallel_reduce(
      tbb::blocked_range<int>(0, height, 8), StageTotals{},
      [&](const tbb::blocked_range<int>& rows, StageTotals partial) {
        for (int i = rows.begin(); i < rows.end(); ++i)
          for (int j = 0; j < width; ++j) {
            const std::size_t t = std::size_t(i) * width + j;
            float ratio[8] = {};
            for (int k = 0; k < planes; ++k) {
              const int c = detail::lanes_passed(masks[k][t]);
              bool loose = pending_count[c];
              if (c == 0) {  // the floor, certified as texel_slack certifies it
                const detail::LaneFloor floor = detail::lane_floor(plan, state.heights.data(), t, k, planes);
                loose = floor.floor / std::min(plan.lane_upper[0], floor.upper) < keep;
                ratio[k] = floor.floor;
              } else {
                ratio[k] = plan.lane_ratio[c];
              }
              partial.pending += loose || (sectors == 8 && planes == 4);
            }
            float* target = out + t * sectors;
            if (sectors == 8) {
              for (int k = 0; k < 8; ++k) target[k] = ratio[planes == 8 ? k : k / 2];
              for (int k = 0; k < 8; ++k) partial.ratio_sum += target[k];
            } else {
              target[0] = std::min(std::min(ratio[0], ratio[1]), std::min(ratio[2], ratio[3]));
              partial.ratio_sum += target[0];
            }
          }
        return partial;
      },
      StageTotals::add);
  return totals;
}

// Per texel and group, the slack that stage L's lane masks certify (what refinement and pending()
// read), computed only when something needs it.
void ensure_slack(BudgetedBaker::State& state) {
  if (!state.slack_stale) return;
  const Grid& grid = state.grid;
  const int width = grid.width;
  const std::size_t count = state.heights.size();
  const int planes = swept_planes(state);
  state.slack.resize(count);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, count, 1 << 14),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t t = r.begin(); t < r.end(); ++t) {
                        int c[8];
                        for (int k = 0; k < planes; ++k)
                          c[k] = detail::lanes_passed(state.lane_masks[k * count + t]);
                        state.slack[t] = texel_slack(state, planes, t, c);
                      }
                    });
  const int groups = group_count(grid);
  state.group_slack.resize(groups);
  state.group_stage.resize(groups);
  tbb::parallel_for(tbb::blocked_range<int>(0, groups, 16), [&](const tbb::blocked_range<int>& range) {
    for (int group = range.begin(); group < range.end(); ++group) {
      const GroupRect g = group_rect(grid, group);
      float group_slack = 1.0f;
      for (int i = g.i0; i <= g.i1; ++i)
        for (int j = g.j0; j <= g.j1; ++j)
          group_slack = std::min(group_slack, state.slack[std::size_t(i) * width + j]);
      state.group_slack[group] = group_slack;
      state.group_stage[group] = 1;  // stage A only certifies, and stage L did
    }
  });
  state.slack_stale = false;
}

BakeStats finish(const BudgetedBaker::State& state, const detail::BudgetClock& clock, float keep,
                 long long refined, float* out, const StageTotals* known = nullptr) {
  BakeStats stats;
  stats.mode = Mode::budgeted;
  stats.width = state.grid.width;
  stats.height = state.grid.height;
  stats.sector_count = state.grid.sector_count;
  const int sectors = state.grid.sector_count;
  // pending texels and the sum of the ratios: as stage L counted them when nothing changed since,
  // else a full pass over the map, in parallel
  const StageTotals totals =
      known ? *known
            : tbb::parallel_reduce(
                  tbb::blocked_range<std::size_t>(0, state.heights.size(), 16384), StageTotals{},
                  [&](const tbb::blocked_range<std::size_t>& texels, StageTotals partial) {
                    for (std::size_t t = texels.begin(); t < texels.end(); ++t) {
                      partial.pending += state.slack[t] < keep;
                      float row_sum = 0.0f;
                      for (int k = 0; k < sectors; ++k) row_sum += out[t * sectors + k];
                      partial.ratio_sum += row_sum;
                    }
                    return partial;
                  },
                  StageTotals::add);
  stats.texels_fallback = totals.pending;
  stats.texels_refined = refined;
  stats.work = clock.work;
  stats.mean_ratio = totals.ratio_sum / double(state.heights.size() * sectors);
  stats.milliseconds = clock.elapsed();
  return stats;
}

}  // namespace

BakeStats BudgetedBaker::bake(HeightView heights, const Budget& budget, ConeView out) {
  State& state = *state_;
  check_view(state, heights, out);
  const float keep = keep_of(budget);
  detail::BudgetClock clock(budget);
  state.heights.assign(heights.data, heights.data + std::size_t(heights.width) * heights.height);
  state.search_ready = false;
  state.upper.clear();  // bounds from real blockers of the previous heights
  const StageTotals totals = run_stage_l(state, keep, clock, out.data);
  if (totals.pending == 0) return finish(state, clock, keep, 0, out.data, &totals);
  ensure_slack(state);
  long long refined = 0;
  if (!clock.exhausted()) {
    ensure_search_state(state);
    run_refinement(state, clock, keep, out.data, refined);
  }
  return finish(state, clock, keep, refined, out.data);
}

BakeStats BudgetedBaker::refine(const Budget& budget, ConeView out) {
  State& state = *state_;
  if (state.heights.empty()) throw BakeError("refine() needs a previous bake() or update()");
  if (out.data == nullptr || out.width != state.grid.width || out.height != state.grid.height ||
      out.sector_count != state.grid.sector_count)
    throw BakeError("cone map output does not match the baker");
  const float keep = keep_of(budget);
  detail::BudgetClock clock(budget);
  ensure_slack(state);
  ensure_search_state(state);
  long long refined = 0;
  run_refinement(state, clock, keep, out.data, refined);
  return finish(state, clock, keep, refined, out.data);
}

namespace {

// A dirty rectangle's largest new height, and the largest height that fell in it (its old value).
struct DirtyInfo {
  Rect rect;
  float new_max = 0.0f;
  float fallen_max = -1.0f;  // < 0: nothing fell
};

// What an update reaches, per group: its own heights changed, a raised texel can lower its ratios
// (repair now), or a lowered texel may have been its blocker (refine later).
enum Reach : std::uint8_t { touched = 1, raised = 2, fell = 4 };

// The dirty rectangles clipped to the map, with `inside` marking their texels; throws when a height
// changed outside them.
std::vector<Rect> clip_dirty(const BudgetedBaker::State& state, HeightView heights,
                             std::span<const Rect> dirty, std::vector<std::uint8_t>& inside) {
  const int width = state.grid.width, height = state.grid.height;
  std::vector<Rect> rects;
  inside.assign(state.heights.size(), 0);
  for (Rect r : dirty) {
    r.x0 = std::clamp(r.x0, 0, width), r.x1 = std::clamp(r.x1, 0, width);
    r.y0 = std::clamp(r.y0, 0, height), r.y1 = std::clamp(r.y1, 0, height);
    if (r.x0 >= r.x1 || r.y0 >= r.y1) continue;
    rects.push_back(r);
    for (int i = r.y0; i < r.y1; ++i) std::memset(&inside[std::size_t(i) * width + r.x0], 1, r.x1 - r.x0);
  }
  for (std::size_t t = 0; t < state.heights.size(); ++t)
    if (!inside[t] && heights.data[t] != state.heights[t])
      throw BakeError("height changed outside the dirty region at texel (" + std::to_string(t / width) +
                      ", " + std::to_string(t % width) + ")");
  return rects;
}

// per rectangle: the largest new height, and the largest height that fell (old value)
std::vector<DirtyInfo> dirty_infos(const BudgetedBaker::State& state, HeightView heights,
                                   const std::vector<Rect>& rects) {
  const int width = state.grid.width;
  std::vector<DirtyInfo> infos;
  for (const Rect& r : rects) {
    DirtyInfo info{r};
    for (int i = r.y0; i < r.y1; ++i)
      for (int j = r.x0; j < r.x1; ++j) {
        const std::size_t t = std::size_t(i) * width + j;
        info.new_max = std::max(info.new_max, heights.data[t]);
        if (heights.data[t] < state.heights[t]) info.fallen_max = std::max(info.fallen_max, state.heights[t]);
      }
    infos.push_back(info);
  }
  return infos;
}

// group-level bound of a dirty rectangle with height `top` against texels of height >= group_min
float rect_bound(const Grid& grid, const GroupRect& g, const Rect& r, float top, float group_min) {
  const int width = grid.width, height = grid.height;
  const int tiles = grid.address == Address::wrap ? 1 : 0;
  float bound = 1.0f;
  if (!(top > group_min)) return bound;
  for (int ty = -tiles; ty <= tiles; ++ty)
    for (int tx = -tiles; tx <= tiles; ++tx) {
      const int x0 = r.x0 + tx * width, x1 = r.x1 - 1 + tx * width;
      const int y0 = r.y0 + ty * height, y1 = r.y1 - 1 + ty * height;
      const int gap_x = detail::interval_gap(x0 - g.j1, x1 - g.j0);
      const int gap_y = detail::interval_gap(y0 - g.i1, y1 - g.i0);
      bound = std::min(bound, detail::pair_ratio(grid.distance(gap_x, gap_y), top - group_min));
    }
  return bound;
}

// What the change reaches, per group (Reach flags), from the new heights and the stored ratios.
std::vector<std::uint8_t> update_reach(const BudgetedBaker::State& state, HeightView heights,
                                       const float* ratios, const std::vector<std::uint8_t>& inside,
                                       const std::vector<DirtyInfo>& infos) {
  const Grid& grid = state.grid;
  const int sectors = grid.sector_count, width = grid.width;
  const int groups = group_count(grid);
  std::vector<std::uint8_t> reach(groups, 0);
  tbb::parallel_for(tbb::blocked_range<int>(0, groups, 16), [&](const tbb::blocked_range<int>& range) {
    for (int group = range.begin(); group < range.end(); ++group) {
      const GroupRect g = group_rect(grid, group);
      bool touches = false;
      float group_min = 1.0f, group_max_ratio = 0.0f;
      for (int i = g.i0; i <= g.i1; ++i)
        for (int j = g.j0; j <= g.j1; ++j) {
          const std::size_t t = std::size_t(i) * width + j;
          touches |= inside[t] != 0;
          group_min = std::min(group_min, heights.data[t]);
          for (int k = 0; k < sectors; ++k)
            group_max_ratio = std::max(group_max_ratio, ratios[t * sectors + k]);
        }
      std::uint8_t flags = touches ? touched : 0;
      if (!touches)
        for (const DirtyInfo& info : infos) {
          if (rect_bound(grid, g, info.rect, info.new_max, group_min) < group_max_ratio) flags |= raised;
          if (info.fallen_max >= 0.0f &&
              rect_bound(grid, g, info.rect, info.fallen_max, group_min) <= group_max_ratio)
            flags |= fell;
        }
      reach[group] = flags;
    }
  });
  return reach;
}

// Rough cost of the incremental update in pyramid-node visits: stage L about 2 per texel; the repair
// of a raised group one search over the dirty blocks per texel; a texel left to refine (touched or
// fell) about 500, what stage B spends per texel on the ocean.
long long incremental_cost(const Grid& grid, const std::vector<DirtyInfo>& infos,
                           const std::vector<std::uint8_t>& reach) {
  const int tiles = grid.address == Address::wrap ? 1 : 0;
  long long dirty_nodes = 0;  // group-level blocks over the rectangles, with their wrap images
  for (const DirtyInfo& info : infos)
    dirty_nodes += (long long)(((info.rect.x1 - 1) >> group_level) - (info.rect.x0 >> group_level) + 1) *
                   (((info.rect.y1 - 1) >> group_level) - (info.rect.y0 >> group_level) + 1) *
                   (tiles ? 9 : 1);
  long long incremental = 0;
  for (std::uint8_t flags : reach) {
    if (flags & (touched | fell)) incremental += group_size * group_size * 500ll;
    if (flags & raised) incremental += group_size * group_size * 2 * dirty_nodes;
  }
  return incremental;
}

// Per group, as reached: touched groups get their floor now, raised ones an exact search over the
// dirty blocks from the stored ratios, those a fallen blocker may have served are left to refine.
void repair_groups(BudgetedBaker::State& state, HeightView heights, float* ratios,
                   const std::vector<std::uint8_t>& reach, const std::vector<DirtyInfo>& infos,
                   detail::BudgetClock& clock) {
  const Grid& grid = state.grid;
  const int sectors = grid.sector_count, width = grid.width;
  const SearchContext context{grid, state.pyramid};
  tbb::parallel_for(
      tbb::blocked_range<int>(0, group_count(grid), 4), [&](const tbb::blocked_range<int>& range) {
        std::vector<Node> dirty_nodes;
        long long work = 0;
        float best[8];
        for (int group = range.begin(); group < range.end(); ++group) {
          const GroupRect g = group_rect(grid, group);
          if (reach[group] &
              touched) {  // the group's own heights changed: its floor now, the rest within the budget
            stage0_group(state, group, ratios);
            continue;
          }
          work += (long long)infos.size();
          if (reach[group] &
              raised) {  // repair now: exact search over the dirty blocks, from the stored ratios
            for (const DirtyInfo& info : infos) {
              const std::vector<Node> nodes = detail::nodes_covering(context, info.rect, group_level);
              dirty_nodes.insert(dirty_nodes.end(), nodes.begin(), nodes.end());
            }
            for (int i = g.i0; i <= g.i1; ++i)
              for (int j = g.j0; j <= g.j1; ++j) {
                const std::size_t t = std::size_t(i) * width + j;
                std::copy_n(ratios + t * sectors, sectors, best);
                work += detail::search_texel(context, i, j, heights.data[t], dirty_nodes, best);
                std::copy_n(best, sectors, ratios + t * sectors);
              }
            dirty_nodes.clear();
          }
          if (reach[group] & fell) {  // stale ratios stay conservative; tighten them later
            for (int i = g.i0; i <= g.i1; ++i)
              for (int j = g.j0; j <= g.j1; ++j) state.slack[std::size_t(i) * width + j] = 0.0f;
            state.group_slack[group] = 0.0f;
          }
        }
        clock.work += work;
      });
}

}  // namespace

BakeStats BudgetedBaker::update(HeightView heights, std::span<const Rect> dirty, const Budget& budget,
                                ConeView out, UpdatePolicy policy) {
  State& state = *state_;
  if (state.heights.empty()) return bake(heights, budget, out);
  check_view(state, heights, out);
  ensure_slack(state);  // from the previous frame's stage L, before its heights go
  const float keep = keep_of(budget);
  detail::BudgetClock clock(budget);

  // what changed, and what the change reaches
  std::vector<std::uint8_t> inside;
  const std::vector<Rect> rects = clip_dirty(state, heights, dirty, inside);
  const std::vector<DirtyInfo> infos = dirty_infos(state, heights, rects);
  const std::vector<std::uint8_t> reach = update_reach(state, heights, out.data, inside, infos);
  if (policy != UpdatePolicy::incremental) {
    if (policy == UpdatePolicy::rebake ||
        incremental_cost(state.grid, infos, reach) > 2 * (long long)state.heights.size()) {
      clock.work += group_count(state.grid);
      return bake(heights, budget, out);
    }
  }

  // repair what the change reached, then refine within the budget
  set_heights(state, heights);
  // a blocker that fell may have been some texel's best upper bound: forget them all
  if (std::any_of(infos.begin(), infos.end(), [](const DirtyInfo& info) { return info.fallen_max >= 0.0f; }))
    std::fill(state.upper.begin(), state.upper.end(), 1.0f);
  repair_groups(state, heights, out.data, reach, infos, clock);
  long long refined = 0;
  run_refinement(state, clock, keep, out.data, refined);
  return finish(state, clock, keep, refined, out.data);
}

BakeStats bake_budgeted(HeightView heights, Address address, const Budget& budget, ConeView out) {
  validate(heights, out);
  BudgetedBaker baker(heights.width, heights.height, out.sector_count, address);
  return baker.bake(heights, budget, out);
}

}  // namespace displace::bake
