// tests/render/pass_rows_test.cpp - the rows each pass of the unbounded plane draws (render/pass_rows.cpp)
// against every pixel's own class, computed as the fragment shader computes it (in float).
#include "render/pass_rows.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "render/render.h"
#include "render/shaders/config.h"

namespace {

using namespace displace;
using render::Camera;
using render::detail::PassRows;
using render::detail::RowRange;

enum class PixelClass { level_zero, coarser, sky };

// surface.frag.glsl's pixel_direction, the sky test and choose_level, in float
PixelClass classify(const Camera& camera, const Camera::PixelRays& rays, int px, int py, int levels,
                    int pinned, float texels_per_unit) {
  const glm::vec3 corner(rays.corner), along_x(rays.along_x), along_y(rays.along_y);
  const float x = float(px) + 0.5f, y = float(py) + 0.5f;
  const glm::vec3 through = corner + x * along_x + y * along_y;
  const glm::vec3 d = glm::normalize(through);
  if (camera.eye.z <= 0.0f || d.z >= 0.0f) return PixelClass::sky;
  int level = pinned;
  if (level < 0) {
    const float pixel_angle = glm::length(along_y) / glm::length(through);
    const float distance = camera.eye.z / -d.z;
    const float texels = distance * pixel_angle * texels_per_unit;
    const float detail = std::log2(std::max(texels, 1e-30f)) +
                         float(LEVEL_ANISOTROPY) * std::log2(-1.0f / d.z) + float(LEVEL_BIAS);
    level = int(std::clamp(std::floor(detail), 0.0f, float(levels)));
  }
  return std::clamp(level, 0, levels) > 0 ? PixelClass::coarser : PixelClass::level_zero;
}

struct Case {
  std::string name;
  Camera camera;
  int levels = 8;
  int pinned = -1;
  double texels_per_unit = 1024.0;
  bool tight = true;  // an upright camera: the ranges hold at most two rows more than their pixels'
};

Camera camera(glm::vec3 eye, glm::vec3 look_at, int width, int height, glm::vec3 up = {0.0f, 0.0f, 1.0f},
              float fov = 50.0f) {
  Camera c;
  c.eye = eye;
  c.look_at = look_at;
  c.up = up;
  c.fov_y_degrees = fov;
  c.width = width;
  c.height = height;
  return c;
}

std::vector<Case> cases() {
  const glm::vec3 sea_eye{0.3f, 0.2f, 0.08f}, sea_ahead{0.3f, 1.2f, 0.0f};
  std::vector<Case> all = {
      {"the sea", camera(sea_eye, sea_ahead, 256, 256)},
      {"the sea, wide", camera(sea_eye, sea_ahead, 331, 197)},
      {"the sea, tall", camera(sea_eye, sea_ahead, 64, 512)},
      {"the sea from a 4096 map", camera(sea_eye, sea_ahead, 320, 180), 12, -1, 8.0 * 4096.0},
      {"grazing", camera({0.5f, 0.5f, 0.002f}, {0.5f, 1.5f, 0.0f}, 200, 150)},
      {"a wide lens", camera(sea_eye, sea_ahead, 300, 200, {0.0f, 0.0f, 1.0f}, 120.0f)},
      {"looking down", camera({0.5f, 0.5f, 0.6f}, {0.5f, 0.55f, 0.0f}, 128, 128)},
      {"looking up", camera({0.5f, 0.5f, 0.1f}, {0.5f, 1.5f, 0.6f}, 128, 96)},
      {"below the plane", camera({0.5f, 0.5f, -0.1f}, {0.5f, 1.5f, -0.1f}, 96, 64)},
      {"pinned to level 0", camera(sea_eye, sea_ahead, 160, 120), 8, 0},
      {"pinned to level 3", camera(sea_eye, sea_ahead, 160, 120), 8, 3},
      {"no levels", camera(sea_eye, sea_ahead, 160, 120), 0},
  };
  Case rolled{"rolled", camera(sea_eye, sea_ahead, 256, 192, {0.5f, 0.0f, 1.0f})};
  rolled.tight = false;
  all.push_back(rolled);
  Case sideways{"sideways", camera(sea_eye, {1.3f, 0.4f, -0.02f}, 256, 192, {-0.3f, 0.4f, 1.0f})};
  sideways.tight = false;
  all.push_back(sideways);
  return all;
}

std::string range_text(RowRange r) {
  return r.empty() ? "empty" : "[" + std::to_string(r.begin) + ", " + std::to_string(r.end) + ")";
}

TEST(PassRows, EveryPixelLiesInItsPassesRowsAndUprightViewsWasteAtMostTwoRows) {
  for (const Case& c : cases()) {
    const Camera::PixelRays rays = c.camera.pixel_rays();
    const PassRows rows = render::detail::level_pass_rows(c.camera, c.levels, c.pinned, c.texels_per_unit);
    // the rows the pixels of each class hold (empty: none)
    RowRange seen[3];
    long count[3] = {0, 0, 0};
    for (int py = 0; py < c.camera.height; ++py)
      for (int px = 0; px < c.camera.width; ++px) {
        int k = int(classify(c.camera, rays, px, py, c.levels, c.pinned, float(c.texels_per_unit)));
        if (k == int(PixelClass::sky) && c.levels == 0) k = int(PixelClass::level_zero);  // one pass
        if (count[k]++ == 0) seen[k].begin = py;
        seen[k].end = py + 1;
      }
    const RowRange drawn[3] = {rows.level_zero, rows.coarser, rows.sky};
    const char* names[3] = {"level 0", "coarser levels", "sky"};
    for (int k = 0; k < 3; ++k) {
      const std::string what = c.name + ", " + names[k] + ": pixels in rows " + range_text(seen[k]) +
                               ", drawn " + range_text(drawn[k]);
      if (count[k] > 0) {
        EXPECT_LE(drawn[k].begin, seen[k].begin) << what;
        EXPECT_GE(drawn[k].end, seen[k].end) << what;
      }
      if (c.tight) {
        if (count[k] == 0) {
          EXPECT_TRUE(drawn[k].empty()) << what;
        } else {
          EXPECT_GE(drawn[k].begin, seen[k].begin - 2) << what;
          EXPECT_LE(drawn[k].end, seen[k].end + 2) << what;
        }
      }
    }
  }
}

// The views above hold pixels of each kind, so that the containment is tested on every pass.
TEST(PassRows, TheViewsHoldEveryKindOfPixel) {
  const std::vector<Case> all = cases();
  const Case& sea = all.front();
  const Camera::PixelRays rays = sea.camera.pixel_rays();
  long count[3] = {0, 0, 0};
  for (int py = 0; py < sea.camera.height; ++py)
    for (int px = 0; px < sea.camera.width; ++px)
      ++count[int(classify(sea.camera, rays, px, py, sea.levels, sea.pinned, float(sea.texels_per_unit)))];
  EXPECT_GT(count[0], 1000);
  EXPECT_GT(count[1], 1000);
  EXPECT_GT(count[2], 1000);
  // and the passes share few rows: the point of drawing each over its own
  const PassRows rows =
      render::detail::level_pass_rows(sea.camera, sea.levels, sea.pinned, sea.texels_per_unit);
  EXPECT_LE(rows.coarser.end - rows.level_zero.begin, 8)
      << range_text(rows.coarser) << " " << range_text(rows.level_zero);
  EXPECT_LE(rows.sky.end - rows.coarser.begin, 8) << range_text(rows.sky) << " " << range_text(rows.coarser);
}

}  // namespace
