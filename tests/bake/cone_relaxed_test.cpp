// tests/bake/cone_relaxed_test.cpp - the relaxed baker (bake/cone_relaxed.cpp) against its reference
// search (bake_relaxed_reference, tested against the definition in cone_relaxed_reference_test.cpp):
// on every texel and sector of every map, never a wider cone (compared bit for bit), and in fact the
// same map.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include "bake/bake.h"
#include "sim/sim.h"
#include "tests/bake/bake_checks.h"
#include "tests/test_maps.h"

namespace displace::bake {
namespace {

using test::Map;

// A flat floor with one 2 x 2 pillar off the centre: every ratio is set by the pillar's rays.
Map make_relaxed_pillar(int w, int h) {
  Map m = test::make_flat(w, h, 0.2f);
  m.name = "pillar";
  for (int i = h / 3; i < h / 3 + 2; ++i)
    for (int j = w / 4; j < w / 4 + 2; ++j) m.at(i, j) = 0.9f;
  return m;
}

// Relief across the wrap seams: a ramp along u that drops at the seam, a ridge on row 0 and peaks on
// the corner texels, so that the nearest blockers of the texels near an edge are periodic images.
Map make_relaxed_seams(int w, int h) {
  Map m{"seams", w, h, std::vector<float>(std::size_t(w) * h)};
  for (int i = 0; i < h; ++i)
    for (int j = 0; j < w; ++j) m.at(i, j) = 0.1f + 0.4f * float(j) / float(w);
  for (int j = 0; j < w; ++j) m.at(0, j) = 0.75f;
  m.at(0, 0) = 0.95f;
  m.at(h - 1, w - 1) = 0.85f;
  return m;
}

Map built_in(const char* name, int w, int h) {
  Map m{name, w, h, std::vector<float>(std::size_t(w) * h)};
  if (std::string(name) == "built-in bricks")
    sim::brick_heights(w, h, 1, m.values);
  else
    sim::cliff_heights(w, h, 1, m.values);
  return m;
}

struct Comparison {
  long long wider = 0, narrower = 0, count = 0;
  double sum = 0.0, reference_sum = 0.0;  // of the ratios
};

// Texel by texel and sector by sector, bit for bit: how many ratios are above the reference's.
Comparison compare_relaxed(const ConeMap& cones, const ConeMap& reference) {
  Comparison c;
  for (std::size_t n = 0; n < cones.ratios.size(); ++n) {
    c.wider += cones.ratios[n] > reference.ratios[n];
    c.narrower += cones.ratios[n] < reference.ratios[n];
    c.sum += cones.ratios[n];
    c.reference_sum += reference.ratios[n];
    ++c.count;
  }
  return c;
}

ConeMap relaxed_of(const Map& map, int sectors, Address address, bool reference) {
  ConeMap cones = make_cone_map(map, sectors);
  if (reference)
    bake_relaxed_reference(view_of(map), address, cones.view());
  else
    bake_relaxed(view_of(map), address, cones.view());
  return cones;
}

// Every texel of every map, 1 and 4 sectors, wrap and clamp: never wider than the reference.
void expect_never_wider(const std::vector<Map>& maps) {
  for (const Map& map : maps)
    for (int sectors : {1, 4})
      for (Address address : {Address::wrap, Address::clamp}) {
        const std::string what = map.name + " " + std::to_string(map.width) + "x" +
                                 std::to_string(map.height) + " n=" + std::to_string(sectors) + " " +
                                 address_name(address);
        const Comparison c = compare_relaxed(relaxed_of(map, sectors, address, false),
                                             relaxed_of(map, sectors, address, true));
        EXPECT_EQ(c.wider, 0) << what;
        EXPECT_EQ(c.narrower, 0) << what << ": the search prunes only what cannot lower a ratio";
        std::printf("relaxed %-36s mean ratio / reference's %.6f\n", what.c_str(), c.sum / c.reference_sum);
      }
}

TEST(RelaxedCones, NeverWiderThanTheReferenceOnTheHardMaps) {
  std::vector<Map> maps = hard_maps();  // cliffs, spikes, flat fields, steps, bricks, non-square, 1 x 1
  maps.push_back(make_relaxed_pillar(20, 14));
  maps.push_back(make_relaxed_seams(18, 12));
  maps.push_back(test::make_pockets(32, 24));
  maps.push_back(test::make_flat(7, 5, 1.0f));  // every texel at the top: nothing can be higher
  expect_never_wider(maps);
}

TEST(RelaxedCones, NeverWiderThanTheReferenceOnOceanAndBricks) {
  expect_never_wider({test::make_ocean(24, 24), test::make_ocean(32, 16), test::make_bricks(24, 20),
                      built_in("built-in bricks", 32, 32), built_in("built-in cliff", 32, 32)});
}

// The comparison is bit for bit: one ratio raised by one float step is caught, on every map.
TEST(RelaxedCones, TheComparisonCatchesACone1UlpTooWide) {
  for (const Map& map : {make_relaxed_pillar(12, 10), test::make_fractal_cliff(13, 7)}) {
    const ConeMap reference = relaxed_of(map, 4, Address::wrap, true);
    ConeMap widened = relaxed_of(map, 4, Address::wrap, false);
    ASSERT_EQ(compare_relaxed(widened, reference).wider, 0) << map.name;
    std::size_t n = 0;  // the first ratio below 1 (a ratio of 1 cannot be wider)
    while (n < widened.ratios.size() && !(widened.ratios[n] < 1.0f)) ++n;
    ASSERT_LT(n, widened.ratios.size()) << map.name;
    widened.ratios[n] = std::nextafter(widened.ratios[n], 2.0f);
    EXPECT_EQ(compare_relaxed(widened, reference).wider, 1) << map.name;
  }
}

// The search seeds each texel with the blockers of the texels before it in its band of rows, so its
// work depends on where the bands start; the map must not. With wrap, every computation depends on
// offsets only: a map moved by whole texels bakes to the moved map, bit for bit, whichever rows
// start the bands.
TEST(RelaxedCones, AMovedMapBakesToTheMovedMap) {
  const Map map = test::make_pockets(24, 40);
  for (int sectors : {1, 4}) {
    const ConeMap baked = relaxed_of(map, sectors, Address::wrap, false);
    for (const auto& [down, right] : {std::pair{3, 5}, std::pair{1, 0}, std::pair{7, 11}}) {
      Map moved = map;
      for (int i = 0; i < map.height; ++i)
        for (int j = 0; j < map.width; ++j)
          moved.at((i + down) % map.height, (j + right) % map.width) =
              map.values[std::size_t(i) * map.width + j];
      const ConeMap moved_baked = relaxed_of(moved, sectors, Address::wrap, false);
      long long differ = 0;
      for (int i = 0; i < map.height; ++i)
        for (int j = 0; j < map.width; ++j)
          for (int k = 0; k < sectors; ++k)
            differ +=
                moved_baked.at((i + down) % map.height, (j + right) % map.width, k) != baked.at(i, j, k);
      EXPECT_EQ(differ, 0) << "n=" << sectors << " moved by " << down << ", " << right;
    }
  }
}

TEST(RelaxedCones, NeverBelowTheConservativeRatio) {
  for (const Map& map :
       {test::make_spikes(24, 24), test::make_pockets(24, 24), test::make_fractal_cliff(20, 20)})
    for (int sectors : {1, 4}) {
      const ConeMap exact = exact_of(map, sectors, Address::wrap);
      const ConeMap relaxed = relaxed_of(map, sectors, Address::wrap, false);
      for (std::size_t n = 0; n < relaxed.ratios.size(); ++n) {
        ASSERT_GE(relaxed.ratios[n], exact.ratios[n]) << map.name << " n=" << sectors;
        ASSERT_LE(relaxed.ratios[n], 1.0f) << map.name << " n=" << sectors;
      }
    }
}

}  // namespace
}  // namespace displace::bake
