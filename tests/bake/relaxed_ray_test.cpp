// tests/bake/relaxed_ray_test.cpp - the first-cell rule of bake/relaxed_ray.h against the walk it
// stands in for: where leaves_no_exit_in_first_cell holds, exit_parameter (the walk both relaxed
// bakers follow) finds no exit in that cell, even at the rule's edge and for offsets of thousands of
// texels; without the rule's margin over the walk's rounding, it does (so the check can fail).
#include "bake/relaxed_ray.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

namespace displace::bake::detail {
namespace {

constexpr int max_offset = 4096;

struct Trials {
  long long tested = 0;  // rays that met the rule (or, without the margin, the exact condition)
  long long exits = 0;   // of which the walk left the relief in the first cell
};

// Random blockers d at offsets up to max_offset texels (diagonals, axes and between, every sign) and
// first cells whose rise is just below the largest the rule allows, on a 4 x 4 wrap map (the walk
// reads d's cell only; the offset is the ray's direction). with_margin false: the rise is set just
// below the ray's descent itself, where the ray stays inside the exact cell.
Trials walk_first_cells(bool with_margin, int count) {
  constexpr int size = 4;
  std::vector<double> first_ends(max_offset + 2);
  for (std::size_t n = 1; n < first_ends.size(); ++n) first_ends[n] = double(n + 1) / double(n);
  std::mt19937_64 random(1);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  Trials trials;
  for (int t = 0; t < count; ++t) {
    const int n = std::max(1, int(std::exp(uniform(random) * std::log(double(max_offset)))));
    const double pick = uniform(random);
    const int m = pick < 0.3 ? n : pick < 0.45 ? 0 : int(uniform(random) * n);
    const bool y_larger = uniform(random) < 0.5;
    const int dx = (y_larger ? m : n) * (uniform(random) < 0.5 ? -1 : 1);
    const int dy = (y_larger ? n : m) * (uniform(random) < 0.5 ? -1 : 1);
    const float h0 = float(0.05 + 0.9 * uniform(random));
    const double drop = 1.0 - double(h0), descent = drop / n;
    // the largest rise the rule allows (bisection on the rule itself), or the descent
    double target = descent;
    if (with_margin) {
      double low = 0.0, high = descent;
      if (!leaves_no_exit_in_first_cell(drop, n, low)) continue;
      for (int step = 0; step < 64; ++step) {
        const double middle = 0.5 * (low + high);
        (leaves_no_exit_in_first_cell(drop, n, middle) ? low : high) = middle;
      }
      target = low;
    }
    target -= 1e-12 * uniform(random);
    if (!(target > 0.0)) continue;
    // the cell's drops from h0 along x, along y and to the far corner, scaled so that the largest
    // of a, b, a + b and c is the target rise
    double a = 1.5 * uniform(random) - 0.5, b = 1.5 * uniform(random) - 0.5, c = 1.5 * uniform(random) - 0.5;
    const double largest = std::max(std::max(a, b), std::max(a + b, c));
    if (!(largest > 0.0)) continue;
    a *= target / largest;
    b *= target / largest;
    c *= target / largest;
    const float hx = float(h0 - a), hy = float(h0 - b), hxy = float(h0 - c);
    if (!(hx >= 0.0f && hx <= 1.0f && hy >= 0.0f && hy <= 1.0f && hxy >= 0.0f && hxy <= 1.0f)) continue;
    const double rise = first_cell_rise(h0, hx, hy, hxy);
    if (with_margin ? !leaves_no_exit_in_first_cell(drop, n, rise) : !(descent > rise)) continue;
    // the cell the walk enters first: the + side along a 0 component
    const int sx = dx < 0 ? -1 : 1, sy = dy < 0 ? -1 : 1;
    std::vector<float> heights(size * size, 0.0f);
    const auto at = [&](int i, int j) -> float& {
      return heights[std::size_t(((i % size) + size) % size) * size +
                     std::size_t(((j % size) + size) % size)];
    };
    at(dy, dx) = h0;
    at(dy, dx + sx) = hx;
    at(dy + sy, dx) = hy;
    at(dy + sy, dx + sx) = hxy;
    const RelaxedSurface surface{heights.data(),         size,   size, Address::wrap, first_ends.data(),
                                 int(first_ends.size()), nullptr};
    const double cell_end = first_ends[std::size_t(n)];
    long long work = 0;
    const double exit = exit_parameter(
        surface, 0.0, 0.0, dx, dy, drop, cell_end, [](double) { return false; }, work);
    ++trials.tested;
    trials.exits += exit < cell_end;
  }
  return trials;
}

TEST(RelaxedRay, WhereTheFirstCellRuleHoldsTheWalkFindsNoExitThere) {
  const Trials trials = walk_first_cells(true, 200000);
  EXPECT_GT(trials.tested, 20000);
  EXPECT_EQ(trials.exits, 0) << "of " << trials.tested << " rays at the rule's edge";
}

// The margin is what makes the rule hold: a ray that descends just faster than the exact cell rises
// stays inside it, yet the walk's float quadratic, with terms of about n^2, finds it leaving.
TEST(RelaxedRay, WithoutTheMarginTheWalksRoundingFindsExits) {
  const Trials trials = walk_first_cells(false, 200000);
  EXPECT_GT(trials.tested, 20000);
  EXPECT_GT(trials.exits, trials.tested / 100) << "of " << trials.tested << " rays";
  std::printf("without the margin: %lld exits of %lld rays\n", trials.exits, trials.tested);
}

}  // namespace
}  // namespace displace::bake::detail
