// demos/commands/bake.cpp - `displace bake`: a cone map from a height image (--input) or a scene's
// heights, with one of the bakers, to an EXR or an engine-ready PNG.
//
// The one fact to know: a PNG cone map is baked from the heights quantized to 8 bits, the heights
// it stores, so its cones are conservative for what an engine reads back (see cone_export.h).
#include <fmt/format.h>

#include <iostream>
#include <optional>
#include <ostream>

#include "demos/cli/command.h"
#include "demos/cli/flags.h"
#include "demos/cli/scene_flags.h"
#include "demos/commands/settings.h"
#include "demos/cone_bake.h"
#include "demos/error.h"
#include "demos/heights.h"
#include "demos/memory.h"
#include "demos/progress.h"

namespace displace::app {
namespace {

const cli::Words<Baker> mode_words = {{"exact", Baker::exact},
                                      {"original", Baker::original},
                                      {"paper-adaptive", Baker::paper_adaptive},
                                      {"budgeted", Baker::budgeted},
                                      {"full", Baker::full}};
const cli::Words<ConeKind> cone_kind_words = {{"center", ConeKind::center}, {"bilinear", ConeKind::bilinear}};

struct BakeDraft {
  cli::SceneFlags scene;
  BakeSettings settings;
  std::string output;
  Baker mode = Baker::exact;
  double budget = 0.0, tolerance = 0.0;
  bool relaxed = false;
};

void declare_bake_flags(CLI::App& command, BakeDraft& draft) {
  command.option_defaults()->group("Cones");
  command.add_option("--sectors", draft.settings.sector_count, "cone sectors per texel")
      ->type_name("1|4|8")
      ->transform(CLI::Validator(
          [](std::string& text) -> std::string {
            int value = 0;
            if (cli::read_number(text, value) != std::errc{})
              return "expects an integer, got " + cli::in_quotes(text);
            if (!bake::is_valid_sector_count(value)) return "must be 1, 4 or 8, got " + std::to_string(value);
            text = std::to_string(value);
            return {};
          },
          ""))
      ->required();
  cli::add_value(command, "--mode", draft.mode, "the baker (bilinear cones: budgeted or full)",
                 cli::word_list(mode_words), cli::word_in(mode_words));
  cli::add_switch(command, "--relaxed", draft.relaxed, "relaxed cones (sectors 1 or 4), its own baker");
  cli::add_value(command, "--cones", draft.settings.cones,
                 "between texel centres, or the renderer's bilinear cones with apex heights",
                 cli::word_list(cone_kind_words), cli::word_in(cone_kind_words));
  cli::add_value(command, "--budget-ms", draft.budget,
                 "budgeted: refinement time (default unlimited; 0 allowed)", "MS",
                 cli::number_in({0.0, cli::max_budget_milliseconds, "ms"}));
  command
      .add_option("--tolerance", draft.tolerance,
                  "budgeted: refine while a ratio may be more than T below exact (default 0.25)")
      ->type_name("T")
      ->transform(cli::tolerance_in_range());
  cli::add_value(command, "--address", draft.settings.address,
                 "how the map continues past its edges (default wrap)", cli::word_list(cli::address_words),
                 cli::word_in(cli::address_words));
  command.option_defaults()->group("Options");
  cli::add_value(command, "--output", draft.output,
                 "the cone map (.png: heights quantized to 8 bits before baking)", "FILE.exr|FILE.png",
                 cli::output_file({".exr", ".png"}))
      ->required();
  cli::add_switch(command, "--stats", draft.settings.stats, "print one JSON line instead of the human line");
}

// The baker the flags name, and what applies to it only.
void choose_baker(const CLI::App& command, const BakeDraft& draft, BakeSettings& settings) {
  using cli::given;
  if (settings.cones == ConeKind::bilinear) {
    if (draft.relaxed) throw usage_error("--cones bilinear bakes with --mode budgeted|full, not --relaxed");
    if (!given(command, "--mode"))
      throw usage_error("'displace bake --cones bilinear' needs --mode budgeted|full");
    if (draft.mode != Baker::budgeted && draft.mode != Baker::full) {
      throw usage_error(std::string("--cones bilinear bakes with --mode budgeted|full, not --mode ") +
                        baker_name(draft.mode));
    }
    settings.baker = draft.mode;
  } else if (draft.relaxed) {
    if (settings.sector_count != 1 && settings.sector_count != 4) {
      throw usage_error("--relaxed supports --sectors 1 or 4, got " + std::to_string(settings.sector_count));
    }
    if (given(command, "--mode")) throw usage_error("--relaxed is its own baker; drop --mode");
    settings.baker = Baker::relaxed;
  } else {
    if (!given(command, "--mode")) {
      throw usage_error("'displace bake' needs --mode exact|original|paper-adaptive|budgeted (or --relaxed)");
    }
    if (draft.mode == Baker::full)
      throw usage_error("--mode full bakes bilinear cones only: add --cones bilinear");
    settings.baker = draft.mode;
  }
  if (given(command, "--budget-ms")) {
    if (settings.baker != Baker::budgeted) throw usage_error("--budget-ms applies to --mode budgeted only");
    settings.budget_milliseconds = draft.budget;
  }
  if (given(command, "--tolerance")) {
    if (settings.baker != Baker::budgeted) throw usage_error("--tolerance applies to --mode budgeted only");
    settings.tolerance = float(draft.tolerance);
  }
}

}  // namespace

void run_bake(const BakeSettings& settings, std::ostream& out) {
  // refused before the work when it cannot fit: a source before it is synthesized, a file once its
  // size is known
  const render::MemoryLimits limits = host_limits();
  const pipeline::Scene& scene = settings.scene;
  const bool image = scene.source == pipeline::SourceKind::image;
  if (!image) {
    std::vector<render::Allocation> needs = synthesis_memory(scene);
    for (render::Allocation& bake :
         bake_memory(scene.map_size, scene.map_size, settings.sector_count, settings.baker, settings.cones)) {
      needs.push_back(std::move(bake));
    }
    require_memory(needs, limits);
  }
  // the renderer's bilinear cones on the device ([backend] bake): the device's heights too where the sim
  // runs there
  const bool on_device =
      settings.cones == ConeKind::bilinear && pipeline::runs_on_default_device(scene.bake_backend);
  const bool sim_on_device = sim_wants_device(scene);
  std::optional<render::Renderer> renderer;
  if (on_device || sim_on_device) renderer.emplace(render::RendererOptions{});
  SceneHeights input = scene_heights(scene, scene.start, sim_on_device ? &*renderer : nullptr);
  if (image) {
    require_memory(
        bake_memory(input.width, input.height, settings.sector_count, settings.baker, settings.cones),
        limits);
  }
  const bool png = settings.output_format == ImageFormat::png;
  if (png) quantize_heights_8bit(input.heights);  // bake the heights the PNG will store

  const bool bilinear = settings.cones == ConeKind::bilinear;
  ProgressLine progress(std::cerr, stderr_is_terminal(),
                        "baking " + std::to_string(settings.sector_count) + "-sector " +
                            (bilinear ? "bilinear cones" : "cones") + " (" + baker_name(settings.baker) +
                            ")");
  const BakedCones baked =
      on_device
          ? bake_bilinear_on_device(*renderer, input.heights, input.width, input.height,
                                    settings.sector_count, settings.baker, settings.address,
                                    settings.budget_milliseconds, scene.device_first_pass)
          : (bilinear ? bake_bilinear : bake_cones)(
                input.heights, input.width, input.height, settings.sector_count, settings.baker,
                settings.address, settings.budget_milliseconds, settings.tolerance, progress.callback());
  progress.finish();
  const ConeMapExport cones{input.width,    input.height,   settings.sector_count,
                            input.heights,  baked.ratios,   settings.address,
                            settings.baker, settings.cones, baked.apex};
  Metadata metadata = image ? input.metadata : source_attributes_for_cones(input.metadata);
  metadata.push_back({"displace:heights_quantized_8bit", png ? 1 : 0});
  if (png) {
    write_cone_png(settings.output, cones, metadata);
  } else {
    write_cone_exr(settings.output, cones, metadata);
  }
  if (settings.stats) {
    out << stats_json(baked.stats, settings.baker, settings.address, settings.cones) << '\n';
    return;
  }
  out << "displace: baked " << settings.sector_count
      << (bilinear ? "-sector bilinear cones (with apex heights) for " : "-sector cones for ") << input.width
      << " x " << input.height << " heights from " << input.description << " with the "
      << baker_name(settings.baker) << " baker"
      << (on_device ? " on the device (" + renderer->device().name + ")" : "") << " ("
      << address_name(settings.address)
      << (settings.baker == Baker::budgeted ? ", " + budget_phrase(settings.budget_milliseconds) : "")
      << "): " << stats_phrase(baked.stats) << "; wrote '" << settings.output.string() << "'"
      << (png ? " (heights quantized to 8 bits before baking)" : "") << '\n';
}

Finish add_bake_command(CLI::App& command) {
  command.description(
      "Bake a cone map from a height image (--input) or a scene's heights. 8/16-bit images map as value / "
      "maximum; float images map their min..max to 0..1 unless --height-range is given or `displace sim` "
      "wrote them. A .png output quantizes the heights to 8 bits before baking, so that its cones hold "
      "for the heights it stores. --cones bilinear: the renderer's cone maps, safe for the bilinear "
      "surface from anywhere in a texel's square, with an apex height per texel.");
  command.footer(
      "--stats prints one JSON object on a line (the output style of docs/cli.md: snake_case keys, units in "
      "the\n"
      "names): mode (exact, budgeted, ...), cones (center, bilinear), width, height (texels), sectors, "
      "address\n"
      "(wrap, clamp), bake_ms (the bake's wall time), texels_refined, texels_fallback (texels left at the\n"
      "conservative fallback), blocker_tests (texel pairs and pyramid nodes examined), mean_ratio.");
  auto draft = std::make_shared<BakeDraft>();
  cli::add_scene_flags(command, draft->scene, cli::scene_source, "ocean");
  declare_bake_flags(command, *draft);
  return [&command, draft] {
    BakeSettings settings = draft->settings;
    settings.scene = cli::finish_scene(command, draft->scene);
    choose_baker(command, *draft, settings);
    settings.output = draft->output;
    settings.output_format = lower_extension(settings.output) == ".png" ? ImageFormat::png : ImageFormat::exr;
    return ParsedCommand{"bake", settings, [settings](std::ostream& out) { run_bake(settings, out); }};
  };
}

}  // namespace displace::app
