// demos/commands/report.cpp - `displace report`: what accuracy costs in time, measured on this machine
// and written as the CSV and JSON behind every figure (demos/report_parts.h); demos/report/plot_report.py
// turns them into PNG figures (matplotlib) and the report's README.md.
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <ostream>
#include <string>
#include <thread>
#include <vector>

#include "demos/cli/command.h"
#include "demos/cli/flags.h"
#include "demos/cli/scene_flags.h"
#include "demos/commands/settings.h"
#include "demos/error.h"
#include "demos/frame_output.h"
#include "demos/heights.h"
#include "demos/report_parts.h"
#include "pipeline/frame_pipeline.h"
#include "pipeline/maps.h"

#ifndef DISPLACE_REPORT_SCRIPT
#error "DISPLACE_REPORT_SCRIPT (the plotting script's path) is set by demos/CMakeLists.txt"
#endif

extern char** environ;

namespace displace::app {
namespace {

using namespace report;

class Stopwatch {
 public:
  double seconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }

 private:
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
};

// ---- the plots

std::string python_interpreter() {
  if (const char* chosen = std::getenv("DISPLACE_PYTHON"); chosen && *chosen) return chosen;
  // Debian's interpreter, where python3-matplotlib lives (a pyenv or venv python3 earlier on the
  // PATH usually lacks it)
  if (::access("/usr/bin/python3", X_OK) == 0) return "/usr/bin/python3";
  return "python3";
}

void run_plots(const std::filesystem::path& directory) {
  const std::string python = python_interpreter();
  const std::string script = DISPLACE_REPORT_SCRIPT;
  const std::string target = directory.string();
  std::vector<char*> argv = {const_cast<char*>(python.c_str()), const_cast<char*>(script.c_str()),
                             const_cast<char*>(target.c_str()), nullptr};
  pid_t child = 0;
  if (::posix_spawnp(&child, python.c_str(), nullptr, nullptr, argv.data(), environ) != 0) {
    throw runtime_error(
        fmt::format("cannot start {} for the report's figures (apt-get install python3-matplotlib, "
                    "or --no-plots for the data alone)",
                    python));
  }
  int status = 0;
  while (::waitpid(child, &status, 0) < 0) {
    if (errno != EINTR) throw runtime_error("lost the plotting script's process");
  }
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    throw runtime_error(fmt::format(
        "the report's plotting script {} failed (its message is above); the data is in {}", script, target));
  }
}

}  // namespace

void run_report(const ReportSettings& settings, std::ostream& out) {
  const Plan plan = make_plan(settings.quick, settings.image_side);
  // every scene read first: one that cannot be read fails before the long runs and writes nothing
  for (const pipeline::Scene& scene : settings.scenes) scene_heights(scene, scene.start);
  std::error_code error;
  std::filesystem::create_directories(settings.output, error);
  if (error)
    throw runtime_error("cannot make the report's directory " + settings.output.string() + ": " +
                        error.message());

  const Stopwatch whole;
  render::Renderer renderer(settings.renderer);
  pipeline::MapMaker maps(renderer.device().max_image_dimension_3d);
  out << fmt::format("displace report ({}) on {} ({}), {} x {} pixels, into {}\n",
                     settings.quick ? "quick" : "full", renderer.device().name, renderer.device().type,
                     plan.image_side, plan.image_side, settings.output.string())
      << std::flush;

  nlohmann::json seconds;
  const auto timed = [&](const char* part, const auto& work) {
    const Stopwatch watch;
    work();
    seconds[part] = std::round(watch.seconds() * 10.0) / 10.0;
  };
  const pipeline::Scene& main = main_scene(settings.scenes);
  timed("cost", [&] { cost_part(renderer, maps, settings.scenes, plan, settings.output, out); });
  timed("grazing", [&] { grazing_part(renderer, maps, settings.scenes, plan, settings.output, out); });
  timed("bake", [&] { bake_part(renderer, main, plan, settings.output, out); });
  timed("frame", [&] { frame_part(renderer, plan, settings.output, out); });
  timed("heatmaps", [&] { heatmap_part(renderer, maps, main, plan, settings.output, out); });
  require_no_validation_messages(settings.renderer.validate, renderer.validation_messages());

  // what the plots and the README say about how the data was made
  nlohmann::json json;
  json["mode"] = settings.quick ? "quick" : "full";
  json["command"] = settings.quick ? "displace report --quick" : "displace report";
  json["device"] = renderer.device().name;
  json["device_type"] = renderer.device().type;
  json["cpu_threads"] = std::thread::hardware_concurrency();
  const std::time_t now = std::time(nullptr);
  char date[32];
  std::strftime(date, sizeof(date), "%Y-%m-%d", std::gmtime(&now));
  json["date"] = date;
  json["target_rmse"] = sweep_target_rmse;
  json["image_side"] = plan.image_side;
  json["refine"] = 8;
  json["scenes"] = nlohmann::json::array();
  for (const pipeline::Scene& scene : settings.scenes) json["scenes"].push_back(scene.name);
  json["main_scene"] = main.name;
  json["steps"] = plan.steps;
  json["repeat"] = plan.repeat;
  json["elevations"] = plan.elevations;
  json["grazing_steps"] = plan.grazing_steps;
  json["horizon_steps"] = plan.horizon_steps;
  json["max_grazing_tile"] = max_grazing_tile;
  json["bake_steps"] = plan.bake_steps;
  json["default_tolerance"] = default_tolerance;
  json["bake_view_elevation"] = bake_view_elevation;
  const pipeline::Scene water = pipeline::builtin_scene("water");  // the frame part's scene
  json["frame"] = {{"scene", "water"},           {"map_size", plan.frame_map_size},
                   {"width", plan.frame_width},  {"height", plan.frame_height},
                   {"frames", plan.frame_count}, {"method", render::method_info(water.method).name},
                   {"steps", water.steps}};
  json["heatmap_steps"] = plan.heatmap_steps;
  json["seconds"] = seconds;
  json["seconds"]["total"] = std::round(whole.seconds() * 10.0) / 10.0;
  files::write_file(settings.output / "report.json", json.dump(2) + '\n');
  if (settings.plots) run_plots(settings.output);
  out << fmt::format("  wrote {} in {:.0f} s\n",
                     (settings.output / (settings.plots ? "README.md" : "report.json")).string(),
                     whole.seconds());
}

namespace {

constexpr int max_report_image_side = 2048;  // --size of `displace report`

// A --scene of report: a built-in scene, a TOML file, or a height image as a scene of its own (a
// user's map is rarely a tile: clamped at its edges).
pipeline::Scene report_scene(const std::string& word, bool invert) {
  const std::string extension = lower_extension(std::filesystem::path(word));
  const std::vector<std::string> names = pipeline::builtin_scene_names();
  if (extension == ".toml" || std::find(names.begin(), names.end(), word) != names.end()) {
    return cli::named_scene(word);
  }
  pipeline::Scene image;
  image.name = std::filesystem::path(word).stem().string();
  image.source = pipeline::SourceKind::image;
  image.image = word;
  image.image_read.invert = invert;
  image.address = bake::Address::clamp;
  return image;
}

}  // namespace

Finish add_report_command(CLI::App& command) {
  command.description(
      "What accuracy costs in time: every method's error against fetches and device milliseconds, grazing "
      "views, the bake's tightness and price, the frame loop's budget against its error, and iteration "
      "heatmaps; the CSV and JSON behind each figure, the figures (PNG, matplotlib) and a README.md that "
      "embeds them.");
  struct Draft {
    ReportSettings settings;
    std::vector<std::string> scenes;
    bool invert = false, no_plots = false;
    std::string output = "docs/report";
  };
  auto draft = std::make_shared<Draft>();
  command
      .add_option("--scene", draft->scenes,
                  "a built-in scene, a TOML scene file or a height image (default: ocean, bricks, cliff)")
      ->type_name("NAME|FILE.toml|IMAGE")
      ->check(cli::not_empty())
      ->allow_extra_args(false)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  cli::add_switch(command, "--invert", draft->invert, "height images store depth (1 = deepest)");
  cli::add_switch(command, "--quick", draft->settings.quick,
                  "fewer step counts, frames and budgets at 128 x 128 pixels (minutes, for CI)");
  cli::add_value(command, "--size", draft->settings.image_side,
                 "the render figures' square images, pixels a side (default 256, --quick 128)", "N",
                 cli::integer_in(16, max_report_image_side));
  cli::add_value(command, "--output", draft->output, "the report's directory (default docs/report)", "DIR",
                 cli::not_empty());
  cli::add_switch(command, "--no-plots", draft->no_plots,
                  "write the data (CSV, JSON) without running the plotting script");
  cli::add_renderer_flags(command, draft->settings.renderer);
  return [draft] {
    ReportSettings settings = draft->settings;
    bool any_image = false;
    for (const std::string& word : draft->scenes) {
      settings.scenes.push_back(report_scene(word, draft->invert));
      any_image |= settings.scenes.back().source == pipeline::SourceKind::image;
    }
    if (draft->invert && !any_image) throw usage_error("--invert needs a height image in --scene");
    if (settings.scenes.empty()) {
      for (const char* name : {"bricks", "ocean", "cliff"})
        settings.scenes.push_back(pipeline::builtin_scene(name));
    }
    settings.output = draft->output;
    settings.plots = !draft->no_plots;
    cli::finish_renderer(settings.renderer);
    return ParsedCommand{"report", settings, [settings](std::ostream& out) { run_report(settings, out); }};
  };
}

}  // namespace displace::app
