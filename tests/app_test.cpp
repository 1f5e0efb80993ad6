// tests/app_test.cpp - the application layer: image I/O round trips, the conservative PNG cone
// encoding, and the `displace` binary meeting bad input with one clear error, never a crash.
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

namespace {

namespace fs = std::filesystem;
using namespace displace::app;

// A fresh directory under the system temp directory, removed with everything in it.
class TempDir {
 public:
  TempDir() {
    static std::atomic<int> counter{0};
    path_ = fs::temp_directory_path() /
            ("displace_app_test_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ignored;
    fs::remove_all(path_, ignored);
  }
  fs::path operator/(const std::string& name) const { return path_ / name; }

 private:
  fs::path path_;
};

// Writes an image with OpenImageIO directly, independently of image_io.
void write_with_oiio(const fs::path& file, int width, int height, int channels, OIIO::TypeDesc type,
                     const void* pixels, const std::vector<std::string>& names = {},
                     const std::vector<std::pair<std::string, float>>& attributes = {}) {
  OIIO::ImageSpec spec(width, height, channels, type);
  if (!names.empty()) spec.channelnames = names;
  for (const auto& [name, value] : attributes) spec.attribute(name, value);
  auto output = OIIO::ImageOutput::create(file.string());
  ASSERT_TRUE(output) << OIIO::geterror();
  ASSERT_TRUE(output->open(file.string(), spec)) << output->geterror();
  ASSERT_TRUE(output->write_image(type, pixels)) << output->geterror();
  ASSERT_TRUE(output->close());
}

void write_bytes(const fs::path& file, const std::string& bytes) {
  std::ofstream stream(file, std::ios::binary);
  stream << bytes;
}

std::string read_text(const fs::path& file) {
  std::ifstream stream(file);
  std::stringstream text;
  text << stream.rdbuf();
  return text.str();
}

// ---------------------------------------------------------------------------------------------
// image_io

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

// Random 8-bit samples: they do not compress, so half the file is about half the pixels.
std::vector<std::uint8_t> noise_pixels(int width, int height, int channels, unsigned seed) {
  std::mt19937 random(seed);
  std::vector<std::uint8_t> pixels(std::size_t(width) * height * channels);
  for (auto& p : pixels) p = std::uint8_t(random() >> 24);
  return pixels;
}

// `file`'s first `fraction` of bytes, written as `cut`.
void write_first_part(const fs::path& file, const fs::path& cut, double fraction) {
  const std::string bytes = read_text(file);
  write_bytes(cut, bytes.substr(0, std::size_t(double(bytes.size()) * fraction)));
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

// ---------------------------------------------------------------------------------------------
// cone_export

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

// ---------------------------------------------------------------------------------------------
// progress line

// A fake clock in seconds.
struct FakeClock {
  double now = 0.0;
  ProgressLine::Clock clock() {
    return [this] { return now; };
  }
};

TEST(ProgressLine, DrawsOnATerminalOnlyAfterASecondThenErasesItself) {
  std::ostringstream stream;
  FakeClock time;  // steps of binary fractions, so the printed tenths are not ties
  ProgressLine line(stream, true, "baking cones", time.clock());
  time.now += 0.25;
  line.update(0.1);
  time.now += 0.5;
  line.update(0.3);
  EXPECT_EQ(stream.str(), "") << "a bake under a second shows nothing";
  time.now += 0.75;  // 1.5 s
  line.callback()(0.42);
  EXPECT_EQ(stream.str(), "\rdisplace: baking cones  42% (1.5 s)");
  time.now += 0.0625;
  line.update(0.5);  // too soon after the last redraw
  EXPECT_EQ(stream.str(), "\rdisplace: baking cones  42% (1.5 s)");
  time.now += 8.8125;  // 10.375 s: the line grows by a character
  line.update(0.999);
  time.now += 0.0625;
  line.update(1.0);  // the last report is always drawn
  const std::string drawn = stream.str();
  EXPECT_NE(drawn.find("\rdisplace: baking cones  99% (10.4 s)"), std::string::npos) << drawn;
  const std::string last = "displace: baking cones 100% (10.4 s)";
  EXPECT_TRUE(drawn.ends_with("\r" + last)) << drawn;
  line.finish();
  const std::string erased = stream.str().substr(drawn.size());
  EXPECT_EQ(erased, "\r" + std::string(last.size(), ' ') + "\r");
  EXPECT_EQ(stream.str().find('\n'), std::string::npos) << "one line, updated in place";
  line.update(1.0);
  line.finish();
  EXPECT_EQ(stream.str().size(), drawn.size() + erased.size()) << "nothing after finish";
}

TEST(ProgressLine, DrawsNothingWhenNotATerminalOrWhenQuick) {
  std::ostringstream stream;
  FakeClock time;
  {
    ProgressLine line(stream, false, "baking cones", time.clock());
    for (int k = 1; k <= 100; ++k) {
      time.now += 0.5;
      line.update(k / 100.0);
    }
  }
  {
    ProgressLine quick(stream, true, "baking cones", time.clock());
    time.now += 0.5;
    quick.update(1.0);
  }
  EXPECT_EQ(stream.str(), "");
}

// From many threads at once (as a bake's reports could come, were they not serialized): every draw
// is whole.
TEST(ProgressLine, UpdatesFromManyThreadsDrawWholeLines) {
  std::ostringstream stream;
  std::atomic<int> ticks{0};
  ProgressLine line(stream, true, "baking", [&] { return 10.0 * ticks.fetch_add(1); });
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&] {
      for (int k = 0; k < 200; ++k) line.update(k / 200.0);
    });
  for (std::thread& thread : threads) thread.join();
  line.finish();
  const std::string text = stream.str();
  std::size_t lines = 0;
  for (std::size_t at = text.find("\rdisplace: baking "); at != std::string::npos;
       at = text.find("\rdisplace: baking ", at + 1)) {
    ++lines;
    const std::size_t end = text.find('\r', at + 1);
    const std::string one = text.substr(at + 1, end - at - 1);
    EXPECT_NE(one.find("%"), std::string::npos) << one;
    EXPECT_NE(one.find(" s)"), std::string::npos) << one;
  }
  EXPECT_EQ(lines, 800u);
}

// ---------------------------------------------------------------------------------------------
// options

CommandSettings parse(std::initializer_list<std::string_view> args) {
  const std::vector<std::string_view> list(args);
  return parse_command_line(list);
}

TEST(Options, ParsesABakeCommandIntoTypedSettings) {
  const CommandSettings settings =
      parse({"bake", "--input", "h.exr", "--channel", "2", "--height-range=-1,3", "--sectors", "8", "--mode",
             "budgeted", "--budget-ms", "4.5", "--address", "clamp", "--output", "c.PNG", "--stats"});
  const BakeSettings& bake = std::get<BakeSettings>(settings);
  const FileInput& input = std::get<FileInput>(bake.input);
  EXPECT_EQ(input.path, "h.exr");
  EXPECT_EQ(input.load.channel.index, 2);
  EXPECT_EQ(input.load.range->low, -1.0f);
  EXPECT_EQ(input.load.range->high, 3.0f);
  EXPECT_EQ(bake.sector_count, 8);
  EXPECT_EQ(bake.baker, Baker::budgeted);
  EXPECT_EQ(bake.budget_milliseconds, 4.5);
  EXPECT_EQ(bake.address, displace::bake::Address::clamp);
  EXPECT_EQ(bake.output_format, ImageFormat::png);
  EXPECT_TRUE(bake.stats);
}

TEST(Options, RejectsWhatDoesNotApply) {
  const auto usage_of = [](std::span<const std::string_view> args) {
    try {
      parse_command_line(args);
    } catch (const AppError& error) {
      return error.kind == ErrorKind::usage;
    }
    return false;
  };
  const auto usage = [&](std::initializer_list<std::string_view> args) {
    return usage_of(std::span<const std::string_view>(args.begin(), args.size()));
  };
  EXPECT_TRUE(usage({"bake", "--input", "h.exr", "--sectors", "4", "--mode", "exact"}));  // no output
  EXPECT_TRUE(usage({"bake", "--input", "h.exr", "--map-size", "4", "--sectors", "4", "--mode", "exact",
                     "--output", "c.exr"}));
  EXPECT_TRUE(usage({"bake", "--source", "ocean", "--map-size", "8", "--time", "0", "--invert", "--sectors",
                     "4", "--mode", "exact", "--output", "c.exr"}));
  EXPECT_TRUE(usage({"sim", "--source", "sinusoids", "--map-size", "8", "--time", "0", "--spectrum",
                     "jonswap", "--output", "h.exr"}));
  EXPECT_TRUE(usage({"sim", "--source", "ocean", "--map-size", "8", "--time", "inf", "--output", "h.exr"}));
  EXPECT_TRUE(usage(
      {"sim", "--source", "ocean", "--map-size", "8", "--time", "0", "--seed", "-3", "--output", "h.exr"}));
  EXPECT_TRUE(usage({"sim", "--source", "ocean", "--map-size", "20000", "--time", "0", "--output", "h.exr"}));
  EXPECT_TRUE(usage({"sim", "--source", "ocean", "--map-size", "8", "--time", "0", "--output", "h.png"}));
  EXPECT_TRUE(usage({"bake", "--input", "h.exr", "--sectors", "4", "--mode", "exact", "--budget-ms", "3",
                     "--output", "c.exr"}));
  EXPECT_TRUE(usage({"bake", "--input", "h.exr", "--sectors", "4", "--mode", "exact", "--mode", "original",
                     "--output", "c.exr"}));
  for (const char* mode : {"exact", "original", "paper-adaptive"}) {
    EXPECT_TRUE(usage({"bake", "--input", "h.exr", "--sectors", "4", "--cones", "bilinear", "--mode", mode,
                       "--output", "c.exr"}));
  }
  EXPECT_TRUE(usage({"bake", "--input", "h.exr", "--sectors", "4", "--mode", "full", "--output", "c.exr"}));
  // shards and resumed runs need deterministic frames: no wall-clock budget; one run's preview
  for (const char* flag : {"--shard", "--resume"}) {
    std::vector<std::string_view> args = {"sequence", "--frames",    "0:3", "--output",
                                          "f_#.png",  "--budget-ms", "33",  flag};
    if (std::string_view(flag) == "--shard") args.push_back("1/2");
    EXPECT_TRUE(usage_of(args)) << flag;
    args.erase(args.begin() + 5, args.begin() + 7);  // the same without the budget
    EXPECT_FALSE(usage_of(args)) << flag;
  }
  EXPECT_TRUE(
      usage({"sequence", "--frames", "0:3", "--output", "f_#.png", "--shard", "1/2", "--preview", "p.gif"}));
  // lagged cone maps are real-time only: they need a frame budget
  EXPECT_TRUE(usage({"bench-frame", "--cone-lag", "2"}));
  EXPECT_TRUE(usage({"bench-frame", "--budget-ms", "10", "--cone-lag", "65"}));
  EXPECT_FALSE(usage({"bench-frame", "--budget-ms", "10", "--cone-lag", "2"}));
  EXPECT_EQ(std::get<BenchFrameSettings>(parse({"bench-frame", "--budget-ms", "10", "--cone-lag", "2"}))
                .scene.cone_lag_frames,
            2);
  EXPECT_TRUE(usage({"play", "--frames", "3", "--cone-lag", "2"}));  // --frames is deterministic
  EXPECT_EQ(std::get<PlaySettings>(parse({"play", "--cone-lag", "2"})).cone_lag, 2);
  EXPECT_TRUE(usage({"bake", "--input", "h.exr", "--sectors", "4", "--cones", "bilinear", "--mode", "full",
                     "--budget-ms", "0", "--output", "c.exr"}));
}

TEST(Options, ParsesBilinearCones) {
  const BakeSettings budgeted =
      std::get<BakeSettings>(parse({"bake", "--input", "h.exr", "--sectors", "8", "--cones", "bilinear",
                                    "--mode", "budgeted", "--budget-ms", "0", "--output", "c.exr"}));
  EXPECT_EQ(budgeted.cones, ConeKind::bilinear);
  EXPECT_EQ(budgeted.baker, Baker::budgeted);
  EXPECT_EQ(budgeted.budget_milliseconds, 0.0);
  const BakeSettings full =
      std::get<BakeSettings>(parse({"bake", "--input", "h.exr", "--sectors", "1", "--cones=bilinear",
                                    "--mode", "full", "--output", "c.png"}));
  EXPECT_EQ(full.cones, ConeKind::bilinear);
  EXPECT_EQ(full.baker, Baker::full);
  const BakeSettings center = std::get<BakeSettings>(
      parse({"bake", "--input", "h.exr", "--sectors", "4", "--mode", "exact", "--output", "c.exr"}));
  EXPECT_EQ(center.cones, ConeKind::center);
}

// Numbers are decimal whatever CLI11 would make of them; sweep scenes and render AOVs may repeat;
// --help is the command's own help.
TEST(Options, ReadsDecimalNumbersRepeatsAndHelp) {
  const RenderSettings render = std::get<RenderSettings>(
      parse({"render", "--source", "bricks", "--map-size", "016", "--method", "pom", "--steps", "010",
             "--aov", "uv=a.exr", "--aov=depth=b.exr", "--size=64x48", "--output", "f.png"}));
  EXPECT_EQ(std::get<SourceSettings>(render.input).size, 16);
  EXPECT_EQ(render.method.steps, 10);
  ASSERT_EQ(render.aovs.size(), 2u);
  EXPECT_EQ(render.aovs[1].aov, Aov::depth);
  EXPECT_EQ(render.aovs[1].file, "b.exr");
  EXPECT_EQ(render.view.camera.width, 64);
  EXPECT_EQ(render.view.camera.height, 48);
  const SweepSettings sweep = std::get<SweepSettings>(
      parse({"sweep", "--scene", "bricks", "--scene", "cliff", "--steps", "4,08", "--output", "s.csv"}));
  ASSERT_EQ(sweep.scenes.size(), 2u);
  EXPECT_EQ(sweep.scenes[1].name, "cliff");
  EXPECT_EQ(sweep.steps, (std::vector<int>{4, 8}));
  EXPECT_TRUE(std::isinf(sweep.cone_budget.milliseconds));
  const SweepSettings starved =
      std::get<SweepSettings>(parse({"sweep", "--bake-budget-ms", "2.5", "--bake-tolerance", "0.4",
                                     "--methods", "csm", "--output", "s.csv"}));
  EXPECT_EQ(starved.cone_budget.milliseconds, 2.5);
  EXPECT_EQ(starved.cone_budget.tolerance, 0.4f);
  const HelpSettings help = std::get<HelpSettings>(parse({"render", "--method", "nope", "--help"}));
  EXPECT_NE(help.text.find("--steps INT:[1, 4096]"), std::string::npos) << help.text;
  EXPECT_TRUE(std::get<HelpSettings>(parse({"help"})).text.empty());  // the overview
}

TEST(Options, ParsesTheRenderBakeBudget) {
  const RenderSettings budget =
      std::get<RenderSettings>(parse({"render", "--source", "ocean", "--map-size", "16", "--time", "0",
                                      "--method", "acm8", "--bake-budget-ms", "0", "--output", "f.png"}));
  EXPECT_EQ(budget.cone_budget.milliseconds, 0.0);
  const RenderSettings unlimited =
      std::get<RenderSettings>(parse({"render", "--source", "ocean", "--map-size", "16", "--time", "0",
                                      "--method", "acm8", "--output", "f.png"}));
  EXPECT_TRUE(std::isinf(unlimited.cone_budget.milliseconds));
  EXPECT_EQ(unlimited.cone_budget.tolerance, displace::bake::Budget{}.tolerance);
  const RenderSettings loose =
      std::get<RenderSettings>(parse({"render", "--source", "ocean", "--map-size", "16", "--time", "0",
                                      "--method", "csm", "--bake-tolerance", "0.45", "--output", "f.png"}));
  EXPECT_EQ(loose.cone_budget.tolerance, 0.45f);
  EXPECT_TRUE(std::isinf(loose.cone_budget.milliseconds));
}

// Interactive play starts a scene that sets no budget at a real-time frame budget (an unlimited bake
// is a third of a second a frame at 256); --frames keeps the scene's budget (deterministic frames,
// as `displace sequence` renders them), and so does a scene that sets a frame budget or a work limit.
TEST(Options, PlayStartsAtARealTimeBudgetUnlessTheSceneSetsOne) {
  PlaySettings interactive;
  EXPECT_EQ(play_scene(interactive).frame_ms, interactive_budget_ms);
  PlaySettings fixed;
  fixed.frames = 3;
  EXPECT_TRUE(std::isinf(play_scene(fixed).frame_ms));
  const TempDir dir;
  const std::vector<std::pair<std::string, double>> files = {
      {"[budget]\nframe_ms = 10\n", 10.0},
      {"[budget]\nbake_work = 500\n", std::numeric_limits<double>::infinity()}};
  for (const auto& [text, expected] : files) {
    const fs::path file = dir / "scene.toml";
    std::ofstream(file) << "[source]\nkind = \"sinusoids\"\n" << text;
    PlaySettings from_file;
    from_file.scene = file.string();
    EXPECT_EQ(play_scene(from_file).frame_ms, expected) << text;
  }
}

// ---------------------------------------------------------------------------------------------
// the binary

struct RunResult {
  bool exited = false;  // exited normally (not killed by a signal)
  int exit_code = -1;
  std::string out, err;
};

// `prefix` goes before the binary (a wrapper such as "xvfb-run -a ", or "env -u DISPLAY ").
RunResult run_displace(const TempDir& dir, const std::string& arguments, const std::string& prefix = "") {
  const fs::path out = dir / "stdout.txt", err = dir / "stderr.txt";
  const std::string command = prefix + "'" + std::string(DISPLACE_BINARY) + "' " + arguments + " >'" +
                              out.string() + "' 2>'" + err.string() + "'";
  const int status = std::system(command.c_str());
  RunResult result;
  result.exited = status != -1 && WIFEXITED(status);
  result.exit_code = result.exited ? WEXITSTATUS(status) : -1;
  result.out = read_text(out);
  result.err = read_text(err);
  return result;
}

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
  EXPECT_NE(help.out.find("displace bake"), std::string::npos);
  EXPECT_EQ(run_displace(dir, "help").exit_code, 0);
  const RunResult none = run_displace(dir, "");
  EXPECT_EQ(none.exit_code, 2);
  EXPECT_NE(none.err.find("usage"), std::string::npos);
}

// `scene --print NAME` writes a TOML scene file that reads back to the built-in scene.
TEST(Cli, ScenePrintWritesTomlThatParsesBack) {
  namespace pipeline = displace::pipeline;
  TempDir dir;
  for (const std::string& name : pipeline::builtin_scene_names()) {
    const RunResult result = run_displace(dir, "scene --print " + name);
    ASSERT_EQ(result.exit_code, 0) << name << "\n" << result.err;
    EXPECT_EQ(result.err, "");
    const pipeline::Scene printed = pipeline::parse_scene(result.out, name + ".toml");
    const pipeline::Scene builtin = pipeline::builtin_scene(name);
    EXPECT_EQ(printed.name, builtin.name);
    EXPECT_EQ(printed.source, builtin.source) << name;
    EXPECT_EQ(printed.map_size, builtin.map_size) << name;
    EXPECT_EQ(printed.method, builtin.method) << name;
    EXPECT_EQ(printed.steps, builtin.steps) << name;
    EXPECT_EQ(printed.camera.eye, builtin.camera.eye) << name;
    EXPECT_EQ(printed.ocean.choppiness, builtin.ocean.choppiness) << name;
    EXPECT_EQ(printed.keyframes.size(), builtin.keyframes.size()) << name;
    EXPECT_EQ(pipeline::scene_toml(printed), result.out) << name;  // nothing lost on the way
  }
  const RunResult unknown = run_displace(dir, "scene --print nowhere");
  EXPECT_EQ(unknown.exit_code, 2);
  EXPECT_EQ(unknown.out, "");
  for (const std::string& name : pipeline::builtin_scene_names()) {
    EXPECT_NE(unknown.err.find(name), std::string::npos) << unknown.err;
  }
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
      {"sim", "--map-size INT:[2, 16384]"},   {"bake", "--tolerance T:[0, 1)"},
      {"render", "--steps INT:[1, 4096]"},    {"sweep", "--repeat INT:[1, 100]"},
      {"demo", "--map-size INT:[2, 8192]"},   {"scene", "--print " + scene_names},
      {"sim", "(ocean: even, at most 8192)"}, {"play", "--frames N:[1, 1000000000]"},
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

TEST(Cli, BakesAPngWhoseConesHoldForItsHeights) {
  TempDir dir;
  std::mt19937 random(5);
  std::vector<std::uint8_t> pixels(16 * 12);
  for (auto& p : pixels) p = std::uint8_t(random());
  write_with_oiio(dir / "h.png", 16, 12, 1, OIIO::TypeDesc::UINT8, pixels.data());

  const RunResult result = run_displace(dir, "bake --input '" + (dir / "h.png").string() +
                                                 "' --sectors 4 --mode exact --address clamp --output '" +
                                                 (dir / "c.png").string() + "' --stats");
  ASSERT_EQ(result.exit_code, 0) << result.err;
  EXPECT_EQ(std::count(result.out.begin(), result.out.end(), '\n'), 1) << result.out;
  for (const char* key :
       {"\"mode\":\"exact\"", "\"width\":16", "\"height\":12", "\"sectors\":4", "\"address\":\"clamp\"",
        "\"milliseconds\":", "\"texels_refined\":", "\"texels_fallback\":", "\"work\":", "\"mean_ratio\":"}) {
    EXPECT_NE(result.out.find(key), std::string::npos) << key << " in " << result.out;
  }

  // the stored cones are conservative for the stored heights
  const DecodedConeMap decoded = read_cone_png(dir / "c.png");
  ASSERT_EQ(decoded.width, 16);
  std::vector<float> exact(16 * 12 * 4);
  displace::bake::bake_exact({decoded.heights.data(), 16, 12}, displace::bake::Address::clamp,
                             {exact.data(), 16, 12, 4});
  for (std::size_t k = 0; k < exact.size(); ++k) EXPECT_LE(decoded.ratios[k], exact[k]) << k;
  for (std::size_t k = 0; k < pixels.size(); ++k) EXPECT_EQ(decoded.heights[k], float(pixels[k]) / 255.0f);
}

// `bake --cones bilinear`: an EXR with channels height, apex and cone0..cone{n-1}, at budget 0 and
// with the full baker, whose maps are bake_bilinear_cones' own for the heights it stores.
TEST(Cli, BakesBilinearConesToAnExrWithApexHeights) {
  TempDir dir;
  namespace bake = displace::bake;
  const std::string source =
      "bake --source bricks --map-size 24 --seed 3 --sectors 4 --address clamp --cones bilinear ";
  const RunResult budgeted =
      run_displace(dir, source + "--mode budgeted --budget-ms 0 --output '" + (dir / "b.exr").string() + "'");
  ASSERT_EQ(budgeted.exit_code, 0) << budgeted.err;
  EXPECT_NE(budgeted.out.find("bilinear cones"), std::string::npos) << budgeted.out;
  EXPECT_NE(budgeted.out.find("0 ms budget"), std::string::npos) << budgeted.out;
  const RunResult full =
      run_displace(dir, source + "--mode full --stats --output '" + (dir / "f.exr").string() + "'");
  ASSERT_EQ(full.exit_code, 0) << full.err;
  for (const char* key :
       {"\"mode\":\"full\"", "\"cones\":\"bilinear\"", "\"sectors\":4", "\"mean_ratio\":"}) {
    EXPECT_NE(full.out.find(key), std::string::npos) << key << " in " << full.out;
  }

  for (const auto& [file, mode] : {std::pair{"b.exr", "budgeted"}, std::pair{"f.exr", "full"}}) {
    const FloatImage image = read_float_image(dir / file);
    std::vector<std::string> names = image.channel_names;  // EXR stores channels sorted by name
    std::sort(names.begin(), names.end());
    EXPECT_EQ(names, (std::vector<std::string>{"apex", "cone0", "cone1", "cone2", "cone3", "height"}))
        << file;
    EXPECT_EQ(std::get<std::string>(find_attribute(image.metadata, "displace:cones")->value), "bilinear")
        << file;
    EXPECT_EQ(std::get<std::string>(find_attribute(image.metadata, "displace:mode")->value), mode) << file;
    const std::vector<float> heights = image.channel("height"), apex = image.channel("apex");
    ASSERT_EQ(heights.size(), 24u * 24u);
    std::vector<float> ratios(heights.size() * 4), baked_apex(heights.size());
    bake::bake_bilinear_cones({heights.data(), 24, 24}, bake::Address::clamp, {ratios.data(), 24, 24, 4},
                              baked_apex);
    const bool full_mode = std::string(mode) == "full";
    if (full_mode) {
      EXPECT_EQ(apex, baked_apex);
    }
    std::vector<std::vector<float>> planes;
    for (int k = 0; k < 4; ++k) planes.push_back(image.channel("cone" + std::to_string(k)));
    for (std::size_t t = 0; t < heights.size(); ++t) {
      EXPECT_GE(apex[t], heights[t]) << file << " texel " << t;
      for (int k = 0; k < 4; ++k) {
        const float ratio = planes[std::size_t(k)][t];
        EXPECT_TRUE(ratio > 0.0f && ratio <= 1.0f) << file << " texel " << t;
        if (full_mode) {
          EXPECT_EQ(ratio, ratios[t * 4 + std::size_t(k)]) << t;
        }
      }
    }
  }
}

// A bake of about a second or more with stderr in a file, not a terminal: no progress line.
TEST(Cli, ALongBakeDrawsNoProgressWhenStderrIsNotATerminal) {
  TempDir dir;
  const RunResult result =
      run_displace(dir,
                   "bake --source ocean --map-size 256 --time 0 --sectors 4 --cones bilinear "
                   "--mode full --output '" +
                       (dir / "c.exr").string() + "'");
  ASSERT_EQ(result.exit_code, 0) << result.err;
  EXPECT_EQ(result.err, "");
  EXPECT_NE(result.out.find("displace: baked 4-sector bilinear cones"), std::string::npos) << result.out;
}

// Modes and flags that do not go with --cones bilinear: exit 2, one error naming the problem.
TEST(Cli, BilinearConesRefuseOtherModesWithOneError) {
  TempDir dir;
  const std::string bake =
      "bake --source ocean --map-size 16 --time 0 --sectors 4 --output '" + (dir / "c.exr").string() + "' ";
  const struct {
    std::string arguments, message;
  } cases[] = {
      {bake + "--cones bilinear --mode exact", "--cones bilinear bakes with --mode budgeted|full"},
      {bake + "--cones bilinear --mode original", "--cones bilinear bakes with --mode budgeted|full"},
      {bake + "--cones bilinear --mode paper-adaptive", "--cones bilinear bakes with --mode budgeted|full"},
      {bake + "--cones bilinear --relaxed", "not --relaxed"},
      {bake + "--cones bilinear", "needs --mode budgeted|full"},
      {bake + "--mode full", "--mode full bakes bilinear cones only"},
      {bake + "--cones center --mode full", "--mode full bakes bilinear cones only"},
      {bake + "--cones bilinear --mode full --budget-ms 0", "--budget-ms applies to --mode budgeted only"},
      {bake + "--cones bilinear --mode full --tolerance 0.1", "--tolerance applies to --mode budgeted only"},
      {bake + "--cones bilinear --mode budgeted --budget-ms -1", "--budget-ms must be between 0"},
      {bake + "--cones sideways --mode full", "--cones must be one of center|bilinear"},
  };
  for (const auto& test : cases) {
    const RunResult result = run_displace(dir, test.arguments);
    EXPECT_TRUE(result.exited) << test.arguments;
    EXPECT_EQ(result.exit_code, 2) << test.arguments << "\n" << result.err;
    EXPECT_NE(result.err.find(test.message), std::string::npos) << test.arguments << "\n" << result.err;
    EXPECT_EQ(result.err.find("displace: error: "), result.err.rfind("displace: error: ")) << result.err;
  }
  EXPECT_FALSE(fs::exists(dir / "c.exr"));
}

// A bilinear cone map PNG for engines, decoded: every ratio at most and every apex at least what
// bake_bilinear_cones bakes for the heights it stores, on every texel; cone panels, then the height
// panel, then the apex panel.
TEST(Cli, BakesABilinearPngThatDecodesConservatively) {
  TempDir dir;
  namespace bake = displace::bake;
  std::mt19937 random(8);
  std::vector<std::uint8_t> pixels(20 * 14);
  for (auto& p : pixels) p = std::uint8_t(random() % 4 == 0 ? random() : 90 + random() % 20);
  write_with_oiio(dir / "h.png", 20, 14, 1, OIIO::TypeDesc::UINT8, pixels.data());
  for (const int sectors : {1, 4, 8})
    for (const bake::Address address : {bake::Address::wrap, bake::Address::clamp}) {
      const std::string address_word = address == bake::Address::wrap ? "wrap" : "clamp";
      const fs::path file = dir / ("c" + std::to_string(sectors) + address_word + ".png");
      const RunResult result =
          run_displace(dir, "bake --input '" + (dir / "h.png").string() + "' --sectors " +
                                std::to_string(sectors) + " --address " + address_word +
                                " --cones bilinear --mode full --output '" + file.string() + "'");
      ASSERT_EQ(result.exit_code, 0) << result.err;

      const DecodedConeMap decoded = read_cone_png(file);
      ASSERT_EQ(decoded.kind, ConeKind::bilinear);
      ASSERT_EQ(decoded.width, 20);
      ASSERT_EQ(decoded.height, 14);
      ASSERT_EQ(decoded.sector_count, sectors);
      for (std::size_t k = 0; k < pixels.size(); ++k)
        ASSERT_EQ(decoded.heights[k], float(pixels[k]) / 255.0f);
      std::vector<float> ratios(pixels.size() * std::size_t(sectors)), apex(pixels.size());
      bake::bake_bilinear_cones({decoded.heights.data(), 20, 14}, address, {ratios.data(), 20, 14, sectors},
                                apex);
      long long below = 0;
      for (std::size_t k = 0; k < ratios.size(); ++k) {
        EXPECT_LE(decoded.ratios[k], ratios[k]) << sectors << " " << address_word << " " << k;
        below += decoded.ratios[k] < ratios[k];
      }
      EXPECT_GT(below, 0);  // the check compares against something, not against itself
      for (std::size_t t = 0; t < apex.size(); ++t) {
        EXPECT_GE(decoded.apex[t], apex[t]) << sectors << " " << address_word << " " << t;
        EXPECT_LE(decoded.apex[t], apex[t] + 1.0f / 255.0f + 1e-6f);
      }

      // layout: ceil(n / 4) cone panels, the height panel, the apex panel
      const Rgba8Image image = read_rgba8_image(file);
      const int panels = (sectors + 3) / 4;
      ASSERT_EQ(image.width, (panels + 2) * 20);
      ASSERT_EQ(image.height, 14);
      for (int i = 0; i < 14; ++i)
        for (int j = 0; j < 20; ++j) {
          const std::size_t t = std::size_t(i * 20 + j);
          const auto pixel = [&](int panel) {
            return &image.pixels[std::size_t(i * image.width + panel * 20 + j) * 4];
          };
          EXPECT_EQ(pixel(panels)[0], pixels[t]);
          EXPECT_EQ(pixel(panels + 1)[0], encode_height_up(apex[t]));
          for (const int panel : {panels, panels + 1}) {
            EXPECT_EQ(pixel(panel)[1], 0);
            EXPECT_EQ(pixel(panel)[2], 0);
            EXPECT_EQ(pixel(panel)[3], 255);
          }
          if (sectors == 1) {
            EXPECT_EQ(pixel(0)[1], 0);
            EXPECT_EQ(pixel(0)[3], 255);
          }
        }
    }
}

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

namespace {

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

// --bake-tolerance: an unlimited bake at tolerance 0 searches texels that one at 0.9 leaves to stage
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
      "--method acm8 --compare reference --output '" +
      out + "' --bake-tolerance ";
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
      {ok, 2},  // no --method
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
      {ok + " --method relief --bake-tolerance 0.5", 2},  // relief reads no cone map
      {ok + " --method acm4 --bake-tolerance 1", 2},
      {ok + " --method acm4 --bake-tolerance -0.1", 2},
      {ok + " --method acm4 --bake-tolerance nan", 2},
  };
  for (const auto& test : cases) {
    const RunResult result = run_displace(dir, test.arguments);
    EXPECT_TRUE(result.exited) << test.arguments;
    EXPECT_EQ(result.exit_code, test.exit_code) << test.arguments << "\n" << result.err;
    EXPECT_NE(result.err.find("displace: error: "), std::string::npos) << test.arguments << "\n"
                                                                       << result.err;
    EXPECT_EQ(result.err.find("displace: error: "), result.err.rfind("displace: error: ")) << result.err;
  }
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

}  // namespace

namespace {

// A sweep of a small scene file: one CSV row per method and step count, the fewest fetches that
// reach the target, and the cone maps it rendered from - baked at the budget and tolerance asked
// (budget 0: stage L alone, no texel searched; unlimited at tolerance 0: texels searched).
TEST(Cli, SweepsASceneFileAndSaysWhatItsConeMapsCost) {
  TempDir dir;
  std::ofstream(dir / "small.scene") << "# a small ocean\n--source ocean\n--map-size 32\n--time 0\n"
                                        "--size 40x32\n";
  const std::string csv = (dir / "s.csv").string();
  const std::string common = "sweep --scene '" + (dir / "small.scene").string() +
                             "' --methods acm4,pom --steps 16,64 --repeat 1 --output '" + csv + "' ";
  auto searched = [](const std::string& out) {
    const std::size_t at = out.find("cone maps, 4 sectors: ");
    EXPECT_NE(at, std::string::npos) << out;
    const std::size_t end = out.find(" texels searched", at), of = out.rfind(" of ", end);
    const std::size_t from = out.rfind(", ", of);
    return std::stol(out.substr(from + 2, of - from - 2));
  };
  const RunResult starved = run_displace(dir, common + "--bake-budget-ms 0");
  ASSERT_EQ(starved.exit_code, 0) << starved.err;
  EXPECT_NE(starved.out.find("cone maps baked within a 0 ms budget at tolerance 0.25"), std::string::npos)
      << starved.out;
  EXPECT_EQ(searched(starved.out), 0) << starved.out;
  // only acm4 reads cone maps
  EXPECT_EQ(starved.out.find("cone maps, 1 sector"), std::string::npos) << starved.out;
  std::ifstream table(csv);
  std::string line;
  int rows = 0;
  std::getline(table, line);
  EXPECT_EQ(line.rfind("scene,method,steps,", 0), 0u) << line;
  while (std::getline(table, line)) rows += line.rfind("small,", 0) == 0 ? 1 : 0;
  EXPECT_EQ(rows, 4);  // 2 methods x 2 step counts
  const RunResult exact = run_displace(dir, common + "--bake-tolerance 0");
  ASSERT_EQ(exact.exit_code, 0) << exact.err;
  EXPECT_NE(exact.out.find("cone maps baked with an unlimited budget at tolerance 0\n"), std::string::npos)
      << exact.out;
  EXPECT_GT(searched(exact.out), 0) << exact.out;
}

TEST(Cli, SweepRejectsMalformedSceneFilesWithOneError) {
  TempDir dir;
  const auto scene = [&](const std::string& name, const std::string& text) {
    std::ofstream(dir / name) << text;
    return "sweep --scene '" + (dir / name).string() + "' --output '" + (dir / "s.csv").string() + "'";
  };
  const struct {
    std::string arguments;
    int exit_code;
  } cases[] = {
      // a scene file's content is a file's, not the command line's: exit status 1 like any bad file
      {scene("method.scene", "--source ocean\n--map-size 16\n--time 0\n--method pom\n"), 1},
      {scene("two.scene", "--source ocean\n--map-size 16 --time\n"), 1},
      {scene("word.scene", "source ocean\n"), 1},
      {scene("empty.scene", "# nothing\n"), 1},
      {"sweep --scene '" + (dir / "missing.scene").string() + "' --output s.csv", 1},  // a missing file
  };
  for (const auto& [arguments, exit_code] : cases) {
    const RunResult result = run_displace(dir, arguments);
    EXPECT_EQ(result.exit_code, exit_code) << arguments << "\n" << result.err;
    EXPECT_EQ(result.err.find("displace: error: "), result.err.rfind("displace: error: ")) << result.err;
    EXPECT_NE(result.err.find("scene"), std::string::npos) << result.err;
    EXPECT_EQ(result.err.find("--help"), std::string::npos) << result.err;
  }
  EXPECT_FALSE(fs::exists(dir / "s.csv"));
}

}  // namespace

namespace {

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

// `displace play --frames N` under Xvfb: a window, a swapchain on lavapipe, zero validation messages,
// and the screenshot of frame N - 1 is, bit for bit, what the frame pipeline renders for that index.
TEST(Cli, ReportRejectsBadFlagsAndUnreadableScenesWithOneError) {
  TempDir dir;
  const std::string output = " --no-plots --output '" + (dir / "r").string() + "'";
  const RunResult small = run_displace(dir, "report --size 8" + output);
  EXPECT_EQ(small.exit_code, 2);
  EXPECT_NE(small.err.find("--size"), std::string::npos) << small.err;
  const RunResult invert = run_displace(dir, "report --invert --scene ocean" + output);
  EXPECT_EQ(invert.exit_code, 2);
  EXPECT_NE(invert.err.find("--invert needs a height image"), std::string::npos) << invert.err;
  const RunResult missing =
      run_displace(dir, "report --scene '" + (dir / "missing.png").string() + "'" + output);
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_NE(missing.err.find("missing.png"), std::string::npos) << missing.err;
  EXPECT_EQ(std::count(missing.err.begin(), missing.err.end(), '\n'), 1) << missing.err;
  const RunResult bad_file =
      run_displace(dir, "report --scene '" + (dir / "missing.txt").string() + "'" + output);
  EXPECT_EQ(bad_file.exit_code, 1);
  EXPECT_NE(bad_file.err.find("missing.txt"), std::string::npos) << bad_file.err;
  EXPECT_FALSE(fs::exists(dir / "r")) << "a report that cannot start writes nothing";
}

TEST(Cli, PlayRendersThePipelinesFramesInAWindow) {
  if (std::system("command -v xvfb-run >/dev/null 2>&1") != 0) {
    GTEST_SKIP() << "xvfb-run is missing ('apt-get install xvfb'); `displace play` needs a display";
  }
  namespace pipeline = displace::pipeline;
  namespace render = displace::render;
  TempDir dir;
  const fs::path shot = dir / "play.png";
  const RunResult played = run_displace(
      dir, "play --frames 3 --size 64x64 --map-size 32 --screenshot '" + shot.string() + "' --validate",
      "xvfb-run -a ");
  ASSERT_EQ(played.exit_code, 0) << played.err << played.out;
  EXPECT_EQ(played.err.find("validation"), std::string::npos) << played.err;
  EXPECT_NE(played.out.find("play: 3 frames of water"), std::string::npos) << played.out;
  // after the warm-up a frame allocates no device memory (frames 3..6 of 8; the last reads back)
  const RunResult longer = run_displace(dir, "play --frames 8 --size 64x64 --map-size 32", "xvfb-run -a ");
  ASSERT_EQ(longer.exit_code, 0) << longer.err;
  EXPECT_NE(longer.out.find(", 0 device allocations in frames 3..6"), std::string::npos) << longer.out;
  const Rgba8Image image = read_rgba8_image(shot);

  pipeline::Scene scene = pipeline::builtin_scene("water");
  scene.camera.width = scene.camera.height = 64;
  scene.map_size = 32;
  render::RendererOptions options;
  options.validate = true;
  render::Renderer renderer(options);
  pipeline::FramePipeline frames(scene, renderer);
  render::Frame frame;
  frames.run(2, frame, render::output_color);
  EXPECT_EQ(renderer.validation_messages(), 0);
  ASSERT_EQ(image.width, 64);
  ASSERT_EQ(image.height, 64);
  ASSERT_EQ(image.pixels.size(), frame.color.size());
  long long different = 0;
  for (std::size_t i = 0; i < frame.color.size(); ++i) different += image.pixels[i] != frame.color[i];
  EXPECT_EQ(different, 0) << "bytes of the screenshot that differ from the pipeline's frame 2";
}

// Without a display, `displace play` says how to get one and exits 1; its help lists the keys.
TEST(Cli, PlayWithoutADisplaySaysWhatToRun) {
  TempDir dir;
  const RunResult result =
      run_displace(dir, "play --frames 1 --size 64x64 --map-size 32", "env -u DISPLAY -u WAYLAND_DISPLAY ");
  EXPECT_EQ(result.exit_code, 1) << result.err;
  EXPECT_EQ(result.err,
            "displace: error: no display: run 'xvfb-run -a displace play ...' or render frames headless with "
            "'displace sequence'\n");
  const RunResult help = run_displace(dir, "play --help");
  EXPECT_EQ(help.exit_code, 0);
  for (const char* key :
       {"Space", "Shift+M", "Up / Down", "Right / Left", "screenshot", "orbit", "--frames"}) {
    EXPECT_NE(help.out.find(key), std::string::npos) << key;
  }
  const RunResult usage = run_displace(dir, "play --screenshot f.png");
  EXPECT_EQ(usage.exit_code, 2);
  EXPECT_NE(usage.err.find("--screenshot needs --frames"), std::string::npos) << usage.err;
}

}  // namespace

namespace {

std::string file_bytes(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// Every file of `directory` with its bytes, except the CSVs and job logs (which hold timings).
std::map<std::string, std::string> frames_in(const fs::path& directory) {
  std::map<std::string, std::string> files;
  for (const auto& entry : fs::directory_iterator(directory)) {
    const std::string name = entry.path().filename().string();
    if (entry.path().extension() == ".csv" || name.find("joblog") != std::string::npos) continue;
    files[name] = file_bytes(entry.path());
  }
  return files;
}

const char* const small_sequence = "--scene water --map-size 32 --size 48x32 --bake-work 800";

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
      {"render --source bricks --map-size 16384 --method reference --tile 64 --size 16x16" + to_png, "",
       "more than 32-bit indices address: lower --tile or --map-size"},
      {"render --source bricks --map-size 8192 --method acm8 --size 16x16" + to_png, limit,
       "lower --map-size"},
      {"bake --source bricks --map-size 16384 --sectors 8 --mode budgeted --output '" +
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

}  // namespace

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

// The GNU parallel recipe (demos/farm/parallel.sh) on this machine: three shards as parallel jobs
// give the files of one run.
TEST(Cli, GnuParallelShardsGiveTheFilesOfOneRun) {
  if (std::system("command -v parallel >/dev/null 2>&1") != 0) {
    GTEST_SKIP() << "GNU parallel is not installed (cmake/setup.sh installs it)";
  }
  TempDir dir;
  const std::string whole = dir.operator/("whole").string(), farm = dir.operator/("farm").string();
  ASSERT_EQ(run_displace(dir, std::string("sequence ") + small_sequence + " --frames 0:4 --output '" + whole +
                                  "/f_##.png'")
                .exit_code,
            0);
  const std::string script = std::string(DISPLACE_SOURCE_DIR) + "/demos/farm/parallel.sh";
  const std::string command = "DISPLACE='" + std::string(DISPLACE_BINARY) + "' bash '" + script +
                              "' 3 0:4 '" + farm + "/f_##.png' " + small_sequence + " >/dev/null 2>&1";
  ASSERT_EQ(std::system(command.c_str()), 0);
  EXPECT_TRUE(fs::exists(fs::path(farm) / "parallel.joblog"));
  EXPECT_EQ(frames_in(farm), frames_in(whole));
  EXPECT_EQ(frames_in(whole).size(), 5u);
}

// bench-frame: the per-stage table and its JSON, no Vulkan allocation after warm-up.
TEST(Cli, BenchFrameWritesTheTableAndItsJson) {
  TempDir dir;
  const std::string json = dir.operator/("bench.json").string();
  const RunResult run = run_displace(
      dir,
      "bench-frame --scene water --map-size 32 --size 32x32 --frames 6 --warm-up 2 --budget-ms 50 --json '" +
          json + "'");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_NE(run.out.find("p50 ms"), std::string::npos) << run.out;
  const nlohmann::json parsed = nlohmann::json::parse(read_text(json));
  EXPECT_EQ(parsed["frames"], 6);
  EXPECT_EQ(parsed["budget_ms"], 50.0);
  for (const char* stage : {"sim", "bake", "upload", "render", "frame"}) {
    for (const char* key : {"p50_ms", "p95_ms", "p99_ms"})
      EXPECT_TRUE(parsed["stages"][stage][key].is_number());
  }
  EXPECT_TRUE(parsed["within_budget"].is_number());
  EXPECT_EQ(parsed["ffts_per_frame"], 6.0);
  EXPECT_EQ(parsed["effects"], nlohmann::json({"heights", "choppy", "foam"}));
  EXPECT_EQ(parsed["vulkan_allocations_after_warmup"], 0);
  // every frame came back, and resident memory was sampled (the soak's figures, tests/soak.sh)
  EXPECT_EQ(parsed["frames_rendered"], 6);
  const nlohmann::json& rss = parsed["rss_kb"];
  ASSERT_TRUE(rss.is_object()) << parsed.dump();
  EXPECT_GT(rss["after_warmup"].get<long long>(), 0);
  EXPECT_GE(rss["max"].get<long long>(), rss["end"].get<long long>());
  EXPECT_GE(rss["max"].get<long long>(), rss["after_warmup"].get<long long>());
  EXPECT_EQ(rss["growth"].get<long long>(),
            rss["end"].get<long long>() - rss["after_warmup"].get<long long>());
  EXPECT_EQ(parsed["overlapped"], true);
  EXPECT_EQ(parsed["pinned_threads"], 0);
  // --serial: the same table from the stages run one after another; --pin-threads: with the main
  // thread, TBB's worker(s) and lavapipe's rasterizers each on one CPU (none pinned on one CPU)
  const RunResult serial = run_displace(dir,
                                        "bench-frame --scene water --map-size 32 --size 32x32 --frames 3 "
                                        "--warm-up 2 --serial --pin-threads --json '" +
                                            json + "'");
  ASSERT_EQ(serial.exit_code, 0) << serial.err;
  EXPECT_NE(serial.out.find("stages in series"), std::string::npos) << serial.out;
  const nlohmann::json in_series = nlohmann::json::parse(read_text(json));
  EXPECT_EQ(in_series["overlapped"], false);
  cpu_set_t cpus;
  if (sched_getaffinity(0, sizeof cpus, &cpus) == 0 && CPU_COUNT(&cpus) >= 2) {
    EXPECT_NE(serial.out.find("pinned one per CPU"), std::string::npos) << serial.out;
    EXPECT_GE(in_series["pinned_threads"].get<int>(), 2);
  }
  EXPECT_EQ(in_series["frames_rendered"], 3);
  EXPECT_EQ(in_series["ffts_per_frame"], 6.0);
  EXPECT_EQ(in_series["vulkan_allocations_after_warmup"], 0);
  EXPECT_GT(in_series["stages"]["render"]["p50_ms"].get<double>(), 0.0);
}

// Flag limits agree with what the code accepts, and usage errors exit 2 with the project's words.
TEST(Cli, OceanSizeAndZeroLightAreUsageErrors) {
  TempDir dir;
  const RunResult big =
      run_displace(dir, "render --source ocean --map-size 16384 --time 0 --method bump --output a.png");
  EXPECT_EQ(big.exit_code, 2);
  EXPECT_NE(big.err.find("at most 8192"), std::string::npos) << big.err;
  EXPECT_EQ(big.err.find("OceanParams"), std::string::npos) << big.err;
  const RunResult dark = run_displace(
      dir, "render --source ocean --map-size 16 --time 0 --method bump --light 0,0,0 --output a.png");
  EXPECT_EQ(dark.exit_code, 2);
  EXPECT_NE(dark.err.find("--light"), std::string::npos) << dark.err;
}
