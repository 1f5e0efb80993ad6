// tests/render/cpu_trace_test.cpp - the exact CPU trace and the image comparison (render/cpu_trace.cpp,
// render/compare.cpp).
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

#include "render/map_pack.h"
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

// The exact CPU intersection (cell walk + quadratic per cell) against a dense march: on random
// fields and rays it finds the march's crossing, never a later one, and its point is on the surface.
TEST(CpuTrace, FirstCrossingMatchesADenseMarchAndNeverSkipsAClip) {
  std::mt19937 random(11);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  long long rays = 0, agree = 0;
  for (int trial = 0; trial < 6; ++trial) {
    const int width = 5 + trial * 3, height = 7 + trial;
    const bake::Address address = trial % 2 == 0 ? bake::Address::wrap : bake::Address::clamp;
    const HeightField field = field_of(width, height, [&](int, int) { return unit(random); });
    const double tile = 1.0 + trial % 3;
    for (int r = 0; r < 200; ++r, ++rays) {
      const glm::dvec3 origin(unit(random) * tile, unit(random) * tile, 1.0);
      const double azimuth = unit(random) * 2.0 * std::numbers::pi, reach = 0.02 + 2.0 * unit(random);
      const glm::dvec3 descent(reach * std::cos(azimuth), reach * std::sin(azimuth), -1.0);
      const double exact = render::first_crossing(field, address, tile, origin, descent);
      auto gap = [&](double s) {
        const glm::dvec3 p = origin + s * descent;
        return p.z - render::bilinear_height(field, address, p.x, p.y);
      };
      auto outside = [&](double s) {
        const glm::dvec3 p = origin + s * descent;
        return p.x < 0.0 || p.x > tile || p.y < 0.0 || p.y > tile;
      };
      // march in steps of 1/512 texel of travel until the surface or the patch side
      const double step =
          1.0 / (std::max(std::abs(descent.x) * width, std::abs(descent.y) * height) * 512.0 + 1.0);
      double marched = 1.0;
      bool left = false;
      for (double s = 0.0; s <= 1.0; s += step) {
        if (gap(s) <= 0.0 || outside(s)) {
          marched = s;
          left = gap(s) > 0.0;
          break;
        }
      }
      if (left) {  // the march left the patch first: the walk must report a miss too, or an earlier hit
        EXPECT_TRUE(outside(exact) || exact <= marched) << "ray " << r;
        if (outside(exact)) ++agree;
        continue;
      }
      ASSERT_LE(exact, marched + 1e-12) << "the cell walk found a later crossing than the march, ray " << r;
      if (!outside(exact) && exact > 0.0 && exact < 1.0) {
        ASSERT_NEAR(gap(exact), 0.0, 1e-9) << "not on the surface, ray " << r;
      }
      if (marched - exact <= step) ++agree;
    }
  }
  // the march can skip a clip thinner than its step; on these fields that is rare
  EXPECT_GE(agree, rays * 99 / 100) << agree << " of " << rays;
}

TEST(CpuTrace, CompareCountsPixelsEitherFrameHitAndNeedsColourAndUv) {
  render::Frame frame, reference;
  frame.width = reference.width = 2;
  frame.height = reference.height = 1;
  frame.color = {10, 10, 10, 255, 0, 0, 0, 255};
  reference.color = {10, 10, 10, 255, 30, 30, 30, 255};
  frame.uv = {0.5f, 0.5f, 1.0f, 0, 0, 0};         // pixel 0 hit, pixel 1 off the relief
  reference.uv = {0.5f, 0.5f, 1.0f, 0, 0, 1.0f};  // the reference hit both
  const render::ImageError error = render::compare(frame, reference);
  EXPECT_EQ(error.pixels, 2);
  EXPECT_DOUBLE_EQ(error.max_error, 30.0);
  EXPECT_DOUBLE_EQ(error.rmse, std::sqrt(3 * 900.0 / 6));
  EXPECT_DOUBLE_EQ(error.fraction_over_10, 0.5);
  frame.uv.clear();  // read back without uv: an error, not a read past the end
  EXPECT_THROW(render::compare(frame, reference), render::RenderError);
}

TEST(CpuTrace, FindsAClipFarThinnerThanAnyMarchStep) {
  // one spike of height 1 on a floor of 0: the bilinear tent's tip is a clip ~0.002 texels long at
  // h = 0.999, which an eighth-texel march steps over
  HeightField field = constant_field(16, 0.0f);
  field.heights[std::size_t(8) * 16 + 8] = 1.0f;
  const double centre = 8.5 / 16.0, travel = 40.0 / 16.0;  // 40 texels of travel per unit of height
  const glm::dvec3 origin(centre - 0.001 * travel, centre, 1.0);
  const glm::dvec3 descent(travel, 0.0, -1.0);
  const double s = render::first_crossing(field, bake::Address::clamp, 1.0, origin, descent);
  const glm::dvec3 p = origin + s * descent;
  EXPECT_NEAR(p.x * 16.0, 8.5, 0.01);
  EXPECT_NEAR(p.z, render::bilinear_height(field, bake::Address::clamp, p.x, p.y), 1e-9);
}

}  // namespace
