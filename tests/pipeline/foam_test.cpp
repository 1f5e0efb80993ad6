// tests/pipeline/foam_test.cpp - the foam controls ([material] foam_coverage, foam_intensity,
// foam_color): intensity 0 draws what no foam draws, a higher coverage foams more texels, and the
// colour reaches the picture.
#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>

#include "pipeline/frame_pipeline.h"
#include "pipeline/scene.h"
#include "render/render.h"

namespace {

using namespace displace;

render::Renderer& foam_renderer() {
  static render::Renderer renderer([] {
    render::RendererOptions options;
    options.validate = true;
    return options;
  }());
  return renderer;
}

pipeline::Scene foam_scene() {
  pipeline::Scene scene = pipeline::builtin_scene("water");
  scene.map_size = 64;
  scene.camera.width = scene.camera.height = 64;
  scene.sim_backend = scene.bake_backend =
      pipeline::Backend::cpu;  // the CPU's foam (auto: the device on a GPU)
  return scene;
}

render::Frame frame_of(const pipeline::Scene& scene) {
  pipeline::FramePipeline frames(scene, foam_renderer());
  render::Frame frame;
  frames.run(0, frame, render::output_color);
  return frame;
}

TEST(Foam, ControlsReachTheMapAndThePicture) {
  pipeline::Scene scene = foam_scene();
  ASSERT_TRUE(scene.foam);
  // coverage: the foam map covers more as the threshold rises
  double covered[2] = {};
  for (int n = 0; n < 2; ++n) {
    scene.foam_coverage = n == 0 ? 0.85f : 1.1f;
    pipeline::HeightSource source(pipeline::source_settings(scene), pipeline::scene_effects(scene));
    pipeline::HeightFrame heights;
    source.make(0.0, 0, heights);
    covered[n] = std::accumulate(heights.foam.begin(), heights.foam.end(), 0.0);
  }
  EXPECT_GT(covered[1], 2.0 * covered[0]);
  EXPECT_GT(covered[0], 0.0);

  // intensity 0 draws the sea without foam
  scene.foam_coverage = 1.1f;
  pipeline::Scene hidden = scene;
  hidden.foam_intensity = 0.0f;
  pipeline::Scene none = scene;
  none.foam = false;
  EXPECT_EQ(frame_of(hidden).color, frame_of(none).color);
  // and a red foam makes the foamed sea redder than a white one
  pipeline::Scene red = scene;
  red.foam_color = {1.0f, 0.0f, 0.0f};
  const render::Frame white_frame = frame_of(scene), red_frame = frame_of(red);
  long long redder = 0;
  for (std::size_t p = 0; p < red_frame.color.size(); p += 4) {
    redder += red_frame.color[p] >= white_frame.color[p] && red_frame.color[p + 2] < white_frame.color[p + 2];
  }
  EXPECT_GT(redder, 0);
  EXPECT_EQ(foam_renderer().validation_messages(), 0);
}

TEST(Foam, KeysAreCheckedAndKept) {
  const pipeline::Scene scene = pipeline::apply_scene(
      pipeline::builtin_scene("water"),
      "[material]\nfoam_coverage = 1.05\nfoam_intensity = 0.5\nfoam_color = [1.0, 0.9, 0.8]\n", "test");
  EXPECT_FLOAT_EQ(scene.foam_coverage, 1.05f);
  EXPECT_FLOAT_EQ(scene.foam_intensity, 0.5f);
  const pipeline::Scene again = pipeline::parse_scene(pipeline::scene_toml(scene), "again");
  EXPECT_FLOAT_EQ(again.foam_coverage, 1.05f);
  EXPECT_FLOAT_EQ(again.foam_color.g, 0.9f);
  EXPECT_THROW(pipeline::apply_scene(scene, "[material]\nfoam_intensity = 2\n", "test"),
               pipeline::SceneError);
  EXPECT_THROW(pipeline::apply_scene(scene, "[material]\nfoam_color = [1, -1, 0]\n", "test"),
               pipeline::SceneError);
  EXPECT_THROW(pipeline::apply_scene(scene, "[material]\nfoam_coverage = 3\n", "test"), pipeline::SceneError);
}

}  // namespace
