// tests/demos/cli_render_test.cpp - `displace render`, end to end.
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

TEST(Cli, RendersWithAovsAndComparesToTheReference) {
  TempDir dir;
  const std::string out = (dir / "frame.png").string();
  const RunResult result =
      run_displace(dir,
                   "render --source ocean --map-size 32 --time 0 --method acm4 --steps 32 --size 48x40 "
                   "--validate --output '" +
                       out + "' --aov uv='" + (dir / "uv.exr").string() + "' --aov iterations='" +
                       (dir / "it.png").string() + "' --aov depth='" + (dir / "depth.exr").string() +
                       "' --compare reference");
  ASSERT_EQ(result.exit_code, 0) << result.err;
  EXPECT_NE(result.out.find("compare reference: rmse"), std::string::npos) << result.out;
  const FloatImage uv = read_float_image(dir / "uv.exr");
  EXPECT_EQ(uv.width, 48);
  EXPECT_EQ(uv.height, 40);
  const auto hit = uv.channel("hit");
  const auto u = uv.channel("u");
  std::size_t hits = 0;
  for (std::size_t p = 0; p < hit.size(); ++p) {
    EXPECT_TRUE(hit[p] == 0.0f || hit[p] == 1.0f);
    if (hit[p] == 1.0f) {
      ++hits;
      EXPECT_GE(u[p], 0.0f);
      EXPECT_LE(u[p], 1.0f);
    } else {
      EXPECT_EQ(u[p], 0.0f);
    }
  }
  EXPECT_GT(hits, hit.size() / 4);
  EXPECT_TRUE(fs::exists(dir / "it.png"));
  EXPECT_TRUE(fs::exists(dir / "depth.exr"));
  EXPECT_TRUE(fs::exists(out));
}

// --bake-budget-ms: the cone methods render from maps baked at that budget, 0 included, and the
// picture still matches the reference (the maps are conservative at any budget).
TEST(Cli, RendersConeMethodsFromMapsBakedAtBudgetZero) {
  TempDir dir;
  for (const char* method : {"acm4", "relaxed"}) {
    const std::string out = (dir / (std::string(method) + ".png")).string();
    const RunResult result = run_displace(
        dir, std::string("render --source bricks --map-size 32 --seed 2 --size 48x40 --steps 64 --method ") +
                 method + " --bake-budget-ms 0 --compare reference --output '" + out + "'");
    ASSERT_EQ(result.exit_code, 0) << method << "\n" << result.err;
    EXPECT_NE(result.out.find("within a 0 ms budget"), std::string::npos) << result.out;
    const std::size_t at = result.out.find("compare reference: rmse ");
    ASSERT_NE(at, std::string::npos) << result.out;
    EXPECT_LT(std::stod(result.out.substr(at + 24)), 3.0) << method << "\n" << result.out;
    const Rgba8Image written = read_rgba8_image(out);  // kept: the attribute points into it
    const Attribute* budget = find_attribute(written.metadata, "displace:bake_budget_ms");
    ASSERT_NE(budget, nullptr) << method;
    EXPECT_EQ(std::get<std::string>(budget->value), "0") << method;  // PNG text chunks hold numbers as text
  }
}

// A one-off render bakes within the first picture's budget unless told otherwise, and says so; a
// long one prints a line per stage on stderr (StageLines, whose own test holds the timing).
TEST(Cli, RenderBakesWithinTheFirstPicturesBudgetByDefault) {
  TempDir dir;
  const RunResult result = run_displace(dir, "render --source ocean --map-size 32 --size 48x40 --output '" +
                                                 (dir / "first.png").string() + "'");
  ASSERT_EQ(result.exit_code, 0) << result.err;
  EXPECT_NE(result.out.find("within a " + std::to_string(int(first_picture_budget_ms)) + " ms budget: "),
            std::string::npos)
      << result.out;
  EXPECT_NE(result.out.find(", mean ratio 0."), std::string::npos) << result.out;
  // stderr: nothing, or (on a loaded machine, past a second) one "displace render: STAGE in T s" line
  // per stage
  std::istringstream lines(result.err);
  for (std::string line; std::getline(lines, line);) {
    EXPECT_EQ(line.rfind("displace render: ", 0), 0u) << result.err;
    EXPECT_EQ(line.substr(line.size() - 2), " s") << result.err;
  }
}

// --tolerance: an unlimited bake at tolerance 0 searches texels that one at 0.9 leaves to stage
// L (none on this map), and both render the reference's picture; the line and the file say which.
TEST(Cli, RendersConeMethodsFromMapsBakedAtALooseTolerance) {
  TempDir dir;
  const std::string out = (dir / "acm8.png").string();
  auto searched = [](const std::string& line) {
    const std::size_t at = line.find(" texels searched");
    EXPECT_NE(at, std::string::npos) << line;
    const std::size_t of = line.rfind(" of ", at), from = line.rfind(", ", of);
    return std::stol(line.substr(from + 2, of - from - 2));
  };
  const std::string common =
      "render --source ocean --map-size 32 --time 0 --size 48x40 --steps 64 "
      "--method acm8 --bake-budget-ms unlimited --compare reference --output '" +
      out + "' --tolerance ";
  const RunResult tight = run_displace(dir, common + "0");
  ASSERT_EQ(tight.exit_code, 0) << tight.err;
  EXPECT_GT(searched(tight.out), 0) << tight.out;
  const RunResult result = run_displace(dir, common + "0.9");
  ASSERT_EQ(result.exit_code, 0) << result.err;
  EXPECT_NE(result.out.find("with an unlimited budget at tolerance 0.9: "), std::string::npos) << result.out;
  EXPECT_EQ(searched(result.out), 0) << result.out;
  for (const RunResult* run : {&tight, &result}) {
    const std::size_t at = run->out.find("compare reference: rmse ");
    ASSERT_NE(at, std::string::npos) << run->out;
    EXPECT_LT(std::stod(run->out.substr(at + 24)), 3.0) << run->out;
  }
  const Rgba8Image written = read_rgba8_image(out);
  const Attribute* tolerance = find_attribute(written.metadata, "displace:bake_tolerance");
  ASSERT_NE(tolerance, nullptr);
  EXPECT_EQ(std::stof(std::get<std::string>(tolerance->value)), 0.9f);  // PNG text: the float's digits
  EXPECT_EQ(find_attribute(written.metadata, "displace:bake_budget_ms"), nullptr);
}

// --albedo and --shadows: a red albedo image shades every hit red (green and blue hold only the
// white highlight, equal), and shadows darken some pixels without changing which pixels hit.
TEST(Cli, RendersWithAnAlbedoImageAndShadows) {
  TempDir dir;
  std::vector<std::uint8_t> red(4 * 4 * 4, 0);
  for (std::size_t p = 0; p < 16; ++p) red[p * 4] = red[p * 4 + 3] = 255;
  write_png_rgba8(dir / "red.png", 4, 4, red, {});
  const std::string common =
      "render --source bricks --map-size 32 --method acm4 --steps 64 --size 40x40 --validate "
      "--light 1,0.5,0.4 --albedo '" +
      (dir / "red.png").string() + "' --output '";
  const RunResult plain = run_displace(dir, common + (dir / "plain.png").string() + "'");
  ASSERT_EQ(plain.exit_code, 0) << plain.err;
  const RunResult shadowed = run_displace(dir, common + (dir / "shadowed.png").string() + "' --shadows");
  ASSERT_EQ(shadowed.exit_code, 0) << shadowed.err;
  const Rgba8Image a = read_rgba8_image(dir / "plain.png"), b = read_rgba8_image(dir / "shadowed.png");
  ASSERT_EQ(a.pixels.size(), b.pixels.size());
  std::size_t hits = 0, darker = 0;
  for (std::size_t p = 0; p < a.pixels.size() / 4; ++p) {
    const std::uint8_t* x = &a.pixels[p * 4];
    const std::uint8_t* y = &b.pixels[p * 4];
    if (x[0] == 20 && x[1] == 20 && x[2] == 26) continue;  // the background
    ++hits;
    EXPECT_EQ(x[1], x[2]);
    EXPECT_GT(x[0], x[1]);
    EXPECT_LE(y[0], x[0]);
    darker += y[0] + 8 < x[0];
  }
  EXPECT_GT(hits, 800u);
  EXPECT_GT(darker, 50u);
}

// --surface mesh:FILE.obj renders a mesh from an OBJ file; a malformed one is one error naming its line.
TEST(Cli, RendersAMeshFromAnObjFile) {
  TempDir dir;
  {
    std::ofstream obj(dir / "quad.obj");
    obj << "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3 4/4\n";
    std::ofstream bad(dir / "bad.obj");
    bad << "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n";
  }
  const std::string common = "render --source bricks --map-size 32 --size 48x48 --validate --output '" +
                             (dir / "m.png").string() + "' --surface mesh:";
  for (const char* method : {"acm4", "relief", "reference"}) {
    const RunResult result = run_displace(
        dir, common + "'" + (dir / "quad.obj").string() + "' --method " + method + " --compare reference");
    EXPECT_EQ(result.exit_code, 0) << method << "\n" << result.err;
    EXPECT_NE(result.out.find("compare reference: rmse"), std::string::npos) << result.out;
  }
  const RunResult bad = run_displace(dir, common + "'" + (dir / "bad.obj").string() + "' --method acm4");
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_NE(bad.err.find("line 4"), std::string::npos) << bad.err;
}

TEST(Cli, RenderRejectsBadInputWithOneError) {
  TempDir dir;
  const std::string ok =
      "render --source ocean --map-size 16 --time 0 --output '" + (dir / "f.png").string() + "'";
  const struct {
    std::string arguments;
    int exit_code;
  } cases[] = {
      {ok + " --method no-such-method", 2},
      {ok + " --scene no-such-scene", 1},  // neither built in nor a file
      {ok + " --method pom --steps 0", 2},
      {ok + " --method pom --size 0x10", 2},
      {ok + " --method pom --eye 0.5,0.5,1 --look-at 0.5,0.5,1", 2},
      {ok + " --method pom --eye 1,2", 2},
      {ok + " --method pom --tile 2 --address clamp", 2},
      {ok + " --method pom --fov-y 0", 2},
      {ok + " --method pom --depth-scale nan", 2},
      {ok + " --method pom --aov colour=x.exr", 2},
      {ok + " --method pom --aov uv=x.png", 2},
      {ok + " --method pom --device no-such-device", 1},
      {"render --input '" + (dir / "missing.png").string() + "' --method pom --output f.png", 1},
      {ok + " --method pom --albedo '" + (dir / "missing.png").string() + "'", 1},
      {ok + " --method pom --shadows yes", 2},
      {ok + " --method pom --surface mesh:", 2},
      {ok + " --method pom --surface mesh:'" + (dir / "missing.obj").string() + "'", 1},
      {ok + " --method pom --bake-budget-ms 0", 2},  // pom reads no cone map
      {ok + " --method acm4 --bake-budget-ms -1", 2},
      {ok + " --method acm4 --bake-budget-ms inf", 2},
      {ok + " --method acm4 --bake-budget-ms unlimit", 2},
      {ok + " --method acm4 --budget-ms 5", 2},      // render's flag is --bake-budget-ms
      {ok + " --method relief --tolerance 0.5", 2},  // relief reads no cone map
      {ok + " --method acm4 --tolerance 1", 2},
      {ok + " --method acm4 --tolerance -0.1", 2},
      {ok + " --method acm4 --tolerance nan", 2},
  };
  for (const auto& test : cases) {
    const RunResult result = run_displace(dir, test.arguments);
    EXPECT_TRUE(result.exited) << test.arguments;
    EXPECT_EQ(result.exit_code, test.exit_code) << test.arguments << "\n" << result.err;
    EXPECT_NE(result.err.find("displace: error: "), std::string::npos) << test.arguments << "\n"
                                                                       << result.err;
    EXPECT_EQ(result.err.find("displace: error: "), result.err.rfind("displace: error: ")) << result.err;
  }
  // a device the loader lacks is named by the flag, not by the library's option
  const RunResult no_device = run_displace(dir, ok + " --method pom --device no-such-device");
  EXPECT_NE(no_device.err.find("--device 'no-such-device' matches no Vulkan device"), std::string::npos)
      << no_device.err;
}

TEST(Cli, RendersAQuadricAndRefusesWhatItCannot) {
  TempDir dir;
  const std::string base =
      "render --source ocean --map-size 32 --time 0 --size 40x40 --output '" + (dir / "f.png").string() + "'";
  const RunResult result = run_displace(
      dir, base + " --surface sphere --radius 0.3 --method acm4 --validate --compare reference --aov uv='" +
               (dir / "uv.exr").string() + "'");
  ASSERT_EQ(result.exit_code, 0) << result.err;
  EXPECT_NE(result.out.find("compare reference: rmse"), std::string::npos) << result.out;
  const RunResult shadowed = run_displace(
      dir, base + " --surface cylinder --method relief --shadows --validate --compare reference");
  ASSERT_EQ(shadowed.exit_code, 0) << shadowed.err;
  EXPECT_NE(shadowed.out.find("compare reference: rmse"), std::string::npos) << shadowed.out;
  const FloatImage uv = read_float_image(dir / "uv.exr");
  const auto hit = uv.channel("hit");
  EXPECT_GT(std::count(hit.begin(), hit.end(), 1.0f), 200);
  const Attribute* surface = find_attribute(uv.metadata, "displace:surface");
  ASSERT_NE(surface, nullptr);
  EXPECT_EQ(std::get<std::string>(surface->value), "sphere");
  const struct {
    std::string arguments;
    int exit_code;
  } cases[] = {
      {base + " --surface torus --method relief", 2},
      {base + " --surface cone --method parallax", 2},  // the parallax family stays on the plane
      {base + " --surface sphere --radius 20 --method relief", 2},
      {base + " --surface sphere --depth-scale 0.2 --method relief", 1},                    // D above R / 2
      {base + " --surface cylinder --eye 0.5,0.5,0 --look-at 0.5,1,0 --method relief", 1},  // inside it
  };
  for (const auto& test : cases) {
    const RunResult refused = run_displace(dir, test.arguments);
    EXPECT_EQ(refused.exit_code, test.exit_code) << test.arguments << "\n" << refused.err;
    EXPECT_NE(refused.err.find("displace: error: "), std::string::npos) << refused.err;
    EXPECT_EQ(refused.err.find("displace: error: "), refused.err.rfind("displace: error: ")) << refused.err;
  }
}

TEST(Cli, RenderWithoutAnyVulkanDriverSaysWhatToInstall) {
  TempDir dir;
  // point the loader at no driver at all: it then finds no device
  const RunResult result =
      run_displace(dir, "render --source ocean --map-size 16 --time 0 --method pom --output '" +
                            (dir / "f.png").string() + "'");
  ASSERT_EQ(result.exit_code, 0) << result.err;  // with the real drivers it works
  const std::string command =
      "VK_ICD_FILENAMES=/nonexistent/icd.json VK_DRIVER_FILES=/nonexistent/icd.json '" +
      std::string(DISPLACE_BINARY) + "' render --source ocean --map-size 16 --time 0 " +
      "--method pom --output '" + (dir / "g.png").string() + "' 2>'" + (dir / "err.txt").string() + "'";
  const int status = std::system(command.c_str());
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 1);
  const std::string err = read_text(dir / "err.txt");
  EXPECT_NE(err.find("mesa-vulkan-drivers"), std::string::npos) << err;
  EXPECT_FALSE(fs::exists(dir / "g.png"));
}

// One scene model: `render --scene S` draws the picture `sequence --scene S --frames 0:0` draws at the
// same size, bit for bit (frame 0 of the frame pipeline either way), for a static scene and for the
// water (choppy crests, foam, the water material); and a flag is the key it names (--steps 8 is
// [render] steps = 8 in a scene file).
TEST(Cli, RenderDrawsTheFrameZeroOfTheSequence) {
  TempDir dir;
  std::ofstream(dir / "eight.toml") << "[source]\nkind = \"bricks\"\nmap_size = 64\n[render]\nsteps = 8\n";
  const struct {
    std::string render, sequence;
  } cases[] = {
      {"--scene bricks --map-size 64", "--scene bricks --map-size 64"},
      {"--scene water --map-size 64", "--scene water --map-size 64"},
      {"--scene bricks --map-size 64 --steps 8", "--scene '" + (dir / "eight.toml").string() + "'"},
  };
  int index = 0;
  for (const auto& test : cases) {
    const std::string name = std::to_string(index++);
    const fs::path picture = dir / ("render" + name + ".png");
    const RunResult render =
        run_displace(dir, "render " + test.render + " --size 96x64 --output '" + picture.string() + "'");
    ASSERT_EQ(render.exit_code, 0) << test.render << "\n" << render.err;
    const RunResult sequence =
        run_displace(dir, "sequence " + test.sequence + " --size 96x64 --frames 0:0 --output '" +
                              (dir / ("sequence" + name + "_#.png")).string() + "'");
    ASSERT_EQ(sequence.exit_code, 0) << test.sequence << "\n" << sequence.err;
    const Rgba8Image rendered = read_rgba8_image(picture);
    const Rgba8Image frame = read_rgba8_image(dir / ("sequence" + name + "_0.png"));
    EXPECT_EQ(rendered.width, 96);
    EXPECT_EQ(rendered.height, 64);
    EXPECT_TRUE(rendered.pixels == frame.pixels) << test.render << " against " << test.sequence;
  }
}

}  // namespace
