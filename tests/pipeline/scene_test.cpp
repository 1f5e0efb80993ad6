// tests/pipeline/scene_test.cpp - scene files (pipeline/scene.cpp).
#include "pipeline/scene.h"

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
#include <numbers>
#include <set>
#include <string>
#include <string_view>
#include <thread>

#include "pipeline/frame_pipeline.h"
#include "pipeline/thread_pinning.h"
#include "render/render.h"
#include "tests/pipeline/pipeline_checks.h"
#include "tests/render_fixtures.h"

namespace {

using namespace displace;
using displace::testing::shared_renderer;
using pipeline::FramePipeline;
using pipeline::FrameRecord;
using pipeline::Scene;
using pipeline::SceneError;

TEST(Scene, EveryKeyRoundTripsThroughTheTomlItPrints) {
  for (const std::string& name : pipeline::builtin_scene_names()) {
    Scene scene = pipeline::builtin_scene(name);
    scene.keyframes = {{0.0, {0.5f, -0.4f, 0.5f}, {0.5f, 0.5f, 0.0f}},
                       {2.0, {0.2f, -0.4f, 0.6f}, {0.5f, 0.4f, 0.0f}}};
    scene.frame_ms = 16.0;
    scene.bake_work = 5000;
    scene.cone_lag_frames = 3;
    scene.cone_ahead = true;
    scene.device_first_pass = {2, 3, true};
    const std::string text = pipeline::scene_toml(scene);
    const Scene back = pipeline::parse_scene(text, name);
    EXPECT_EQ(pipeline::scene_toml(back), text) << name;
    EXPECT_TRUE(back.device_first_pass.group) << name;
    EXPECT_TRUE(back.cone_ahead) << name;
  }
}

// The group's first pass has no rings: turned on without a ring radius, it takes none (the default
// first pass's rings would make the bake refuse it); with one, both stay for the bake to refuse.
TEST(Scene, TheGroupsFirstPassTakesNoRingsUnlessGiven) {
  const Scene base = pipeline::builtin_scene("water");
  EXPECT_EQ(base.device_first_pass.ring_radius, bake::default_first_pass_rings);
  const Scene group = pipeline::apply_scene(base, "[backend]\ndevice_group = true\n", "group.toml");
  EXPECT_TRUE(group.device_first_pass.group);
  EXPECT_EQ(group.device_first_pass.ring_radius, 0);
  const Scene both =
      pipeline::apply_scene(base, "[backend]\ndevice_group = true\ndevice_rings = 1\n", "both.toml");
  EXPECT_EQ(both.device_first_pass.ring_radius, 1);
  const Scene after = pipeline::apply_scene(group, "[backend]\ndevice_window = 2\n", "window.toml");
  EXPECT_EQ(after.device_first_pass.ring_radius, 0);  // a later file that leaves the group on
}

TEST(Scene, BadFilesGetOneErrorNamingFileLineAndKey) {
  EXPECT_EQ(error_of("[render]\nsteps = 0\n"), "scene.toml:2: render.steps: must be in [1, 4096]");
  EXPECT_EQ(
      error_of("[render]\nmethod = \"magic\"\n").rfind("scene.toml:2: render.method: must be one of bump", 0),
      0u);
  EXPECT_EQ(error_of("[ocean]\nwindspeed = 3\n").rfind("scene.toml:2: ocean.windspeed: unknown key", 0), 0u);
  EXPECT_EQ(error_of("colour = 1\n").rfind("scene.toml:1: colour: unknown key", 0), 0u);
  EXPECT_EQ(error_of("[source]\nkind = \"lava\"\n"),
            "scene.toml:2: source.kind: 'lava' is not one of ocean, sinusoids, bricks, cliff, image");
  EXPECT_EQ(error_of("[source]\nmap_size = 255\n"),
            "scene.toml:2: source.map_size: must be even for the ocean");
  EXPECT_EQ(error_of("[time]\nfps = \"fast\"\n"), "scene.toml:2: time.fps: must be a number");
  EXPECT_EQ(error_of("[camera]\neye = [1, 2]\n"),
            "scene.toml:2: camera.eye: must be an array of 3 numbers [x, y, z]");
  EXPECT_EQ(error_of("[render]\nsize = [0, 10]\n"),
            "scene.toml:2: render.size: must be between [1, 1] and [16384, 16384]");
  EXPECT_EQ(error_of("[render]\nshadows = 1\n"), "scene.toml:2: render.shadows: must be true or false");
  EXPECT_EQ(error_of("[render]\nmethod = \"relaxed\"\nsurface = \"sphere\"\n"),
            "scene.toml:3: render.surface: render.method relaxed does not render on sphere");
  EXPECT_EQ(error_of("[camera]\nkeyframes = [{time = 1, eye = [0, 0, 1], look_at = [0, 0, 0]}, "
                     "{time = 1, eye = [0, 0, 1], look_at = [0, 0, 0]}]\n")
                .rfind("scene.toml:2: camera.keyframes: times must increase", 0),
            0u);
  EXPECT_EQ(error_of("[camera]\neye = [0.5, 0.5, 0.5]\nlook_at = [0.5, 0.5, 0.5]\n")
                .rfind("scene.toml:1: camera:", 0),
            0u);
  EXPECT_EQ(error_of("[render\nsteps = 3\n").rfind("scene.toml:1: ", 0), 0u);  // malformed
  EXPECT_EQ(error_of("render = 3\n"), "scene.toml:1: render: must be a table ([render])");
  try {
    pipeline::read_scene_file("/nonexistent/scene.toml");
    ADD_FAILURE() << "a missing file was read";
  } catch (const SceneError& error) {
    EXPECT_EQ(std::string(error.what()), "/nonexistent/scene.toml: cannot open the scene file");
  }
  EXPECT_THROW(pipeline::builtin_scene("lava"), SceneError);
}

// Every key, with a value of the wrong type and one out of range: one error naming that key.
TEST(Scene, EveryKeyRefusesBadValuesNamingTheKey) {
  const std::pair<const char*, std::vector<const char*>> keys[] = {
      {"source.kind", {"3", "\"lava\""}},
      {"source.map_size", {"\"big\"", "1", "9000"}},
      {"source.seed", {"-1", "1.5"}},
      {"ocean.patch_size", {"\"a\"", "0"}},
      {"ocean.spectrum", {"1", "\"pink\""}},
      {"ocean.wind_speed", {"false", "1000"}},
      {"ocean.wind_direction", {"\"n\"", "400"}},
      {"ocean.choppiness", {"[1]", "-1"}},
      {"ocean.seed", {"\"x\""}},
      {"ocean.depth", {"\"deep\"", "0", "1e5"}},
      {"ocean.spreading_model", {"1", "\"cos4\""}},
      {"ocean.beaufort", {"13", "-1", "6.5"}},
      {"ocean.hs", {"\"big\"", "0", "60"}},
      {"ocean.tp", {"-1", "100"}},
      {"swell.hs", {"\"a\"", "-1", "0.0001"}},
      {"swell.tp", {"0", "61"}},
      {"swell.direction", {"400"}},
      {"swell.spreading", {"-1", "101"}},
      {"sinusoids.wave_count", {"1.5", "0"}},
      {"sinusoids.patch_size", {"true", "0"}},
      {"sinusoids.steepness", {"\"s\"", "2"}},
      {"sinusoids.seed", {"\"x\""}},
      {"material.kind", {"1", "\"glass\""}},
      {"material.foam", {"1"}},
      {"material.albedo", {"1"}},
      {"ocean.size", {"7", "\"big\"", "0"}},
      {"camera.eye", {"1", "[1, 2]", "[\"a\", 1, 2]"}},
      {"camera.look_at", {"[1, 2, 3, 4]"}},
      {"camera.up", {"\"up\""}},
      {"camera.fov_y", {"\"wide\"", "180"}},
      {"camera.keyframes", {"3", "[1, 2]"}},
      {"render.method", {"1", "\"magic\""}},
      {"render.steps", {"\"many\"", "0", "5000"}},
      {"render.refine", {"-1", "65"}},
      {"render.size", {"1", "[0, 10]", "[10]"}},
      {"render.surface", {"\"torus\""}},
      {"render.shadows", {"\"yes\""}},
      {"render.light", {"[0, 0, 0]", "2"}},
      {"render.depth_scale", {"0", "11"}},
      {"render.tile", {"0", "65"}},
      {"time.start", {"\"now\"", "1e13"}},
      {"time.fps", {"0", "1e5"}},
      {"budget.frame_ms", {"-1", "\"fast\""}},
      {"budget.bake_work", {"-2", "0.5"}},
      {"budget.tolerance", {"2", "\"loose\""}},
      {"budget.cone_lag_frames", {"-1", "65", "1.5"}},
      {"budget.cone_ahead", {"1", "\"yes\""}},
      {"backend.sim", {"1", "\"gpu\""}},
      {"backend.bake", {"\"gpu\""}},
      {"backend.device_rings", {"-1", "9", "\"two\""}},
      {"backend.device_group", {"1", "\"yes\""}},
      {"backend.device_window", {"0", "5", "1.5"}},
      {"name", {"1"}}};
  for (const auto& [key, values] : keys) {
    const std::string path = key;
    const std::size_t dot = path.find('.');
    for (const char* value : values) {
      // appended piece by piece: GCC 12 warns (-Wrestrict, a false positive) on "[" + std::string
      std::string text;
      if (dot != std::string::npos) text.append("[").append(path, 0, dot).append("]\n");
      text.append(path, dot == std::string::npos ? 0 : dot + 1).append(" = ").append(value).append("\n");
      const std::string error = error_of(text);
      EXPECT_NE(error.find(key), std::string::npos) << text << " -> " << error;
      EXPECT_EQ(error.rfind("scene.toml:", 0), 0u) << text << " -> " << error;
    }
  }
}

// The sea state comes one way in a table - the wind (wind_speed, fetch), the Beaufort force, or hs and tp -
// and contradictions are refused with one line naming the key.
TEST(Scene, SeaStateKeysOneWayAtATime) {
  EXPECT_EQ(
      error_of("[ocean]\nbeaufort = 6\nwind_speed = 10\n"),
      "scene.toml:2: ocean.beaufort: gives the wind speed and a fully developed sea: not with wind_speed "
      "or fetch");
  EXPECT_EQ(error_of("[ocean]\nspectrum = \"jonswap\"\nhs = 2\ntp = 7\nfetch = 30\n"),
            "scene.toml:3: ocean.hs: hs and tp give the sea state: not with wind_speed, fetch or beaufort");
  EXPECT_EQ(error_of("[ocean]\nspectrum = \"jonswap\"\ntp = 7\nbeaufort = 4\n"),
            "scene.toml:3: ocean.tp: hs and tp give the sea state: not with wind_speed, fetch or beaufort");
  EXPECT_EQ(error_of("[ocean]\nspectrum = \"tma\"\nhs = 2\n"),
            "scene.toml:3: ocean.hs: hs and tp go together: the significant height (metres) and the peak "
            "period (seconds)");
  EXPECT_EQ(error_of("[ocean]\nhs = 2\ntp = 7\n"),
            "scene.toml:2: ocean.hs: hs and tp make a pierson-moskowitz, jonswap or tma sea, not phillips");
  EXPECT_EQ(error_of("[ocean]\nspectrum = \"pierson-moskowitz\"\nfetch = 30\n"),
            "scene.toml:3: ocean.fetch: applies to spectrum = \"jonswap\" or \"tma\" only");
  EXPECT_EQ(
      error_of("[ocean]\nspreading_model = \"mitsuyasu\"\nspreading = 4\n"),
      "scene.toml:3: ocean.spreading: the exponent of spreading_model = \"cos2s\"; mitsuyasu sets its own");
  EXPECT_EQ(error_of("[swell]\ntp = 10\n"),
            "scene.toml:1: swell.hs: a swell needs its significant height (hs, metres)");

  // what each way sets
  const Scene beaufort = pipeline::parse_scene("[ocean]\nspectrum = \"jonswap\"\nbeaufort = 9\n", "s");
  EXPECT_FLOAT_EQ(beaufort.ocean.wind_speed, sim::beaufort_wind_speed(9));
  EXPECT_EQ(beaufort.ocean.fetch, sim::max_fetch);
  const Scene sea = pipeline::parse_scene(
      "[ocean]\nspectrum = \"tma\"\nhs = 1.5\ntp = 8\ndepth = 5\nspreading_model = \"donelan-banner\"\n"
      "[swell]\nhs = 0.5\ntp = 12\ndirection = 90\nspreading = 30\n",
      "s");
  EXPECT_EQ(sea.ocean.spectrum, sim::Spectrum::tma);
  EXPECT_EQ(sea.ocean.significant_height, 1.5f);
  EXPECT_EQ(sea.ocean.peak_period, 8.0f);
  EXPECT_EQ(sea.ocean.depth, 5.0f);
  EXPECT_EQ(sea.ocean.spreading_model, sim::Spreading::donelan_banner);
  EXPECT_EQ(sea.ocean.swell.significant_height, 0.5f);
  EXPECT_NEAR(sea.ocean.swell.direction, std::numbers::pi / 2.0, 1e-6);
  EXPECT_FALSE(std::isfinite(pipeline::parse_scene("", "s").ocean.depth));  // absent: deep water

  // over a scene with hs and tp, the wind takes over (and the other way round)
  const Scene windy = pipeline::apply_scene(sea, "[ocean]\nwind_speed = 14\n", "flags");
  EXPECT_EQ(windy.ocean.significant_height, 0.0f);
  EXPECT_EQ(windy.ocean.peak_period, 0.0f);
  EXPECT_EQ(windy.ocean.wind_speed, 14.0f);
  EXPECT_EQ(pipeline::apply_scene(sea, "[ocean]\nhs = 3\n", "flags").ocean.peak_period, 8.0f);
  EXPECT_EQ(pipeline::apply_scene(sea, "[swell]\nhs = 0\n", "flags").ocean.swell.significant_height, 0.0f);
  // every built-in makes a sea the ocean accepts
  for (const std::string& name : pipeline::builtin_scene_names()) {
    const Scene scene = pipeline::builtin_scene(name);
    sim::OceanParams params = scene.ocean;
    params.size = scene.map_size;
    EXPECT_NO_THROW(sim::SeaSpectrum{params}) << name;
  }
}

// [ocean] size is the map size; an albedo material names its image next to the scene file.
TEST(Scene, OceanSizeAndAlbedoMaterial) {
  EXPECT_EQ(pipeline::parse_scene("[ocean]\nsize = 64\n", "s.toml").map_size, 64);
  EXPECT_NE(error_of("[source]\nmap_size = 32\n[ocean]\nsize = 64\n").find("ocean.size: differs"),
            std::string::npos);
  const Scene albedo =
      pipeline::parse_scene("[material]\nkind = \"albedo\"\nalbedo = \"a.png\"\n", "dir/s.toml");
  EXPECT_EQ(albedo.albedo, std::filesystem::path("dir/a.png"));
  EXPECT_EQ(pipeline::parse_scene(pipeline::scene_toml(albedo), "x").albedo, albedo.albedo);
  EXPECT_NE(error_of("[material]\nkind = \"albedo\"\n").find("material.albedo"), std::string::npos);
  EXPECT_NE(error_of("[material]\nalbedo = \"a.png\"\n").find("material.albedo"), std::string::npos);
  // the pipeline hands the image to the renderer: a red albedo shades the bricks red
  Scene scene = small_scene("bricks", 16, 16);
  scene.method = render::Method::relief;
  scene.albedo = "red.png";
  std::vector<std::string> read;
  const pipeline::AlbedoLoader loader = [&](const std::filesystem::path& file) {
    read.push_back(file.string());
    return render::Albedo{1, 1, {255, 0, 0, 255}};
  };
  EXPECT_THROW(FramePipeline(scene, shared_renderer()), SceneError);
  FramePipeline red(scene, shared_renderer(), {}, {}, loader);
  render::Frame frame;
  red.run(0, frame, render::output_all);
  EXPECT_EQ(read, std::vector<std::string>{"red.png"});
  long long reddish = 0, hit = 0;
  for (std::size_t p = 0; p < frame.uv.size() / 3; ++p) {
    if (frame.uv[p * 3 + 2] < 0.5f) continue;
    ++hit;
    reddish += frame.color[p * 4] > 2 * frame.color[p * 4 + 1] + 10;
  }
  EXPECT_GT(hit, 50);
  EXPECT_EQ(reddish, hit);
  shared_renderer().clear_albedo();
}

TEST(Scene, CameraKeyframesPassThroughEveryKeyAndHoldOutside) {
  Scene scene = pipeline::builtin_scene("calm");
  scene.keyframes = {{0.0, {0.0f, -1.0f, 1.0f}, {0.5f, 0.5f, 0.0f}},
                     {1.0, {1.0f, -1.0f, 1.0f}, {0.5f, 0.5f, 0.0f}},
                     {3.0, {1.0f, 0.0f, 2.0f}, {0.4f, 0.5f, 0.0f}}};
  for (const pipeline::CameraKey& key : scene.keyframes) {
    const render::View view = pipeline::scene_view(scene, key.time);
    EXPECT_LT(glm::length(view.camera.eye - key.eye), 1e-6f);
    EXPECT_LT(glm::length(view.camera.look_at - key.look_at), 1e-6f);
  }
  EXPECT_EQ(pipeline::scene_view(scene, -5.0).camera.eye, scene.keyframes.front().eye);
  EXPECT_EQ(pipeline::scene_view(scene, 9.0).camera.eye, scene.keyframes.back().eye);
  // smooth: no jump between two close times inside a segment
  const glm::vec3 a = pipeline::scene_view(scene, 1.999).camera.eye,
                  b = pipeline::scene_view(scene, 2.001).camera.eye;
  EXPECT_LT(glm::length(a - b), 0.01f);
}

}  // namespace
