// tests/demos/cli_sim_test.cpp - `displace sim`, end to end.
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

TEST(Cli, SimWritesMetresWithItsMapping) {
  TempDir dir;
  const RunResult result =
      run_displace(dir, "sim --source sinusoids --map-size 24 --time 0.5 --seed 9 --output '" +
                            (dir / "h.exr").string() + "'");
  ASSERT_EQ(result.exit_code, 0) << result.err;
  const FloatImage image = read_float_image(dir / "h.exr");
  ASSERT_EQ(image.channel_names, std::vector<std::string>{"height"});
  EXPECT_EQ(std::get<std::string>(find_attribute(image.metadata, "displace:source")->value), "sinusoids");
  EXPECT_EQ(std::get<std::string>(find_attribute(image.metadata, "displace:seed")->value), "9");
  EXPECT_EQ(std::get<float>(find_attribute(image.metadata, "displace:time")->value), 0.5f);

  // the same heights and mapping as sim/ makes them, and bake --input picks the mapping up
  displace::sim::SinusoidParams params;
  params.seed = 9;
  const std::vector<displace::sim::Wave> waves = displace::sim::make_sinusoid_waves(params);
  std::vector<float> expected(24 * 24);
  displace::sim::sinusoid_heights(waves, params.patch_size, 0.5, 24, 24, expected);
  const displace::sim::HeightMapping mapping = displace::sim::sinusoid_mapping(waves);
  EXPECT_EQ(image.channel("height"), expected);
  const LoadedHeights loaded = load_heights(dir / "h.exr", {});
  EXPECT_EQ(loaded.mapping_origin, MappingOrigin::file_metadata);
  EXPECT_EQ(loaded.mapping.scale, mapping.scale);
  EXPECT_EQ(loaded.mapping.bias, mapping.bias);
}

// The ocean's sim says what sea it made, warns (one line on stderr) where the patch leaves it out, writes
// its frequency spectrum on request, and refuses contradictory sea-state flags with one error line.
TEST(Cli, SimSaysWhatSeaItMade) {
  TempDir dir;
  const RunResult developed = run_displace(
      dir, "sim --spectrum pierson-moskowitz --wind-speed 10 --map-size 64 --patch-size 400 --output '" +
               (dir / "h.exr").string() + "' --frequency-spectrum '" + (dir / "s.csv").string() + "'");
  ASSERT_EQ(developed.exit_code, 0) << developed.err;
  // Pierson-Moskowitz at 10 m/s: Hs 2.24 m, Tp 7.49 s
  EXPECT_NE(developed.out.find("the sea: pierson-moskowitz, Hs 2.24 m, Tp 7.49 s"), std::string::npos)
      << developed.out;
  EXPECT_NE(developed.out.find("the 400 m patch and 64 samples hold 98.0% of its variance"),
            std::string::npos)
      << developed.out;
  EXPECT_EQ(developed.err.find("warning"), std::string::npos) << developed.err;
  const std::string csv = read_text(dir / "s.csv");
  EXPECT_EQ(csv.rfind("frequency_hz,synthesized_m2_per_hz,analytic_m2_per_hz,modes\n", 0), 0u) << csv;
  EXPECT_GT(std::count(csv.begin(), csv.end(), '\n'), 20);

  // the sea: 20 m/s over 200 km on the 200 m patch
  const RunResult young =
      run_displace(dir, "sim --spectrum jonswap --wind-speed 20 --fetch 200 --map-size 64 --output '" +
                            (dir / "h.exr").string() + "'");
  ASSERT_EQ(young.exit_code, 0) << young.err;
  EXPECT_EQ(young.err.find("displace sim: warning: patch too small: "), 0u) << young.err;
  EXPECT_EQ(std::count(young.err.begin(), young.err.end(), '\n'), 1) << young.err;
  EXPECT_NE(young.err.find("a patch of "), std::string::npos) << young.err;

  for (const std::string flags : {"--beaufort 6 --wind-speed 10", "--spectrum tma --hs 2",
                                  "--spectrum jonswap --hs 2 --tp 6 --fetch 20", "--hs 1 --tp 5",
                                  "--spreading-model mitsuyasu --spreading 3", "--swell-tp 9"}) {
    const RunResult refused =
        run_displace(dir, "sim " + flags + " --map-size 16 --output '" + (dir / "r.exr").string() + "'");
    EXPECT_EQ(refused.exit_code, 2) << flags << "\n" << refused.err;
    EXPECT_EQ(refused.err.find("displace: error: "), 0u) << flags << "\n" << refused.err;
    EXPECT_EQ(refused.err.find("displace: error: "), refused.err.rfind("displace: error: ")) << refused.err;
  }
  EXPECT_FALSE(fs::exists(dir / "r.exr"));
}

}  // namespace
