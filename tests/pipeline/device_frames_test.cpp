// tests/pipeline/device_frames_test.cpp - frames of the device path (pipeline::FramePipeline with
// [backend] sim = "device") against the CPU path's: the same hits within a texel on the water scenes,
// no validation messages, nothing allocated after warm-up.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numeric>
#include <string>

#include "pipeline/frame_pipeline.h"
#include "pipeline/scene.h"
#include "render/render.h"
#include "render/testing.h"

namespace {

using namespace displace;

render::Renderer& frames_renderer() {
  static render::Renderer renderer = [] {
    render::RendererOptions options;
    options.validate = true;
    render::Renderer made(options);
    render::testing::hold_async_work(made);  // lagged bands run as late as a GPU's other queue may run them
    return made;
  }();
  return renderer;
}

pipeline::Scene small_scene(const std::string& name, pipeline::Backend sim,
                            pipeline::Backend bake = pipeline::Backend::cpu) {
  pipeline::Scene scene = pipeline::builtin_scene(name);
  scene.map_size = 128;
  scene.camera.width = scene.camera.height = 96;
  scene.sim_backend = sim;
  scene.bake_backend = bake;
  // the patch: near the unbounded sea's horizon rays nearly parallel to it end where their 32 steps
  // run out, which the slightest change of a height moves by many texels
  scene.unbounded = false;
  return scene;
}

// Share of pixels where both frames hit within one texel of each other (or both miss).
double agreeing_share(const render::Frame& a, const render::Frame& b, int map_size) {
  const std::size_t pixels = a.uv.size() / 3;
  std::size_t agree = 0;
  for (std::size_t p = 0; p < pixels; ++p) {
    const bool hit_a = a.uv[3 * p + 2] > 0.5f, hit_b = b.uv[3 * p + 2] > 0.5f;
    if (!hit_a && !hit_b) {
      ++agree;
      continue;
    }
    if (hit_a != hit_b) continue;
    const double du = double(a.uv[3 * p] - b.uv[3 * p]) * map_size;
    const double dv = double(a.uv[3 * p + 1] - b.uv[3 * p + 1]) * map_size;
    if (std::hypot(du, dv) <= 1.0) ++agree;
  }
  return double(agree) / double(pixels);
}

TEST(DeviceFrames, HitWithinATexelOfTheCpuPathsOnTheWaterScenes) {
  render::Renderer& renderer = frames_renderer();
  for (const char* name : {"water", "calm", "ripples"}) {
    SCOPED_TRACE(name);
    render::Frame cpu_frame, device_frame;
    const pipeline::Scene cpu_scene = small_scene(name, pipeline::Backend::cpu);
    for (long long index : {0LL, 90LL}) {
      SCOPED_TRACE("frame " + std::to_string(index));
      unsigned cpu_effects = 0;
      double cpu_loop_error = 0.0;
      {
        pipeline::FramePipeline cpu(cpu_scene, renderer);
        const pipeline::FrameRecord record = cpu.run(index, cpu_frame, render::output_uv);
        EXPECT_FALSE(record.sim_on_device);
        cpu_effects = record.effects;
        cpu_loop_error = cpu.loop_error();
      }
      // the sim on the device (the cones baked on the CPU from its heights), then the bake there too
      for (pipeline::Backend bake : {pipeline::Backend::cpu, pipeline::Backend::device}) {
        SCOPED_TRACE(std::string("bake on the ") + pipeline::backend_word(bake));
        pipeline::FramePipeline device(small_scene(name, pipeline::Backend::device, bake), renderer);
        const pipeline::FrameRecord record = device.run(index, device_frame, render::output_uv);
        EXPECT_TRUE(record.sim_on_device);
        EXPECT_EQ(record.bake_on_device, bake == pipeline::Backend::device);
        // what the CPU's sim would report, without one (the device path makes none)
        EXPECT_EQ(record.effects, cpu_effects);
        EXPECT_EQ(device.loop_error(), cpu_loop_error);
        EXPECT_GE(agreeing_share(cpu_frame, device_frame, cpu_scene.map_size), 0.999);
      }
    }
  }
  EXPECT_EQ(renderer.validation_messages(), 0);
}

// The scene's first pass reaches the device bake: rings of radius 2 hit where the search does, in
// fewer fetches (their ratios are larger on the ocean), and a shape the kernels refuse is refused
// before anything is recorded.
TEST(DeviceFrames, TheScenesFirstPassReachesTheDeviceBake) {
  render::Renderer& renderer = frames_renderer();
  pipeline::Scene scene = small_scene("water", pipeline::Backend::device, pipeline::Backend::device);
  scene.bake_work = 0;  // the first pass alone
  render::Frame search_frame, rings_frame, group_frame;
  const unsigned outputs = render::output_uv | render::output_fetches;
  scene.device_first_pass = {4, 0};
  pipeline::FramePipeline(scene, renderer).run(0, search_frame, outputs);
  scene.device_first_pass = {4, 2};
  pipeline::FramePipeline(scene, renderer).run(0, rings_frame, outputs);
  EXPECT_GE(agreeing_share(search_frame, rings_frame, scene.map_size), 0.999);
  const auto fetches = [](const render::Frame& frame) {
    return std::accumulate(frame.fetches.begin(), frame.fetches.end(), 0.0);
  };
  std::printf("fetches: search's first pass %.0f, rings 2 %.0f\n", fetches(search_frame),
              fetches(rings_frame));
  EXPECT_LT(fetches(rings_frame), fetches(search_frame));
  // the group's first pass: its own maps (other fetches), the same hits
  scene.device_first_pass = {4, 0, true};
  pipeline::FramePipeline(scene, renderer).run(0, group_frame, outputs);
  EXPECT_GE(agreeing_share(search_frame, group_frame, scene.map_size), 0.999);
  std::printf("fetches: the group's first pass %.0f\n", fetches(group_frame));
  EXPECT_NE(fetches(group_frame), fetches(search_frame));
  for (const bake::DeviceFirstPass first_pass :
       {bake::DeviceFirstPass{0, 1}, bake::DeviceFirstPass{4, 9}, bake::DeviceFirstPass{4, 1, true}}) {
    scene.device_first_pass = first_pass;
    EXPECT_THROW(pipeline::FramePipeline(scene, renderer), pipeline::SceneError);
  }
  EXPECT_EQ(renderer.validation_messages(), 0);
}

// The device path checks the source's size as the CPU's sim does.
TEST(DeviceFrames, RefuseAMapSizeNoSimTakes) {
  render::Renderer& renderer = frames_renderer();
  for (int size : {pipeline::min_map_size / 2, pipeline::max_map_size * 2}) {
    pipeline::Scene scene = small_scene("water", pipeline::Backend::device, pipeline::Backend::device);
    scene.map_size = size;
    try {
      pipeline::FramePipeline device(scene, renderer);
      ADD_FAILURE() << "a map of " << size << " was taken";
    } catch (const pipeline::SceneError& error) {
      EXPECT_NE(std::string(error.what()).find("map_size must be between"), std::string::npos)
          << error.what();
    }
  }
}

TEST(DeviceFrames, AllocateNothingAfterWarmUp) {
  render::Renderer& renderer = frames_renderer();
  pipeline::FramePipeline device(small_scene("water", pipeline::Backend::device, pipeline::Backend::device),
                                 renderer);
  render::Frame frame;
  for (long long index = 0; index < 2; ++index) device.run(index, frame, render::output_color);
  const long long allocations = renderer.memory_allocations();
  for (long long index = 2; index < 6; ++index) {
    const pipeline::FrameRecord record = device.run(index, frame, render::output_color);
    EXPECT_EQ(record.ffts, 6);  // heights, the choppy displacement, the foam's Jacobian
    EXPECT_TRUE(record.bake_on_device);
  }
  EXPECT_EQ(renderer.memory_allocations(), allocations);
  EXPECT_EQ(renderer.validation_messages(), 0);
}

// Lagged cone maps on the device path (real time, `cone_lag_frames`): each frame reports the age of
// the map it samples (a whole map on frame 0, then one begun every N frames and served from its
// N-th) and how far its apexes were raised; nothing is allocated once every frame slot ran a frame
// (each slot's readback is made on its first; run alone, the test's renderer has none). What the maps
// hold is DeviceCones.LaggedMapsAreOldMapsRaisedAndHoldForEachFramesHeights.
TEST(DeviceFrames, LaggedConeMapsReportTheirAgeAndLift) {
  render::Renderer& renderer = frames_renderer();
  pipeline::Scene scene = small_scene("water", pipeline::Backend::device, pipeline::Backend::device);
  scene.frame_ms = 0.0;  // real time, where lagged maps apply
  scene.cone_lag_frames = 2;
  pipeline::FramePipeline device(scene, renderer);
  render::Frame frame;
  long long allocations = 0;
  int lifted = 0;
  for (long long n = 0; n < 9; ++n) {
    const pipeline::FrameRecord record = device.run(n, frame, render::output_color);
    if (n == render::frames_in_flight - 1) allocations = renderer.memory_allocations();
    const long long begun = n < 3 ? 0 : 1 + 2 * ((n - 3) / 2);
    EXPECT_EQ(record.cone_lag, n - begun) << "frame " << n;
    EXPECT_GE(record.cone_lift, 0.0f) << "frame " << n;
    if (record.cone_lag == 0) {
      EXPECT_EQ(record.cone_lift, 0.0f) << "frame " << n;
    }
    if (record.cone_lift > 0.0f) ++lifted;
  }
  EXPECT_GT(lifted, 0);  // the sea rises somewhere between a map's frame and the frames it serves
  EXPECT_EQ(renderer.memory_allocations(), allocations);
  EXPECT_EQ(renderer.validation_messages(), 0);
}

// Maps made ahead (Scene::cone_ahead, a lag of 1): each frame bakes the next frame's map beside its
// draw from heights simulated at the next frame's time and simulates its own after that, so every
// frame from the second on samples a map of its own heights, one frame old, raised by a lift of
// about 0 (the same sim at the same time; plain lag 1 raises by the sea's rise over a frame), and
// hits where the frames with their own maps (no lag) hit. Two sims a frame; refused where it cannot apply.
TEST(DeviceFrames, MapsMadeAheadAreEachFramesOwnHeights) {
  render::Renderer& renderer = frames_renderer();
  pipeline::Scene scene = small_scene("water", pipeline::Backend::device, pipeline::Backend::device);
  scene.frame_ms = 0.0;  // real time, where lagged maps apply
  pipeline::Scene lagged_scene = scene, ahead_scene = scene;
  lagged_scene.cone_lag_frames = ahead_scene.cone_lag_frames = 1;
  ahead_scene.cone_ahead = true;
  // one pipeline at a time: a renderer samples one DeviceSim's heights
  std::vector<render::Frame> own_frames(6);
  {
    pipeline::FramePipeline own(scene, renderer);
    for (long long n = 0; n < 6; ++n) own.run(n, own_frames[std::size_t(n)], render::output_uv);
  }
  float lagged_lift = 0.0f;
  {
    pipeline::FramePipeline lagged(lagged_scene, renderer);
    render::Frame frame;
    for (long long n = 0; n < 6; ++n)
      lagged_lift = std::max(lagged_lift, lagged.run(n, frame, render::output_uv).cone_lift);
  }
  pipeline::FramePipeline ahead(ahead_scene, renderer);
  render::Frame ahead_frame;
  for (long long n = 0; n < 6; ++n) {
    SCOPED_TRACE("frame " + std::to_string(n));
    const pipeline::FrameRecord record = ahead.run(n, ahead_frame, render::output_uv);
    EXPECT_EQ(record.ffts, 12);  // the next frame's heights and this one's, 6 FFTs each
    if (n > 0) {
      EXPECT_EQ(record.cone_lag, 1);
      EXPECT_LE(record.cone_lift, 1e-5f);
    }
    EXPECT_GE(agreeing_share(own_frames[std::size_t(n)], ahead_frame, scene.map_size), 0.999);
  }
  EXPECT_GT(lagged_lift, 1e-3f);
  for (const auto& [lag, sim] :
       {std::pair{2, pipeline::Backend::device}, std::pair{1, pipeline::Backend::cpu}}) {
    pipeline::Scene refused = ahead_scene;
    refused.cone_lag_frames = lag;
    refused.sim_backend = sim;
    EXPECT_THROW(pipeline::FramePipeline(refused, renderer), pipeline::SceneError);
  }
  EXPECT_EQ(renderer.validation_messages(), 0);
}

}  // namespace
