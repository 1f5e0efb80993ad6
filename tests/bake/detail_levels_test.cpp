// tests/bake/detail_levels_test.cpp - the levels of detail (bake/detail_levels.cpp): the chain of 2 x 2
// box means, and every level's bilinear cones keeping the contract for that level's own surface
// (the brute-force check the level-0 maps pass, tests/bake/bake_checks.h).
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "bake/bake.h"
#include "tests/bake/bake_checks.h"
#include "tests/test_maps.h"

namespace displace::bake {
namespace {

using test::Map;

// Levels 1 .. detail_level_count of `map`, each downsampled from the one below.
std::vector<Map> level_chain(const Map& map) {
  std::vector<Map> chain;
  const Map* below = &map;
  const int levels = detail_level_count(map.width, map.height);
  for (int level = 1; level <= levels; ++level) {
    Map coarse;
    coarse.name = map.name + "-level" + std::to_string(level);
    coarse.width = below->width / 2;
    coarse.height = below->height / 2;
    coarse.values.resize(std::size_t(coarse.width) * std::size_t(coarse.height));
    downsample_heights(view_of(*below), coarse.values);
    chain.push_back(std::move(coarse));
    below = &chain.back();
  }
  return chain;
}

TEST(DetailLevels, CountHalvesWhileSidesStayEvenAndLargeEnough) {
  EXPECT_EQ(detail_level_count(512, 512), 9);  // 256 .. 1
  EXPECT_EQ(detail_level_count(64, 64), 6);    // 32 .. 1
  EXPECT_EQ(detail_level_count(64, 48), 4);    // 32 x 24 .. 4 x 3 (then a side is odd)
  EXPECT_EQ(detail_level_count(15, 16), 0);    // odd
  EXPECT_EQ(detail_level_count(8, 8), 3);
  EXPECT_EQ(detail_level_count(1, 1), 0);
  EXPECT_EQ(detail_level_count(8192, 8192), max_detail_levels);  // the largest map, down to 1 x 1
  EXPECT_EQ(detail_level_count(1 << 15, 1 << 15), max_detail_levels);
}

TEST(DetailLevels, EachTexelIsTheMeanOfItsFourAndTheMeanHeightIsKept) {
  Map map = test::make_ocean(32, 16);
  std::vector<float> coarse(16 * 8);
  downsample_heights(view_of(map), coarse);
  double fine_sum = 0.0, coarse_sum = 0.0;
  for (float h : map.values) fine_sum += h;
  for (int i = 0; i < 8; ++i)
    for (int j = 0; j < 16; ++j) {
      const double mean = (double(map.at(2 * i, 2 * j)) + map.at(2 * i, 2 * j + 1) +
                           map.at(2 * i + 1, 2 * j) + map.at(2 * i + 1, 2 * j + 1)) /
                          4.0;
      const float h = coarse[std::size_t(i) * 16 + std::size_t(j)];
      EXPECT_NEAR(h, mean, 1e-6) << i << " " << j;
      EXPECT_TRUE(h >= 0.0f && h <= 1.0f);
      coarse_sum += h;
    }
  EXPECT_NEAR(coarse_sum * 4.0, fine_sum, 1e-3);
  std::vector<float> wrong(10);
  EXPECT_THROW(downsample_heights(view_of(map), wrong), BakeError);
  const Map odd = test::make_flat(9, 8);
  std::vector<float> half(4 * 4);
  EXPECT_THROW(downsample_heights(view_of(odd), half), BakeError);
}

// Each level's slope moments are the means, over the level-0 texels its texel covers, of level 0's
// central-difference gradient (wrapped) and its square - brute force in double - so the variance
// they give (mean |g|^2 less |mean g|^2) is that of the slopes under the texel, never negative
// beyond rounding, 0 on a plane and on level 0.
TEST(DetailLevels, SlopeMomentsAreTheMeansOfLevelZerosGradientOverEachTexel) {
  for (const Map& map : {test::make_ocean(32, 16), test::make_fractal_cliff(16, 16), test::make_flat(8, 4)}) {
    const int width = map.width, height = map.height;
    std::vector<float> moments(std::size_t(width) * std::size_t(height) * 3);
    gradient_moments(view_of(map), moments);
    auto gradient = [&](int i, int j) {  // double, wrapped
      auto at = [&](int a, int b) {
        return double(map.values[std::size_t((a + height) % height) * std::size_t(width) +
                                 std::size_t((b + width) % width)]);
      };
      return std::array<double, 2>{(at(i, j + 1) - at(i, j - 1)) * width / 2.0,
                                   (at(i + 1, j) - at(i - 1, j)) * height / 2.0};
    };
    std::vector<float> below = moments;
    for (int level = 1; level <= detail_level_count(width, height); ++level) {
      const int w = width >> level, h = height >> level, block = 1 << level;
      std::vector<float> coarse(std::size_t(w) * std::size_t(h) * 3);
      downsample_moments(below, w * 2, h * 2, coarse);
      for (int i = 0; i < h; ++i)
        for (int j = 0; j < w; ++j) {
          double mean_u = 0.0, mean_v = 0.0, mean_square = 0.0;
          for (int a = 0; a < block; ++a)
            for (int b = 0; b < block; ++b) {
              const auto g = gradient(i * block + a, j * block + b);
              mean_u += g[0];
              mean_v += g[1];
              mean_square += g[0] * g[0] + g[1] * g[1];
            }
          const double n = double(block) * block;
          const float* m = coarse.data() + (std::size_t(i) * std::size_t(w) + std::size_t(j)) * 3;
          const double scale = 1e-5 * (1.0 + mean_square / n);
          EXPECT_NEAR(m[0], mean_u / n, 1e-4 * (1.0 + std::abs(mean_u / n)))
              << map.name << " level " << level;
          EXPECT_NEAR(m[1], mean_v / n, 1e-4 * (1.0 + std::abs(mean_v / n)))
              << map.name << " level " << level;
          EXPECT_NEAR(m[2], mean_square / n, scale * 10) << map.name << " level " << level;
          EXPECT_GE(double(m[2]) - double(m[0]) * m[0] - double(m[1]) * m[1], -scale * 10) << map.name;
          if (map.name.find("flat") != std::string::npos) {
            EXPECT_EQ(m[2], 0.0f);
          }
        }
      below = std::move(coarse);
    }
  }
  std::vector<float> wrong(5);
  const Map map = test::make_ocean(8, 8);
  EXPECT_THROW(gradient_moments(view_of(map), wrong), BakeError);
  std::vector<float> fine(9 * 8 * 3), half(4 * 4 * 3);
  EXPECT_THROW(downsample_moments(fine, 9, 8, half), BakeError);
}

// Every level's cone maps - the map maker's baker (BilinearBaker) at no budget and unlimited - are
// never pierced by that level's bilinear surface from any point of a texel's square.
TEST(DetailLevels, EveryLevelsConesKeepTheBilinearContract) {
  long long pairs = 0;
  int levels_checked = 0;
  const std::vector<Map> maps = {test::make_ocean(32, 32), test::make_fractal_cliff(32, 16),
                                 test::make_bricks(32, 32), test::make_spikes(16, 32)};
  Budget none;
  none.max_work = 0;
  for (const Map& map : maps) {
    for (const Map& level : level_chain(map)) {
      ++levels_checked;
      for (int sectors : {1, 4, 8}) {
        for (const Budget& budget : {none, Budget{}}) {
          BilinearBaker baker(level.width, level.height, sectors, Address::wrap);
          ConeMap cones = make_cone_map(level, sectors);
          std::vector<float> apex(level.values.size());
          baker.bake(view_of(level), budget, cones.view(), apex);
          for (float r : cones.ratios) ASSERT_TRUE(r > 0.0f && r <= 1.0f) << level.name;
          const int stride = level.width * level.height > 128 ? 3 : 1;
          const BilinearCheck check = check_bilinear(level, Address::wrap, cones, apex, stride);
          pairs += check.pairs;
          EXPECT_EQ(check.violations, 0) << level.name << " " << level.width << "x" << level.height
                                         << " sectors " << sectors << " worst " << check.worst;
        }
      }
    }
  }
  std::printf("detail levels: %d levels, %lld (p, x) pairs checked\n", levels_checked, pairs);
  EXPECT_EQ(levels_checked, 18);  // 16 .. 1; 16 x 8 .. 2 x 1; 16 .. 1; 8 x 16 .. 1 x 2
  EXPECT_GT(pairs, 1000000);
}

}  // namespace
}  // namespace displace::bake
