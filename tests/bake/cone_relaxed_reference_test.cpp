// tests/bake/cone_relaxed_reference_test.cpp - the relaxed baker's reference search
// (bake/cone_relaxed_reference.cpp) against the definition; bake_relaxed is tested against it
// (cone_relaxed_test.cpp).
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

// A smooth dome: rays aimed down its flank enter the relief and stay inside for long, so the relaxed
// cones there are much wider than the conservative ones.
Map make_reference_dome(int w, int h) {
  Map m{"dome", w, h, std::vector<float>(std::size_t(w) * h)};
  for (int i = 0; i < h; ++i)
    for (int j = 0; j < w; ++j) {
      const float x = (j + 0.5f) / w - 0.5f, y = (i + 0.5f) / h - 0.5f;
      m.at(i, j) = 0.9f * std::exp(-(x * x + y * y) / 0.03f);
    }
  return m;
}

TEST(RelaxedReference, NeverBelowConservativeAndWiderOnSmoothSlopes) {
  for (const Map& map : {make_reference_dome(24, 24), test::make_spikes(24, 24), test::make_bricks(24, 24),
                         test::make_fractal_cliff(20, 20)})
    for (int sectors : {1, 4}) {
      const ConeMap exact = exact_of(map, sectors, Address::wrap);
      ConeMap relaxed = make_cone_map(map, sectors);
      bake_relaxed_reference(view_of(map), Address::wrap, relaxed.view());
      double relaxed_sum = 0, exact_sum = 0;
      for (std::size_t n = 0; n < relaxed.ratios.size(); ++n) {
        ASSERT_GE(relaxed.ratios[n], exact.ratios[n]);
        ASSERT_LE(relaxed.ratios[n], 1.0f);
        relaxed_sum += relaxed.ratios[n];
        exact_sum += exact.ratios[n];
      }
      std::printf("relaxed %-14s n=%d: mean relaxed / mean conservative = %.3f\n", map.name.c_str(), sectors,
                  relaxed_sum / exact_sum);
      if (map.name == "dome") {
        EXPECT_GT(relaxed_sum, exact_sum * 1.05) << "sectors " << sectors;
      }
    }
}

// The definition, brute force in double: for every texel c and every texel d (with wrap images), the
// ray from (c, 1) through (d, h(d)) is followed at an eighth of a texel until it leaves the relief;
// the relaxed ratio is the smallest |E - c| / (h(E) - h(c)) over exits E above c, per sector. The
// ocean's smooth slopes give rays that graze the surface where they start, where an exit seen in
// rounding noise would make ratios narrower than the march's (counted as off by more than 2%).
TEST(RelaxedReference, MatchesTheDefinitionByBruteForce) {
  for (const Map& map :
       {make_reference_dome(16, 12), test::make_fractal_cliff(14, 14), test::make_ocean(16, 16)}) {
    const int sectors = 4;
    ConeMap relaxed = make_cone_map(map, sectors);
    bake_relaxed_reference(view_of(map), Address::wrap, relaxed.view());
    auto height_at = [&](double x, double y) {  // texel units, texel (i, j) centred at (j, i)
      const int j = int(std::floor(x)), i = int(std::floor(y));
      const double tx = x - j, ty = y - i;
      auto at = [&](int a, int b) {
        return double(map.values[std::size_t(((a % map.height) + map.height) % map.height) * map.width +
                                 ((b % map.width) + map.width) % map.width]);
      };
      return (at(i, j) * (1 - tx) + at(i, j + 1) * tx) * (1 - ty) +
             (at(i + 1, j) * (1 - tx) + at(i + 1, j + 1) * tx) * ty;
    };
    double worst = 0.0;
    int far_off = 0, count = 0;
    for (int ci = 0; ci < map.height; ++ci)
      for (int cj = 0; cj < map.width; ++cj) {
        const double hc = map.values[std::size_t(ci) * map.width + cj];
        double best[4] = {1, 1, 1, 1};
        for (int dy = -map.height - ci; dy < 2 * map.height - ci; ++dy)
          for (int dx = -map.width - cj; dx < 2 * map.width - cj; ++dx) {
            if (dx == 0 && dy == 0) continue;
            const double hd = height_at(cj + dx, ci + dy);
            if (!(hd > hc)) continue;
            const double len = std::sqrt(double(dx) * dx + double(dy) * dy);
            double s_inside = 1.0;
            bool constrained = true;
            if (hd < 1.0) {
              for (double s = 1.0 + 0.01 / len;; s += 0.01 / len) {
                const double z = 1.0 - (1.0 - hd) * s;
                if (z <= hc) {
                  constrained = false;
                  break;
                }
                if (height_at(cj + s * dx, ci + s * dy) <= z) break;
                s_inside = s;
              }
            }
            if (!constrained) continue;
            const double z = 1.0 - (1.0 - hd) * s_inside;
            const double du = s_inside * dx / map.width, dv = s_inside * dy / map.height;
            const double ratio = std::min(1.0, std::sqrt(du * du + dv * dv) / (z - hc));
            double azimuth = std::atan2(double(dy) / map.height, double(dx) / map.width);
            if (azimuth < 0) azimuth += 2 * std::numbers::pi;
            for (int k = 0; k < 4; ++k) {
              const double lo = k * std::numbers::pi / 2, hi = (k + 1) * std::numbers::pi / 2;
              if ((azimuth >= lo - 1e-12 && azimuth <= hi + 1e-12) ||
                  (k == 0 && azimuth >= 2 * std::numbers::pi - 1e-12) || (k == 3 && azimuth <= 1e-12))
                best[k] = std::min(best[k], ratio);
            }
          }
        for (int k = 0; k < 4; ++k) {
          // never wider than the fine march allows: an exit the march finds is never missed
          EXPECT_LE(relaxed.at(ci, cj, k), best[k] * 1.02) << map.name << " texel " << ci << "," << cj;
          const double diff = std::fabs(relaxed.at(ci, cj, k) - best[k]) / best[k];
          far_off += diff > 0.02;
          worst = std::max(worst, diff);
          ++count;
        }
      }
    std::printf(
        "relaxed %s: largest relative difference to the brute-force definition %.4f, %d of %d off by "
        "more than 2%%\n",
        map.name.c_str(), worst, far_off, count);
    // the baker solves each bilinear cell exactly; the reference marches at 1/100 texel and can step
    // over an exit thinner than that
    EXPECT_LE(far_off, count / 100) << map.name;
  }
}

}  // namespace
}  // namespace displace::bake
