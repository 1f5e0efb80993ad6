// tests/demos/cone_export_test.cpp - the conservative PNG and EXR cone encodings (demos/cone_export.cpp).
#include "demos/cone_export.h"

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

std::vector<float> awkward_ratios() {
  std::vector<float> ratios = {0.0f,
                               1.0f,
                               std::numeric_limits<float>::denorm_min(),
                               std::numeric_limits<float>::min(),
                               1e-9f,
                               1e-6f,
                               1.0f / (255.0f * 255.0f),
                               0.5f,
                               0.999999f};
  // every quantization boundary and its float neighbours
  for (int q = 0; q <= 255; ++q) {
    const float boundary = (float(q) / 255.0f) * (float(q) / 255.0f);
    ratios.push_back(boundary);
    ratios.push_back(std::nextafter(boundary, 0.0f));
    ratios.push_back(std::min(1.0f, std::nextafter(boundary, 2.0f)));
  }
  std::mt19937 random(7);
  std::uniform_real_distribution<float> uniform(0.0f, 1.0f);
  for (int k = 0; k < 20000; ++k) ratios.push_back(uniform(random));
  for (int k = 0; k < 2000; ++k) ratios.push_back(std::pow(uniform(random), 8.0f));  // tiny values
  return ratios;
}

TEST(ConeExport, RatioBytesNeverExceedTheRatioAndLoseAtMostOneStep) {
  for (const float ratio : awkward_ratios()) {
    const std::uint8_t byte = encode_ratio(ratio);
    const float decoded = decode_ratio(byte);
    EXPECT_LE(decoded, ratio) << "ratio " << ratio << " byte " << int(byte);
    if (byte < 255) {
      EXPECT_GT(decode_ratio(std::uint8_t(byte + 1)), ratio) << "ratio " << ratio;
    }
    EXPECT_LE(std::sqrt(double(ratio)) - std::sqrt(double(decoded)), 1.0 / 255.0 + 1e-6);
  }
  EXPECT_EQ(encode_ratio(1.0f), 255);
  EXPECT_EQ(encode_ratio(0.0f), 0);
}

struct RandomConeMap {
  int width, height, sector_count;
  std::vector<float> heights, ratios;
  ConeMapExport view() const {
    return {width, height, sector_count, heights, ratios, displace::bake::Address::clamp, Baker::exact};
  }
};

RandomConeMap random_cone_map(int width, int height, int sector_count, unsigned seed) {
  RandomConeMap map{width, height, sector_count, {}, {}};
  std::mt19937 random(seed);
  std::uniform_real_distribution<float> uniform(0.0f, 1.0f);
  const std::vector<float> awkward = awkward_ratios();
  for (int k = 0; k < width * height; ++k) map.heights.push_back(uniform(random));
  for (int k = 0; k < width * height * sector_count; ++k) {
    map.ratios.push_back(k % 3 == 0 ? awkward[std::size_t(k) % 300] : uniform(random));
  }
  map.ratios[3 % map.ratios.size()] = 0.0f;  // alpha 0 with colour set: must not be premultiplied
  return map;
}

TEST(ConeExport, PngDecodesToConservativeRatiosAndItsLayout) {
  TempDir dir;
  for (const int sectors : {1, 4, 8}) {
    const RandomConeMap map = random_cone_map(7, 5, sectors, unsigned(sectors));
    const fs::path file = dir / ("cones" + std::to_string(sectors) + ".png");
    write_cone_png(file, map.view());

    const DecodedConeMap decoded = read_cone_png(file);
    ASSERT_EQ(decoded.width, 7);
    ASSERT_EQ(decoded.height, 5);
    ASSERT_EQ(decoded.sector_count, sectors);
    for (std::size_t k = 0; k < map.ratios.size(); ++k) {
      EXPECT_LE(decoded.ratios[k], map.ratios[k]) << sectors << " sectors, sample " << k;
      EXPECT_LE(std::sqrt(map.ratios[k]) - std::sqrt(decoded.ratios[k]), 1.0f / 255.0f + 1e-6f);
    }
    for (std::size_t k = 0; k < map.heights.size(); ++k) {
      EXPECT_EQ(decoded.heights[k], std::round(map.heights[k] * 255.0f) / 255.0f);
    }

    // the raw layout: (panels + 1) * W wide; unused cone channels 0 with alpha 255; height G = B = 0, A = 255
    const Rgba8Image image = read_rgba8_image(file);
    const int panels = (sectors + 3) / 4;
    ASSERT_EQ(image.width, (panels + 1) * 7);
    for (int i = 0; i < 5; ++i) {
      for (int j = 0; j < 7; ++j) {
        const std::uint8_t* height_pixel = &image.pixels[std::size_t(i * image.width + panels * 7 + j) * 4];
        EXPECT_EQ(height_pixel[0], std::lround(map.heights[std::size_t(i * 7 + j)] * 255.0f));
        EXPECT_EQ(height_pixel[1], 0);
        EXPECT_EQ(height_pixel[2], 0);
        EXPECT_EQ(height_pixel[3], 255);
        if (sectors == 1) {
          const std::uint8_t* cone_pixel = &image.pixels[std::size_t(i * image.width + j) * 4];
          EXPECT_EQ(cone_pixel[1], 0);
          EXPECT_EQ(cone_pixel[2], 0);
          EXPECT_EQ(cone_pixel[3], 255);
        }
      }
    }
  }
}

TEST(ConeExport, ExrRoundTripIsExact) {
  TempDir dir;
  const RandomConeMap map = random_cone_map(6, 4, 8, 11);
  write_cone_exr(dir / "cones.exr", map.view());
  const FloatImage image = read_float_image(dir / "cones.exr");
  EXPECT_EQ(image.channel("height"), map.heights);
  for (int s = 0; s < 8; ++s) {
    const std::vector<float> plane = image.channel("cone" + std::to_string(s));
    for (std::size_t k = 0; k < plane.size(); ++k) EXPECT_EQ(plane[k], map.ratios[k * 8 + std::size_t(s)]);
  }
  EXPECT_EQ(std::get<int>(find_attribute(image.metadata, "displace:sectors")->value), 8);
  EXPECT_EQ(std::get<std::string>(find_attribute(image.metadata, "displace:address")->value), "clamp");
  EXPECT_EQ(std::get<std::string>(find_attribute(image.metadata, "displace:mode")->value), "exact");
}

TEST(ConeExport, HeightBytesRoundUpByAtMostOneStep) {
  std::mt19937 random(17);
  std::uniform_real_distribution<float> uniform(0.0f, 1.0f);
  std::vector<float> heights = {0.0f,
                                1.0f,
                                1e-30f,
                                0.5f,
                                128.0f / 255.0f,
                                std::nextafter(128.0f / 255.0f, 1.0f),
                                std::nextafter(1.0f, 0.0f)};
  for (int k = 0; k < 20000; ++k) heights.push_back(uniform(random));
  for (int k = 0; k <= 255; ++k) heights.push_back(float(k) / 255.0f);
  for (const float h : heights) {
    const std::uint8_t byte = encode_height_up(h);
    EXPECT_GE(decode_height(byte), h) << h;
    if (byte > 0) {
      EXPECT_LT(decode_height(std::uint8_t(byte - 1)), h) << h;
    }
  }
  for (int k = 0; k <= 255; ++k) EXPECT_EQ(encode_height_up(float(k) / 255.0f), k);
}

// A bilinear cone map in a PNG: ratios rounded down, apex heights rounded up, heights exact, and
// its layout: cone panels, the height panel, the apex panel.
TEST(ConeExport, BilinearPngDecodesToConservativeRatiosAndApexesAndItsLayout) {
  TempDir dir;
  for (const int sectors : {1, 4, 8}) {
    RandomConeMap map = random_cone_map(7, 5, sectors, unsigned(sectors + 20));
    quantize_heights_8bit(map.heights);
    std::vector<float> apex(map.heights.size());
    for (std::size_t t = 0; t < apex.size(); ++t) {
      apex[t] =
          std::min(1.0f, map.heights[t] + 0.3f * map.ratios[t * std::size_t(sectors)]);  // off the 8-bit grid
    }
    ConeMapExport view = map.view();
    view.kind = ConeKind::bilinear;
    view.baker = Baker::full;
    view.apex = apex;
    const fs::path file = dir / ("bilinear" + std::to_string(sectors) + ".png");
    write_cone_png(file, view);

    const DecodedConeMap decoded = read_cone_png(file);
    ASSERT_EQ(decoded.kind, ConeKind::bilinear);
    ASSERT_EQ(decoded.width, 7);
    ASSERT_EQ(decoded.height, 5);
    ASSERT_EQ(decoded.apex.size(), apex.size());
    EXPECT_EQ(decoded.heights, map.heights);
    for (std::size_t k = 0; k < map.ratios.size(); ++k) EXPECT_LE(decoded.ratios[k], map.ratios[k]) << k;
    for (std::size_t t = 0; t < apex.size(); ++t) {
      EXPECT_GE(decoded.apex[t], apex[t]) << t;
      EXPECT_LE(decoded.apex[t], apex[t] + 1.0f / 255.0f + 1e-6f) << t;
    }

    const Rgba8Image image = read_rgba8_image(file);
    const int panels = (sectors + 3) / 4;
    ASSERT_EQ(image.width, (panels + 2) * 7);
    for (int i = 0; i < 5; ++i)
      for (int j = 0; j < 7; ++j) {
        const std::size_t t = std::size_t(i * 7 + j);
        const std::uint8_t* height_pixel = &image.pixels[std::size_t(i * image.width + panels * 7 + j) * 4];
        const std::uint8_t* apex_pixel = height_pixel + 7 * 4;
        EXPECT_EQ(height_pixel[0], std::lround(map.heights[t] * 255.0f));
        EXPECT_EQ(apex_pixel[0], encode_height_up(apex[t]));
        for (const std::uint8_t* pixel : {height_pixel, apex_pixel}) {
          EXPECT_EQ(pixel[1], 0);
          EXPECT_EQ(pixel[2], 0);
          EXPECT_EQ(pixel[3], 255);
        }
      }
  }
  // heights off the 8-bit grid would not be what the cones were baked for
  RandomConeMap unquantized = random_cone_map(3, 2, 4, 1);
  std::vector<float> apex(unquantized.heights.size(), 1.0f);
  ConeMapExport view = unquantized.view();
  view.kind = ConeKind::bilinear;
  view.apex = apex;
  EXPECT_THROW(write_cone_png(dir / "bad.png", view), AppError);
}

TEST(ConeExport, QuantizedHeightsAreWhatThePngStores) {
  std::vector<float> heights = {0.0f, 1.0f, 0.5f, 0.123f, 0.998f, 0.002f};
  quantize_heights_8bit(heights);
  for (float h : heights) EXPECT_EQ(h, std::round(h * 255.0f) / 255.0f);
  EXPECT_EQ(heights[2], 128.0f / 255.0f);
}

}  // namespace
