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

// The overlay is drawn in the window only: the screenshot is the scene's picture whether the overlay
// is shown (the default) or hidden, the window's picture is that picture without the overlay and
// differs from it where the overlay is with it, and validation finds nothing in either run.
TEST(Cli, PlayOverlayIsDrawnInTheWindowOnly) {
  if (std::system("command -v xvfb-run >/dev/null 2>&1") != 0) {
    GTEST_SKIP() << "xvfb-run is missing ('apt-get install xvfb'); `displace play` needs a display";
  }
  TempDir dir;
  const std::string play = "play --frames 3 --size 128x96 --map-size 32 --validate";
  const RunResult shown = run_displace(dir,
                                       play + " --screenshot '" + (dir / "shown.png").string() +
                                           "' --window-shot '" + (dir / "shown_window.png").string() + "'",
                                       "xvfb-run -a ");
  ASSERT_EQ(shown.exit_code, 0) << shown.err << shown.out;
  EXPECT_EQ(shown.err.find("validation"), std::string::npos) << shown.err;
  const RunResult hidden =
      run_displace(dir,
                   play + " --no-overlay --screenshot '" + (dir / "hidden.png").string() +
                       "' --window-shot '" + (dir / "hidden_window.png").string() + "'",
                   "xvfb-run -a ");
  ASSERT_EQ(hidden.exit_code, 0) << hidden.err << hidden.out;
  EXPECT_EQ(hidden.err.find("validation"), std::string::npos) << hidden.err;

  const Rgba8Image shot = read_rgba8_image(dir / "shown.png");
  const Rgba8Image hidden_shot = read_rgba8_image(dir / "hidden.png");
  const Rgba8Image window = read_rgba8_image(dir / "shown_window.png");
  const Rgba8Image hidden_window = read_rgba8_image(dir / "hidden_window.png");
  ASSERT_EQ(shot.width, 128);
  ASSERT_EQ(shot.height, 96);
  EXPECT_EQ(shot.pixels, hidden_shot.pixels) << "the overlay changed the screenshot";
  ASSERT_EQ(window.width, shot.width);
  ASSERT_EQ(window.height, shot.height);
  ASSERT_EQ(hidden_window.pixels.size(), shot.pixels.size());
  // RGB of each pixel: the window's alpha is the swapchain's, not the picture's
  auto differing_pixels = [&](const Rgba8Image& image, int x0, int y0, int x1, int y1) {
    long long count = 0;
    for (int y = y0; y < y1; ++y) {
      for (int x = x0; x < x1; ++x) {
        const std::size_t at = (std::size_t(y) * std::size_t(shot.width) + std::size_t(x)) * 4;
        count += !std::equal(&image.pixels[at], &image.pixels[at + 3], &shot.pixels[at]);
      }
    }
    return count;
  };
  EXPECT_EQ(differing_pixels(hidden_window, 0, 0, shot.width, shot.height), 0)
      << "the hidden overlay's window is not the screenshot";
  // the overlay's window spans the top-left corner (8 pixels in) and beyond this small window
  const long long covered = differing_pixels(window, 8, 8, shot.width, shot.height);
  EXPECT_GT(covered, (shot.width - 8) * (shot.height - 8) / 2)
      << "the overlay is not in the window's picture";
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
  for (const char* key : {"Space", "Shift+M", "Up / Down", "Right / Left", "screenshot", "orbit", "--frames",
                          "overlay", "--no-overlay", "--window-shot"}) {
    EXPECT_NE(help.out.find(key), std::string::npos) << key;
  }
  const RunResult usage = run_displace(dir, "play --screenshot f.png");
  EXPECT_EQ(usage.exit_code, 2);
  EXPECT_NE(usage.err.find("--screenshot needs --frames"), std::string::npos) << usage.err;
  const RunResult window_usage = run_displace(dir, "play --window-shot f.png");
  EXPECT_EQ(window_usage.exit_code, 2);
  EXPECT_NE(window_usage.err.find("--window-shot needs --frames"), std::string::npos) << window_usage.err;
}

}  // namespace
