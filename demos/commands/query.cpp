// demos/commands/query.cpp - `displace query`: heights of a scene's surface at points read from a CSV
// (or standard input), for one time, as a CSV or JSON (pipeline/query.h: the surface the renderer
// draws, camera-independent).
#include "pipeline/query.h"

#include <fmt/format.h>

#include <charconv>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <ostream>
#include <sstream>
#include <string>
#include <vector>

#include "demos/cli/command.h"
#include "demos/cli/flags.h"
#include "demos/cli/scene_flags.h"
#include "demos/commands/settings.h"
#include "demos/error.h"
#include "demos/frame_output.h"
#include "demos/heights.h"

namespace displace::app {
namespace {

// "x,y" lines (a first line "x,y" is the header; blank lines are skipped); refuses anything else with
// the source's name and line.
std::vector<pipeline::QueryPoint> read_points(std::istream& in, const std::string& name) {
  std::vector<pipeline::QueryPoint> points;
  std::string line;
  for (long long number = 1; std::getline(in, line); ++number) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.find_first_not_of(" \t") == std::string::npos) continue;
    if (number == 1 && line == "x,y") continue;
    const auto comma = line.find(',');
    auto parse = [&](std::string_view text, double& value) {
      while (!text.empty() && (text.front() == ' ' || text.front() == '\t')) text.remove_prefix(1);
      while (!text.empty() && (text.back() == ' ' || text.back() == '\t')) text.remove_suffix(1);
      const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
      return error == std::errc{} && end == text.data() + text.size() && std::isfinite(value);
    };
    pipeline::QueryPoint point;
    if (comma == std::string::npos || !parse(std::string_view(line).substr(0, comma), point.x) ||
        !parse(std::string_view(line).substr(comma + 1), point.y)) {
      throw usage_error(fmt::format("{}:{}: expects two finite numbers 'x,y' (metres), got '{}'", name,
                                    number, line.substr(0, 60)));
    }
    points.push_back(point);
  }
  return points;
}

}  // namespace

void run_query(const QuerySettings& settings, std::ostream& out) {
  std::vector<pipeline::QueryPoint> points;
  if (settings.points == "-") {
    points = read_points(std::cin, "standard input");
  } else {
    std::ifstream file(settings.points);
    if (!file) throw usage_error(fmt::format("cannot read the points file '{}'", settings.points));
    points = read_points(file, settings.points);
  }
  pipeline::QueryResult result;
  try {
    pipeline::HeightQuery query(settings.scene, height_loader(settings.scene.image_read));
    query.query(points, settings.scene.start, result);
  } catch (const pipeline::SceneError& error) {
    throw usage_error(error.what());
  }
  std::ostringstream text;
  if (settings.json) {
    nlohmann::ordered_json rows = nlohmann::ordered_json::array();
    for (std::size_t n = 0; n < points.size(); ++n) {
      rows.push_back({{"x_m", points[n].x},
                      {"y_m", points[n].y},
                      {"height_m", result.height_m[n]},
                      {"z", result.z[n]},
                      {"normal", {result.normal[n].x, result.normal[n].y, result.normal[n].z}},
                      {"displacement_m", {result.displacement[n].x, result.displacement[n].y}}});
    }
    text << nlohmann::ordered_json{{"scene", settings.scene.name},
                                   {"time_s", settings.scene.start},
                                   {"points", rows}}
                .dump(2)
         << '\n';
  } else {
    text << "x,y,height_m,z,nx,ny,nz,dx,dy\n";
    for (std::size_t n = 0; n < points.size(); ++n) {
      text << fmt::format("{},{},{:.7g},{:.7g},{:.7g},{:.7g},{:.7g},{:.7g},{:.7g}\n", points[n].x,
                          points[n].y, result.height_m[n], result.z[n], result.normal[n].x,
                          result.normal[n].y, result.normal[n].z, result.displacement[n].x,
                          result.displacement[n].y);
    }
  }
  if (settings.output == "-") {
    out << text.str();
    return;
  }
  files::write_file(settings.output, text.str());
  out << fmt::format("displace query: {} points of {} at t = {:g} s; wrote '{}'\n", points.size(),
                     settings.scene.name, settings.scene.start, settings.output);
}

Finish add_query_command(CLI::App& command) {
  command.description(
      "Heights of a scene's surface at points (CSV columns x,y in metres; '-' reads standard input) at one "
      "time (--time): the surface the renderer draws, camera-independent, with its normal and, for choppy "
      "water, the horizontal displacement. CSV columns x,y,height_m,z,nx,ny,nz,dx,dy (z and the normal in "
      "the renderer's world), or JSON with --json.");
  command.footer(
      "--json writes one object (snake_case keys, units in the names): scene, time_s, points: an array of\n"
      "{x_m, y_m, height_m, z (the renderer's world z), normal ([x, y, z], unit length, the renderer's\n"
      "world), displacement_m ([x, y]: where the water there came from; 0 without choppy crests)}.");
  auto flags = std::make_shared<cli::SceneFlags>();
  auto settings = std::make_shared<QuerySettings>();
  cli::add_scene_flags(command, *flags, cli::scene_source | cli::scene_view, "ocean");
  command.option_defaults()->group("Options");
  cli::add_value(command, "--points", settings->points, "the points, CSV x,y in metres", "IN.csv|-",
                 cli::not_empty())
      ->required();
  cli::add_value(command, "--output", settings->output, "the answers", "OUT.csv|OUT.json|-", cli::not_empty())
      ->required();
  cli::add_switch(command, "--json", settings->json, "JSON instead of CSV");
  return [&command, flags, settings] {
    QuerySettings finished = *settings;
    finished.scene = cli::finish_scene(command, *flags);
    return ParsedCommand{"query", finished, [finished](std::ostream& out) { run_query(finished, out); }};
  };
}

}  // namespace displace::app
