// tests/bake/max_pyramid_test.cpp - the max pyramid (bake/max_pyramid.cpp).
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

TEST(MaxPyramid, ParentsAreMaximaOfChildrenForOddSizes) {
  const Map map = test::make_fractal_cliff(13, 7);
  const MaxPyramid pyramid = build_max_pyramid(view_of(map));
  ASSERT_EQ(pyramid.widths.back(), 1);
  ASSERT_EQ(pyramid.heights.back(), 1);
  for (std::size_t level = 1; level < pyramid.levels.size(); ++level) {
    const int w = pyramid.widths[level], h = pyramid.heights[level];
    const int fw = pyramid.widths[level - 1], fh = pyramid.heights[level - 1];
    EXPECT_EQ(w, (fw + 1) / 2);
    EXPECT_EQ(h, (fh + 1) / 2);
    for (int i = 0; i < h; ++i)
      for (int j = 0; j < w; ++j) {
        float m = 0.0f;
        for (int di = 0; di < 2; ++di)
          for (int dj = 0; dj < 2; ++dj)
            if (2 * i + di < fh && 2 * j + dj < fw)
              m = std::max(m, pyramid.levels[level - 1][std::size_t(2 * i + di) * fw + 2 * j + dj]);
        EXPECT_EQ(pyramid.levels[level][std::size_t(i) * w + j], m);
      }
  }
  EXPECT_EQ(pyramid.levels.back()[0], *std::max_element(map.values.begin(), map.values.end()));
}

// Built into a kept pyramid (the bakers' frame loop), the pyramid is the fresh one, whatever size the
// kept one had before.
TEST(MaxPyramid, RebuiltIntoAKeptPyramidEqualsAFreshOne) {
  MaxPyramid kept;
  for (const auto& [w, h] : {std::pair{13, 7}, std::pair{33, 20}, std::pair{5, 9}, std::pair{5, 9}}) {
    const Map map = test::make_fractal_cliff(w, h);
    build_max_pyramid(view_of(map), kept);
    const MaxPyramid fresh = build_max_pyramid(view_of(map));
    EXPECT_EQ(kept.widths, fresh.widths) << w << " x " << h;
    EXPECT_EQ(kept.heights, fresh.heights) << w << " x " << h;
    EXPECT_EQ(kept.levels, fresh.levels) << w << " x " << h;
  }
}

}  // namespace
}  // namespace displace::bake
