// tests/demos/cli_play_test.cpp - `displace play`, end to end.
#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>
#include <sched.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <span>
#include <sstream>
#include <string>
#include <vector>

#include "bake/bake.h"
#include "demos/cli/command.h"
#include "demos/commands/settings.h"
#include "demos/cone_export.h"
#include "demos/heights.h"
#include "demos/image_io.h"
#include "demos/obj_io.h"
#include "demos/play.h"
#include "demos/progress.h"
#include "pipeline/frame_pipeline.h"
#include "pipeline/scene.h"
#include "render/render.h"
#include "tests/demos/demos_fixtures.h"

namespace {

namespace fs = std::filesystem;
using namespace displace::app;

TEST(Cli, PlayRendersThePipelinesFramesInAWindow) {
  if (std::system("command -v xvfb-run >/dev/null 2>&1") != 0) {
    GTEST_SKIP() << "xvfb-run is missing ('apt-get install xvfb'); `displace play` needs a display";
  }
  namespace pipeline = displace::pipeline;
  namespace render = displace::render;
  TempDir dir;
  const fs::path shot = dir / "play.png";
  const RunResult played = run_displace(
      dir, "play --frames 3 --size 64x64 --map-size 32 --screenshot '" + shot.string() + "' --validate",
      "xvfb-run -a ");
  ASSERT_EQ(played.exit_code, 0) << played.err << played.out;
  EXPECT_EQ(played.err.find("validation"), std::string::npos) << played.err;
  EXPECT_NE(played.out.find("play: 3 frames of water"), std::string::npos) << played.out;
  // after the warm-up a frame allocates no device memory (frames 3..6 of 8; the last reads back)
  const RunResult longer = run_displace(dir, "play --frames 8 --size 64x64 --map-size 32", "xvfb-run -a ");
  ASSERT_EQ(longer.exit_code, 0) << longer.err;
  EXPECT_NE(longer.out.find(", 0 device allocations in frames 3..6"), std::string::npos) << longer.out;
  const Rgba8Image image = read_rgba8_image(shot);

  pipeline::Scene scene = pipeline::builtin_scene("water");
  scene.camera.width = scene.camera.height = 64;
  scene.map_size = 32;
  render::RendererOptions options;
  options.validate = true;
  render::Renderer renderer(options);
  pipeline::FramePipeline frames(scene, renderer);
  render::Frame frame;
  frames.run(2, frame, render::output_color);
  EXPECT_EQ(renderer.validation_messages(), 0);
  ASSERT_EQ(image.width, 64);
  ASSERT_EQ(image.height, 64);
  ASSERT_EQ(image.pixels.size(), frame.color.size());
  long long different = 0;
  for (std::size_t i = 0; i < frame.color.size(); ++i) different += image.pixels[i] != frame.color[i];
  EXPECT_EQ(different, 0) << "bytes of the screenshot that differ from the pipeline's frame 2";
}

// Without a display, `displace play` says how to get one and exits 1; its help lists the keys.
TEST(Cli, PlayWithoutADisplaySaysWhatToRun) {
  TempDir dir;
  const RunResult result =
      run_displace(dir, "play --frames 1 --size 64x64 --map-size 32", "env -u DISPLAY -u WAYLAND_DISPLAY ");
  EXPECT_EQ(result.exit_code, 1) << result.err;
  EXPECT_EQ(result.err,
            "displace: error: no display: run 'xvfb-run -a displace play ...' or render frames headless with "
            "'displace sequence'\n");
  const RunResult help = run_displace(dir, "play --help");
  EXPECT_EQ(help.exit_code, 0);
  for (const char* key :
       {"Space", "Shift+M", "Up / Down", "Right / Left", "screenshot", "orbit", "--frames"}) {
    EXPECT_NE(help.out.find(key), std::string::npos) << key;
  }
  const RunResult usage = run_displace(dir, "play --screenshot f.png");
  EXPECT_EQ(usage.exit_code, 2);
  EXPECT_NE(usage.err.find("--screenshot needs --frames"), std::string::npos) << usage.err;
}

}  // namespace
