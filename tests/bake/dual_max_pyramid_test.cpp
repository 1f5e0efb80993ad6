// tests/bake/dual_max_pyramid_test.cpp - the dual max pyramid of the bilinear surface
// (bake/dual_max_pyramid.cpp).
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

// The bilinear surface, written here from the convention in bake.h (texel centres at (j + 0.5) / W,
// wrap or clamp addressing), in double: x = u W - 0.5, y = v H - 0.5.
double bilinear_at(const Map& map, Address address, double x, double y) {
  auto texel = [&](long long i, long long j) {
    if (address == Address::wrap) {
      i = ((i % map.height) + map.height) % map.height;
      j = ((j % map.width) + map.width) % map.width;
    } else {
      i = std::clamp<long long>(i, 0, map.height - 1);
      j = std::clamp<long long>(j, 0, map.width - 1);
    }
    return double(map.values[std::size_t(i) * map.width + j]);
  };
  const double x0 = std::floor(x), y0 = std::floor(y), fx = x - x0, fy = y - y0;
  const auto j = (long long)x0, i = (long long)y0;
  return (texel(i, j) * (1 - fx) + texel(i, j + 1) * fx) * (1 - fy) +
         (texel(i + 1, j) * (1 - fx) + texel(i + 1, j + 1) * fx) * fy;
}

std::vector<Map> dual_pyramid_maps() {
  std::vector<Map> maps;
  std::uint64_t seed = 11;
  for (auto [w, h] :
       {std::pair{1, 1}, {1, 5}, {5, 1}, {2, 3}, {7, 13}, {16, 16}, {17, 9}, {32, 20}, {37, 29}}) {
    Map map{"random", w, h, std::vector<float>(std::size_t(w) * h)};
    for (int i = 0; i < h; ++i)
      for (int j = 0; j < w; ++j) map.at(i, j) = test::hash01(seed, i, j);
    maps.push_back(std::move(map));
    ++seed;
  }
  maps.push_back(test::make_spikes(23, 17));
  maps.push_back(test::make_fractal_cliff(19, 33));
  return maps;
}

// Every node against brute force: the bilinear surface sampled on a grid of quarter cells over the
// node's footprint (which includes every texel centre in it). A node never under-bounds the surface
// and equals its max (the max sits at a texel centre).
TEST(DualMaxPyramid, EveryNodeIsTheBilinearMaxOverItsFootprint) {
  constexpr int samples_per_cell = 4;
  for (const Map& map : dual_pyramid_maps()) {
    for (const Address address : {Address::wrap, Address::clamp}) {
      SCOPED_TRACE(map.name + " " + std::to_string(map.width) + "x" + std::to_string(map.height) +
                   (address == Address::wrap ? " wrap" : " clamp"));
      const DualMaxPyramid pyramid = build_dual_max_pyramid(view_of(map), address);
      const int cells_x = pyramid.widths[0], cells_y = pyramid.heights[0];
      ASSERT_EQ(pyramid.origin, address == Address::wrap ? 0 : -1);
      ASSERT_EQ(cells_x, address == Address::wrap ? map.width : map.width + 1);
      ASSERT_EQ(cells_y, address == Address::wrap ? map.height : map.height + 1);
      ASSERT_EQ(pyramid.widths.back(), 1);
      ASSERT_EQ(pyramid.heights.back(), 1);
      ASSERT_EQ(pyramid.offsets.back() + 1, pyramid.values.size());
      for (std::size_t level = 0; level < pyramid.widths.size(); ++level) {
        const int w = pyramid.widths[level], h = pyramid.heights[level], span = 1 << level;
        if (level > 0) {
          EXPECT_EQ(w, (pyramid.widths[level - 1] + 1) / 2);
          EXPECT_EQ(h, (pyramid.heights[level - 1] + 1) / 2);
        }
        for (int b = 0; b < h; ++b)
          for (int a = 0; a < w; ++a) {
            // footprint in cells, truncated at the grid's end
            const int x_lo = a * span, x_hi = std::min((a + 1) * span, cells_x);
            const int y_lo = b * span, y_hi = std::min((b + 1) * span, cells_y);
            double sampled = 0.0, at_centres = 0.0;
            for (int sy = y_lo * samples_per_cell; sy <= y_hi * samples_per_cell; ++sy)
              for (int sx = x_lo * samples_per_cell; sx <= x_hi * samples_per_cell; ++sx) {
                const double x = double(sx) / samples_per_cell + pyramid.origin;
                const double y = double(sy) / samples_per_cell + pyramid.origin;
                const double value = bilinear_at(map, address, x, y);
                sampled = std::max(sampled, value);
                if (sx % samples_per_cell == 0 && sy % samples_per_cell == 0)
                  at_centres = std::max(at_centres, value);
              }
            const float node = pyramid.values[pyramid.offsets[level] + std::size_t(b) * w + a];
            ASSERT_GE(double(node), sampled - 1e-12) << "level " << level << " node " << a << "," << b;
            ASSERT_EQ(double(node), at_centres) << "level " << level << " node " << a << "," << b;
          }
      }
    }
  }
}

// The lookup the renderer makes: a surface point at texture coordinates (u, v) (anywhere on a 3 x 3
// tiling with wrap, on the patch with clamp) falls in the node floor((u W - 0.5 - origin) / 2^L)
// (its period's with wrap) of every level, and that node is at least the surface there.
TEST(DualMaxPyramid, TheNodeUnderEverySurfacePointBoundsIt) {
  for (const Map& map : dual_pyramid_maps()) {
    for (const Address address : {Address::wrap, Address::clamp}) {
      const DualMaxPyramid pyramid = build_dual_max_pyramid(view_of(map), address);
      const double extent = address == Address::wrap ? 3.0 : 1.0;
      const int cells_x = pyramid.widths[0], cells_y = pyramid.heights[0];
      for (int sample = 0; sample < 2000; ++sample) {
        const double u = extent * test::hash01(97, sample, 1), v = extent * test::hash01(97, sample, 2);
        const double x = u * map.width - 0.5, y = v * map.height - 0.5;
        const double surface = bilinear_at(map, address, x, y);
        auto cell = [&](double coordinate, int cells) {
          const auto c = (long long)std::floor(coordinate - pyramid.origin);
          return int(address == Address::wrap ? ((c % cells) + cells) % cells : c);
        };
        const int cx = cell(x, cells_x), cy = cell(y, cells_y);
        ASSERT_TRUE(cx >= 0 && cx < cells_x && cy >= 0 && cy < cells_y) << u << "," << v;
        for (std::size_t level = 0; level < pyramid.widths.size(); ++level) {
          const float node =
              pyramid.values[pyramid.offsets[level] + std::size_t(cy >> level) * pyramid.widths[level] +
                             std::size_t(cx >> level)];
          ASSERT_GE(double(node), surface - 1e-12)
              << map.name << " at " << u << "," << v << " level " << level;
        }
      }
    }
  }
}

TEST(DualMaxPyramid, RejectsBadInput) {
  const float nan_height = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(build_dual_max_pyramid({nullptr, 0, 0}, Address::wrap), BakeError);
  EXPECT_THROW(build_dual_max_pyramid({&nan_height, 1, 1}, Address::clamp), BakeError);
}

}  // namespace
}  // namespace displace::bake
