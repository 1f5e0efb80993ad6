// tests/demos/options_test.cpp - the command line parsed into typed settings (demos/options.cpp).

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

ParsedCommand parse(std::initializer_list<std::string_view> args) {
  const std::vector<std::string_view> list(args);
  return parse_command_line(list);
}

template <typename Settings>
Settings settings_of(const ParsedCommand& command) {
  return std::any_cast<Settings>(command.settings);
}

TEST(Options, ParsesABakeCommandIntoTypedSettings) {
  const BakeSettings bake = settings_of<BakeSettings>(
      parse({"bake", "--input", "h.exr", "--channel", "2", "--height-range=-1,3", "--sectors", "8", "--mode",
             "budgeted", "--budget-ms", "4.5", "--address", "clamp", "--output", "c.PNG", "--stats"}));
  EXPECT_EQ(bake.scene.source, displace::pipeline::SourceKind::image);
  EXPECT_EQ(bake.scene.image, "h.exr");
  const HeightLoadSettings load = load_settings(bake.scene.image_read);
  EXPECT_EQ(load.channel.index, 2);
  EXPECT_EQ(load.range->low, -1.0f);
  EXPECT_EQ(load.range->high, 3.0f);
  EXPECT_EQ(bake.sector_count, 8);
  EXPECT_EQ(bake.baker, Baker::budgeted);
  EXPECT_EQ(bake.budget_milliseconds, 4.5);
  EXPECT_EQ(bake.address, displace::bake::Address::clamp);
  EXPECT_EQ(bake.output_format, ImageFormat::png);
  EXPECT_TRUE(bake.stats);
}

TEST(Options, RejectsWhatDoesNotApply) {
  const auto usage_of = [](std::span<const std::string_view> args) {
    try {
      parse_command_line(args);
    } catch (const AppError& error) {
      return error.kind == ErrorKind::usage;
    }
    return false;
  };
  const auto usage = [&](std::initializer_list<std::string_view> args) {
    return usage_of(std::span<const std::string_view>(args.begin(), args.size()));
  };
  EXPECT_TRUE(usage({"bake", "--input", "h.exr", "--sectors", "4", "--mode", "exact"}));  // no output
  EXPECT_TRUE(usage({"bake", "--input", "h.exr", "--map-size", "4", "--sectors", "4", "--mode", "exact",
                     "--output", "c.exr"}));
  EXPECT_TRUE(usage({"bake", "--source", "ocean", "--map-size", "8", "--time", "0", "--invert", "--sectors",
                     "4", "--mode", "exact", "--output", "c.exr"}));
  EXPECT_TRUE(usage({"sim", "--source", "sinusoids", "--map-size", "8", "--time", "0", "--spectrum",
                     "jonswap", "--output", "h.exr"}));
  EXPECT_TRUE(usage({"sim", "--source", "ocean", "--map-size", "8", "--time", "inf", "--output", "h.exr"}));
  EXPECT_TRUE(usage(
      {"sim", "--source", "ocean", "--map-size", "8", "--time", "0", "--seed", "-3", "--output", "h.exr"}));
  EXPECT_TRUE(usage({"sim", "--source", "ocean", "--map-size", "20000", "--time", "0", "--output", "h.exr"}));
  EXPECT_TRUE(usage({"sim", "--source", "ocean", "--map-size", "8", "--time", "0", "--output", "h.png"}));
  EXPECT_TRUE(usage({"bake", "--input", "h.exr", "--sectors", "4", "--mode", "exact", "--budget-ms", "3",
                     "--output", "c.exr"}));
  EXPECT_TRUE(usage({"bake", "--input", "h.exr", "--sectors", "4", "--mode", "exact", "--mode", "original",
                     "--output", "c.exr"}));
  for (const char* mode : {"exact", "original", "paper-adaptive"}) {
    EXPECT_TRUE(usage({"bake", "--input", "h.exr", "--sectors", "4", "--cones", "bilinear", "--mode", mode,
                       "--output", "c.exr"}));
  }
  EXPECT_TRUE(usage({"bake", "--input", "h.exr", "--sectors", "4", "--mode", "full", "--output", "c.exr"}));
  // shards and resumed runs need deterministic frames: no wall-clock budget; one run's preview
  for (const char* flag : {"--shard", "--resume"}) {
    std::vector<std::string_view> args = {"sequence", "--frames",    "0:3", "--output",
                                          "f_#.png",  "--budget-ms", "33",  flag};
    if (std::string_view(flag) == "--shard") args.push_back("1/2");
    EXPECT_TRUE(usage_of(args)) << flag;
    args.erase(args.begin() + 5, args.begin() + 7);  // the same without the budget
    EXPECT_FALSE(usage_of(args)) << flag;
  }
  EXPECT_TRUE(
      usage({"sequence", "--frames", "0:3", "--output", "f_#.png", "--shard", "1/2", "--preview", "p.gif"}));
  // the device bake's first pass: rings 0 .. 8, a window of 1 .. 4 cells
  const auto bake_with = [&](std::string_view flag, std::string_view value) {
    const std::vector<std::string_view> args{"bake",     "--sectors", "4",  "--mode", "budgeted",
                                             "--output", "c.exr",     flag, value};
    return args;
  };
  EXPECT_FALSE(usage_of(bake_with("--device-rings", "8")));
  EXPECT_TRUE(usage_of(bake_with("--device-rings", "9")));
  EXPECT_TRUE(usage_of(bake_with("--device-window", "0")));
  const auto first_pass = [&](std::string_view flag, std::string_view value) {
    return std::any_cast<BakeSettings>(parse_command_line(bake_with(flag, value)).settings)
        .scene.device_first_pass;
  };
  EXPECT_EQ(first_pass("--device-window", "3").ring_radius, displace::bake::default_first_pass_rings);
  EXPECT_EQ(first_pass("--device-rings", "3").ring_radius, 3);
  EXPECT_EQ(first_pass("--device-window", "3").window_radius, 3);
  EXPECT_FALSE(first_pass("--device-window", "3").group);
  const std::vector<std::string_view> group{"bake",     "--sectors", "4",     "--mode",
                                            "budgeted", "--output",  "c.exr", "--device-group"};
  const displace::bake::DeviceFirstPass by_groups =
      std::any_cast<BakeSettings>(parse_command_line(group).settings).scene.device_first_pass;
  EXPECT_TRUE(by_groups.group);
  EXPECT_EQ(by_groups.ring_radius, 0);  // the group's first pass has no rings of its own
  // lagged cone maps are real-time only: they need a frame budget
  EXPECT_TRUE(usage({"bench-frame", "--cone-lag", "2"}));
  EXPECT_TRUE(usage({"bench-frame", "--budget-ms", "10", "--cone-lag", "65"}));
  EXPECT_FALSE(usage({"bench-frame", "--budget-ms", "10", "--cone-lag", "2"}));
  EXPECT_EQ(settings_of<BenchFrameSettings>(parse({"bench-frame", "--budget-ms", "10", "--cone-lag", "2"}))
                .scene.cone_lag_frames,
            2);
  EXPECT_TRUE(usage({"play", "--frames", "3", "--cone-lag", "2"}));  // --frames is deterministic
  EXPECT_EQ(settings_of<PlaySettings>(parse({"play", "--cone-lag", "2"})).scene.cone_lag_frames, 2);
  EXPECT_TRUE(settings_of<BenchFrameSettings>(
                  parse({"bench-frame", "--budget-ms", "10", "--cone-lag", "1", "--cone-ahead"}))
                  .scene.cone_ahead);
  EXPECT_TRUE(usage({"bake", "--input", "h.exr", "--sectors", "4", "--cones", "bilinear", "--mode", "full",
                     "--budget-ms", "0", "--output", "c.exr"}));
}

TEST(Options, ParsesBilinearCones) {
  const BakeSettings budgeted =
      settings_of<BakeSettings>(parse({"bake", "--input", "h.exr", "--sectors", "8", "--cones", "bilinear",
                                       "--mode", "budgeted", "--budget-ms", "0", "--output", "c.exr"}));
  EXPECT_EQ(budgeted.cones, ConeKind::bilinear);
  EXPECT_EQ(budgeted.baker, Baker::budgeted);
  EXPECT_EQ(budgeted.budget_milliseconds, 0.0);
  const BakeSettings full =
      settings_of<BakeSettings>(parse({"bake", "--input", "h.exr", "--sectors", "1", "--cones=bilinear",
                                       "--mode", "full", "--output", "c.png"}));
  EXPECT_EQ(full.cones, ConeKind::bilinear);
  EXPECT_EQ(full.baker, Baker::full);
  const BakeSettings center = settings_of<BakeSettings>(
      parse({"bake", "--input", "h.exr", "--sectors", "4", "--mode", "exact", "--output", "c.exr"}));
  EXPECT_EQ(center.cones, ConeKind::center);
}

// Numbers are decimal whatever CLI11 would make of them; sweep scenes and render AOVs may repeat;
// --help is the command's own help.
TEST(Options, ReadsDecimalNumbersRepeatsAndHelp) {
  const RenderSettings render = settings_of<RenderSettings>(
      parse({"render", "--source", "bricks", "--map-size", "016", "--method", "pom", "--steps", "010",
             "--aov", "uv=a.exr", "--aov=depth=b.exr", "--size=64x48", "--output", "f.png"}));
  EXPECT_EQ(render.scene.map_size, 16);
  EXPECT_EQ(render.scene.source, displace::pipeline::SourceKind::bricks);
  EXPECT_EQ(render.scene.steps, 10);
  ASSERT_EQ(render.aovs.size(), 2u);
  EXPECT_EQ(render.aovs[1].aov, Aov::depth);
  EXPECT_EQ(render.aovs[1].file, "b.exr");
  EXPECT_EQ(render.scene.camera.width, 64);
  EXPECT_EQ(render.scene.camera.height, 48);
  const SweepSettings sweep = settings_of<SweepSettings>(
      parse({"sweep", "--scene", "bricks", "--scene", "cliff", "--steps", "4,08", "--output", "s.csv"}));
  ASSERT_EQ(sweep.scenes.size(), 2u);
  EXPECT_EQ(sweep.scenes[1].name, "cliff");
  EXPECT_EQ(sweep.steps, (std::vector<int>{4, 8}));
  EXPECT_EQ(sweep.scenes[0].frame_ms, first_picture_budget_ms);  // a scene that sets none
  const SweepSettings tightest = settings_of<SweepSettings>(
      parse({"sweep", "--scene", "bricks", "--bake-budget-ms", "unlimited", "--output", "s.csv"}));
  EXPECT_TRUE(std::isinf(tightest.scenes[0].frame_ms));
  const SweepSettings starved = settings_of<SweepSettings>(parse(
      {"sweep", "--bake-budget-ms", "2.5", "--tolerance", "0.4", "--methods", "csm", "--output", "s.csv"}));
  ASSERT_EQ(starved.scenes.size(), 3u);  // the default scenes, each with the cone maps' budget
  for (const displace::pipeline::Scene& scene : starved.scenes) {
    EXPECT_EQ(scene.frame_ms, 2.5);
    EXPECT_EQ(scene.tolerance, 0.4f);
  }
  // --help: the command's own help, whatever else is on the line; `help` the overview
  const auto help_text = [](const ParsedCommand& command) {
    std::ostringstream text;
    command.run(text);
    return text.str();
  };
  const ParsedCommand help = parse({"render", "--method", "nope", "--help"});
  EXPECT_EQ(help.name, "help");
  EXPECT_NE(help_text(help).find("--steps INT:[1, 4096]"), std::string::npos) << help_text(help);
  const ParsedCommand overview = parse({"help"});
  EXPECT_EQ(overview.name, "help");
  EXPECT_NE(help_text(overview).find("bench-frame"), std::string::npos);
}

TEST(Options, ParsesTheRenderBakeBudget) {
  const RenderSettings budget =
      settings_of<RenderSettings>(parse({"render", "--source", "ocean", "--map-size", "16", "--time", "0",
                                         "--method", "acm8", "--bake-budget-ms", "0", "--output", "f.png"}));
  EXPECT_EQ(budget.scene.frame_ms, 0.0);
  // the first picture's budget when nothing sets one; unlimited on request; none for a method
  // without cone maps
  const RenderSettings first =
      settings_of<RenderSettings>(parse({"render", "--source", "ocean", "--map-size", "16", "--time", "0",
                                         "--method", "acm8", "--output", "f.png"}));
  EXPECT_EQ(first.scene.frame_ms, first_picture_budget_ms);
  const RenderSettings unlimited = settings_of<RenderSettings>(
      parse({"render", "--source", "ocean", "--map-size", "16", "--time", "0", "--method", "acm8",
             "--bake-budget-ms", "unlimited", "--output", "f.png"}));
  EXPECT_TRUE(std::isinf(unlimited.scene.frame_ms));
  const RenderSettings relief = settings_of<RenderSettings>(
      parse({"render", "--source", "ocean", "--map-size", "16", "--method", "relief", "--output", "f.png"}));
  EXPECT_TRUE(std::isinf(relief.scene.frame_ms));
  EXPECT_EQ(unlimited.scene.tolerance, displace::bake::Budget{}.tolerance);
  const RenderSettings loose =
      settings_of<RenderSettings>(parse({"render", "--source", "ocean", "--map-size", "16", "--time", "0",
                                         "--method", "csm", "--tolerance", "0.45", "--output", "f.png"}));
  EXPECT_EQ(loose.scene.tolerance, 0.45f);
  EXPECT_EQ(loose.scene.frame_ms, first_picture_budget_ms);
}

// Interactive play starts a scene that sets no budget at a real-time frame budget (an unlimited bake
// is a third of a second a frame at 256); --frames keeps the scene's budget (deterministic frames,
// as `displace sequence` renders them), and so does a scene that sets a frame budget or a work limit.
TEST(Options, PlayStartsAtARealTimeBudgetUnlessTheSceneSetsOne) {
  PlaySettings interactive;
  interactive.scene = displace::pipeline::builtin_scene("water");
  EXPECT_EQ(play_scene(interactive).frame_ms, interactive_budget_ms);
  PlaySettings fixed = interactive;
  fixed.frames = 3;
  EXPECT_TRUE(std::isinf(play_scene(fixed).frame_ms));
  const TempDir dir;
  const std::vector<std::pair<std::string, double>> files = {
      {"[budget]\nframe_ms = 10\n", 10.0},
      {"[budget]\nbake_work = 500\n", std::numeric_limits<double>::infinity()}};
  for (const auto& [text, expected] : files) {
    const fs::path file = dir / "scene.toml";
    std::ofstream(file) << "[source]\nkind = \"sinusoids\"\n" << text;
    PlaySettings from_file;
    from_file.scene = displace::pipeline::read_scene_file(file);
    EXPECT_EQ(play_scene(from_file).frame_ms, expected) << text;
  }
}

}  // namespace
