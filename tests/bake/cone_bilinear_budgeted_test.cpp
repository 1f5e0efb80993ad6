// tests/bake/cone_bilinear_budgeted_test.cpp - the budgeted bilinear baker (bake/cone_bilinear_budgeted.cpp).
#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <numbers>
#include <numeric>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "bake/bake.h"
#include "bake/lane_sweep.h"
#include "tests/bake/bake_checks.h"
#include "tests/test_maps.h"

namespace displace::bake {
namespace {

using test::Map;

// ---- the budgeted bilinear baker (BilinearBaker): bake_bilinear_cones' contract at every budget

struct BudgetedBilinear {
  ConeMap cones;
  std::vector<float> apex;
  BakeStats stats;
};

// The budgets every claim is tested at: 0 ms, a work limit of 0, small work limits, fake clocks that
// run out after a few readings (mid-refinement), and unlimited.
std::vector<Budget> bilinear_budgets() {
  std::vector<Budget> budgets;
  Budget zero;
  zero.milliseconds = 0.0;
  budgets.push_back(zero);
  for (long long work : {0ll, 1ll, 40ll, 400ll}) {
    Budget b;
    b.max_work = work;
    budgets.push_back(b);
  }
  for (double ms : {1.0, 2.0, 5.0}) {
    Budget b;
    b.clock = FakeClock{}.function();
    b.milliseconds = ms;
    budgets.push_back(b);
  }
  budgets.push_back(Budget{});
  Budget exact_search;  // tolerance 0: every texel not already at 1 is searched
  exact_search.tolerance = 0.0f;
  budgets.push_back(exact_search);
  return budgets;
}

BudgetedBilinear bake_bilinear_budgeted(const Map& map, int sectors, Address address, const Budget& budget) {
  BudgetedBilinear b{make_cone_map(map, sectors), std::vector<float>(map.values.size()), {}};
  BilinearBaker baker(map.width, map.height, sectors, address);
  b.stats = baker.bake(view_of(map), budget, b.cones.view(), b.apex);
  return b;
}

TEST(BilinearBaker, NeverPiercedAtAnyBudget) {
  long long pairs = 0;
  const std::vector<Budget> budgets = bilinear_budgets();
  for (const Map& map : bilinear_maps())
    for (int sectors : {1, 4, 8})
      for (Address address : {Address::wrap, Address::clamp}) {
        const BilinearCones full = bake_bilinear(map, sectors, address);
        for (std::size_t n = 0; n < budgets.size(); ++n) {
          const BudgetedBilinear b = bake_bilinear_budgeted(map, sectors, address, budgets[n]);
          // the apex is exactly bake_bilinear_cones'
          ASSERT_EQ(b.apex, full.apex) << map.name;
          for (float r : b.cones.ratios) ASSERT_TRUE(r > 0.0f && r <= 1.0f) << map.name << " " << r;
          // every texel of a 0 ms or 0-work bake keeps stage L's ratios; the check below holds anyway
          const int stride = n == 0 || n + 2 >= budgets.size() ? 1 : 3;
          const BilinearCheck check = check_bilinear(map, address, b.cones, b.apex, stride);
          pairs += check.pairs;
          ASSERT_EQ(check.violations, 0)
              << map.name << " " << map.width << "x" << map.height << " sectors " << sectors << " "
              << address_name(address) << " budget " << n << " worst " << check.worst;
          if (n + 2 == budgets.size()) {  // unlimited, tolerance 0.25: within it of the full bake
            // (searched texels are at least the full bake; certified ones at least 0.75 of a
            // certified upper bound of the best ratio, which the full bake does not exceed)
            for (std::size_t v = 0; v < b.cones.ratios.size(); ++v)
              ASSERT_GE(b.cones.ratios[v], 0.75f * full.cones.ratios[v] * (1.0f - 1e-6f))
                  << map.name << " value " << v;
          }
          if (n + 1 == budgets.size()) {  // tolerance 0, unlimited: never below the full bake
            EXPECT_EQ(b.stats.texels_fallback, 0);
            for (std::size_t v = 0; v < b.cones.ratios.size(); ++v)
              ASSERT_GE(b.cones.ratios[v], full.cones.ratios[v]) << map.name << " value " << v;
          }
        }
      }
  std::printf("budgeted bilinear cones: %lld (p, x) pairs checked\n", pairs);
  EXPECT_GT(pairs, 1000000);
}

// The check has teeth on this baker's maps too: stage L's ratios 10% too large are caught.
TEST(BilinearBaker, CheckCatchesStageLRatiosTenPercentTooLarge) {
  Budget zero;
  zero.milliseconds = 0.0;
  int caught = 0, tried = 0;
  for (const Map& map :
       {make_ramp(8, 6), make_noise(6, 6), test::make_fractal_cliff(10, 8), test::make_bricks(12, 8)})
    for (Address address : {Address::wrap, Address::clamp}) {
      BudgetedBilinear b = bake_bilinear_budgeted(map, 4, address, zero);
      for (float& r : b.cones.ratios) r = std::min(1.0f, r * 1.1f);
      ++tried;
      if (check_bilinear(map, address, b.cones, b.apex).violations > 0) ++caught;
    }
  std::printf("stage L ratios x1.1 caught on %d of %d maps\n", caught, tried);
  EXPECT_GE(caught, tried / 2);
}

// Stage L's floor from the surface's Lipschitz constant G (the largest rise of s per unit of uv
// length): s(x) - H_c <= s(x) - s(p) <= G |x - p|, so no ratio is below 1 / G. On a clamped map
// with a 4-texel ramp from 0.1 to 0.9 across its middle, the texels on the ramp have uphill ratios
// of exactly 1 / G, and a 0 ms bake reaches 1 / G everywhere - within the floor's rounding - but
// never passes the full bake; on a sinusoid field every ratio is at least 1 / G of its steepest cell.
TEST(BilinearBaker, StageLHoldsTheLipschitzFloor) {
  Budget zero;
  zero.milliseconds = 0.0;
  for (const auto& [w, h] : {std::pair{24, 9}, std::pair{9, 24}, std::pair{20, 20}}) {
    Map ramp = test::make_flat(w, h, 0.1f);
    const int start = w / 2 - 2;
    for (int i = 0; i < h; ++i)
      for (int j = 0; j < w; ++j) ramp.at(i, j) = 0.1f + 0.2f * float(std::clamp(j - start, 0, 4));
    const double rise = 0.2 * double(w);  // per unit of u
    const BudgetedBilinear b = bake_bilinear_budgeted(ramp, 4, Address::clamp, zero);
    const std::string where = std::to_string(w) + "x" + std::to_string(h);
    for (std::size_t v = 0; v < b.cones.ratios.size(); ++v)
      ASSERT_GE(b.cones.ratios[v], float(0.9999 / rise)) << where << " value " << v;
    EXPECT_EQ(check_bilinear(ramp, Address::clamp, b.cones, b.apex).violations, 0) << where;
    // the bound is tight here: 1% more is pierced (the full bake, itself a lower bound, stays below it)
    ConeMap raised = b.cones;
    for (float& r : raised.ratios) r = std::min(1.0f, std::max(r, float(1.01 / rise)));
    EXPECT_GT(check_bilinear(ramp, Address::clamp, raised, b.apex).violations, 0) << where;
  }
  Map waves{"waves", 32, 20, std::vector<float>(32 * 20)};
  for (int i = 0; i < waves.height; ++i)
    for (int j = 0; j < waves.width; ++j)
      waves.at(i, j) = float(0.5 + 0.3 * std::sin(0.7 * j + 0.2 * i) * std::cos(0.45 * i));
  double steepest = 0.0;  // the largest gradient bound of a cell, in uv (wrap)
  for (int i = 0; i < waves.height; ++i)
    for (int j = 0; j < waves.width; ++j) {
      const int i1 = (i + 1) % waves.height, j1 = (j + 1) % waves.width;
      const double du = std::max(std::abs(double(waves.at(i, j1)) - waves.at(i, j)),
                                 std::abs(double(waves.at(i1, j1)) - waves.at(i1, j))) *
                        waves.width;
      const double dv = std::max(std::abs(double(waves.at(i1, j)) - waves.at(i, j)),
                                 std::abs(double(waves.at(i1, j1)) - waves.at(i, j1))) *
                        waves.height;
      steepest = std::max(steepest, std::hypot(du, dv));
    }
  const BudgetedBilinear b = bake_bilinear_budgeted(waves, 4, Address::wrap, zero);
  for (float r : b.cones.ratios) ASSERT_GE(r, float(0.9999 / steepest));
  EXPECT_EQ(check_bilinear(waves, Address::wrap, b.cones, b.apex).violations, 0);
}

TEST(BilinearBaker, RandomMapsNeverPierced) {
  Budget zero;
  zero.milliseconds = 0.0;
  // a few spikes on a flat field: away from them only the far cells (the lane sweeps) decide
  for (int n = 0; n < 6; ++n) {
    const int w = 14 + n, h = 18 - n;
    Map map = test::make_flat(w, h, 0.1f);
    map.name = "sparse-spikes-" + std::to_string(n);
    for (int s = 0; s < 3; ++s)
      map.at(int(test::hash01(41, n, s) * h), int(test::hash01(43, n, s) * w)) =
          0.3f + 0.7f * test::hash01(47, n, s);
    for (int sectors : {4, 8})
      for (Address address : {Address::wrap, Address::clamp}) {
        const BudgetedBilinear b = bake_bilinear_budgeted(map, sectors, address, zero);
        const BilinearCheck check = check_bilinear(map, address, b.cones, b.apex, 2);
        ASSERT_EQ(check.violations, 0)
            << map.name << " sectors " << sectors << " " << address_name(address) << " worst " << check.worst;
      }
  }
  for (int n = 0; n < 24; ++n) {
    const int w = 1 + int(test::hash01(31, n, 1) * 9), h = 1 + int(test::hash01(31, n, 2) * 9);
    Map map = test::make_flat(w, h, 0.0f);
    map.name = "random-" + std::to_string(n);
    const int kind = n % 3;
    for (int i = 0; i < h; ++i)
      for (int j = 0; j < w; ++j) {
        const float r = test::hash01(37, n * 97 + i, j);
        map.at(i, j) = kind == 0 ? r : kind == 1 ? (r > 0.8f ? 1.0f : 0.0f) : std::round(r * 4.0f) / 4.0f;
      }
    for (int sectors : {1, 4, 8})
      for (Address address : {Address::wrap, Address::clamp}) {
        const BudgetedBilinear b = bake_bilinear_budgeted(map, sectors, address, zero);
        const BilinearCheck check = check_bilinear(map, address, b.cones, b.apex);
        ASSERT_EQ(check.violations, 0) << map.name << " " << w << "x" << h << " sectors " << sectors << " "
                                       << address_name(address) << " worst " << check.worst;
      }
  }
}

// Chains of update() with random raises and lowerings inside the dirty rectangles, at budget 0 and
// unlimited: conservative after every frame; heights changed outside the rectangles are an error.
TEST(BilinearBaker, UpdateChainsStayConservative) {
  for (Map map : {make_noise(9, 7), test::make_bricks(12, 8), test::make_spikes(9, 9)})
    for (int sectors : {1, 4, 8})
      for (Address address : {Address::wrap, Address::clamp})
        for (bool unlimited : {false, true}) {
          Budget budget;
          if (!unlimited) budget.milliseconds = 0.0;
          BilinearBaker baker(map.width, map.height, sectors, address);
          ConeMap cones = make_cone_map(map, sectors);
          std::vector<float> apex(map.values.size());
          baker.bake(view_of(map), budget, cones.view(), apex);
          for (int frame = 0; frame < 6; ++frame) {
            const std::uint64_t seed = 1000 + frame;
            Rect rect;
            rect.x0 = int(test::hash01(seed, 1, 0) * map.width);
            rect.y0 = int(test::hash01(seed, 2, 0) * map.height);
            rect.x1 = std::min(map.width, rect.x0 + 1 + int(test::hash01(seed, 3, 0) * 3));
            rect.y1 = std::min(map.height, rect.y0 + 1 + int(test::hash01(seed, 4, 0) * 3));
            for (int i = rect.y0; i < rect.y1; ++i)
              for (int j = rect.x0; j < rect.x1; ++j) {
                const float change = test::hash01(seed, i, j) - (frame % 2 ? 0.3f : 0.7f);
                map.at(i, j) = std::clamp(map.at(i, j) + change, 0.0f, 1.0f);
              }
            const Rect rects[] = {rect};
            baker.update(view_of(map), rects, budget, cones.view(), apex);
            const BilinearCheck check = check_bilinear(map, address, cones, apex);
            ASSERT_EQ(check.violations, 0)
                << map.name << " sectors " << sectors << " " << address_name(address) << " frame " << frame
                << " unlimited " << unlimited;
            const BilinearCones full = bake_bilinear(map, sectors, address);
            ASSERT_EQ(apex, full.apex) << map.name << " frame " << frame;
          }
          // a height changed outside the dirty rectangles is refused
          Map changed = map;
          changed.at(0, 0) = changed.at(0, 0) > 0.5f ? 0.1f : 0.9f;
          const Rect elsewhere[] = {{map.width - 1, map.height - 1, map.width, map.height}};
          if (map.width > 1 || map.height > 1) {
            EXPECT_THROW(baker.update(view_of(changed), elsewhere, budget, cones.view(), apex), BakeError);
          }
        }
}

// The certified upper bounds (lanes and near witnesses) are real: an unlimited bake keeps every
// ratio within the tolerance of the full bake, which the best ratio bounds, at every tolerance; and
// the witnesses do certify (a smooth map is not searched whole).
TEST(BilinearBaker, UpperBoundsHoldAtEveryTolerance) {
  std::vector<Map> maps = bilinear_maps();
  for (int n = 0; n < 12; ++n) {
    const int w = 2 + int(test::hash01(53, n, 1) * 12), h = 2 + int(test::hash01(53, n, 2) * 12);
    Map map = test::make_flat(w, h, 0.0f);
    map.name = "random-" + std::to_string(n);
    for (int i = 0; i < h; ++i)
      for (int j = 0; j < w; ++j) {
        const float r = test::hash01(59, n * 97 + i, j);
        map.at(i, j) = n % 2 ? r : (r > 0.85f ? 1.0f : 0.2f * r);
      }
    maps.push_back(map);
  }
  for (const Map& map : maps)
    for (int sectors : {1, 4})
      for (Address address : {Address::wrap, Address::clamp}) {
        const BilinearCones full = bake_bilinear(map, sectors, address);
        for (float tolerance : {0.02f, 0.1f, 0.5f, 0.9f}) {
          Budget budget;
          budget.tolerance = tolerance;
          const BudgetedBilinear b = bake_bilinear_budgeted(map, sectors, address, budget);
          for (std::size_t v = 0; v < b.cones.ratios.size(); ++v)
            ASSERT_GE(b.cones.ratios[v], (1.0f - tolerance) * full.cones.ratios[v] * (1.0f - 1e-6f))
                << map.name << " sectors " << sectors << " " << address_name(address) << " tolerance "
                << tolerance << " value " << v;
        }
      }
  const Map smooth = make_noise(32, 32);
  Budget budget;
  budget.tolerance = 0.5f;
  const BudgetedBilinear b = bake_bilinear_budgeted(smooth, 4, Address::wrap, budget);
  EXPECT_LT(b.stats.texels_refined, 32 * 32);
}

TEST(BilinearBaker, RefineContinuesAndPendingFalls) {
  const Map map = test::make_fractal_cliff(24, 20);
  for (Address address : {Address::wrap, Address::clamp}) {
    BilinearBaker baker(map.width, map.height, 4, address);
    ConeMap cones = make_cone_map(map, 4);
    std::vector<float> apex(map.values.size());
    Budget zero;
    zero.max_work = 0;
    zero.tolerance = 0.0f;
    baker.bake(view_of(map), zero, cones.view(), apex);
    const long long first = baker.pending();
    EXPECT_GT(first, 0);
    Budget some;
    some.max_work = 2000;
    some.tolerance = 0.0f;
    long long previous = first;
    for (int call = 0; call < 1000 && baker.pending() > 0; ++call) {
      const BakeStats stats = baker.refine(some, cones.view(), apex);
      EXPECT_LT(baker.pending(), previous);
      previous = baker.pending();
      ASSERT_EQ(check_bilinear(map, address, cones, apex, 5).violations, 0);
      // the stats' mean follows the ratios as refinement raises them
      EXPECT_NEAR(stats.mean_ratio, mean_ratio(cones), 1e-6);
    }
    EXPECT_EQ(baker.pending(), 0);
    const BilinearCones full = bake_bilinear(map, 4, address);
    for (std::size_t v = 0; v < cones.ratios.size(); ++v) ASSERT_GE(cones.ratios[v], full.cones.ratios[v]);
  }
}

// A budget that runs out has searched the texels whose ratios can rise most first: on an ocean, a
// cliff and bricks, the texels that a work limit of a tenth of the unlimited bake's raised gain, on
// average, over 1.5x what the unlimited bake's raised texels gain (1.8-2.3x; texel order gives
// 0.9-1.2x). NeverPiercedAtAnyBudget holds such maps to the contract.
TEST(BilinearBaker, ALimitedRefinementSearchesTheLargestGainsFirst) {
  const Map maps[] = {test::make_ocean(96, 96), test::make_fractal_cliff(96, 80), test::make_bricks(96, 96)};
  for (const Map& map : maps) {
    for (int sectors : {1, 4}) {
      std::vector<float> apex(map.values.size());
      auto baked = [&](long long max_work) {
        BilinearBaker baker(map.width, map.height, sectors, Address::wrap);
        ConeMap cones = make_cone_map(map, sectors);
        Budget budget;
        budget.max_work = max_work;
        const BakeStats stats = baker.bake(view_of(map), budget, cones.view(), apex);
        return std::pair{cones, stats};
      };
      const auto [stage_l, none] = baked(0);
      const auto [unlimited, all] = baked(-1);
      const auto [limited, some] = baked(all.work / 10);
      // per texel, what the unlimited bake raised its ratios by; over the texels it raised, and
      // over those the limited bake raised
      double raised_sum = 0.0, limited_sum = 0.0;
      long long raised = 0, limited_count = 0;
      for (std::size_t t = 0; t < map.values.size(); ++t) {
        double gain = 0.0;
        bool limited_raised = false;
        for (int k = 0; k < sectors; ++k) {
          const std::size_t v = t * std::size_t(sectors) + std::size_t(k);
          gain += double(unlimited.ratios[v]) - double(stage_l.ratios[v]);
          limited_raised |= limited.ratios[v] != stage_l.ratios[v];
        }
        if (gain <= 0.0) continue;
        raised_sum += gain;
        ++raised;
        if (limited_raised) {
          limited_sum += gain;
          ++limited_count;
        }
      }
      ASSERT_GT(raised, 0) << map.name;
      ASSERT_GT(limited_count, 0) << map.name;
      const double ratio = (limited_sum / double(limited_count)) / (raised_sum / double(raised));
      EXPECT_GT(ratio, 1.5) << map.name << " sectors " << sectors << ": " << limited_count << " of "
                            << raised;
      EXPECT_GT(some.mean_ratio, none.mean_ratio) << map.name;
    }
  }
}

// The first stage in steps (begin / advance: the pipeline's lagged maps). With the budget spent,
// each advance() runs one step; however the steps are spread, the map is bake()'s bit for bit; `out`
// and the apexes are left alone until the last step, the stage works on the heights begin() copied,
// an unlimited budget finishes in one call with bake()'s refinement, and bake() mid-stage ends it.
TEST(BilinearBaker, StagedFirstStageEqualsTheWholeBake) {
  std::vector<Map> maps = hard_maps();
  maps.push_back(test::make_fractal_cliff(96, 130));  // rows for every part of the near field
  maps.push_back(test::make_bricks(140, 40));
  Budget spent;
  spent.milliseconds = 0.0;
  for (const Map& map : maps)
    for (int sectors : {1, 4, 8})
      for (Address address : {Address::wrap, Address::clamp}) {
        std::ostringstream described;
        described << map.name << " " << map.width << "x" << map.height << " sectors " << sectors << " "
                  << address_name(address);
        const std::string what = described.str();
        const BudgetedBilinear expected = bake_bilinear_budgeted(map, sectors, address, spent);
        BilinearBaker baker(map.width, map.height, sectors, address);
        ConeMap cones = make_cone_map(map, sectors);
        std::vector<float> apex(map.values.size(), -1.0f);
        std::fill(cones.ratios.begin(), cones.ratios.end(), -1.0f);
        Map input = map;
        baker.begin(view_of(input));
        std::fill(input.values.begin(), input.values.end(), 0.5f);  // the stage has its own copy
        EXPECT_THROW(baker.refine(spent, cones.view(), apex), BakeError) << what;
        BakeStats stats;
        int calls = 1;
        for (; !baker.advance(spent, cones.view(), apex, stats); ++calls) {
          ASSERT_TRUE(baker.in_progress()) << what;
          ASSERT_LT(calls, BilinearBaker::first_stage_steps()) << what;
          for (float r : cones.ratios) ASSERT_EQ(r, -1.0f) << what;
          for (float a : apex) ASSERT_EQ(a, -1.0f) << what;
        }
        EXPECT_FALSE(baker.in_progress()) << what;
        EXPECT_GE(calls, 6) << what;  // the apexes in 2 parts, the cells, 2 sweeps, the near field
        if (map.height > 96) {
          EXPECT_EQ(calls, BilinearBaker::first_stage_steps()) << what;
        }
        EXPECT_EQ(cones.ratios, expected.cones.ratios) << what;
        EXPECT_EQ(apex, expected.apex) << what;
        EXPECT_EQ(stats.work, expected.stats.work) << what;
        EXPECT_EQ(stats.texels_fallback, expected.stats.texels_fallback) << what;
        EXPECT_EQ(baker.pending(), expected.stats.texels_fallback) << what;
        // bake() emits each row as stage L finishes it, advance() all rows at the end: the same sum
        EXPECT_EQ(stats.mean_ratio, expected.stats.mean_ratio) << what;
        EXPECT_THROW(baker.advance(spent, cones.view(), apex, stats), BakeError) << what;  // nothing begun
        if (sectors != 4) continue;
        // an unlimited budget: one call, refined as bake() refines
        Budget unlimited;
        unlimited.tolerance = 0.0f;
        const BudgetedBilinear refined = bake_bilinear_budgeted(map, sectors, address, unlimited);
        baker.begin(view_of(map));
        ASSERT_TRUE(baker.advance(unlimited, cones.view(), apex, stats)) << what;
        EXPECT_EQ(cones.ratios, refined.cones.ratios) << what;
        EXPECT_EQ(stats.texels_refined, refined.stats.texels_refined) << what;
        // bake() in the middle of a stage ends it
        baker.begin(view_of(input));
        EXPECT_FALSE(baker.advance(spent, cones.view(), apex, stats)) << what;
        baker.bake(view_of(map), spent, cones.view(), apex);
        EXPECT_FALSE(baker.in_progress()) << what;
        EXPECT_EQ(cones.ratios, expected.cones.ratios) << what;
      }
}

TEST(BilinearBaker, RejectsBadInput) {
  EXPECT_THROW(BilinearBaker(0, 4, 4, Address::wrap), BakeError);
  EXPECT_THROW(BilinearBaker(4, 4, 3, Address::wrap), BakeError);
  BilinearBaker baker(4, 4, 4, Address::wrap);
  const Map ok = test::make_flat(4, 4);
  std::vector<float> ratios(16 * 4), apex(16);
  EXPECT_THROW(baker.refine({}, {ratios.data(), 4, 4, 4}, apex), BakeError);  // nothing baked yet
  EXPECT_THROW(baker.bake(view_of(ok), {}, {ratios.data(), 4, 4, 4}, {apex.data(), 15}), BakeError);
  const Map other = test::make_flat(5, 4);
  std::vector<float> other_ratios(20 * 4), other_apex(20);
  EXPECT_THROW(baker.bake(view_of(other), {}, {other_ratios.data(), 5, 4, 4}, other_apex), BakeError);
  Map nan_map = test::make_flat(4, 4);
  nan_map.at(1, 1) = std::nanf("");
  EXPECT_THROW(baker.bake(view_of(nan_map), {}, {ratios.data(), 4, 4, 4}, apex), BakeError);
  Budget bad;
  bad.tolerance = 1.5f;
  EXPECT_THROW(baker.bake(view_of(ok), bad, {ratios.data(), 4, 4, 4}, apex), BakeError);
  EXPECT_NO_THROW(baker.bake(view_of(ok), {}, {ratios.data(), 4, 4, 4}, apex));
  for (float r : ratios) EXPECT_EQ(r, 1.0f);
}

}  // namespace
}  // namespace displace::bake
