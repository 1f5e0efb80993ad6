// bake/cone_relaxed_budgeted.cpp - relaxed cone maps within a budget (RelaxedBaker): BudgetedBaker's
// stage L over the whole map first, then bake_relaxed's search (relaxed_search.h) while the budget
// lasts, 16 texels of a row at a time, continued by refine().
//
// The one fact: every ratio emitted is a lower bound of bake_relaxed's. Stage L's ratios are lower
// bounds of the exact conservative ratios (tested in cone_budgeted_test.cpp), and a relaxed ratio is
// never below the conservative one: both are minima over the same blockers d, of V(c, d) >= p(c, d)
// and of p(c, d) (relaxed_ray.h). A piece the search has done holds bake_relaxed's ratios, bit for
// bit, whichever pieces were done with it (the seeds change the work only).
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/partitioner.h>

#include <algorithm>
#include <atomic>
#include <string>
#include <vector>

#include "bake/budget_clock.h"
#include "bake/geometry.h"
#include "bake/relaxed_search.h"

namespace displace::bake {

constexpr int piece_texels = 16;  // texels of a row the search does between looks at the budget

struct RelaxedBaker::State {
  State(int w, int h, int sectors, Address addr)
      : width(w),
        height(h),
        sector_count(sectors),
        address(addr),
        pieces((w + piece_texels - 1) / piece_texels),
        conservative(w, h, sectors, addr) {}

  int width, height, sector_count;
  Address address;
  int pieces;                                     // per row; the last one may be shorter
  BudgetedBaker conservative;                     // stage L, the first stage
  std::vector<float> heights;                     // of the last bake()
  std::unique_ptr<detail::RelaxedSearch> search;  // over `heights`
  std::vector<unsigned char> done;                // piece p of row i at [i * pieces + p]: relaxed
};

RelaxedBaker::RelaxedBaker(int width, int height, int sector_count, Address address) {
  if (width <= 0 || height <= 0 || width > max_map_side || height > max_map_side)
    throw BakeError("relaxed baker needs a map of 1 to " + std::to_string(max_map_side) + " texels a side");
  if (sector_count != 1 && sector_count != 4)
    throw BakeError("relaxed cone maps support 1 or 4 sectors, not " + std::to_string(sector_count));
  state_ = std::make_unique<State>(width, height, sector_count, address);
}
RelaxedBaker::~RelaxedBaker() = default;
RelaxedBaker::RelaxedBaker(RelaxedBaker&&) noexcept = default;
RelaxedBaker& RelaxedBaker::operator=(RelaxedBaker&&) noexcept = default;

namespace {

void check_output(const RelaxedBaker::State& state, const ConeView& out) {
  if (out.data == nullptr || out.width != state.width || out.height != state.height ||
      out.sector_count != state.sector_count)
    throw BakeError("relaxed baker was made for a different map size or sector count");
}

long long pending_texels(const RelaxedBaker::State& state) {
  long long count = 0;
  for (std::size_t n = 0; n < state.done.size(); ++n) {
    const int first = int(n % state.pieces) * piece_texels;
    if (!state.done[n]) count += std::min(piece_texels, state.width - first);
  }
  return count;
}

// The pieces not yet done, in order, in parallel, each begun only while the budget lasts.
BakeStats refine_pieces(RelaxedBaker::State& state, const Budget& budget, ConeView out) {
  detail::BudgetClock clock(budget);
  std::vector<std::size_t> pending;
  for (std::size_t n = 0; n < state.done.size(); ++n)
    if (!state.done[n]) pending.push_back(n);
  std::atomic<long long> refined{0};
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, pending.size(), 1),
      [&](const tbb::blocked_range<std::size_t>& range) {
        for (std::size_t n = range.begin(); n < range.end(); ++n) {
          if (clock.exhausted()) return;
          const int row = int(pending[n] / state.pieces),
                    first = int(pending[n] % state.pieces) * piece_texels;
          const int last = std::min(first + piece_texels, state.width);
          clock.work += state.search->texels(row, first, last, out.data);
          state.done[pending[n]] = 1;
          refined += last - first;
        }
      },
      tbb::simple_partitioner());
  BakeStats stats;
  stats.mode = Mode::budgeted;
  stats.width = state.width;
  stats.height = state.height;
  stats.sector_count = state.sector_count;
  stats.texels_refined = refined;
  stats.texels_fallback = pending_texels(state);
  stats.work = clock.work;
  stats.milliseconds = clock.elapsed();
  stats.mean_ratio = detail::mean_of(out.data, std::size_t(state.width) * state.height * state.sector_count);
  return stats;
}

}  // namespace

long long RelaxedBaker::pending() const { return state_->search ? pending_texels(*state_) : 0; }

BakeStats RelaxedBaker::bake(HeightView heights, const Budget& budget, ConeView out) {
  State& state = *state_;
  validate(heights, out);
  check_output(state, out);
  detail::BudgetClock clock(budget);
  state.heights.assign(heights.data, heights.data + std::size_t(heights.width) * heights.height);
  const HeightView kept{state.heights.data(), state.width, state.height};
  // the first stage, always completed: stage L of the centre-to-centre cones
  Budget first = budget;
  first.milliseconds = 0.0;
  first.max_work = 0;
  state.conservative.bake(kept, first, out);
  state.search = std::make_unique<detail::RelaxedSearch>(kept, state.address, state.sector_count);
  state.done.assign(std::size_t(state.height) * state.pieces, 0);
  Budget rest = budget;  // what stage L left of the time (its work is not counted)
  rest.milliseconds = budget.milliseconds - clock.elapsed();
  BakeStats stats = refine_pieces(state, rest, out);
  stats.milliseconds = clock.elapsed();
  return stats;
}

BakeStats RelaxedBaker::refine(const Budget& budget, ConeView out) {
  State& state = *state_;
  if (!state.search) throw BakeError("refine() needs a previous bake()");
  check_output(state, out);
  return refine_pieces(state, budget, out);
}

}  // namespace displace::bake
