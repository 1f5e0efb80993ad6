// tests/bake/cone_relaxed_budgeted_test.cpp - RelaxedBaker (bake/cone_relaxed_budgeted.cpp): at every
// budget never a ratio above the reference relaxed map's (bit for bit, every texel and sector), and
// the reference map itself once nothing is pending.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "bake/bake.h"
#include "tests/bake/bake_checks.h"
#include "tests/test_maps.h"

namespace displace::bake {
namespace {

using test::Map;

std::vector<Map> budgeted_relaxed_maps() {
  return {test::make_pockets(32, 24), test::make_ocean(24, 24), test::make_fractal_cliff(13, 7),
          test::make_bricks(30, 18),  test::make_spikes(1, 9),  test::make_flat(5, 4, 1.0f)};
}

ConeMap reference_relaxed(const Map& map, int sectors, Address address) {
  ConeMap cones = make_cone_map(map, sectors);
  bake_relaxed_reference(view_of(map), address, cones.view());
  return cones;
}

long long wider_than(const ConeMap& cones, const ConeMap& reference) {
  long long wider = 0;
  for (std::size_t n = 0; n < cones.ratios.size(); ++n) wider += cones.ratios[n] > reference.ratios[n];
  return wider;
}

// The budgets of one bake: none, a clock that runs out after a few readings, work limits, unlimited.
std::vector<std::pair<std::string, Budget>> relaxed_budgets() {
  std::vector<std::pair<std::string, Budget>> budgets;
  Budget zero;
  zero.milliseconds = 0.0;
  budgets.emplace_back("0 ms", zero);
  for (long long work : {0LL, 40LL, 400LL}) {
    Budget limited;
    limited.max_work = work;
    budgets.emplace_back("work " + std::to_string(work), limited);
  }
  FakeClock clock;
  Budget ticking;
  ticking.milliseconds = 5.0;
  ticking.clock = clock.function();
  budgets.emplace_back("fake clock, 5 readings", ticking);
  budgets.emplace_back("unlimited", Budget{});
  return budgets;
}

TEST(RelaxedBaker, AtEveryBudgetNeverWiderThanTheReference) {
  for (const Map& map : budgeted_relaxed_maps())
    for (int sectors : {1, 4})
      for (Address address : {Address::wrap, Address::clamp}) {
        const ConeMap reference = reference_relaxed(map, sectors, address);
        for (const auto& [name, budget] : relaxed_budgets()) {
          const std::string what =
              map.name + " n=" + std::to_string(sectors) + " " + address_name(address) + ", " + name;
          RelaxedBaker baker(map.width, map.height, sectors, address);
          ConeMap cones = make_cone_map(map, sectors);
          const BakeStats stats = baker.bake(view_of(map), budget, cones.view());
          EXPECT_EQ(wider_than(cones, reference), 0) << what;
          EXPECT_EQ(stats.texels_fallback, baker.pending()) << what;
          if (name == "unlimited") {
            EXPECT_EQ(baker.pending(), 0) << what;
            EXPECT_EQ(cones.ratios, reference.ratios) << what;
          }
          if (name == "0 ms" || name == "work 0") {
            EXPECT_EQ(baker.pending(), (long long)map.width * map.height) << what;
          }
        }
      }
}

// refine() with a small work limit at a time: each call never wider, pending falls to 0, and then the
// map is the reference's; a new bake() starts over on new heights.
TEST(RelaxedBaker, RefineReachesTheReferenceMap) {
  const Map map = test::make_pockets(28, 20);
  const Map other = test::make_fractal_cliff(28, 20);
  for (int sectors : {1, 4}) {
    const ConeMap reference = reference_relaxed(map, sectors, Address::wrap);
    RelaxedBaker baker(map.width, map.height, sectors, Address::wrap);
    ConeMap cones = make_cone_map(map, sectors);
    Budget small;
    small.max_work = 30;
    baker.bake(view_of(map), small, cones.view());
    long long pending = baker.pending(), calls = 0;
    while (pending > 0) {
      ASSERT_LT(++calls, 1000) << "n=" << sectors;
      baker.refine(small, cones.view());
      EXPECT_EQ(wider_than(cones, reference), 0) << "n=" << sectors << " call " << calls;
      EXPECT_LT(baker.pending(), pending) << "n=" << sectors;  // a piece at least per call
      pending = baker.pending();
    }
    EXPECT_GT(calls, 1) << "n=" << sectors;
    EXPECT_EQ(cones.ratios, reference.ratios) << "n=" << sectors;

    baker.bake(view_of(other), small, cones.view());
    EXPECT_EQ(wider_than(cones, reference_relaxed(other, sectors, Address::wrap)), 0) << "n=" << sectors;
  }
}

TEST(RelaxedBaker, RejectsWhatItCannotBake) {
  EXPECT_THROW(RelaxedBaker(8, 8, 8, Address::wrap), BakeError);
  EXPECT_THROW(RelaxedBaker(0, 8, 1, Address::wrap), BakeError);
  RelaxedBaker baker(8, 6, 1, Address::clamp);
  const Map map = test::make_spikes(8, 6);
  ConeMap cones = make_cone_map(map, 1);
  EXPECT_THROW(baker.refine({}, cones.view()), BakeError);  // nothing baked yet
  ConeMap four = make_cone_map(map, 4);
  EXPECT_THROW(baker.bake(view_of(map), {}, four.view()), BakeError);
  const Map larger = test::make_spikes(9, 6);
  ConeMap larger_cones = make_cone_map(larger, 1);
  EXPECT_THROW(baker.bake(view_of(larger), {}, larger_cones.view()), BakeError);
}

}  // namespace
}  // namespace displace::bake
