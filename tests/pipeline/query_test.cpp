// tests/pipeline/query_test.cpp - height queries (pipeline/query.h) against the bilinear surface of the
// CPU's own heights: texel centres, edges, corners and across the wrap; normals from the surface's
// slopes; the choppy displacement as a fixed point of the displacement field; one make per time and
// nothing allocated by a repeated query.
#include "pipeline/query.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "pipeline/height_source.h"
#include "pipeline/scene.h"

namespace {

using namespace displace;

// Bilinear of a periodic W x H grid at texel coordinates (x, y) (centres at integers).
double periodic_bilinear(const std::vector<float>& grid, int width, int height, double x, double y) {
  const double fx = std::floor(x), fy = std::floor(y);
  auto at = [&](double i, double j) {
    const int row = int(i - height * std::floor(i / height)), column = int(j - width * std::floor(j / width));
    return double(grid[std::size_t(row) * std::size_t(width) + std::size_t(column)]);
  };
  const double tx = x - fx, ty = y - fy;
  const double top = at(fy, fx) + (at(fy, fx + 1) - at(fy, fx)) * tx;
  const double bottom = at(fy + 1, fx) + (at(fy + 1, fx + 1) - at(fy + 1, fx)) * tx;
  return top + (bottom - top) * ty;
}

pipeline::Scene query_scene(const char* name) {
  pipeline::Scene scene = pipeline::builtin_scene(name);
  scene.map_size = 64;
  scene.sim_backend = scene.bake_backend =
      pipeline::Backend::cpu;  // the CPU path (auto: the device on a GPU)
  return scene;
}

TEST(Query, EqualsTheBilinearSurfaceOfTheHeightsEverywhere) {
  for (const char* name : {"water", "calm", "ripples"}) {
    SCOPED_TRACE(name);
    const pipeline::Scene scene = query_scene(name);
    const double time = 1.25;
    pipeline::HeightSource source(pipeline::source_settings(scene),
                                  pipeline::scene_effects(scene) & ~unsigned(pipeline::effect_foam));
    pipeline::HeightFrame frame;
    source.make(time, 0, frame);
    ASSERT_EQ(frame.clamped, 0u);
    const std::vector<float> raw(frame.raw.begin(), frame.raw.end());
    pipeline::HeightQuery query(scene);
    const double patch = query.patch_metres();
    const int n = scene.map_size;
    // texel centres, edges between them, corners, and the same across the wrap
    std::vector<pipeline::QueryPoint> points;
    for (double i : {0.5, 1.0, 17.5, 31.0, 63.5, 64.0}) {
      for (double j : {0.5, 1.0, 40.25, 63.5, 64.0}) {
        for (double wrap : {0.0, -1.0, 2.0})
          points.push_back({(j / n + wrap) * patch, (i / n - wrap) * patch});
      }
    }
    pipeline::QueryResult result;
    query.query(points, time, result);
    ASSERT_EQ(result.height_m.size(), points.size());
    const sim::HeightMapping mapping = source.mapping();
    for (std::size_t k = 0; k < points.size(); ++k) {
      const double x = points[k].x / patch * n - 0.5, y = points[k].y / patch * n - 0.5;
      const double metres = periodic_bilinear(raw, n, n, x, y);
      EXPECT_NEAR(result.height_m[k], metres, 1e-5) << k;
      const double h = periodic_bilinear(frame.field.heights, n, n, x, y);
      EXPECT_NEAR(result.z[k], scene.depth_scale * (h - 1.0), 1e-6);
      EXPECT_NEAR(metres * mapping.scale + mapping.bias, h, 1e-5);
      EXPECT_NEAR(glm::length(result.normal[k]), 1.0f, 1e-5f);
    }
    // normals: inside a cell, the slopes of z over the renderer's world x and y (x = u / tile)
    const double step = 1e-4;  // patch widths, well inside one texel
    const pipeline::QueryPoint inside{(10.3 / n) * patch, (20.6 / n) * patch};
    const std::vector<pipeline::QueryPoint> around = {inside,
                                                      {inside.x + step * patch, inside.y},
                                                      {inside.x - step * patch, inside.y},
                                                      {inside.x, inside.y + step * patch},
                                                      {inside.x, inside.y - step * patch}};
    query.query(around, time, result);
    const double tile = scene.tile;
    const double dz_dx = (result.z[1] - result.z[2]) / (2.0 * step / tile);
    const double dz_dy = (result.z[3] - result.z[4]) / (2.0 * step / tile);
    const glm::dvec3 expected = glm::normalize(glm::dvec3(-dz_dx, -dz_dy, 1.0));
    EXPECT_NEAR(result.normal[0].x, expected.x, 2e-3);
    EXPECT_NEAR(result.normal[0].y, expected.y, 2e-3);
  }
}

TEST(Query, ChoppyDisplacementIsWhereTheWaterCameFrom) {
  const pipeline::Scene water = query_scene("water");
  pipeline::HeightQuery query(water);
  const double time = 3.0;
  std::vector<pipeline::QueryPoint> points;
  for (int i = 0; i < 64; ++i)
    points.push_back({(i + 0.5) / 64.0 * 200.0, (0.5 + (i * 7) % 64) / 64.0 * 200.0});
  pipeline::QueryResult result;
  query.query(points, time, result);
  // the displacement field D itself, to check p + D(p) = x with p = x - displacement
  sim::OceanParams params = water.ocean;
  params.size = water.map_size;
  sim::Ocean ocean(params);
  sim::OceanFrame frame;
  ocean.evaluate(time, sim::ocean_displacement, frame);
  double largest = 0.0, worst_residual = 0.0;
  for (std::size_t k = 0; k < points.size(); ++k) {
    const glm::dvec2 moved(result.displacement[k]);
    largest = std::max(largest, glm::length(moved));
    const double px = (points[k].x - moved.x) / 200.0 * 64.0 - 0.5,
                 py = (points[k].y - moved.y) / 200.0 * 64.0 - 0.5;
    const glm::dvec2 field(periodic_bilinear(frame.displacement_x, 64, 64, px, py),
                           periodic_bilinear(frame.displacement_y, 64, 64, px, py));
    worst_residual = std::max(worst_residual, glm::length(field - moved));
  }
  EXPECT_GT(largest, 0.1);          // metres: choppy water moves
  EXPECT_LT(worst_residual, 0.05);  // metres: a fixed point (within the resampling's settle, and folds)
  pipeline::HeightQuery calm(query_scene("calm"));
  calm.query(points, time, result);
  for (const glm::vec2& moved : result.displacement) EXPECT_EQ(moved, glm::vec2(0.0f));
}

TEST(Query, MakesHeightsOncePerTimeAndAllocatesNothingAgain) {
  pipeline::HeightQuery query(query_scene("water"));
  std::vector<pipeline::QueryPoint> points(1000, {12.0, 34.0});
  pipeline::QueryResult result;
  query.query(points, 2.0, result);
  const float* heights = result.height_m.data();
  const glm::vec3* normals = result.normal.data();
  query.query(points, 2.0, result);
  EXPECT_EQ(query.heights_made(), 1);
  EXPECT_EQ(result.height_m.data(), heights);
  EXPECT_EQ(result.normal.data(), normals);
  query.query(points, 2.5, result);
  EXPECT_EQ(query.heights_made(), 2);
  EXPECT_THROW(query.query(points, NAN, result), pipeline::SceneError);
  // the periodic surface repeats: a point and its image one patch on answer alike
  const std::vector<pipeline::QueryPoint> images = {{12.0, 34.0}, {212.0, -166.0}};
  query.query(images, 2.5, result);
  EXPECT_NEAR(result.height_m[0], result.height_m[1], 1e-5);
}

}  // namespace
