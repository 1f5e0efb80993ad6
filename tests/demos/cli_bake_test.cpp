// tests/demos/cli_bake_test.cpp - `displace bake`, end to end.
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
  for (const char* key : {"\"mode\":\"exact\"", "\"width\":16", "\"height\":12", "\"sectors\":4",
                          "\"address\":\"clamp\"", "\"bake_ms\":", "\"texels_refined\":",
                          "\"texels_fallback\":", "\"blocker_tests\":", "\"mean_ratio\":"}) {
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

// `bake --input h.png` (20 x 14 8-bit heights `pixels` in dir) with `flags`, --sectors and --address,
// to a PNG named after them; decoded, of the kind asked, holding those heights.
void bake_png(const TempDir& dir, const std::vector<std::uint8_t>& pixels, int sectors,
              const std::string& address_word, const std::string& flags, ConeKind kind,
              DecodedConeMap& decoded) {
  std::string name = "c";  // appended: GCC 12 warns (-Wrestrict) on "c" + std::string here
  name.append(std::to_string(sectors)).append(address_word).append(".png");
  const fs::path file = dir / name;
  const RunResult result = run_displace(dir, "bake --input '" + (dir / "h.png").string() + "' --sectors " +
                                                 std::to_string(sectors) + " --address " + address_word +
                                                 " " + flags + " --output '" + file.string() + "'");
  ASSERT_EQ(result.exit_code, 0) << result.err;
  decoded = read_cone_png(file);
  ASSERT_EQ(decoded.kind, kind);
  ASSERT_EQ(decoded.width, 20);
  ASSERT_EQ(decoded.height, 14);
  ASSERT_EQ(decoded.sector_count, sectors);
  for (std::size_t k = 0; k < pixels.size(); ++k) ASSERT_EQ(decoded.heights[k], float(pixels[k]) / 255.0f);
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
      DecodedConeMap decoded;
      ASSERT_NO_FATAL_FAILURE(bake_png(dir, pixels, sectors, address_word, "--cones bilinear --mode full",
                                       ConeKind::bilinear, decoded));
      std::string name = "c";  // bake_png's file
      name.append(std::to_string(sectors)).append(address_word).append(".png");
      const fs::path file = dir / name;
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

// A relaxed cone map PNG for engines (issue 49), decoded: every ratio at most the relaxed ratio of
// the definition (bake_relaxed_reference) for the heights it stores, on every texel and sector, with
// 1 and 4 sectors, wrap and clamp; so what an engine decodes is never too wide.
TEST(Cli, BakesARelaxedPngThatDecodesNeverTooWide) {
  TempDir dir;
  namespace bake = displace::bake;
  std::mt19937 random(11);
  std::vector<std::uint8_t> pixels(20 * 14);
  for (auto& p : pixels) p = std::uint8_t(random() % 5 == 0 ? random() : 60 + random() % 30);
  write_with_oiio(dir / "h.png", 20, 14, 1, OIIO::TypeDesc::UINT8, pixels.data());
  for (const int sectors : {1, 4})
    for (const bake::Address address : {bake::Address::wrap, bake::Address::clamp}) {
      const std::string address_word = address == bake::Address::wrap ? "wrap" : "clamp";
      DecodedConeMap decoded;
      ASSERT_NO_FATAL_FAILURE(
          bake_png(dir, pixels, sectors, address_word, "--relaxed", ConeKind::center, decoded));
      std::vector<float> relaxed(pixels.size() * std::size_t(sectors));
      bake::bake_relaxed_reference({decoded.heights.data(), 20, 14}, address,
                                   {relaxed.data(), 20, 14, sectors});
      long long below = 0;
      for (std::size_t k = 0; k < relaxed.size(); ++k) {
        EXPECT_LE(decoded.ratios[k], relaxed[k]) << sectors << " " << address_word << " " << k;
        EXPECT_EQ(encode_ratio(relaxed[k]), encode_ratio(decoded.ratios[k]))
            << "the byte of the relaxed ratio";
        below += decoded.ratios[k] < relaxed[k];
      }
      EXPECT_GT(below, 0);  // the check compares against something, not against itself
    }
}

}  // namespace
