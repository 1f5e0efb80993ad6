// tests/pipeline/pipeline_checks.h - what the pipeline tests share: small scenes and an injected clock.
// Moved from tests/pipeline_test.cpp; functions are inline, in the anonymous namespace the tests use.
#pragma once

#include <gtest/gtest.h>
#include <sched.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <set>
#include <string>
#include <string_view>
#include <thread>

#include "pipeline/frame_pipeline.h"
#include "pipeline/scene.h"
#include "pipeline/thread_pinning.h"
#include "render/render.h"
#include "tests/render_fixtures.h"

namespace {

using namespace displace;
using displace::testing::shared_renderer;
using pipeline::FramePipeline;
using pipeline::FrameRecord;
using pipeline::Scene;
using pipeline::SceneError;

// A small scene for tests: map_size texels, size x size pixels, an oblique camera.
inline Scene small_scene(const char* builtin, int map_size, int pixels) {
  Scene scene = pipeline::builtin_scene(builtin);
  scene.map_size = map_size;
  scene.camera.width = scene.camera.height = pixels;
  scene.camera.eye = {0.5f, -0.3f, 0.6f};
  scene.camera.look_at = {0.5f, 0.5f, -0.05f};
  scene.camera.fov_y_degrees = 30.0f;
  // the CPU path, which these tests look into (on a GPU `auto` is the device; the device path's own
  // tests name it)
  scene.sim_backend = scene.bake_backend = pipeline::Backend::cpu;
  return scene;
}

inline std::string error_of(const std::string& text) {
  try {
    pipeline::parse_scene(text, "scene.toml");
  } catch (const SceneError& error) {
    return error.what();
  }
  return "(accepted)";
}

}  // namespace
