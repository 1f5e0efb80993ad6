// demos/commands/sweep.cpp - `displace sweep`: what accuracy costs - every method at every step count
// on each scene against the exact reference, one CSV row per scene, method and steps.
#include <fmt/format.h>

#include <array>
#include <ostream>
#include <sstream>

#include "demos/cli/command.h"
#include "demos/cli/flags.h"
#include "demos/cli/scene_flags.h"
#include "demos/commands/settings.h"
#include "demos/error.h"
#include "demos/frame_output.h"
#include "demos/heights.h"
#include "demos/text_file.h"

namespace displace::app {

void run_sweep(const SweepSettings& settings, std::ostream& out) {
  render::Renderer renderer(settings.renderer);
  pipeline::MapMaker maps(renderer.device().max_image_dimension_3d);
  TextFile csv(settings.output);
  csv << "scene,method,steps,refine,rmse,max_error,fraction_over_10,mean_fetches,p99_fetches,mean_iterations,"
         "median_ms,device\n";
  out << "displace sweep on " << renderer.device().name << " (" << renderer.device().type << "), "
      << settings.repeat << " renders per row, median device time\n";
  for (const pipeline::Scene& scene : settings.scenes) {
    // the cone maps within the scene's budget ([budget] frame_ms and tolerance, --budget-ms, --tolerance)
    bake::Budget cone_budget;
    cone_budget.milliseconds = scene.frame_ms;
    cone_budget.tolerance = scene.tolerance;
    maps.set_cone_budget(cone_budget);
    load_scene(renderer, maps, scene);
    const render::View view = start_view(scene);
    const render::Frame reference =
        pipeline::render_with_maps(renderer, maps, view, {render::Method::reference, 1, 0});
    out << fmt::format("scene {}: {} x {} map, {} x {} pixels; cone maps baked {} at tolerance {:g}\n",
                       scene.name, maps.heights().width, maps.heights().height, view.camera.width,
                       view.camera.height, baked_within(cone_budget.milliseconds), cone_budget.tolerance);
    out << "  method            fetches/pixel for rmse <= 3 (steps)   rmse at the most steps\n";
    std::array<bool, 3> cones_used{};  // by render::cone_slot
    for (render::Method method : settings.methods) {
      const render::MethodInfo& info = render::method_info(method);
      if (!render::supports_surface(method, view.surface)) {
        out << fmt::format("  {:<17} skipped: no {} support\n", info.name,
                           render::surface_name(view.surface));
        continue;
      }
      if (info.cone_sectors != 0) cones_used[std::size_t(render::cone_slot(info.cone_sectors))] = true;
      double best_fetches = -1.0;
      int best_steps = 0;
      double last_rmse = 0.0;
      render::Frame frame;
      for (int steps : settings.steps) {
        const MethodRun run = measure_method(renderer, maps, view, {method, steps, settings.refine},
                                             settings.repeat, reference, frame);
        const render::ImageError& error = run.error;
        const FrameSummary& summary = run.summary;
        csv << fmt::format("{},{},{},{},{:.4f},{:.0f},{:.6f},{:.3f},{:.0f},{:.3f},{:.4f},\"{}\"\n",
                           scene.name, info.name, steps, settings.refine, error.rmse, error.max_error,
                           error.fraction_over_10, summary.mean_fetches, summary.p99_fetches,
                           summary.mean_iterations, run.median_ms, renderer.device().name);
        if (error.rmse <= sweep_target_rmse && (best_fetches < 0.0 || summary.mean_fetches < best_fetches)) {
          best_fetches = summary.mean_fetches;
          best_steps = steps;
        }
        last_rmse = error.rmse;
      }
      if (best_fetches >= 0.0) {
        out << fmt::format("  {:<17} {:8.1f} ({}){:{}} {:.2f}\n", info.name, best_fetches, best_steps, "",
                           best_steps >= 10 ? 24 : 25, last_rmse);
      } else {
        out << fmt::format("  {:<17} {:>8}{:25} {:.2f}\n", info.name, "not reached", "", last_rmse);
      }
    }
    for (int sectors : {1, 4, 8}) {  // what the cone methods rendered from
      if (!cones_used[std::size_t(render::cone_slot(sectors))]) continue;
      const bake::BakeStats& stats = maps.cone_stats(sectors);
      out << fmt::format("  cone maps, {} sector{}: {:.1f} ms, mean ratio {:.4f}, {} of {} texels searched\n",
                         sectors, sectors == 1 ? "" : "s", stats.milliseconds, stats.mean_ratio,
                         stats.texels_refined, (long long)stats.width * stats.height);
    }
    csv.save();
  }
  out << "  wrote " << settings.output.string() << '\n';
  require_no_validation_messages(settings.renderer.validate, renderer.validation_messages());
}

namespace {

constexpr int max_repeat = 100;  // sweep renders per row

// "4,8,16": step counts, each in [1, render::max_steps]
CLI::Validator step_list() {
  return cli::text_check(
      [](const std::string& text) -> std::string {
        std::string_view rest = text;
        while (true) {
          const auto comma = rest.find(',');
          std::string one(rest.substr(0, comma));
          if (std::string problem = cli::integer_in(1, render::max_steps)(one); !problem.empty())
            return problem;
          if (comma == std::string_view::npos) return {};
          rest = rest.substr(comma + 1);
        }
      },
      fmt::format("[1, {}] each", render::max_steps));
}

// "all" or "NAME,NAME": known methods
CLI::Validator method_list() {
  return cli::text_check([](const std::string& text) -> std::string {
    if (text == "all") return {};
    std::string_view rest = text;
    while (true) {
      const auto comma = rest.find(',');
      const std::string_view word = rest.substr(0, comma);
      if (!render::find_method(word)) {
        return fmt::format("names an unknown method {} (methods: {})", cli::in_quotes(word),
                           cli::word_list(cli::method_words(), ", "));
      }
      if (comma == std::string_view::npos) return {};
      rest = rest.substr(comma + 1);
    }
  });
}

struct SweepDraft {
  SweepSettings settings;
  std::vector<std::string> scenes;
  std::string methods, steps, size, output, budget, tolerance;
};

void declare_sweep_flags(CLI::App& command, SweepDraft& draft) {
  command
      .add_option("--scene", draft.scenes,
                  "a built-in scene or a TOML scene file (default: bricks, ocean, cliff)")
      ->type_name("NAME|FILE.toml")
      ->check(cli::not_empty())
      ->allow_extra_args(false)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  command.add_option("--methods", draft.methods, "all (but the reference, the default) or a list")
      ->type_name("all|NAME,NAME...")
      ->check(method_list());
  command.add_option("--steps", draft.steps, "the step counts (default 4,8,16,32,64)")
      ->type_name("S,S,...")
      ->check(step_list());
  cli::add_value(command, "--refine", draft.settings.refine, "binary or secant steps (default 8)", "INT",
                 cli::integer_in(0, render::max_refine));
  command
      .add_option("--repeat", draft.settings.repeat,
                  "renders per row; the row reports the median device time (default 3)")
      ->type_name("INT")
      ->transform(cli::integer_in(1, max_repeat));
  command.add_option("--size", draft.size, "the image in pixels of every scene (scene key [render] size)")
      ->type_name("WxH")
      ->check(cli::image_size_check());
  cli::add_value(
      command, "--bake-budget-ms", draft.budget,
      fmt::format("cone methods: bake each scene's cone maps within this time (default: the scene's "
                  "[budget] frame_ms, or {:g} ms; unlimited: the tightest maps)",
                  first_picture_budget_ms),
      "MS|unlimited", cli::bake_budget_in(pipeline::max_frame_ms));
  cli::add_value(command, "--tolerance", draft.tolerance,
                 "cone methods: refine while a ratio may be more than T below the best ([budget] tolerance)",
                 "T", cli::tolerance_in_range());
  command.add_option("--output", draft.output, "the table")
      ->type_name("FILE.csv")
      ->check(cli::text_check([](const std::string& text) {
        return lower_extension(std::filesystem::path(text)) == ".csv"
                   ? std::string()
                   : std::string("of 'displace sweep' must end in .csv");
      }))
      ->required();
  cli::add_renderer_flags(command, draft.settings.renderer);
}

std::vector<int> numbers_of(const std::string& list) {
  std::vector<int> numbers;
  std::istringstream in(list);
  for (std::string one; std::getline(in, one, ',');) numbers.push_back(std::stoi(one));
  return numbers;
}

}  // namespace

Finish add_sweep_command(CLI::App& command) {
  command.description(
      "What accuracy costs: every method at every step count on each scene (seen from its camera at its "
      "start time), against the reference. One CSV row per scene, method and steps.");
  auto draft = std::make_shared<SweepDraft>();
  declare_sweep_flags(command, *draft);
  return [&command, draft] {
    SweepSettings settings = draft->settings;
    for (const std::string& scene : draft->scenes) settings.scenes.push_back(cli::named_scene(scene));
    if (settings.scenes.empty()) {
      for (const char* name : {"bricks", "ocean", "cliff"})
        settings.scenes.push_back(pipeline::builtin_scene(name));
    }
    for (pipeline::Scene& scene : settings.scenes) {
      if (cli::given(command, "--size"))
        std::tie(scene.camera.width, scene.camera.height) = *cli::read_image_size(draft->size);
      if (cli::given(command, "--bake-budget-ms")) {
        scene.frame_ms = cli::bake_budget_value(draft->budget);
      } else if (!std::isfinite(scene.frame_ms)) {
        scene.frame_ms = first_picture_budget_ms;
      }
      if (cli::given(command, "--tolerance")) scene.tolerance = std::stof(draft->tolerance);
    }
    if (draft->methods.empty() || draft->methods == "all") {
      settings.methods = cli::all_methods_but_reference();
    } else {
      std::string_view rest = draft->methods;
      while (true) {
        const auto comma = rest.find(',');
        settings.methods.push_back(render::find_method(rest.substr(0, comma))->method);
        if (comma == std::string_view::npos) break;
        rest = rest.substr(comma + 1);
      }
    }
    settings.steps =
        cli::given(command, "--steps") ? numbers_of(draft->steps) : std::vector<int>{4, 8, 16, 32, 64};
    settings.output = draft->output;
    cli::finish_renderer(settings.renderer);
    return ParsedCommand{"sweep", settings, [settings](std::ostream& out) { run_sweep(settings, out); }};
  };
}

}  // namespace displace::app
