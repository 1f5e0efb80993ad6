// tests/demos/cli_scene_test.cpp - `displace scene`, end to end.
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

// `scene --print NAME` writes a TOML scene file that reads back to the built-in scene.
TEST(Cli, ScenePrintWritesTomlThatParsesBack) {
  namespace pipeline = displace::pipeline;
  TempDir dir;
  for (const std::string& name : pipeline::builtin_scene_names()) {
    const RunResult result = run_displace(dir, "scene --print " + name);
    ASSERT_EQ(result.exit_code, 0) << name << "\n" << result.err;
    EXPECT_EQ(result.err, "");
    const pipeline::Scene printed = pipeline::parse_scene(result.out, name + ".toml");
    const pipeline::Scene builtin = pipeline::builtin_scene(name);
    EXPECT_EQ(printed.name, builtin.name);
    EXPECT_EQ(printed.source, builtin.source) << name;
    EXPECT_EQ(printed.map_size, builtin.map_size) << name;
    EXPECT_EQ(printed.method, builtin.method) << name;
    EXPECT_EQ(printed.steps, builtin.steps) << name;
    EXPECT_EQ(printed.camera.eye, builtin.camera.eye) << name;
    EXPECT_EQ(printed.ocean.choppiness, builtin.ocean.choppiness) << name;
    EXPECT_EQ(printed.keyframes.size(), builtin.keyframes.size()) << name;
    EXPECT_EQ(pipeline::scene_toml(printed), result.out) << name;  // nothing lost on the way
  }
  const RunResult unknown = run_displace(dir, "scene --print nowhere");
  EXPECT_EQ(unknown.exit_code, 2);
  EXPECT_EQ(unknown.out, "");
  for (const std::string& name : pipeline::builtin_scene_names()) {
    EXPECT_NE(unknown.err.find(name), std::string::npos) << unknown.err;
  }
}

}  // namespace
