// tests/bake/cone_exact_test.cpp - the exact baker (bake/cone_exact.cpp) against the definition in
// bake/bake.h.
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

// All pairs, written straight from the definition with its own arithmetic (double, atan2).
ConeMap brute_force(const Map& map, int sectors, Address address) {
  ConeMap cones = make_cone_map(map, sectors);
  const double two_pi = 2.0 * std::numbers::pi;
  const int tiles = address == Address::wrap ? 1 : 0;
  for (int ci = 0; ci < map.height; ++ci)
    for (int cj = 0; cj < map.width; ++cj) {
      const double hc = map.values[std::size_t(ci) * map.width + cj];
      std::vector<double> best(sectors, 1.0);
      for (int qi = 0; qi < map.height; ++qi)
        for (int qj = 0; qj < map.width; ++qj) {
          const double hq = map.values[std::size_t(qi) * map.width + qj];
          if (!(hq > hc)) continue;
          for (int ty = -tiles; ty <= tiles; ++ty)
            for (int tx = -tiles; tx <= tiles; ++tx) {
              const double du = double(qj + tx * map.width - cj) / map.width;
              const double dv = double(qi + ty * map.height - ci) / map.height;
              const double ratio = std::sqrt(du * du + dv * dv) / (hq - hc);
              double azimuth = std::atan2(dv, du);
              if (azimuth < 0) azimuth += two_pi;
              const double sector_width = two_pi / sectors;
              for (int k = 0; k < sectors; ++k) {
                const double lo = k * sector_width, hi = (k + 1) * sector_width;
                const double eps = 1e-10;
                const bool inside = (azimuth >= lo - eps && azimuth <= hi + eps) ||
                                    (k == sectors - 1 && azimuth <= eps) ||
                                    (k == 0 && azimuth >= two_pi - eps);
                if (inside && ratio < best[k]) best[k] = ratio;
              }
            }
        }
      for (int k = 0; k < sectors; ++k)
        cones.ratios[(std::size_t(ci) * map.width + cj) * sectors + k] = float(best[k]);
    }
  return cones;
}

TEST(ExactBaker, MatchesAllPairsOnHardMaps) {
  for (const Map& map : hard_maps())
    for (int sectors : {1, 4, 8})
      for (Address address : {Address::wrap, Address::clamp}) {
        const ConeMap reference = brute_force(map, sectors, address);
        ConeMap exact = make_cone_map(map, sectors);
        bake_exact(view_of(map), address, exact.view());
        for (std::size_t n = 0; n < exact.ratios.size(); ++n)
          ASSERT_NEAR(exact.ratios[n], reference.ratios[n], 1e-5f * reference.ratios[n] + 1e-7f)
              << map.name << " " << map.width << "x" << map.height << " sectors " << sectors << " "
              << address_name(address) << " texel " << n / sectors << " sector " << n % sectors;
      }
}

TEST(ExactBaker, FlatAndOneByOneMapsHaveNoBlockers) {
  for (const Map& map : {test::make_flat(9, 5), test::make_flat(1, 1), test::make_flat(1, 7)}) {
    const ConeMap exact = exact_of(map, 8, Address::wrap);
    for (float r : exact.ratios) EXPECT_EQ(r, 1.0f);
  }
}

}  // namespace
}  // namespace displace::bake
