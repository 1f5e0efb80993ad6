// tests/demos/options_test.cpp - the command line parsed into typed settings (demos/options.cpp).
#include "demos/options.h"

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
#include "demos/commands.h"
#include "demos/cone_export.h"
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

CommandSettings parse(std::initializer_list<std::string_view> args) {
  const std::vector<std::string_view> list(args);
  return parse_command_line(list);
}

TEST(Options, ParsesABakeCommandIntoTypedSettings) {
  const CommandSettings settings =
      parse({"bake", "--input", "h.exr", "--channel", "2", "--height-range=-1,3", "--sectors", "8", "--mode",
             "budgeted", "--budget-ms", "4.5", "--address", "clamp", "--output", "c.PNG", "--stats"});
  const BakeSettings& bake = std::get<BakeSettings>(settings);
  const FileInput& input = std::get<FileInput>(bake.input);
  EXPECT_EQ(input.path, "h.exr");
  EXPECT_EQ(input.load.channel.index, 2);
  EXPECT_EQ(input.load.range->low, -1.0f);
  EXPECT_EQ(input.load.range->high, 3.0f);
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
  // lagged cone maps are real-time only: they need a frame budget
  EXPECT_TRUE(usage({"bench-frame", "--cone-lag", "2"}));
  EXPECT_TRUE(usage({"bench-frame", "--budget-ms", "10", "--cone-lag", "65"}));
  EXPECT_FALSE(usage({"bench-frame", "--budget-ms", "10", "--cone-lag", "2"}));
  EXPECT_EQ(std::get<BenchFrameSettings>(parse({"bench-frame", "--budget-ms", "10", "--cone-lag", "2"}))
                .scene.cone_lag_frames,
            2);
  EXPECT_TRUE(usage({"play", "--frames", "3", "--cone-lag", "2"}));  // --frames is deterministic
  EXPECT_EQ(std::get<PlaySettings>(parse({"play", "--cone-lag", "2"})).cone_lag, 2);
  EXPECT_TRUE(usage({"bake", "--input", "h.exr", "--sectors", "4", "--cones", "bilinear", "--mode", "full",
                     "--budget-ms", "0", "--output", "c.exr"}));
}

TEST(Options, ParsesBilinearCones) {
  const BakeSettings budgeted =
      std::get<BakeSettings>(parse({"bake", "--input", "h.exr", "--sectors", "8", "--cones", "bilinear",
                                    "--mode", "budgeted", "--budget-ms", "0", "--output", "c.exr"}));
  EXPECT_EQ(budgeted.cones, ConeKind::bilinear);
  EXPECT_EQ(budgeted.baker, Baker::budgeted);
  EXPECT_EQ(budgeted.budget_milliseconds, 0.0);
  const BakeSettings full =
      std::get<BakeSettings>(parse({"bake", "--input", "h.exr", "--sectors", "1", "--cones=bilinear",
                                    "--mode", "full", "--output", "c.png"}));
  EXPECT_EQ(full.cones, ConeKind::bilinear);
  EXPECT_EQ(full.baker, Baker::full);
  const BakeSettings center = std::get<BakeSettings>(
      parse({"bake", "--input", "h.exr", "--sectors", "4", "--mode", "exact", "--output", "c.exr"}));
  EXPECT_EQ(center.cones, ConeKind::center);
}

// Numbers are decimal whatever CLI11 would make of them; sweep scenes and render AOVs may repeat;
// --help is the command's own help.
TEST(Options, ReadsDecimalNumbersRepeatsAndHelp) {
  const RenderSettings render = std::get<RenderSettings>(
      parse({"render", "--source", "bricks", "--map-size", "016", "--method", "pom", "--steps", "010",
             "--aov", "uv=a.exr", "--aov=depth=b.exr", "--size=64x48", "--output", "f.png"}));
  EXPECT_EQ(std::get<SourceSettings>(render.input).size, 16);
  EXPECT_EQ(render.method.steps, 10);
  ASSERT_EQ(render.aovs.size(), 2u);
  EXPECT_EQ(render.aovs[1].aov, Aov::depth);
  EXPECT_EQ(render.aovs[1].file, "b.exr");
  EXPECT_EQ(render.view.camera.width, 64);
  EXPECT_EQ(render.view.camera.height, 48);
  const SweepSettings sweep = std::get<SweepSettings>(
      parse({"sweep", "--scene", "bricks", "--scene", "cliff", "--steps", "4,08", "--output", "s.csv"}));
  ASSERT_EQ(sweep.scenes.size(), 2u);
  EXPECT_EQ(sweep.scenes[1].name, "cliff");
  EXPECT_EQ(sweep.steps, (std::vector<int>{4, 8}));
  EXPECT_TRUE(std::isinf(sweep.cone_budget.milliseconds));
  const SweepSettings starved =
      std::get<SweepSettings>(parse({"sweep", "--bake-budget-ms", "2.5", "--bake-tolerance", "0.4",
                                     "--methods", "csm", "--output", "s.csv"}));
  EXPECT_EQ(starved.cone_budget.milliseconds, 2.5);
  EXPECT_EQ(starved.cone_budget.tolerance, 0.4f);
  const HelpSettings help = std::get<HelpSettings>(parse({"render", "--method", "nope", "--help"}));
  EXPECT_NE(help.text.find("--steps INT:[1, 4096]"), std::string::npos) << help.text;
  EXPECT_TRUE(std::get<HelpSettings>(parse({"help"})).text.empty());  // the overview
}

TEST(Options, ParsesTheRenderBakeBudget) {
  const RenderSettings budget =
      std::get<RenderSettings>(parse({"render", "--source", "ocean", "--map-size", "16", "--time", "0",
                                      "--method", "acm8", "--bake-budget-ms", "0", "--output", "f.png"}));
  EXPECT_EQ(budget.cone_budget.milliseconds, 0.0);
  const RenderSettings unlimited =
      std::get<RenderSettings>(parse({"render", "--source", "ocean", "--map-size", "16", "--time", "0",
                                      "--method", "acm8", "--output", "f.png"}));
  EXPECT_TRUE(std::isinf(unlimited.cone_budget.milliseconds));
  EXPECT_EQ(unlimited.cone_budget.tolerance, displace::bake::Budget{}.tolerance);
  const RenderSettings loose =
      std::get<RenderSettings>(parse({"render", "--source", "ocean", "--map-size", "16", "--time", "0",
                                      "--method", "csm", "--bake-tolerance", "0.45", "--output", "f.png"}));
  EXPECT_EQ(loose.cone_budget.tolerance, 0.45f);
  EXPECT_TRUE(std::isinf(loose.cone_budget.milliseconds));
}

// Interactive play starts a scene that sets no budget at a real-time frame budget (an unlimited bake
// is a third of a second a frame at 256); --frames keeps the scene's budget (deterministic frames,
// as `displace sequence` renders them), and so does a scene that sets a frame budget or a work limit.
TEST(Options, PlayStartsAtARealTimeBudgetUnlessTheSceneSetsOne) {
  PlaySettings interactive;
  EXPECT_EQ(play_scene(interactive).frame_ms, interactive_budget_ms);
  PlaySettings fixed;
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
    from_file.scene = file.string();
    EXPECT_EQ(play_scene(from_file).frame_ms, expected) << text;
  }
}

}  // namespace
