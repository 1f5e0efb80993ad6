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

}  // namespace
