// tests/demos/cli_sequence_test.cpp - `displace sequence`, end to end: shards and resumes.
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

std::string file_bytes(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// Every file of `directory` with its bytes, except the CSVs, manifests and job logs (which hold
// timings).
std::map<std::string, std::string> frames_in(const fs::path& directory) {
  std::map<std::string, std::string> files;
  for (const auto& entry : fs::directory_iterator(directory)) {
    const std::string name = entry.path().filename().string();
    if (entry.path().extension() == ".csv" || entry.path().extension() == ".manifest" ||
        name.find("joblog") != std::string::npos)
      continue;
    files[name] = file_bytes(entry.path());
  }
  return files;
}

const char* const small_sequence = "--scene water --map-size 32 --size 48x32 --bake-work 800";

// Frames are deterministic: one run, two round-robin shards, and a resumed run after losing a
// frame give the same files bit for bit; files are renamed into place (no partial file is left),
// and a per-frame CSV of stage times comes with them.
TEST(Cli, SequenceShardsAndResumesGiveTheSameFilesBitForBit) {
  TempDir dir;
  const std::string whole = dir.operator/("whole").string(), split = dir.operator/("split").string();
  const RunResult one =
      run_displace(dir, std::string("sequence ") + small_sequence + " --frames 2:7 --output '" + whole +
                            "/w_####.png' --aov 'depth=" + whole + "/d_###.exr'");
  ASSERT_EQ(one.exit_code, 0) << one.err;
  for (const char* shard : {"2/2", "1/2"}) {
    const RunResult part =
        run_displace(dir, std::string("sequence ") + small_sequence + " --frames 2:7 --output '" + split +
                              "/w_####.png' --aov 'depth=" + split + "/d_###.exr' --shard " + shard);
    ASSERT_EQ(part.exit_code, 0) << part.err;
    EXPECT_NE(part.out.find("rendered 3"), std::string::npos) << part.out;
  }
  const auto expected = frames_in(whole);
  EXPECT_EQ(expected.size(), 12u);
  EXPECT_TRUE(expected.count("w_0002.png") && expected.count("w_0007.png") && expected.count("d_007.exr"));
  EXPECT_EQ(frames_in(split), expected);
  EXPECT_TRUE(fs::exists(fs::path(whole) / "w.csv"));
  EXPECT_TRUE(fs::exists(fs::path(split) / "w.shard1of2.csv"));
  const std::string csv = read_text(fs::path(whole) / "w.csv");
  EXPECT_EQ(csv.rfind("frame,time_s,sim_ms,bake_ms", 0), 0u);
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 7);  // header and six frames

  fs::remove(fs::path(split) / "w_0005.png");
  const RunResult resumed =
      run_displace(dir, std::string("sequence ") + small_sequence + " --frames 2:7 --output '" + split +
                            "/w_####.png' --aov 'depth=" + split + "/d_###.exr' --resume");
  ASSERT_EQ(resumed.exit_code, 0) << resumed.err;
  EXPECT_NE(resumed.out.find("rendered 1, skipped 5"), std::string::npos) << resumed.out;
  EXPECT_EQ(frames_in(split), expected);
  // the resumed run's CSV keeps the shards' rows of the frames it skipped
  const std::string resumed_csv = read_text(fs::path(split) / "w.csv");
  EXPECT_EQ(std::count(resumed_csv.begin(), resumed_csv.end(), '\n'), 7) << resumed_csv;

  EXPECT_EQ(run_displace(dir, "sequence --frames 0:3 --output out.png").exit_code, 2);  // no '#'
  EXPECT_EQ(run_displace(dir, "sequence --frames 3:1 --output o_#.png").exit_code, 2);  // B < A
  EXPECT_EQ(run_displace(dir, "sequence --frames 0:1 --output o_#.png --shard 3/2").exit_code, 2);
  EXPECT_EQ(run_displace(dir, "sequence --frames 0:1 --output o_#.png --scene missing.toml").exit_code, 1);
  const RunResult no_ffmpeg =
      run_displace(dir, "sequence --frames 0:1 --output o_#.png --video v.mp4 --map-size 8 --size 8x8");
  if (no_ffmpeg.exit_code == 1) {
    EXPECT_NE(no_ffmpeg.err.find("ffmpeg"), std::string::npos);
  }
}

// The main job's loop, small: frames 0..T fps - 1 are one whole loop, the line says so and by how much
// the frequencies moved, and frame T fps draws frame 0's pixels.
TEST(Cli, SequenceOfALoopSaysSoAndComesBackToFrameZero) {
  TempDir dir;
  const std::string frames = (dir / "loop").string() + "/l_####.png";
  const RunResult one =
      run_displace(dir, std::string("sequence ") + small_sequence +
                            " --fps 4 --loop-seconds 2 --frames 0:7 --output '" + frames + "'");
  ASSERT_EQ(one.exit_code, 0) << one.err;
  EXPECT_NE(
      one.out.find("a seamless loop of 2 s: frame n + 8 is frame n bit for bit (wave frequencies moved by "
                   "at most "),
      std::string::npos)
      << one.out;
  EXPECT_NE(one.out.find(": frames 0..7 are one whole loop\n"), std::string::npos) << one.out;
  const RunResult next =
      run_displace(dir, std::string("sequence ") + small_sequence +
                            " --fps 4 --loop-seconds 2 --frames 8:8 --output '" + frames + "'");
  ASSERT_EQ(next.exit_code, 0) << next.err;
  EXPECT_EQ(next.out.find("one whole loop"), std::string::npos) << next.out;
  const Rgba8Image first = read_rgba8_image(dir / "loop" / "l_0000.png");
  const Rgba8Image again = read_rgba8_image(dir / "loop" / "l_0008.png");
  const Rgba8Image half = read_rgba8_image(dir / "loop" / "l_0004.png");
  EXPECT_TRUE(first.pixels == again.pixels);
  EXPECT_FALSE(first.pixels == half.pixels);
}

}  // namespace
