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
#include "demos/commands.h"
#include "demos/cone_export.h"
#include "demos/image_io.h"
#include "demos/obj_io.h"
#include "demos/options.h"
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

  // the same heights and mapping as the in-process stage, and bake --input picks the mapping up
  SourceSettings source;
  source.kind = SourceKind::sinusoids;
  source.size = 24;
  source.time = 0.5f;
  source.sinusoids.seed = 9;
  const SynthesizedHeights expected = synthesize(source);
  EXPECT_EQ(image.channel("height"), expected.raw);
  const LoadedHeights loaded = load_heights(dir / "h.exr", {});
  EXPECT_EQ(loaded.mapping_origin, MappingOrigin::file_metadata);
  EXPECT_EQ(loaded.mapping.scale, expected.mapping.scale);
  EXPECT_EQ(loaded.mapping.bias, expected.mapping.bias);
}

}  // namespace
