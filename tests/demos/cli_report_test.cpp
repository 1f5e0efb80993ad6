// tests/demos/cli_report_test.cpp - `displace report`, end to end.
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

// `displace play --frames N` under Xvfb: a window, a swapchain on lavapipe, zero validation messages,
// and the screenshot of frame N - 1 is, bit for bit, what the frame pipeline renders for that index.
TEST(Cli, ReportRejectsBadFlagsAndUnreadableScenesWithOneError) {
  TempDir dir;
  const std::string output = " --no-plots --output '" + (dir / "r").string() + "'";
  const RunResult small = run_displace(dir, "report --size 8" + output);
  EXPECT_EQ(small.exit_code, 2);
  EXPECT_NE(small.err.find("--size"), std::string::npos) << small.err;
  const RunResult invert = run_displace(dir, "report --invert --scene ocean" + output);
  EXPECT_EQ(invert.exit_code, 2);
  EXPECT_NE(invert.err.find("--invert needs a height image"), std::string::npos) << invert.err;
  const RunResult missing =
      run_displace(dir, "report --scene '" + (dir / "missing.png").string() + "'" + output);
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_NE(missing.err.find("missing.png"), std::string::npos) << missing.err;
  EXPECT_EQ(std::count(missing.err.begin(), missing.err.end(), '\n'), 1) << missing.err;
  const RunResult bad_file =
      run_displace(dir, "report --scene '" + (dir / "missing.txt").string() + "'" + output);
  EXPECT_EQ(bad_file.exit_code, 1);
  EXPECT_NE(bad_file.err.find("missing.txt"), std::string::npos) << bad_file.err;
  EXPECT_FALSE(fs::exists(dir / "r")) << "a report that cannot start writes nothing";
}

}  // namespace
