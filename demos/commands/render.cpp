// demos/commands/render.cpp - `displace render`: one picture of a scene with its method, made by the
// frame pipeline as frame 0 (so it is the picture `displace sequence --frames 0:0` draws), with AOVs
// and, on request, the error against the exact reference.
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <cmath>
#include <iostream>
#include <ostream>

#include "demos/cli/command.h"
#include "demos/cli/flags.h"
#include "demos/cli/scene_flags.h"
#include "demos/commands/settings.h"
#include "demos/error.h"
#include "demos/heights.h"
#include "demos/memory.h"
#include "demos/progress.h"
#include "pipeline/frame_pipeline.h"

namespace displace::app {
namespace {

Metadata render_metadata(const pipeline::Scene& scene) {
  Metadata metadata = {{"displace:scene", scene.name},
                       {"displace:source", source_name(scene.source)},
                       {"displace:time", fmt::format("{:.17g}", scene.start)},
                       {"displace:method", std::string(render::method_info(scene.method).name)},
                       {"displace:steps", scene.steps},
                       {"displace:refine", scene.refine}};
  if (std::isfinite(scene.frame_ms)) metadata.push_back({"displace:bake_budget_ms", float(scene.frame_ms)});
  if (scene.tolerance != bake::Budget{}.tolerance)
    metadata.push_back({"displace:bake_tolerance", scene.tolerance});
  if (scene.surface != render::Surface::plane) {
    metadata.push_back({"displace:surface", std::string(render::surface_name(scene.surface))});
    metadata.push_back({"displace:radius", scene.radius});
  }
  return metadata;
}

// What the cone maps cost and claim.
void print_cone_line(const pipeline::Scene& scene, const pipeline::FrameRecord& record, std::ostream& out) {
  const bake::BakeStats& stats = record.cones;
  if (record.bake_on_device) {
    out << fmt::format(
        "  cone maps baked on the device ({} sectors{}; {})\n", stats.sector_count,
        record.sim_on_device ? ", from the device's heights" : "",
        record.bake_device_ms > 0.0
            ? fmt::format("{:.2f} ms of device time{}", record.bake_device_ms,
                          record.levels_device_ms > 0.0
                              ? fmt::format(", {:.2f} of it the levels of detail", record.levels_device_ms)
                              : std::string())
            : std::string("its time not measured yet"));
    return;
  }
  out << "  cone maps baked by the budgeted bilinear baker " << baked_within(scene.frame_ms)
      << (scene.tolerance == bake::Budget{}.tolerance ? std::string()
                                                      : fmt::format(" at tolerance {:g}", scene.tolerance));
  if (stats.sector_count != 0) {
    out << fmt::format(": {:.1f} ms, mean ratio {:.4f}, {} of {} texels searched", stats.milliseconds,
                       stats.mean_ratio, stats.texels_refined, (long long)stats.width * stats.height);
  }
  out << " (conservative at any budget"
      << (record.pending > 0 && std::isfinite(scene.frame_ms)
              ? fmt::format("; {} texels left to refine: --bake-budget-ms unlimited for the tightest maps",
                            record.pending)
              : std::string())
      << ")\n";
}

}  // namespace

void run_render(const RenderSettings& settings, std::ostream& out) {
  const pipeline::Scene& scene = settings.scene;
  if (settings.compare_reference && scene.unbounded)
    throw usage_error(
        "--compare-reference compares on the patch the reference tessellates: add --extent patch");
  // a line per stage on stderr when the render takes long
  StageLines stages(std::cerr, "displace render");
  // the device first: what it offers decides what fits, before anything is synthesized or baked
  render::Renderer renderer(settings.renderer);
  const unsigned outputs =
      frame_outputs(settings.aovs) | (settings.compare_reference ? render::output_all : 0u);
  if (scene.source != pipeline::SourceKind::image) {
    require_memory(render_memory(scene, scene.map_size, scene.map_size, outputs, settings.compare_reference),
                   renderer.memory_limits());
  }
  load_scene_mesh(renderer, scene);
  stages.done("the device ready");
  pipeline::FramePipeline pipeline(scene, renderer, {}, height_loader(scene.image_read), albedo_loader());
  // frame 0, as FramePipeline::run(0) makes it (the whole frame budget to the bake), a stage at a time
  render::Frame frame;
  pipeline::FrameRecord record;
  record.time = pipeline::frame_time(scene, 0);
  pipeline.simulate(record.time, record);
  stages.done("heights made");
  pipeline.bake(scene.frame_ms, record);
  stages.done(fmt::format("maps baked ({})", baked_within(scene.frame_ms)));
  pipeline.upload(record);
  pipeline.draw(pipeline::scene_view(scene, record.time), frame, outputs | render::output_all, record);
  stages.done("uploaded and drawn");
  const render::MethodInfo& info = render::method_info(scene.method);
  const Metadata metadata = render_metadata(scene);
  write_frame_image(settings.output, frame, metadata);
  for (const AovOutput& aov : settings.aovs) write_aov(aov, frame, metadata);
  stages.done("written");
  const FrameSummary summary = summarize(frame);
  out << fmt::format(
      "displace render: {}, {} steps, {} refine, on {} ({}): {} x {}, {} pixels hit, "
      "{:.2f} ms on the device; per pixel: {:.1f} iterations, {:.1f} fetches (p99 {:.0f})\n",
      info.name, scene.steps, scene.refine, renderer.device().name, renderer.device().type, frame.width,
      frame.height, summary.hit_pixels, frame.gpu_milliseconds, summary.mean_iterations, summary.mean_fetches,
      summary.p99_fetches);
  if (info.cone_sectors != 0) print_cone_line(scene, record, out);
  out << "  wrote " << settings.output.string();
  for (const AovOutput& aov : settings.aovs) out << ", " << aov.file.string();
  out << '\n';
  if (settings.compare_reference) {
    render::Frame reference;
    renderer.render(pipeline::scene_view(scene, record.time), {render::Method::reference, 1, 0}, reference);
    const render::ImageError error = render::compare(frame, reference);
    out << fmt::format(
        "  compare reference: rmse {:.3f}, max error {:.0f}, {:.3f}% of {} pixels off by more than 10 "
        "(8-bit units)\n",
        error.rmse, error.max_error, 100.0 * error.fraction_over_10, error.pixels);
  }
  require_no_validation_messages(settings.renderer.validate, renderer.validation_messages());
}

Finish add_render_command(CLI::App& command) {
  command.description(
      "Render a scene with one per-pixel method, baking the maps it needs: frame 0 of the scene at its "
      "start time ([time] start, --time), the picture `displace sequence --frames 0:0` draws. The plane "
      "x, y in [0, 1] (z up; height 1 on z = 0, height 0 at z = -depth_scale), or a quadric or a mesh.");
  struct Draft {
    cli::SceneFlags scene;
    RenderSettings settings;
    std::string output, compare, bake_budget;
    std::vector<std::string> aovs;
  };
  auto draft = std::make_shared<Draft>();
  cli::add_scene_flags(command, draft->scene, cli::scene_all & ~unsigned(cli::scene_frames), "ocean");
  command.option_defaults()->group("Cone maps (scene keys)");
  // the frame's bake: its budget and tolerance ([budget] frame_ms and tolerance)
  cli::SceneFlags& scene_flags = draft->scene;
  cli::add_value(
      command, "--bake-budget-ms", draft->bake_budget,
      fmt::format("cone methods: bake their cone maps within this time (default: the scene's [budget] "
                  "frame_ms, or {:g} ms - the first picture in seconds; 0: the first stage alone; "
                  "unlimited: the tightest maps)",
                  first_picture_budget_ms),
      "MS|unlimited", cli::bake_budget_in(pipeline::max_frame_ms));
  cli::add_value(command, "--tolerance", scene_flags.values["--tolerance"],
                 "cone methods: refine while a ratio may be more than T below the best (default 0.25)", "T",
                 cli::tolerance_in_range());
  cli::add_renderer_flags(command, draft->settings.renderer);
  command.option_defaults()->group("Options");
  cli::add_value(command, "--output", draft->output, "the picture", "FILE.png|FILE.exr",
                 cli::output_file({".png", ".exr"}))
      ->required();
  cli::add_aov_option(command, draft->aovs,
                      "also write uv=F.exr, depth=F.exr, iterations=F.exr|F.png or fetches=F.exr|F.png",
                      false);
  command.add_option("--compare", draft->compare, "also render the reference and print the error against it")
      ->type_name("reference")
      ->check(cli::text_check([](const std::string& text) {
        return text == "reference" ? std::string() : "supports only 'reference', got " + cli::in_quotes(text);
      }));
  return [&command, draft] {
    RenderSettings settings = draft->settings;
    settings.scene = cli::finish_scene(command, draft->scene);
    const render::MethodInfo& info = render::method_info(settings.scene.method);
    if (cli::given(command, "--bake-budget-ms")) {
      settings.scene.frame_ms = cli::bake_budget_value(draft->bake_budget);
    } else if (!std::isfinite(settings.scene.frame_ms) && info.cone_sectors != 0) {
      settings.scene.frame_ms = first_picture_budget_ms;
    }
    for (const char* flag : {"--bake-budget-ms", "--tolerance"}) {
      if (!cli::given(command, flag) || info.cone_sectors != 0) continue;
      std::vector<std::string> cone_methods;
      for (const render::MethodInfo& known : render::method_table()) {
        if (known.cone_sectors != 0) cone_methods.emplace_back(known.name);
      }
      throw usage_error(fmt::format("{} applies to the methods that read cone maps ({}), not --method {}",
                                    flag, fmt::join(cone_methods, ", "), info.name));
    }
    settings.aovs = cli::aov_outputs(draft->aovs);
    settings.compare_reference = cli::given(command, "--compare");
    settings.output = draft->output;
    cli::finish_renderer(settings.renderer);
    return ParsedCommand{"render", settings, [settings](std::ostream& out) { run_render(settings, out); }};
  };
}

}  // namespace displace::app
