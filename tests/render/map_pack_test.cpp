// tests/render/map_pack_test.cpp - map packing (render/map_pack.cpp).
#include "render/map_pack.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <iterator>
#include <memory>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "render/mesh.h"
#include "render/render.h"
#include "sim/sim.h"
#include "tests/height_fields.h"
#include "tests/render/render_checks.h"

namespace {

using namespace displace;
using namespace displace::testing;
using render::Frame;
using render::HeightField;
using render::Method;
using render::MethodInfo;
using render::View;

// The SSE2 packing writes what the scalar loop writes, bit for bit, and finds the same bad values:
// random maps of 1 to 13 columns, random rectangles (tails of 0 to 3 texels, blocks at any column),
// 1, 4 and 8 sectors, with and without the relaxed layer, one bad value in a third of the cases
// (the bytes of maps that are taken compared).
TEST(MapPack, VectorisedEqualsScalar) {
  std::mt19937 random(7);
  auto uniform = [&](int low, int high) { return std::uniform_int_distribution<int>(low, high)(random); };
  auto value = [&] { return std::uniform_real_distribution<float>(0.0f, 1.0f)(random); };
  long long compared = 0, refused = 0;
  for (int round = 0; round < 600; ++round) {
    const int width = uniform(1, 13), height = uniform(1, 5);
    const int sectors = std::array{1, 4, 8}[std::size_t(round % 3)];
    const bool relaxed = round % 2 == 0;
    const std::size_t texels = std::size_t(width) * height;
    std::vector<float> heights(texels), ratios(texels * std::size_t(sectors)), apex(texels), relaxed_ratios;
    for (float& h : heights) h = value();
    for (float& r : ratios) r = value();
    for (float& a : apex) a = value();
    if (relaxed) {
      relaxed_ratios.resize(texels);
      for (float& r : relaxed_ratios) r = value();
    }
    if (round % 3 == 1) {  // one bad value somewhere
      const float bad = std::array{std::nanf(""), -0.5f, 2e30f}[std::size_t(uniform(0, 2))];
      switch (uniform(0, 3)) {
        case 0: heights[std::size_t(uniform(0, int(texels) - 1))] = bad; break;
        case 1: ratios[std::size_t(uniform(0, int(ratios.size()) - 1))] = bad; break;
        case 2: apex[std::size_t(uniform(0, int(texels) - 1))] = bad; break;
        default:
          if (relaxed) relaxed_ratios[std::size_t(uniform(0, int(texels) - 1))] = bad;
      }
    }
    const int x0 = uniform(0, width - 1), y0 = uniform(0, height - 1);
    const bake::Rect rect{x0, y0, uniform(x0 + 1, width), uniform(y0 + 1, height)};
    const std::size_t columns = std::size_t(rect.x1 - rect.x0), rows = std::size_t(rect.y1 - rect.y0);
    const std::size_t row_values = columns * 2 + 6,
                      layer_values = row_values * rows + 10;  // padded, as images are
    const render::ConeMapView cones{sectors, bake::Address::wrap, ratios, apex, relaxed_ratios, 1, 0, {}};
    std::vector<std::uint16_t> fast(layer_values * 10, 0x7777), slow(fast);
    const bool fast_ok =
        render::detail::pack_cones(cones, width, rect, fast.data(), row_values, layer_values, true);
    const bool slow_ok =
        render::detail::pack_cones(cones, width, rect, slow.data(), row_values, layer_values, false);
    EXPECT_EQ(fast_ok, slow_ok) << "round " << round;
    if (slow_ok) {  // a refused map's bytes are never drawn (NaN meets min in another order)
      EXPECT_EQ(fast, slow) << "round " << round;
    }
    const std::size_t row_floats = columns + 3;
    std::vector<float> fast_heights(row_floats * rows, -7.0f), slow_heights(fast_heights);
    const bool fast_heights_ok =
        render::detail::pack_heights(heights, width, rect, fast_heights.data(), row_floats, true);
    const bool slow_heights_ok =
        render::detail::pack_heights(heights, width, rect, slow_heights.data(), row_floats, false);
    EXPECT_EQ(fast_heights_ok, slow_heights_ok) << "round " << round;
    EXPECT_EQ(std::memcmp(fast_heights.data(), slow_heights.data(), fast_heights.size() * sizeof(float)), 0);
    ++compared;
    refused += !slow_ok || !slow_heights_ok;
  }
  EXPECT_EQ(compared, 600);
  EXPECT_GT(refused, 60);  // the bad values land inside the rectangle often enough to test the checks
}

// The cone image's 16-bit encoding claims no more than the baked values: a ratio read back is at
// most the baked one (and at most 1) and loses at most a relative 2^-10 (all of it below 2^-14), an
// apex read back is at least the baked one and at most 3 / 65535 above; a 10% larger ratio or an
// apex 1e-4 lower is not what the encoding gives (so the test can tell).
TEST(MapPack, ConeEncodingIsConservativeAndTight) {
  std::mt19937 random(11);
  std::vector<float> ratios = {0.0f, 1e-9f, 1e-6f, 2e-3f, 0.25f, 0.999999f, 1.0f, 1.5f, 1e30f};
  for (int n = 0; n < 200000; ++n) {
    ratios.push_back(std::exp(std::uniform_real_distribution<float>(-12.0f, 0.5f)(random)));
  }
  long long above = 0, loose = 0;
  for (float ratio : ratios) {
    const float read = render::detail::decode_ratio(render::detail::encode_ratio(ratio));
    const double exact = std::min(double(ratio), 1.0);
    above += double(read) > exact;
    loose += exact >= 0x1p-14 ? double(read) < exact * (1.0 - 0x1p-10) : read != 0.0f;
  }
  EXPECT_EQ(above, 0);
  EXPECT_EQ(loose, 0);
  long long below = 0, high = 0;
  for (int n = 0; n <= 1000000; ++n) {
    const float apex =
        n <= 100000 ? float(n) / 100000.0f : std::uniform_real_distribution<float>(0.0f, 1.0f)(random);
    const double read = render::detail::decode_apex(render::detail::encode_apex(apex));
    below += read < double(apex);
    high += read > double(apex) + 3.0 / 65535.0;
  }
  EXPECT_EQ(below, 0);
  EXPECT_EQ(high, 0);
  EXPECT_LT(render::detail::decode_ratio(render::detail::encode_ratio(0.1f)), 0.11f);
  EXPECT_GT(render::detail::decode_apex(render::detail::encode_apex(0.5f)), 0.5f - 1e-4f);
}

}  // namespace
