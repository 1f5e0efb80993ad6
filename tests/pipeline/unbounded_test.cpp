// tests/pipeline/unbounded_test.cpp - the sea to the horizon ([render] extent = "unbounded"): every
// pixel whose ray points below the horizon hits the relief, in the water scenes' default views and
// from a camera just above the crests looking at the horizon; the sky above is not one colour; the
// scenes that are not water keep their patch.
#include <gtest/gtest.h>

#include <set>
#include <string>
#include <tuple>

#include "pipeline/frame_pipeline.h"
#include "pipeline/scene.h"
#include "render/render.h"

namespace {

using namespace displace;

struct Census {
  long long below = 0, below_hit = 0, above = 0, above_hit = 0;
  std::set<std::tuple<int, int, int>> sky_colours;
};

// Pixels whose ray is clearly below (above) the horizon, and how many of them hit.
Census census(const render::Camera& camera, const render::Frame& frame) {
  Census c;
  for (int y = 0; y < frame.height; ++y) {
    for (int x = 0; x < frame.width; ++x) {
      const double dz = camera.pixel_ray(x + 0.5, y + 0.5).direction.z;
      const std::size_t p = std::size_t(y) * std::size_t(frame.width) + std::size_t(x);
      const bool hit = frame.uv[3 * p + 2] > 0.5f;
      if (dz < -1e-4) {
        ++c.below;
        c.below_hit += hit;
      } else if (dz > 1e-4) {
        ++c.above;
        c.above_hit += hit;
        c.sky_colours.insert({frame.color[4 * p], frame.color[4 * p + 1], frame.color[4 * p + 2]});
      }
    }
  }
  return c;
}

TEST(Unbounded, EveryPixelBelowTheHorizonHitsTheSea) {
  render::RendererOptions options;
  options.validate = true;
  render::Renderer renderer(options);
  struct Case {
    const char* scene;
    bool low_camera;  // just above the crests (2 m over a 200 m patch), looking at the horizon
  };
  for (const Case& c :
       {Case{"water", false}, Case{"calm", false}, Case{"ripples", false}, Case{"water", true}}) {
    SCOPED_TRACE(std::string(c.scene) + (c.low_camera ? ", low camera" : ""));
    pipeline::Scene scene = pipeline::builtin_scene(c.scene);
    ASSERT_TRUE(scene.unbounded);
    scene.map_size = 64;
    scene.camera.width = 96;
    scene.camera.height = 64;
    if (c.low_camera) {
      scene.camera.eye = {0.3f, 0.2f, 0.01f};
      scene.camera.look_at = {0.9f, 2.0f, 0.01f};
    }
    pipeline::FramePipeline frames(scene, renderer);
    render::Frame frame;
    frames.run(0, frame, render::output_color | render::output_uv);
    const Census counted = census(pipeline::scene_view(scene, scene.start).camera, frame);
    EXPECT_GT(counted.below, 0);
    EXPECT_EQ(counted.below_hit, counted.below);
    if (counted.above > 0) {
      EXPECT_EQ(counted.above_hit, 0);
      EXPECT_GT(counted.sky_colours.size(), 1u);
    }
  }
  EXPECT_EQ(renderer.validation_messages(), 0);
}

TEST(Unbounded, OnlyWhereThePlaneCanBeTiled) {
  for (const char* name : {"bricks", "cliff", "ocean"}) EXPECT_FALSE(pipeline::builtin_scene(name).unbounded);
  const pipeline::Scene water = pipeline::builtin_scene("water");
  EXPECT_THROW(pipeline::apply_scene(water, "[render]\nmethod = \"reference\"\n", "test"),
               pipeline::SceneError);
  EXPECT_THROW(pipeline::apply_scene(water, "[render]\naddress = \"clamp\"\n", "test"), pipeline::SceneError);
  EXPECT_THROW(pipeline::apply_scene(water, "[render]\nsurface = \"sphere\"\n", "test"),
               pipeline::SceneError);
  EXPECT_NO_THROW(
      pipeline::apply_scene(water, "[render]\nextent = \"patch\"\nmethod = \"reference\"\n", "test"));
  const pipeline::Scene again = pipeline::parse_scene(pipeline::scene_toml(water), "again");
  EXPECT_TRUE(again.unbounded);
}

}  // namespace
