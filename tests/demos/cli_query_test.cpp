// tests/demos/cli_query_test.cpp - `displace query`, end to end: its heights against a bilinear
// interpolation of `displace sim`'s heights for the same scene and time (texel centres, edges,
// corners, across the wrap), JSON, and bad points refused.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "demos/image_io.h"
#include "tests/demos/demos_fixtures.h"

namespace {

namespace fs = std::filesystem;
using namespace displace::app;

TEST(Cli, QueryEqualsTheBilinearSurfaceOfSimsHeights) {
  TempDir dir;
  const std::string scene = "--scene water --map-size 32 --time 2.5";
  RunResult result = run_displace(dir, "sim " + scene + " --output '" + (dir / "h.exr").string() + "'");
  ASSERT_EQ(result.exit_code, 0) << result.err;
  const FloatImage image = read_float_image(dir / "h.exr");
  const std::vector<float> heights = image.channel("height");
  const int n = 32;
  const double patch = 200.0;
  auto bilinear = [&](double x, double y) {  // texel coordinates, centres at integers, periodic
    auto at = [&](double i, double j) {
      const int row = int(i - n * std::floor(i / n)), column = int(j - n * std::floor(j / n));
      return double(heights[std::size_t(row) * n + std::size_t(column)]);
    };
    const double fx = std::floor(x), fy = std::floor(y), tx = x - fx, ty = y - fy;
    const double top = at(fy, fx) + (at(fy, fx + 1) - at(fy, fx)) * tx;
    const double bottom = at(fy + 1, fx) + (at(fy + 1, fx + 1) - at(fy + 1, fx)) * tx;
    return top + (bottom - top) * ty;
  };
  std::vector<std::pair<double, double>> points;  // in texels: centres (.5), edges (.0), corners, wrapped
  for (double i : {0.5, 1.0, 9.5, 31.5, 32.0, -0.5, 40.25}) {
    for (double j : {0.5, 3.0, 31.5, 32.0, -7.75}) points.push_back({j, i});
  }
  {
    std::ofstream csv(dir / "points.csv");
    csv.precision(17);  // the points where the expectation puts them (6 digits move 251.5625 by 0.5 mm)
    csv << "x,y\n";
    for (const auto& [j, i] : points) csv << j / n * patch << "," << i / n * patch << "\n";
  }
  result = run_displace(dir, "query " + scene + " --points '" + (dir / "points.csv").string() +
                                 "' --output '" + (dir / "out.csv").string() + "'");
  ASSERT_EQ(result.exit_code, 0) << result.err;
  std::ifstream answers(dir / "out.csv");
  std::string line;
  std::getline(answers, line);
  EXPECT_EQ(line, "x,y,height_m,z,nx,ny,nz,dx,dy");
  for (const auto& [j, i] : points) {
    ASSERT_TRUE(std::getline(answers, line));
    std::vector<double> values;
    std::stringstream fields(line);
    for (std::string field; std::getline(fields, field, ',');) values.push_back(std::stod(field));
    ASSERT_EQ(values.size(), 9u) << line;
    EXPECT_NEAR(values[2], bilinear(j - 0.5, i - 0.5), 1e-5) << line;
  }

  // JSON, and points from standard input
  result = run_displace(
      dir, "query " + scene + " --json --points - --output - < '" + (dir / "points.csv").string() + "'");
  ASSERT_EQ(result.exit_code, 0) << result.err;
  const nlohmann::json json = nlohmann::json::parse(result.out);
  ASSERT_EQ(json["points"].size(), points.size());
  EXPECT_NEAR(json["points"][0]["height_m"].get<double>(), bilinear(0.0, 0.0), 1e-5);
  EXPECT_EQ(json["points"][0]["normal"].size(), 3u);

  // bad points: one line naming the file and line, exit 2
  {
    std::ofstream bad(dir / "bad.csv");
    bad << "x,y\n1,2\n3;4\n";
  }
  result = run_displace(dir, "query --scene water --points '" + (dir / "bad.csv").string() + "' --output -");
  EXPECT_EQ(result.exit_code, 2);
  EXPECT_NE(result.err.find("bad.csv:3"), std::string::npos) << result.err;
}

}  // namespace
