// tests/bake/cone_budgeted_test.cpp - the budgeted baker (bake/cone_budgeted.cpp).
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

TEST(BudgetedBaker, ConservativeAtEveryBudget) {
  for (const Map& map : hard_maps())
    for (int sectors : {1, 4, 8})
      for (Address address : {Address::wrap, Address::clamp}) {
        const ConeMap exact = exact_of(map, sectors, address);
        for (int budget_kind = 0; budget_kind < 4; ++budget_kind) {
          Budget budget;
          if (budget_kind == 0) budget.milliseconds = 0.0;  // zero: fallback only
          if (budget_kind == 1) budget.max_work = 50;       // tiny
          if (budget_kind == 2) budget.clock = FakeClock{}.function(), budget.milliseconds = 3.0;
          ConeMap cones = make_cone_map(map, sectors);
          const BakeStats stats = bake_budgeted(view_of(map), address, budget, cones.view());
          const Violations v = violations(cones, exact);
          ASSERT_EQ(v.count, 0) << map.name << " " << map.width << "x" << map.height << " sectors " << sectors
                                << " " << address_name(address) << " budget kind " << budget_kind;
          for (float r : cones.ratios) ASSERT_GT(r, 0.0f) << "a zero ratio would stall a cone stepper";
          EXPECT_EQ(stats.texels_refined + stats.texels_fallback <= (long long)map.width * map.height, true);
          if (budget_kind == 3) {  // unlimited: within the tolerance of exact everywhere
            EXPECT_EQ(stats.texels_fallback, 0);
            for (std::size_t n = 0; n < cones.ratios.size(); ++n)
              ASSERT_GE(cones.ratios[n], (1.0f - budget.tolerance) * exact.ratios[n] * (1.0f - 1e-6f))
                  << map.name << " texel " << n / sectors;
          }
        }
      }
}

// The O(N) floor's rings on bigger, odd-sized maps (more pyramid levels, partial blocks at the seams).
TEST(BudgetedBaker, ZeroBudgetFloorIsConservativeOnLargerOddMaps) {
  for (const Map& map :
       {test::make_fractal_cliff(100, 60, 5), test::make_spikes(77, 129, 3), test::make_bricks(96, 96)})
    for (int sectors : {1, 4, 8})
      for (Address address : {Address::wrap, Address::clamp}) {
        Budget budget;
        budget.milliseconds = 0.0;
        ConeMap cones = make_cone_map(map, sectors);
        const BakeStats stats = bake_budgeted(view_of(map), address, budget, cones.view());
        EXPECT_EQ(stats.texels_refined, 0);
        const Violations v = violations(cones, exact_of(map, sectors, address));
        ASSERT_EQ(v.count, 0) << map.name << " " << map.width << "x" << map.height << " sectors " << sectors
                              << " " << address_name(address) << " worst x" << v.worst;
        for (float r : cones.ratios) ASSERT_GT(r, 0.0f);
      }
}

// The whole baker on non-square maps, 1, 4 and 8 sectors: never above exact at any budget, within the
// tolerance with no limit, and exact with tolerance 0.
TEST(BudgetedBaker, NonSquareMapsConservativeAtEveryBudget) {
  for (const Map& map : aspect_maps())
    for (int sectors : {1, 4, 8})
      for (Address address : {Address::wrap, Address::clamp}) {
        const ConeMap exact = exact_of(map, sectors, address);
        const std::string where = map.name + " " + std::to_string(map.width) + "x" +
                                  std::to_string(map.height) + " " + address_name(address) + " sectors " +
                                  std::to_string(sectors);
        for (int budget_kind = 0; budget_kind < 4; ++budget_kind) {
          Budget budget;
          if (budget_kind == 0) budget.milliseconds = 0.0;
          if (budget_kind == 1) budget.max_work = 50;
          if (budget_kind == 3) budget.tolerance = 0.0f;
          ConeMap cones = make_cone_map(map, sectors);
          const BakeStats stats = bake_budgeted(view_of(map), address, budget, cones.view());
          ASSERT_EQ(violations(cones, exact).count, 0) << where << " budget kind " << budget_kind;
          for (float r : cones.ratios) ASSERT_GT(r, 0.0f) << where;
          if (budget_kind == 2) {
            EXPECT_EQ(stats.texels_fallback, 0) << where;
            for (std::size_t n = 0; n < cones.ratios.size(); ++n) {
              ASSERT_GE(cones.ratios[n], (1.0f - budget.tolerance) * exact.ratios[n] * (1.0f - 1e-6f))
                  << where;
            }
          }
          if (budget_kind == 3) {
            ASSERT_EQ(cones.ratios, exact.ratios) << where;
          }
        }
      }
}

// Non-square maps of 0.26 to 2.1 million texels, wide and tall up to 16:1, wrap and clamp, 4 and 8
// sectors: stage L certifies every texel within the default tolerance, so an unlimited bake ends
// after it (before the moves were fitted to the aspect, a 1024 x 512 brick map left 287,000 texels
// to the refinement and 8 sectors all of them).
TEST(BudgetedBaker, StageLCertifiesNonSquareMapsWithinTheDefaultTolerance) {
  Map waves{"waves", 4096, 256, std::vector<float>(std::size_t(4096) * 256)};
  for (int i = 0; i < waves.height; ++i)
    for (int j = 0; j < waves.width; ++j)
      waves.at(i, j) =
          0.5f +
          0.3f * std::sin(2.0f * std::numbers::pi_v<float> * (7.0f * j / 4096.0f + 3.0f * i / 256.0f)) +
          0.15f * std::cos(2.0f * std::numbers::pi_v<float> * (11.0f * i / 256.0f - 5.0f * j / 4096.0f));
  const Map maps[] = {test::make_ocean(2048, 1024),
                      test::make_ocean(1024, 2048),
                      test::make_bricks(1024, 512),
                      test::make_bricks(512, 1024),
                      waves,
                      test::make_bricks(4096, 256),
                      test::make_bricks(256, 4096)};
  for (const Map& map : maps)
    for (int sectors : {4, 8})
      for (Address address : {Address::wrap, Address::clamp}) {
        BudgetedBaker baker(map.width, map.height, sectors, address);
        ConeMap cones = make_cone_map(map, sectors);
        Budget none;
        none.milliseconds = 0.0;
        const BakeStats stats = baker.bake(view_of(map), none, cones.view());
        const std::string where = map.name + " " + std::to_string(map.width) + "x" +
                                  std::to_string(map.height) + " " + address_name(address) + " sectors " +
                                  std::to_string(sectors);
        EXPECT_EQ(stats.texels_fallback, 0) << where;
        EXPECT_EQ(baker.pending(none.tolerance), 0) << where;
        EXPECT_EQ(stats.texels_refined, 0) << where;
      }
}

TEST(BudgetedBaker, UnlimitedWithZeroToleranceIsExact) {
  for (const Map& map : hard_maps())
    for (int sectors : {1, 4, 8})
      for (Address address : {Address::wrap, Address::clamp}) {
        Budget budget;
        budget.tolerance = 0.0f;
        ConeMap cones = make_cone_map(map, sectors);
        bake_budgeted(view_of(map), address, budget, cones.view());
        ASSERT_EQ(cones.ratios, exact_of(map, sectors, address).ratios) << map.name << " sectors " << sectors;
      }
}

TEST(BudgetedBaker, RefinementContinuesAcrossCallsUntilDone) {
  const Map map = test::make_fractal_cliff(64, 48);
  const ConeMap exact = exact_of(map, 4, Address::wrap);
  BudgetedBaker baker(map.width, map.height, 4, Address::wrap);
  ConeMap cones = make_cone_map(map, 4);
  Budget budget;
  budget.tolerance = 0.0f;
  budget.max_work = 20000;  // a deterministic per-call budget
  BakeStats stats = baker.bake(view_of(map), budget, cones.view());
  long long pending = baker.pending();
  ASSERT_GT(pending, 0) << "the test needs a budget that runs out";
  EXPECT_EQ(violations(cones, exact).count, 0);
  int calls = 0;
  while (baker.pending() > 0 && calls < 1000) {
    stats = baker.refine(budget, cones.view());
    EXPECT_EQ(violations(cones, exact).count, 0);
    EXPECT_LE(baker.pending(), pending);
    pending = baker.pending();
    ++calls;
  }
  EXPECT_EQ(baker.pending(), 0);
  EXPECT_EQ(cones.ratios, exact.ratios);
}

TEST(BudgetedBaker, FakeClockBudgetStopsRefinement) {
  const Map map = test::make_fractal_cliff(64, 64);
  FakeClock clock;
  clock.step = 1.0;
  Budget budget;
  budget.tolerance = 0.0f;
  budget.clock = clock.function();
  budget.milliseconds = 10.0;  // ten clock readings
  ConeMap cones = make_cone_map(map, 4);
  BudgetedBaker baker(map.width, map.height, 4, Address::wrap);
  const BakeStats stats = baker.bake(view_of(map), budget, cones.view());
  EXPECT_GT(stats.texels_fallback, 0);
  EXPECT_LT(stats.texels_refined, 64 * 64);
  EXPECT_GE(stats.milliseconds, 10.0);
  EXPECT_EQ(violations(cones, exact_of(map, 4, Address::wrap)).count, 0);
}

// On a 40 x 32 map (8 sectors from quadrants) and a 48 x 24 one (octant sweeps).
TEST(BudgetedBaker, IncrementalUpdatesStayConservativeAndConverge) {
  std::uint64_t seed = 99;
  using Policy = BudgetedBaker::UpdatePolicy;
  for (const auto& [width, height] : {std::pair{40, 32}, std::pair{48, 24}})
    for (Policy policy : {Policy::incremental, Policy::cheaper, Policy::rebake})
      for (int sectors : {1, 4, 8})
        for (Address address : {Address::wrap, Address::clamp}) {
          Map map = test::make_fractal_cliff(width, height, seed);
          BudgetedBaker baker(map.width, map.height, sectors, address);
          ConeMap cones = make_cone_map(map, sectors);
          Budget unlimited;
          unlimited.tolerance = 0.0f;
          baker.bake(view_of(map), unlimited, cones.view());
          for (int frame = 0; frame < 12; ++frame) {
            // a random local raise or lowering
            const int w = 1 + int(test::hash01(seed, frame, 1) * 6),
                      h = 1 + int(test::hash01(seed, frame, 2) * 6);
            const int x0 = int(test::hash01(seed, frame, 3) * (map.width - w));
            const int y0 = int(test::hash01(seed, frame, 4) * (map.height - h));
            const bool raise = frame % 3 != 1;
            for (int i = y0; i < y0 + h; ++i)
              for (int j = x0; j < x0 + w; ++j) {
                float& value = map.at(i, j);
                value = raise ? std::min(1.0f, value + 0.3f * test::hash01(seed, i, j + frame))
                              : std::max(0.0f, value - 0.3f * test::hash01(seed, i, j + frame));
              }
            const Rect dirty{x0, y0, x0 + w, y0 + h};
            Budget none;
            none.milliseconds = 0.0;
            baker.update(view_of(map), std::span<const Rect>(&dirty, 1), none, cones.view(), policy);
            const ConeMap exact = exact_of(map, sectors, address);
            ASSERT_EQ(violations(cones, exact).count, 0)
                << "frame " << frame << (raise ? " raise" : " lower") << " sectors " << sectors << " "
                << address_name(address) << " policy " << int(policy) << " " << width << "x" << height;
            if (frame % 4 == 3) {  // later frames converge to the full rebake
              baker.refine(unlimited, cones.view());
              EXPECT_EQ(baker.pending(), 0);
              ASSERT_EQ(cones.ratios, exact.ratios) << "frame " << frame;
            }
          }
        }
}

// `cheaper` repairs a tiny change that reaches little incrementally (the changed group keeps the
// stage-0 floor until refined, so with no budget it is pending), and rebakes with stage L when the
// whole map changed (every texel certified at once).
TEST(BudgetedBaker, UpdatePicksTheCheaperRepair) {
  Map map = test::make_flat(256, 256, 0.5f);
  for (int i = 0; i < map.height; ++i)
    for (int j = 0; j < map.width; ++j) map.at(i, j) += 0.002f * test::hash01(5, i, j);
  BudgetedBaker baker(map.width, map.height, 4, Address::wrap);
  ConeMap cones = make_cone_map(map, 4);
  Budget none;
  none.milliseconds = 0.0;
  baker.bake(view_of(map), none, cones.view());
  EXPECT_EQ(baker.pending(none.tolerance), 0);
  map.at(100, 100) += 0.001f;  // tiny and local
  const Rect spot{100, 100, 101, 101};
  baker.update(view_of(map), std::span<const Rect>(&spot, 1), none, cones.view());
  EXPECT_GT(baker.pending(none.tolerance), 0) << "expected the incremental repair";
  EXPECT_EQ(violations(cones, exact_of(map, 4, Address::wrap)).count, 0);
  for (float& h : map.values) h = std::min(1.0f, h + 0.3f * test::hash01(6, int(&h - map.values.data()), 0));
  const Rect all{0, 0, map.width, map.height};
  baker.update(view_of(map), std::span<const Rect>(&all, 1), none, cones.view());
  EXPECT_EQ(baker.pending(none.tolerance), 0) << "expected a new stage L";
  EXPECT_EQ(violations(cones, exact_of(map, 4, Address::wrap)).count, 0);
}

// On large maps the certified bounds loosen (step rounding grows with the side); the lanes still
// certify every texel of smooth and brick maps up to 2048 within the default tolerance, so an
// unlimited bake ends after stage L there too.
TEST(BudgetedBaker, StageLCertifiesLargeMapsWithinTheDefaultTolerance) {
  Map waves{"waves", 2048, 1024, std::vector<float>(std::size_t(2048) * 1024)};
  for (int i = 0; i < waves.height; ++i)
    for (int j = 0; j < waves.width; ++j)
      waves.at(i, j) =
          0.5f +
          0.3f * std::sin(2.0f * std::numbers::pi_v<float> * (7.0f * j / 2048.0f + 3.0f * i / 1024.0f)) +
          0.15f * std::cos(2.0f * std::numbers::pi_v<float> * (11.0f * i / 1024.0f - 5.0f * j / 2048.0f));
  for (const Map& map : {waves, test::make_bricks(2048, 2048)}) {
    BudgetedBaker baker(map.width, map.height, 4, Address::wrap);
    ConeMap cones = make_cone_map(map, 4);
    Budget none;
    none.milliseconds = 0.0;
    const BakeStats stats = baker.bake(view_of(map), none, cones.view());
    EXPECT_EQ(stats.texels_fallback, 0) << map.name;
    EXPECT_EQ(baker.pending(none.tolerance), 0) << map.name;
  }
}

TEST(BudgetedBaker, RejectsHeightsChangedOutsideTheDirtyRegion) {
  Map map = test::make_bricks(16, 16);
  BudgetedBaker baker(16, 16, 4, Address::wrap);
  ConeMap cones = make_cone_map(map, 4);
  baker.bake(view_of(map), {}, cones.view());
  map.at(0, 0) += 0.01f;
  const Rect dirty{8, 8, 10, 10};
  EXPECT_THROW(baker.update(view_of(map), std::span<const Rect>(&dirty, 1), {}, cones.view()), BakeError);
}

}  // namespace
}  // namespace displace::bake
