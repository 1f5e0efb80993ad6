// tests/render/pipelines_test.cpp - the pipeline cache on disk (render/pipelines.cpp).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <iterator>
#include <memory>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "render/map_pack.h"
#include "render/mesh.h"
#include "render/render.h"
#include "sim/sim.h"
#include "tests/render/render_checks.h"
#include "tests/render_fixtures.h"

namespace {

using namespace displace;
using namespace displace::testing;
using render::Frame;
using render::HeightField;
using render::Method;
using render::MethodInfo;
using render::View;

// The pipeline cache: written to the directory asked for when the renderer goes, nothing with
// "off"; a second renderer starts from it.
TEST(Maps, PipelineCacheGoesWhereItIsToldAndNowhereWhenOff) {
  const std::filesystem::path directory =
      std::filesystem::temp_directory_path() / ("displace_cache_test_" + std::to_string(::getpid()));
  std::filesystem::remove_all(directory);
  const HeightField field = waves_field(8);
  auto render_once = [&](const std::string& cache) {
    render::Renderer renderer(displace::testing::headless_options(false, cache));
    pipeline::MapMaker maps;
    maps.set_heights(field);
    pipeline::render_with_maps(renderer, maps, oblique_view(4), {Method::bump, 1, 0});
    EXPECT_EQ(renderer.pipelines_created(), 1);
  };
  render_once("off");
  EXPECT_FALSE(std::filesystem::exists(directory));
  render_once(directory.string());
  long long files = 0;
  for (const auto& entry : std::filesystem::directory_iterator(directory)) {
    files += entry.path().extension() == ".bin" && entry.file_size() >= 32;  // at least its header
  }
  EXPECT_EQ(files, 1);
  render_once(directory.string());  // reads it back
  std::filesystem::remove_all(directory);
}

}  // namespace
