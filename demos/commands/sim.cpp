// demos/commands/sim.cpp - `displace sim`: a scene's heights at one time, as the renderer samples them
// (choppy crests resampled onto the grid), in raw metres to channel `height` of an EXR with the
// source's parameters and its [0, 1] mapping as attributes.
#include <fmt/format.h>

#include <optional>
#include <ostream>

#include "demos/cli/command.h"
#include "demos/cli/flags.h"
#include "demos/cli/scene_flags.h"
#include "demos/commands/settings.h"
#include "demos/error.h"
#include "demos/heights.h"
#include "demos/memory.h"

namespace displace::app {

void run_sim(const SimSettings& settings, std::ostream& out) {
  require_memory(synthesis_memory(settings.scene), host_limits());
  const double time = settings.scene.start;
  std::optional<render::Renderer> renderer;
  if (sim_wants_device(settings.scene)) renderer.emplace(render::RendererOptions{});
  const SceneHeights heights = scene_heights(settings.scene, time, renderer ? &*renderer : nullptr);
  write_height_exr(settings.output, heights);
  out << fmt::format(
      "displace: synthesized {} heights {} x {} at t = {:g} s in {:.1f} ms on the {} (h01 = {}){}; wrote raw "
      "metres to '{}'\n",
      source_name(settings.scene.source), heights.width, heights.height, time, heights.milliseconds,
      renderer ? "device (" + renderer->device().name + ")" : std::string("CPU"),
      mapping_phrase(heights.mapping),
      settings.scene.ocean.loop_seconds > 0.0 && settings.scene.source == pipeline::SourceKind::ocean
          ? fmt::format(", a {:g} s loop (wave frequencies moved by at most {:.2f}%)",
                        settings.scene.ocean.loop_seconds, 100.0 * heights.loop_error)
          : std::string(),
      settings.output.string());
}

Finish add_sim_command(CLI::App& command) {
  command.description(
      "Write a scene's heights at one time (--time, [time] start), as the renderer samples them, in raw "
      "metres to channel `height`, with the source's parameters and the [0, 1] mapping as EXR attributes.");
  auto flags = std::make_shared<cli::SceneFlags>();
  auto output = std::make_shared<std::string>();
  cli::add_scene_flags(command, *flags, cli::scene_source, "ocean");
  command.option_defaults()->group("Options");
  cli::add_value(command, "--output", *output, "the heights", "FILE.exr", cli::output_file({".exr"}))
      ->required();
  return [&command, flags, output] {
    SimSettings settings{cli::finish_scene(command, *flags), *output};
    if (settings.scene.source == pipeline::SourceKind::image)
      throw usage_error("'displace sim' synthesizes heights: not from a height image (--input)");
    return ParsedCommand{"sim", settings, [settings](std::ostream& out) { run_sim(settings, out); }};
  };
}

}  // namespace displace::app
