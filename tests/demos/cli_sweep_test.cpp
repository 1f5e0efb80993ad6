// tests/demos/cli_sweep_test.cpp - `displace sweep`, end to end.
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

// A sweep of a small scene file: one CSV row per method and step count, the fewest fetches that
// reach the target, and the cone maps it rendered from - baked at the budget and tolerance asked
// (budget 0: stage L alone, no texel searched; unlimited at tolerance 0: texels searched).
TEST(Cli, SweepsASceneFileAndSaysWhatItsConeMapsCost) {
  TempDir dir;
  std::ofstream(dir / "small.toml") << "# a small ocean\n[source]\nkind = \"ocean\"\nmap_size = 32\n"
                                       "[render]\nsize = [40, 32]\n";
  const std::string csv = (dir / "s.csv").string();
  const std::string common = "sweep --scene '" + (dir / "small.toml").string() +
                             "' --methods acm4,pom --steps 16,64 --repeat 1 --output '" + csv + "' ";
  auto searched = [](const std::string& out) {
    const std::size_t at = out.find("cone maps, 4 sectors: ");
    EXPECT_NE(at, std::string::npos) << out;
    const std::size_t end = out.find(" texels searched", at), of = out.rfind(" of ", end);
    const std::size_t from = out.rfind(", ", of);
    return std::stol(out.substr(from + 2, of - from - 2));
  };
  const RunResult starved = run_displace(dir, common + "--bake-budget-ms 0");
  ASSERT_EQ(starved.exit_code, 0) << starved.err;
  EXPECT_NE(starved.out.find("cone maps baked within a 0 ms budget at tolerance 0.25"), std::string::npos)
      << starved.out;
  EXPECT_EQ(searched(starved.out), 0) << starved.out;
  // only acm4 reads cone maps
  EXPECT_EQ(starved.out.find("cone maps, 1 sector"), std::string::npos) << starved.out;
  std::ifstream table(csv);
  std::string line;
  int rows = 0;
  std::getline(table, line);
  EXPECT_EQ(line.rfind("scene,method,steps,", 0), 0u) << line;
  while (std::getline(table, line)) rows += line.rfind("small,", 0) == 0 ? 1 : 0;
  EXPECT_EQ(rows, 4);  // 2 methods x 2 step counts
  const RunResult exact = run_displace(dir, common + "--tolerance 0 --bake-budget-ms unlimited");
  ASSERT_EQ(exact.exit_code, 0) << exact.err;
  EXPECT_NE(exact.out.find("cone maps baked with an unlimited budget at tolerance 0\n"), std::string::npos)
      << exact.out;
  EXPECT_GT(searched(exact.out), 0) << exact.out;
}

TEST(Cli, SweepRejectsMalformedSceneFilesWithOneError) {
  TempDir dir;
  const auto scene = [&](const std::string& name, const std::string& text) {
    std::ofstream(dir / name) << text;
    return "sweep --scene '" + (dir / name).string() + "' --output '" + (dir / "s.csv").string() + "'";
  };
  const struct {
    std::string arguments;
    int exit_code;
  } cases[] = {
      // a scene file's content is a file's, not the command line's: exit status 1 like any bad file
      {scene("key.toml", "[source]\nkind = \"ocean\"\nmap_sise = 16\n"), 1},    // an unknown key
      {scene("value.toml", "[source]\nkind = \"ocean\"\nmap_size = 15\n"), 1},  // odd for the ocean
      {scene("flags.toml", "--source ocean\n--map-size 16\n"), 1},  // not TOML (the old flag files)
      {scene("word.toml", "[source]\nkind = \"sea\"\n"), 1},
      {"sweep --scene '" + (dir / "missing.toml").string() + "' --output s.csv", 1},  // a missing file
  };
  for (const auto& [arguments, exit_code] : cases) {
    const RunResult result = run_displace(dir, arguments);
    EXPECT_EQ(result.exit_code, exit_code) << arguments << "\n" << result.err;
    EXPECT_EQ(result.err.find("displace: error: "), result.err.rfind("displace: error: ")) << result.err;
    EXPECT_NE(result.err.find("scene"), std::string::npos) << result.err;
    EXPECT_EQ(result.err.find("--help"), std::string::npos) << result.err;
  }
  EXPECT_FALSE(fs::exists(dir / "s.csv"));
}

}  // namespace
