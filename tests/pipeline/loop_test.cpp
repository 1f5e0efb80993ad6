// tests/pipeline/loop_test.cpp - seamless loops ([ocean] loop_seconds): frames n and n + T fps of the
// frame pipeline are the same frame bit for bit, on the CPU and the device sim, and a frame halfway
// is not.
#include <gtest/gtest.h>

#include "pipeline/frame_pipeline.h"
#include "pipeline/scene.h"
#include "render/render.h"

namespace {

using namespace displace;

TEST(Loop, FrameZeroAndFrameTFpsAreTheSameFrame) {
  render::RendererOptions options;
  options.validate = true;
  render::Renderer renderer(options);
  for (pipeline::Backend sim : {pipeline::Backend::cpu, pipeline::Backend::device}) {
    SCOPED_TRACE(pipeline::backend_word(sim));
    pipeline::Scene scene = pipeline::builtin_scene("water");
    scene.map_size = 64;
    scene.camera.width = scene.camera.height = 48;
    scene.ocean.loop_seconds = 2.0;
    scene.fps = 30.0;
    scene.sim_backend = sim;
    scene.bake_backend = pipeline::Backend::cpu;
    ASSERT_EQ(pipeline::loop_frames(scene), 60);
    pipeline::FramePipeline frames(scene, renderer);
    const unsigned outputs = render::output_color | render::output_uv;
    render::Frame first, looped, halfway;
    frames.run(3, first, outputs);
    frames.run(63, looped, outputs);
    frames.run(33, halfway, outputs);
    EXPECT_EQ(first.color, looped.color);
    EXPECT_EQ(first.uv, looped.uv);
    EXPECT_NE(first.uv, halfway.uv);
  }
  // a loop that holds no whole number of frames leaves the frame times alone
  pipeline::Scene uneven = pipeline::builtin_scene("water");
  uneven.ocean.loop_seconds = 2.01;
  uneven.fps = 30.0;
  EXPECT_EQ(pipeline::loop_frames(uneven), 0);
  EXPECT_EQ(pipeline::frame_time(uneven, 70), uneven.start + 70.0 / 30.0);
  EXPECT_EQ(renderer.validation_messages(), 0);
}

}  // namespace
