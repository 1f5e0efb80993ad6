// tests/demos/image_io_test.cpp - height images in and out (demos/image_io.cpp).
#include "demos/image_io.h"

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

TEST(ImageIo, Loads8BitWithValueOverMax) {
  TempDir dir;
  const std::vector<std::uint8_t> values = {0, 1, 2, 127, 128, 200, 254, 255};
  write_with_oiio(dir / "h.png", 4, 2, 1, OIIO::TypeDesc::UINT8, values.data());
  const LoadedHeights loaded = load_heights(dir / "h.png", {});
  EXPECT_EQ(loaded.width, 4);
  EXPECT_EQ(loaded.height, 2);
  EXPECT_EQ(loaded.format, SampleFormat::uint8);
  EXPECT_EQ(loaded.mapping_origin, MappingOrigin::integer_max);
  EXPECT_FLOAT_EQ(loaded.mapping.scale, 1.0f / 255.0f);
  EXPECT_EQ(loaded.mapping.bias, 0.0f);
  for (std::size_t k = 0; k < values.size(); ++k) {
    EXPECT_EQ(loaded.heights[k], float(values[k]) * loaded.mapping.scale + loaded.mapping.bias);
    EXPECT_NEAR(loaded.heights[k], values[k] / 255.0, 1e-7);
  }
  EXPECT_EQ(loaded.heights.back(), 1.0f);
}

TEST(ImageIo, Loads16Bit) {
  TempDir dir;
  const std::vector<std::uint16_t> values = {0, 1, 256, 32767, 40000, 65534, 65535, 12345, 7};
  write_with_oiio(dir / "h.png", 3, 3, 1, OIIO::TypeDesc::UINT16, values.data());
  const LoadedHeights loaded = load_heights(dir / "h.png", {});
  EXPECT_EQ(loaded.format, SampleFormat::uint16);
  EXPECT_FLOAT_EQ(loaded.mapping.scale, 1.0f / 65535.0f);
  for (std::size_t k = 0; k < values.size(); ++k) EXPECT_NEAR(loaded.heights[k], values[k] / 65535.0, 1e-7);
}

TEST(ImageIo, FloatMapsMinMaxOrTheGivenRange) {
  TempDir dir;
  const std::vector<float> values = {-2.0f, 0.0f, 1.0f, 6.0f, 3.5f, -1.0f};
  write_with_oiio(dir / "h.exr", 3, 2, 1, OIIO::TypeDesc::FLOAT, values.data());

  const LoadedHeights by_min_max = load_heights(dir / "h.exr", {});
  EXPECT_EQ(by_min_max.format, SampleFormat::floating);
  EXPECT_EQ(by_min_max.mapping_origin, MappingOrigin::image_min_max);
  EXPECT_FLOAT_EQ(by_min_max.mapping.scale, 1.0f / 8.0f);
  EXPECT_FLOAT_EQ(by_min_max.mapping.bias, 0.25f);
  EXPECT_EQ(by_min_max.heights[0], 0.0f);
  EXPECT_EQ(by_min_max.heights[3], 1.0f);
  EXPECT_FLOAT_EQ(by_min_max.heights[4], 5.5f / 8.0f);
  EXPECT_EQ(by_min_max.clamped, 0u);

  HeightLoadSettings ranged;
  ranged.range = HeightRange{0.0f, 4.0f};
  const LoadedHeights by_range = load_heights(dir / "h.exr", ranged);
  EXPECT_EQ(by_range.mapping_origin, MappingOrigin::user_range);
  EXPECT_FLOAT_EQ(by_range.mapping.scale, 0.25f);
  EXPECT_EQ(by_range.mapping.bias, 0.0f);
  EXPECT_EQ(by_range.heights[0], 0.0f);  // -2 clamps
  EXPECT_EQ(by_range.heights[2], 0.25f);
  EXPECT_EQ(by_range.heights[3], 1.0f);  // 6 clamps
  EXPECT_EQ(by_range.clamped, 3u);

  // an integer image rejects a float range
  const std::vector<std::uint8_t> bytes = {0, 255};
  write_with_oiio(dir / "b.png", 2, 1, 1, OIIO::TypeDesc::UINT8, bytes.data());
  EXPECT_THROW(load_heights(dir / "b.png", ranged), AppError);
}

TEST(ImageIo, UsesTheMappingDisplaceSimRecorded) {
  TempDir dir;
  const std::vector<float> metres = {-1.0f, 0.0f, 1.0f, 0.5f};
  write_with_oiio(dir / "h.exr", 2, 2, 1, OIIO::TypeDesc::FLOAT, metres.data(), {"height"},
                  {{"displace:height_scale", 0.25f}, {"displace:height_bias", 0.5f}});
  const LoadedHeights loaded = load_heights(dir / "h.exr", {});
  EXPECT_EQ(loaded.mapping_origin, MappingOrigin::file_metadata);
  EXPECT_EQ(loaded.mapping.scale, 0.25f);
  EXPECT_EQ(loaded.mapping.bias, 0.5f);
  EXPECT_EQ(loaded.heights, (std::vector<float>{0.25f, 0.5f, 0.75f, 0.625f}));
}

TEST(ImageIo, InvertTurnsDepthIntoHeight) {
  TempDir dir;
  const std::vector<std::uint8_t> depth = {0, 51, 255, 102};
  write_with_oiio(dir / "d.png", 2, 2, 1, OIIO::TypeDesc::UINT8, depth.data());
  HeightLoadSettings settings;
  settings.invert = true;
  const LoadedHeights loaded = load_heights(dir / "d.png", settings);
  EXPECT_TRUE(loaded.inverted);
  EXPECT_FLOAT_EQ(loaded.mapping.scale, 1.0f / 255.0f);  // recorded before the inversion
  for (std::size_t k = 0; k < depth.size(); ++k) EXPECT_NEAR(loaded.heights[k], 1.0 - depth[k] / 255.0, 1e-7);
}

TEST(ImageIo, ChoosesAChannelByIndexOrName) {
  TempDir dir;
  // RGB, heights in G, noise elsewhere
  const std::vector<std::uint8_t> rgb = {9, 10, 200, 9, 20, 200, 9, 30, 200, 9, 40, 200};
  write_with_oiio(dir / "c.png", 2, 2, 3, OIIO::TypeDesc::UINT8, rgb.data());
  HeightLoadSettings by_index;
  by_index.channel.index = 1;
  HeightLoadSettings by_name;
  by_name.channel.name = "G";
  const LoadedHeights a = load_heights(dir / "c.png", by_index);
  const LoadedHeights b = load_heights(dir / "c.png", by_name);
  EXPECT_EQ(a.channel_name, "G");
  EXPECT_EQ(a.heights, b.heights);
  EXPECT_NEAR(a.heights[3], 40.0 / 255.0, 1e-7);

  // no choice on a colour image, a missing name and an index out of range are clear errors
  EXPECT_THROW(load_heights(dir / "c.png", {}), AppError);
  HeightLoadSettings missing;
  missing.channel.name = "Z";
  try {
    load_heights(dir / "c.png", missing);
    FAIL() << "a missing channel was accepted";
  } catch (const AppError& error) {
    EXPECT_NE(std::string(error.what()).find("c.png"), std::string::npos) << error.what();
    EXPECT_NE(std::string(error.what()).find("'Z'"), std::string::npos) << error.what();
  }
  HeightLoadSettings beyond;
  beyond.channel.index = 3;
  EXPECT_THROW(load_heights(dir / "c.png", beyond), AppError);
}

std::size_t occurrences(const std::string& text, const std::string& part) {
  std::size_t count = 0;
  for (std::size_t at = text.find(part); at != std::string::npos; at = text.find(part, at + 1)) ++count;
  return count;
}

// A file cut short is refused in every format, never read with its missing rows filled in: libjpeg
// and libtiff fill them and only leave a message behind, libpng and OpenEXR fail. The decoders'
// messages come as one line without repeats (OpenImageIO repeats libpng's, libtiff gives one per strip).
TEST(ImageIo, RefusesTruncatedFilesOfEveryFormat) {
  TempDir dir;
  const std::vector<std::uint8_t> pixels = noise_pixels(128, 128, 1, 5);
  for (const std::string extension : {"png", "jpg", "exr", "tif"}) {
    const fs::path whole = dir / ("whole." + extension), cut = dir / ("cut." + extension);
    write_with_oiio(whole, 128, 128, 1, OIIO::TypeDesc::UINT8, pixels.data());
    EXPECT_NO_THROW(load_heights(whole, {})) << extension;
    EXPECT_NO_THROW(read_color_image(whole)) << extension;
    write_first_part(whole, cut, 0.5);
    for (const bool albedo : {false, true}) {
      try {
        if (albedo) {
          read_color_image(cut);
        } else {
          load_heights(cut, {});
        }
        ADD_FAILURE() << "a truncated ." << extension << " was read" << (albedo ? " as an albedo" : "");
      } catch (const AppError& error) {
        const std::string message = error.what();
        EXPECT_EQ(error.kind, ErrorKind::runtime);
        EXPECT_NE(message.find("truncated or corrupt"), std::string::npos) << message;
        EXPECT_NE(message.find(cut.string()), std::string::npos) << message;
        EXPECT_EQ(message.find('\n'), std::string::npos) << message;
        if (extension == "png") {
          EXPECT_EQ(occurrences(message, "hit end of file"), 1u) << message;
        }
        if (extension == "tif") {
          EXPECT_EQ(occurrences(message, "TIFFReadRawStrip"), 1u) << message;
        }
      }
    }
  }
}

// From memory (the fuzz target's way in) the loader gives what it gives from the file, in every
// format the fuzz target picks, refuses the same truncated bytes, and refuses an image larger than
// the caller's max_side before reading it.
TEST(ImageIo, LoadsFromMemoryWhatItLoadsFromTheFile) {
  TempDir dir;
  const std::vector<std::uint8_t> pixels = noise_pixels(64, 48, 1, 9);
  for (const std::string extension : {"png", "jpg", "exr", "tif", "bmp", "hdr"}) {
    const fs::path whole = dir / ("whole." + extension);
    HeightLoadSettings settings;
    if (extension == "hdr") {  // Radiance images are RGB
      std::vector<std::uint8_t> rgb;
      for (const std::uint8_t p : pixels) rgb.insert(rgb.end(), {p, p, p});
      write_with_oiio(whole, 64, 48, 3, OIIO::TypeDesc::UINT8, rgb.data());
      settings.channel.index = 1;
    } else {
      write_with_oiio(whole, 64, 48, 1, OIIO::TypeDesc::UINT8, pixels.data());
    }
    const std::string bytes = read_text(whole);
    const std::span<const std::uint8_t> memory(reinterpret_cast<const std::uint8_t*>(bytes.data()),
                                               bytes.size());
    const LoadedHeights from_file = load_heights(whole, settings);
    const LoadedHeights from_memory = load_heights(memory, "memory." + extension, settings);
    EXPECT_EQ(from_memory.width, 64) << extension;
    EXPECT_EQ(from_memory.height, 48) << extension;
    EXPECT_EQ(from_memory.heights, from_file.heights) << extension;
    EXPECT_EQ(from_memory.format, from_file.format) << extension;

    HeightLoadSettings small = settings;
    small.max_side = 32;
    try {
      load_heights(memory, "memory." + extension, small);
      ADD_FAILURE() << "a 64 x 48 ." << extension << " passed a limit of 32";
    } catch (const AppError& error) {
      EXPECT_NE(std::string(error.what()).find("at most 32 a side"), std::string::npos) << error.what();
    }
    try {
      load_heights(memory.first(memory.size() / 2), "cut." + extension, settings);
      ADD_FAILURE() << "half of a ." << extension << " in memory was read";
    } catch (const AppError& error) {
      EXPECT_NE(std::string(error.what()).find("'cut." + extension + "'"), std::string::npos) << error.what();
    }
  }
}

TEST(ImageIo, BadFilesThrowOneErrorNamingTheFile) {
  TempDir dir;
  write_bytes(dir / "corrupt.png", std::string("\x89PNG\r\n\x1a\n this is not a png at all", 32));
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const std::vector<float> with_nan = {0.0f, nan, 1.0f, 0.5f};
  write_with_oiio(dir / "nan.exr", 2, 2, 1, OIIO::TypeDesc::FLOAT, with_nan.data());
  const std::uint8_t one_texel = 200;
  write_with_oiio(dir / "one.png", 1, 1, 1, OIIO::TypeDesc::UINT8, &one_texel);
  const std::vector<float> with_inf = {0.0f, std::numeric_limits<float>::infinity(), 1.0f, 0.5f};
  write_with_oiio(dir / "inf.exr", 2, 2, 1, OIIO::TypeDesc::FLOAT, with_inf.data());
  for (const char* name : {"missing.png", "corrupt.png", "nan.exr", "inf.exr"}) {
    try {
      load_heights(dir / name, {});
      ADD_FAILURE() << name << " was accepted";
    } catch (const AppError& error) {
      EXPECT_EQ(error.kind, ErrorKind::runtime);
      EXPECT_NE(std::string(error.what()).find(name), std::string::npos) << error.what();
    }
  }
}

TEST(ImageIo, ExrRoundTripIsExact) {
  TempDir dir;
  const std::vector<float> a = {0.0f,        -0.0f,     1e-30f, std::numeric_limits<float>::denorm_min(),
                                1.0f / 3.0f, 12345.678f};
  const std::vector<float> b = {1.0f, 2.0f, 3.0f, 4.0f, 5.0f, -6.5f};
  const ExrChannel channels[] = {{"height", a}, {"cone0", b}};
  const Metadata metadata = {
      {"displace:text", std::string("hello")}, {"displace:number", 0.1f}, {"displace:count", 7}};
  write_exr(dir / "x.exr", 3, 2, channels, metadata);
  const FloatImage image = read_float_image(dir / "x.exr");
  EXPECT_EQ(image.width, 3);
  EXPECT_EQ(image.height, 2);
  const std::vector<float> height = image.channel("height"), cone = image.channel("cone0");
  for (std::size_t k = 0; k < a.size(); ++k) {
    EXPECT_EQ(std::signbit(height[k]), std::signbit(a[k]));
    EXPECT_EQ(height[k], a[k]);
    EXPECT_EQ(cone[k], b[k]);
  }
  ASSERT_NE(find_attribute(image.metadata, "displace:text"), nullptr);
  EXPECT_EQ(std::get<std::string>(find_attribute(image.metadata, "displace:text")->value), "hello");
  EXPECT_EQ(std::get<float>(find_attribute(image.metadata, "displace:number")->value), 0.1f);
  EXPECT_EQ(std::get<int>(find_attribute(image.metadata, "displace:count")->value), 7);
}

}  // namespace
