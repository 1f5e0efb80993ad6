// tests/bake/cone_bilinear_test.cpp - the bilinear cones (bake/cone_bilinear.cpp).
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

TEST(BilinearCones, NeverPiercedByTheBilinearSurfaceFromAnyPointOfTheTexel) {
  long long pairs = 0;
  for (const Map& map : bilinear_maps())
    for (int sectors : {1, 4, 8})
      for (Address address : {Address::wrap, Address::clamp}) {
        const BilinearCones b = bake_bilinear(map, sectors, address);
        const BilinearCheck check = check_bilinear(map, address, b.cones, b.apex);
        pairs += check.pairs;
        EXPECT_EQ(check.violations, 0) << map.name << " " << map.width << "x" << map.height << " sectors "
                                       << sectors << " " << address_name(address) << " worst " << check.worst;
        // H_c is the maximum of s over the texel's square: at least the centre's height
        for (std::size_t t = 0; t < map.values.size(); ++t) ASSERT_GE(b.apex[t], map.values[t]);
        for (float r : b.cones.ratios) ASSERT_TRUE(r > 0.0f && r <= 1.0f) << map.name;
      }
  std::printf("bilinear cones: %lld (p, x) pairs checked\n", pairs);
  EXPECT_GT(pairs, 1000000);
}

// The check has teeth: every ratio 10% too large, or every apex 0.01 too low, is caught.
TEST(BilinearCones, CheckCatchesRatiosTenPercentTooLargeAndApexesTooLow) {
  for (const Map& map : {make_ramp(8, 6), make_noise(6, 6), test::make_fractal_cliff(10, 8)})
    for (int sectors : {1, 4, 8})
      for (Address address : {Address::wrap, Address::clamp}) {
        BilinearCones b = bake_bilinear(map, sectors, address);
        BilinearCones wide = b;
        for (float& r : wide.cones.ratios) r *= 1.1f;
        const BilinearCheck too_wide = check_bilinear(map, address, wide.cones, wide.apex);
        std::vector<float> low = b.apex;
        for (float& h : low) h -= 0.01f;
        const BilinearCheck too_low = check_bilinear(map, address, b.cones, low);
        EXPECT_GT(too_wide.violations, 0)
            << map.name << " sectors " << sectors << " " << address_name(address);
        EXPECT_GT(too_low.violations, 0)
            << map.name << " sectors " << sectors << " " << address_name(address);
      }
}

// On a ramp h = u * slope the bound is tight next to the texel: the uphill sector's ratio is the
// slope's inverse times the far cells' factor, and the sectors that only look downhill or across
// the slope are never blocked (the pieces beyond an edge keep their directions).
TEST(BilinearCones, RampSeesOnlyUphill) {
  Map ramp{"ramp", 32, 8, std::vector<float>(32 * 8)};
  for (int i = 0; i < 8; ++i)
    for (int j = 0; j < 32; ++j) ramp.at(i, j) = 0.8f * (j + 0.5f) / 32.0f;
  const double slope = 0.8;  // height per uv
  const BilinearCones b = bake_bilinear(ramp, 4, Address::clamp);
  for (int i = 0; i < 8; ++i)
    for (int j = 0; j < 31; ++j) {
      EXPECT_EQ(b.cones.at(i, j, 1), 1.0f) << j;
      EXPECT_EQ(b.cones.at(i, j, 2), 1.0f) << j;
      EXPECT_LE(b.cones.at(i, j, 0), 1.0 / slope);
      EXPECT_GE(b.cones.at(i, j, 0), 0.75 / slope) << j;
      EXPECT_NEAR(b.apex[std::size_t(i) * 32 + j], 0.8 * (j + 1.0) / 32.0, 1e-6);
    }
}

// The slope window only raises ratios over the plain construction (no window: every piece bounded by
// distance over height gap, so a texel next to a higher cell gets 0), and keeps every ratio above 0.
// Prints the mean ratio against bake_exact's (between texel centres) for the tightness record.
TEST(BilinearCones, SlopeWindowRaisesEveryRatioAndTightnessIsRecorded) {
  for (const Map& map : {test::make_fractal_cliff(64, 64), test::make_bricks(64, 64), make_noise(48, 40)})
    for (Address address : {Address::wrap, Address::clamp}) {
      const ConeMap exact = exact_of(map, 4, address);
      const BilinearCones plain = bake_bilinear(map, 4, address, 0);
      std::printf("%-14s %-5s exact mean %.4f; bilinear: window 0 mean %.4f", map.name.c_str(),
                  address_name(address), mean_ratio(exact), plain.stats.mean_ratio);
      for (int window : {1, 4, 8}) {
        const BilinearCones b = bake_bilinear(map, 4, address, window);
        std::printf(", window %d mean %.4f", window, b.stats.mean_ratio);
        long long zeros = 0;
        for (std::size_t n = 0; n < b.cones.ratios.size(); ++n) {
          ASSERT_GE(b.cones.ratios[n], plain.cones.ratios[n])
              << map.name << " window " << window << " at " << n;
          zeros += b.cones.ratios[n] == 0.0f;
        }
        EXPECT_EQ(zeros, 0);
      }
      long long plain_zeros = 0;
      for (float r : plain.cones.ratios) plain_zeros += r == 0.0f;
      std::printf("; window 0 zero ratios %.1f%%\n", 100.0 * plain_zeros / double(plain.cones.ratios.size()));
    }
}

// The search's pruning (the far search's bounds and quick rejection, the window's cell test) only
// skips what cannot lower a ratio: the maps equal, bit for bit, those of the search that opens every
// block and bounds every window piece (prune = false), on the hard maps, noise and an ocean, for
// 1, 4 and 8 sectors, wrap and clamp, windows 0, 1, 4 and 9, and more work is done without it.
TEST(BilinearCones, PrunedSearchEqualsTheExhaustiveOne) {
  std::vector<Map> maps = bilinear_maps();
  maps.push_back(make_noise(24, 17));
  maps.push_back(test::make_ocean(32, 16));
  long long compared = 0, pruned_work = 0, whole_work = 0;
  for (const Map& map : maps)
    for (int sectors : {1, 4, 8})
      for (Address address : {Address::wrap, Address::clamp})
        for (int window : {0, 1, 4, 9}) {
          BilinearCones pruned = bake_bilinear(map, sectors, address, window);
          BilinearCones whole{make_cone_map(map, sectors), std::vector<float>(map.values.size()), {}};
          BilinearConeSettings settings{window};
          settings.prune = false;
          whole.stats = bake_bilinear_cones(view_of(map), address, whole.cones.view(), whole.apex, settings);
          ASSERT_EQ(pruned.cones.ratios.size(), whole.cones.ratios.size());
          for (std::size_t n = 0; n < whole.cones.ratios.size(); ++n)
            ASSERT_EQ(pruned.cones.ratios[n], whole.cones.ratios[n])
                << map.name << " " << map.width << "x" << map.height << " sectors " << sectors << " "
                << address_name(address) << " window " << window << " at " << n;
          EXPECT_EQ(pruned.apex, whole.apex);
          pruned_work += pruned.stats.work;
          whole_work += whole.stats.work;
          compared += (long long)whole.cones.ratios.size();
        }
  std::printf("pruned and exhaustive searches: %lld ratios compared, work %lld against %lld\n", compared,
              pruned_work, whole_work);
  EXPECT_LT(2 * pruned_work, whole_work);
}

// Tightness against the best any conservative baker could do for the same apexes: the sampled
// minimum of |x - p| / (s(x) - H_c) per texel and sector is an upper bound of the best ratio.
TEST(BilinearCones, CloseToTheSampledBestRatio) {
  for (const Map& map : {test::make_fractal_cliff(10, 10), make_noise(10, 10), make_ramp(10, 10)})
    for (Address address : {Address::wrap, Address::clamp}) {
      const BilinearCones b = bake_bilinear(map, 4, address);
      const BilinearCheck check = check_bilinear(map, address, b.cones, b.apex);
      const double sampled = std::accumulate(check.sampled.begin(), check.sampled.end(), 0.0);
      const double ours = std::accumulate(b.cones.ratios.begin(), b.cones.ratios.end(), 0.0);
      std::printf("%-14s %-5s mean ratio %.4f, sampled best %.4f: %.3f of it\n", map.name.c_str(),
                  address_name(address), ours / double(check.sampled.size()),
                  sampled / double(check.sampled.size()), ours / sampled);
      EXPECT_GE(ours, 0.6 * sampled) << map.name << " " << address_name(address);
    }
}

TEST(BilinearCones, RejectsBadInput) {
  const Map ok = test::make_flat(4, 4);
  std::vector<float> ratios(16 * 4), apex(16);
  EXPECT_THROW(bake_bilinear_cones(view_of(ok), Address::wrap, {ratios.data(), 4, 4, 3}, apex), BakeError);
  EXPECT_THROW(bake_bilinear_cones(view_of(ok), Address::wrap, {ratios.data(), 4, 4, 4}, {apex.data(), 15}),
               BakeError);
  EXPECT_THROW(bake_bilinear_cones(view_of(ok), Address::wrap, {ratios.data(), 4, 4, 4}, apex, {-1}),
               BakeError);
  EXPECT_THROW(bake_bilinear_cones(view_of(ok), Address::wrap, {ratios.data(), 4, 4, 4}, apex, {65}),
               BakeError);
  Map nan_map = test::make_flat(4, 4);
  nan_map.at(2, 2) = std::nanf("");
  EXPECT_THROW(bake_bilinear_cones(view_of(nan_map), Address::clamp, {ratios.data(), 4, 4, 4}, apex),
               BakeError);
  EXPECT_NO_THROW(bake_bilinear_cones(view_of(ok), Address::clamp, {ratios.data(), 4, 4, 4}, apex));
  for (float r : ratios) EXPECT_EQ(r, 1.0f);
  for (float h : apex) EXPECT_EQ(h, 0.5f);
}

}  // namespace
}  // namespace displace::bake
