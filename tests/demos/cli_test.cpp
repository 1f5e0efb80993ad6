// tests/demos/cli_test.cpp - the `displace` binary as a whole: help, exit statuses, one clear error for bad
// input, memory guards.
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

// A PNG whose header says 0 x 0 (CRC-correct, so only the size is wrong).
std::string zero_size_png() {
  const auto crc32 = [](const std::string& bytes) {
    std::uint32_t crc = 0xffffffffu;
    for (unsigned char byte : bytes) {
      crc ^= byte;
      for (int bit = 0; bit < 8; ++bit) crc = (crc >> 1) ^ (0xedb88320u & (0u - (crc & 1u)));
    }
    return crc ^ 0xffffffffu;
  };
  const auto big_endian = [](std::uint32_t value) {
    return std::string{char(value >> 24), char(value >> 16), char(value >> 8), char(value)};
  };
  const std::string ihdr =
      std::string("IHDR") + big_endian(0) + big_endian(0) + std::string("\x08\x00\x00\x00\x00", 5);
  const std::string iend = "IEND";
  return std::string("\x89PNG\r\n\x1a\n", 8) + big_endian(13) + ihdr + big_endian(crc32(ihdr)) +
         big_endian(0) + iend + big_endian(crc32(iend));
}

TEST(Cli, HelpAndNoArguments) {
  TempDir dir;
  const RunResult help = run_displace(dir, "--help");
  EXPECT_EQ(help.exit_code, 0);
  // the overview is CLI11's help of the root command: every command with its summary
  EXPECT_NE(help.out.find("Usage: displace"), std::string::npos) << help.out;
  for (const char* command :
       {"sim", "bake", "render", "sweep", "report", "sequence", "bench-frame", "play", "scene"}) {
    EXPECT_NE(help.out.find("\n  " + std::string(command) + " "), std::string::npos) << command << "\n"
                                                                                     << help.out;
  }
  EXPECT_EQ(run_displace(dir, "help").exit_code, 0);
  const RunResult none = run_displace(dir, "");
  EXPECT_EQ(none.exit_code, 2);
  EXPECT_NE(none.err.find("Usage: displace"), std::string::npos);
}

// Every command: a usage error exits 2 with one error line and a hint to its --help; a missing
// file (or one that cannot be written) exits 1 with one error line and no hint.
TEST(Cli, EveryCommandExitsTwoOnUsageErrorsAndOneOnMissingFiles) {
  TempDir dir;
  write_bytes(dir / "file.txt", "not a directory");
  const std::string missing = "'" + (dir / "missing.png").string() + "'";
  const std::string render =
      "render --source ocean --map-size 16 --time 0 --method pom --output '" + (dir / "f.png").string() + "'";
  const struct {
    std::string command, usage, missing_file;
  } cases[] = {
      {"sim", "sim --source ocean --map-size 16 --time 0 --output h.exr --frobnicate",
       "sim --source ocean --map-size 16 --time 0 --output '" + (dir / "no/such/dir/h.exr").string() + "'"},
      {"bake", "bake --input " + missing + " --sectors 4 --mode exact --output c.exr --steps 3",
       "bake --input " + missing + " --sectors 4 --mode exact --output '" + (dir / "c.exr").string() + "'"},
      {"render", render + " --steps 0", "render --input " + missing + " --method pom --output f.png"},
      {"sweep", "sweep --repeat 0 --output s.csv",
       "sweep --scene '" + (dir / "missing.scene").string() + "' --output s.csv"},
      {"demo", "demo --map-size 1", "demo --output-dir '" + (dir / "file.txt" / "out").string() + "'"},
  };
  for (const auto& test : cases) {
    const RunResult usage = run_displace(dir, test.usage);
    EXPECT_EQ(usage.exit_code, 2) << test.usage << "\n" << usage.err;
    EXPECT_EQ(usage.err.find("displace: error: "), 0u) << usage.err;
    EXPECT_EQ(usage.err.find("displace: error: "), usage.err.rfind("displace: error: ")) << usage.err;
    EXPECT_NE(usage.err.find("run 'displace " + test.command + " --help'"), std::string::npos) << usage.err;
    const RunResult runtime = run_displace(dir, test.missing_file);
    EXPECT_EQ(runtime.exit_code, 1) << test.missing_file << "\n" << runtime.err;
    EXPECT_EQ(runtime.err.find("displace: error: "), 0u) << runtime.err;
    EXPECT_EQ(runtime.err.find("displace: error: "), runtime.err.rfind("displace: error: ")) << runtime.err;
    EXPECT_EQ(runtime.err.find("--help"), std::string::npos) << runtime.err;
  }
  // --size is an image's pixels everywhere: the error for a map says so
  const RunResult size = run_displace(dir, "sim --source ocean --size 16 --time 0 --output h.exr");
  EXPECT_EQ(size.exit_code, 2);
  EXPECT_NE(size.err.find("--map-size"), std::string::npos) << size.err;
}

// `displace COMMAND --help` is CLI11's help for that command, with the limits of its numbers.
TEST(Cli, EachCommandsHelpShowsTheLimitsOfItsNumbers) {
  TempDir dir;
  std::string scene_names;
  for (const std::string& name : displace::pipeline::builtin_scene_names()) {
    scene_names += (scene_names.empty() ? "" : "|") + name;
  }
  const struct {
    std::string command, limit;
  } cases[] = {
      {"sim", "--map-size N:[2, 8192]"},    {"bake", "--tolerance T:[0, 1)"},
      {"render", "--steps INT:[1, 4096]"},  {"sweep", "--repeat INT:[1, 100]"},
      {"demo", "--map-size INT:[2, 8192]"}, {"scene", "--print " + scene_names},
      {"sim", "(even for the ocean)"},      {"play", "--frames N:[1, 1000000000]"},
  };
  for (const auto& test : cases) {
    const RunResult help = run_displace(dir, test.command + " --help");
    EXPECT_EQ(help.exit_code, 0) << test.command << "\n" << help.err;
    EXPECT_NE(help.out.find("Usage: displace " + test.command), std::string::npos) << help.out;
    EXPECT_NE(help.out.find(test.limit), std::string::npos) << test.limit << " in\n" << help.out;
  }
  const RunResult bake = run_displace(dir, "bake --help");
  EXPECT_NE(bake.out.find("--budget-ms MS:[0, 1e+09] ms"), std::string::npos) << bake.out;
  EXPECT_NE(bake.out.find("--sectors 1|4|8"), std::string::npos) << bake.out;
}

TEST(Cli, BadInputGetsOneClearErrorNeverACrash) {
  TempDir dir;
  std::mt19937 random(3);
  std::string noise(4096, '\0');
  for (char& c : noise) c = char(random());
  write_bytes(dir / "corrupt.png", noise);
  write_bytes(dir / "empty.png", "");
  write_bytes(dir / "zero.png", zero_size_png());
  // a real PNG cut in half
  std::vector<std::uint8_t> pixels(64 * 64);
  for (auto& p : pixels) p = std::uint8_t(random());
  write_with_oiio(dir / "whole.png", 64, 64, 1, OIIO::TypeDesc::UINT8, pixels.data());
  const std::string whole = read_text(dir / "whole.png");
  write_bytes(dir / "truncated.png", whole.substr(0, whole.size() / 2));
  const std::vector<float> with_nan = {0.0f, std::numeric_limits<float>::quiet_NaN(), 1.0f, 0.5f};
  write_with_oiio(dir / "nan.exr", 2, 2, 1, OIIO::TypeDesc::FLOAT, with_nan.data());
  const std::uint8_t one_texel = 200;
  write_with_oiio(dir / "one.png", 1, 1, 1, OIIO::TypeDesc::UINT8, &one_texel);

  const std::string to = " --sectors 4 --mode exact --output '" + (dir / "c.exr").string() + "'";
  const auto input = [&](const std::string& name) {
    return "bake --input '" + (dir / name).string() + "'" + to;
  };
  const struct {
    std::string arguments;
    int exit_code;
  } cases[] = {
      {input("missing.png"), 1},
      {input("corrupt.png"), 1},
      {input("empty.png"), 1},
      {input("zero.png"), 1},
      {input("truncated.png"), 1},
      {input("nan.exr"), 1},
      {input("one.png"), 1},
      {"bake --input '" + (dir / "whole.png").string() + "' --sectors 3 --mode exact --output c.exr", 2},
      {input("whole.png") + " --frobnicate", 2},
      {"sim --source ocean --map-size -5 --time 0 --output h.exr", 2},
      {"bake --input '" + (dir / "whole.png").string() + "' --relaxed --sectors 8 --output c.exr", 2},
      {"sim --source ocean --map-size 16 --time nan --output h.exr", 2},
      {"bake --source ocean --map-size 16 --time 0 --sectors 4 --mode exact", 2},
      {"unknown-command", 2},
      {"bake --source ocean --map-size 16 --time 0 --sectors 4 --mode budgeted --tolerance 1.5 --output "
       "c.exr",
       2},
      {"bake --source ocean --map-size 16 --time 0 --sectors 4 --mode exact --tolerance 0 --output c.exr", 2},
      {"bake --source sinusoids --map-size 1 --time 0 --sectors 4 --mode budgeted --output c.exr", 2},
      {"sim --source ocean --map-size 16 --time 1e30 --output h.exr", 2},
      {"sim --source ocean --map-size 16 --time 0 --wind-speed 1e30 --output h.exr", 2},
      {"sim --source ocean --map-size 16 --time 0 --patch-size 1e-30 --output h.exr", 2},
  };
  for (const auto& test : cases) {
    const RunResult result = run_displace(dir, test.arguments);
    EXPECT_TRUE(result.exited) << test.arguments;
    EXPECT_EQ(result.exit_code, test.exit_code) << test.arguments << "\n" << result.err;
    EXPECT_NE(result.err.find("displace: error: "), std::string::npos) << test.arguments << "\n"
                                                                       << result.err;
    EXPECT_EQ(result.err.find("displace: error: "), result.err.rfind("displace: error: ")) << result.err;
  }
  EXPECT_FALSE(fs::exists(dir / "c.exr"));
}

// The whole of stderr is one line starting "displace: error: ".
void expect_one_error_line(const RunResult& result, const std::string& arguments) {
  EXPECT_EQ(result.err.find("displace: error: "), 0u) << arguments << "\n" << result.err;
  EXPECT_EQ(std::count(result.err.begin(), result.err.end(), '\n'), 1) << arguments << "\n" << result.err;
}

// Truncated and corrupt images of every format: exit status 1 and exactly one line on stderr; what
// libpng prints on its own ("libpng error: ...") is folded into that line, not left on stderr.
TEST(Cli, TruncatedImagesGetOneErrorLineAndNoLibraryNoise) {
  TempDir dir;
  const std::vector<std::uint8_t> pixels = noise_pixels(128, 128, 1, 9);
  std::vector<std::string> broken;
  for (const std::string extension : {"png", "jpg", "exr", "tif"}) {
    const fs::path whole = dir / ("whole." + extension);
    write_with_oiio(whole, 128, 128, 1, OIIO::TypeDesc::UINT8, pixels.data());
    write_first_part(whole, dir / ("cut." + extension), 0.5);
    broken.push_back("cut." + extension);
  }
  write_first_part(dir / "whole.png", dir / "header.png", 0.01);  // cut inside its header
  broken.push_back("header.png");
  std::string flipped = read_text(dir / "whole.png");  // damaged inside the image data
  for (std::size_t i = flipped.size() / 2; i < flipped.size() / 2 + 64; ++i)
    flipped[i] = char(flipped[i] ^ 0x5a);
  write_bytes(dir / "flipped.png", flipped);
  broken.push_back("flipped.png");

  std::vector<std::string> commands;
  for (const std::string& name : broken) {
    commands.push_back("bake --input '" + (dir / name).string() + "' --sectors 4 --mode budgeted --output '" +
                       (dir / "c.exr").string() + "'");
  }
  commands.push_back("render --source bricks --map-size 16 --method bump --size 16x16 --albedo '" +
                     (dir / "cut.png").string() + "' --output '" + (dir / "f.png").string() + "'");
  for (const std::string& arguments : commands) {
    const RunResult result = run_displace(dir, arguments);
    EXPECT_EQ(result.exit_code, 1) << arguments << "\n" << result.err;
    expect_one_error_line(result, arguments);
    EXPECT_EQ(result.err.find("libpng"), std::string::npos) << result.err;
  }
  EXPECT_FALSE(fs::exists(dir / "c.exr"));
  EXPECT_FALSE(fs::exists(dir / "f.png"));
}

// One rule for the exit status: 2 when the command line is wrong (with a hint to the command's
// --help), including a flag that does not fit its input; 1 when a file is missing or malformed,
// whichever command reads it.
TEST(Cli, ExitStatusIsTwoForTheCommandLineAndOneForFiles) {
  TempDir dir;
  const std::vector<std::uint16_t> deep(16 * 16, 1000);
  write_with_oiio(dir / "h16.png", 16, 16, 1, OIIO::TypeDesc::UINT16, deep.data());
  write_bytes(dir / "bad.toml", "name = \"x\"\nmap_size = \"big\"\n");
  write_bytes(dir / "bad.scene", "--source ocean\n--map-size 15\n--time 0\n");
  const std::string missing = (dir / "missing").string();
  const std::string bake_to = " --sectors 4 --mode budgeted --output '" + (dir / "c.exr").string() + "'";
  const std::string render_to = " --method bump --size 16x16 --output '" + (dir / "f.png").string() + "'";
  const std::string frames =
      " --frames 0:0 --map-size 16 --size 16x16 --output '" + (dir / "o_#.png").string() + "'";
  const std::string no_display = "env -u DISPLAY -u WAYLAND_DISPLAY ";
  const struct {
    std::string arguments;
    int exit_code;
    std::string prefix = "";
  } cases[] = {
      {"bake --input '" + (dir / "h16.png").string() + "' --height-range 0,1" + bake_to, 2},
      {"bake --input '" + (dir / "h16.png").string() + "' --channel 3" + bake_to, 2},
      {"bake --input '" + (dir / "h16.png").string() + "' --channel Z" + bake_to, 2},
      {"render --source ocean --map-size 16 --time 0 --light 0,0,0" + render_to, 2},
      {"render --source ocean --map-size 16 --time 0 --tile 65" + render_to, 2},
      {"play --scene water --map-size 15 --frames 1", 2, no_display},
      {"sequence --scene water --map-size 15 --frames 0:0 --output o_#.png", 2},
      {"bake --input '" + missing + ".png'" + bake_to, 1},
      {"render --input '" + missing + ".exr'" + render_to, 1},
      {"render --source bricks --map-size 16 --albedo '" + missing + ".png'" + render_to, 1},
      {"render --source bricks --map-size 16 --surface 'mesh:" + missing + ".obj'" + render_to, 1},
      {"sweep --scene '" + missing + ".scene' --output s.csv", 1},
      {"sweep --scene '" + (dir / "bad.scene").string() + "' --output s.csv", 1},
      {"sequence --scene '" + missing + ".toml'" + frames, 1},
      {"sequence --scene '" + (dir / "bad.toml").string() + "'" + frames, 1},
      {"bench-frame --scene '" + missing + ".toml' --frames 1", 1},
      {"bench-frame --scene '" + (dir / "bad.toml").string() + "' --frames 1", 1},
      {"play --scene '" + missing + ".toml' --frames 1", 1, no_display},
      {"play --scene '" + (dir / "bad.toml").string() + "' --frames 1", 1, no_display},
  };
  for (const auto& test : cases) {
    const RunResult result = run_displace(dir, test.arguments, test.prefix);
    EXPECT_EQ(result.exit_code, test.exit_code) << test.arguments << "\n" << result.err;
    EXPECT_EQ(result.err.find("displace: error: "), 0u) << test.arguments << "\n" << result.err;
    EXPECT_EQ(result.err.find("displace: error: "), result.err.rfind("displace: error: ")) << result.err;
    EXPECT_EQ(result.err.find("--help' for usage") != std::string::npos, test.exit_code == 2)
        << test.arguments << "\n"
        << result.err;
  }
  EXPECT_FALSE(fs::exists(dir / "c.exr"));
  EXPECT_FALSE(fs::exists(dir / "f.png"));
}

// Work that cannot fit is refused before it starts, with one line naming what needs how much, what
// there is and what to lower (exit status 1). DISPLACE_MEMORY_LIMIT_MB holds the guards to 1 GB so
// that the refusals do not depend on this machine; the tessellation beyond 32-bit indices is refused
// on any machine. Nothing of these sizes is allocated: the runs end in about a second.
TEST(Cli, MemoryGuardsRefuseWorkThatCannotFitWithOneLine) {
  TempDir dir;
  const std::string limit = "env DISPLACE_MEMORY_LIMIT_MB=1000 ";
  const std::string to_png = " --output '" + (dir / "f.png").string() + "'";
  const struct {
    std::string arguments, prefix, words;
  } cases[] = {
      {"render --source bricks --map-size 256 --method reference --tile 64" + to_png, limit,
       "the reference's tessellation of a 256 x 256 map tiled 64 times"},
      {"render --source bricks --map-size 256 --method acm4 --compare reference --tile 64" + to_png, limit,
       "--tile"},
      {"render --source bricks --map-size 256 --method acm4 --size 16384x16384" + to_png, limit,
       "16384 x 16384"},
      {"render --source bricks --map-size 8192 --method reference --tile 64 --size 16x16" + to_png, "",
       "more than 32-bit indices address: lower --tile or --map-size"},
      {"render --source bricks --map-size 8192 --method acm8 --size 16x16" + to_png, limit,
       "lower --map-size"},
      {"bake --source bricks --map-size 8192 --sectors 8 --mode budgeted --output '" +
           (dir / "c.exr").string() + "'",
       limit, "lower --map-size"},
      {"sim --source ocean --map-size 8192 --time 0 --output '" + (dir / "h.exr").string() + "'", limit,
       "lower --map-size"},
      {"bench-frame --scene water --map-size 8192 --frames 1", limit, "lower --map-size"},
  };
  for (const auto& test : cases) {
    const RunResult result = run_displace(dir, test.arguments, test.prefix);
    EXPECT_EQ(result.exit_code, 1) << test.arguments << "\n" << result.err;
    expect_one_error_line(result, test.arguments);
    EXPECT_NE(result.err.find(test.words), std::string::npos) << test.arguments << "\n" << result.err;
    EXPECT_EQ(result.out, "") << test.arguments;
  }
  EXPECT_FALSE(fs::exists(dir / "f.png"));
  EXPECT_FALSE(fs::exists(dir / "c.exr"));
  EXPECT_FALSE(fs::exists(dir / "h.exr"));
  // a limit that is not a number of megabytes is a usage error
  const RunResult bad = run_displace(dir, "sim --source bricks --map-size 16 --output h.exr",
                                     "env DISPLACE_MEMORY_LIMIT_MB=lots ");
  EXPECT_EQ(bad.exit_code, 2) << bad.err;
  EXPECT_NE(bad.err.find("DISPLACE_MEMORY_LIMIT_MB"), std::string::npos) << bad.err;
}

// An albedo image has its own limits (1 x 1 to 16384 pixels a side) and its own words.
TEST(Cli, AlbedoImagesHaveTheirOwnLimitsAndWords) {
  TempDir dir;
  const std::vector<std::uint8_t> wide(100000 * 3, 128);
  write_with_oiio(dir / "wide.png", 100000, 1, 3, OIIO::TypeDesc::UINT8, wide.data());
  const std::uint8_t grey = 200;
  write_with_oiio(dir / "one.png", 1, 1, 1, OIIO::TypeDesc::UINT8, &grey);
  const std::string render = "render --source bricks --map-size 16 --method bump --size 16x16 --output '" +
                             (dir / "f.png").string() + "' --albedo ";
  const RunResult refused = run_displace(dir, render + "'" + (dir / "wide.png").string() + "'");
  EXPECT_EQ(refused.exit_code, 1) << refused.err;
  expect_one_error_line(refused, "--albedo wide.png");
  EXPECT_NE(refused.err.find("an albedo image may have at most 16384"), std::string::npos) << refused.err;
  EXPECT_EQ(refused.err.find("height map"), std::string::npos) << refused.err;
  const RunResult one = run_displace(dir, render + "'" + (dir / "one.png").string() + "'");
  EXPECT_EQ(one.exit_code, 0) << one.err;
}

// Flag limits agree with what the code accepts, and usage errors exit 2 with the project's words.
TEST(Cli, OceanSizeAndZeroLightAreUsageErrors) {
  TempDir dir;
  const RunResult big =
      run_displace(dir, "render --source ocean --map-size 16384 --time 0 --method bump --output a.png");
  EXPECT_EQ(big.exit_code, 2);
  EXPECT_NE(big.err.find("between 2 and 8192"), std::string::npos) << big.err;
  EXPECT_EQ(big.err.find("OceanParams"), std::string::npos) << big.err;
  const RunResult dark = run_displace(
      dir, "render --source ocean --map-size 16 --time 0 --method bump --light 0,0,0 --output a.png");
  EXPECT_EQ(dark.exit_code, 2);
  EXPECT_NE(dark.err.find("--light"), std::string::npos) << dark.err;
}

}  // namespace
