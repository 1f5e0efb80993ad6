// tests/demos/obj_io_test.cpp - the OBJ reader (demos/obj_io.cpp).
#include "demos/obj_io.h"

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
#include "demos/play.h"
#include "demos/progress.h"
#include "pipeline/frame_pipeline.h"
#include "pipeline/scene.h"
#include "render/render.h"
#include "tests/demos/demos_fixtures.h"

namespace {

namespace fs = std::filesystem;
using namespace displace::app;

TEST(Obj, ReadsPolygonsWithSharedCornersAndRelativeIndices) {
  std::istringstream in(
      "# a unit square as one quad, and a triangle with negative indices\n"
      "o square\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
      "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\n"
      "f 1/1/1 2/2/1 3/3/1 4/4/1\n"
      "f -4/-4/-1 -2/-2/-1 -1/-1/-1\n");
  const displace::render::Mesh mesh = parse_obj(in, "square.obj");
  EXPECT_EQ(mesh.positions.size(), 4u);  // the second face reuses the corners of the first
  EXPECT_EQ(mesh.triangles.size(), 9u);
  EXPECT_EQ(mesh.normals.size(), 4u);
  EXPECT_EQ(mesh.uvs[2], glm::vec2(1, 1));
  EXPECT_EQ(mesh.triangles[6], 0u);
  EXPECT_EQ(mesh.triangles[8], 3u);
}

TEST(Obj, RejectsMalformedFilesNamingTheLine) {
  const std::pair<std::string, std::string> cases[] = {
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "line 4"},    // no texture coordinates
      {"v 0 0 0\nvt 0 0\nf 1/1 2/1 1/1\n", "out of range"},  // vertex 2 is not there
      {"v 0 0 zero\n", "line 1"},                            // not a number
      {"v 0 0 0\nv 1 0 nan\n", "line 2"},                    // not finite
      {"v 0 0 0\nvt 0 0\ncurv 1 2\n", "unsupported"},        // unknown record
      {"v 0 0 0\nvt 0 0\nf 1/1 1/1\n", "at least 3"},        // a face of two corners
      {"v 0 0 0\n", "no faces"},
  };
  for (const auto& [text, expected] : cases) {
    std::istringstream in(text);
    try {
      parse_obj(in, "bad.obj");
      ADD_FAILURE() << "accepted: " << text;
    } catch (const AppError& error) {
      EXPECT_NE(std::string(error.what()).find(expected), std::string::npos) << error.what();
    }
  }
}

}  // namespace
