// demos/commands/demo.cpp - `displace demo`: the default ocean end to end - heights, cone maps as EXR
// and PNG, pictures with acm4 and with true displacement, and their difference.
#include <fmt/format.h>

#include <limits>
#include <ostream>

#include "demos/cli/command.h"
#include "demos/cli/flags.h"
#include "demos/commands/settings.h"
#include "demos/cone_bake.h"
#include "demos/error.h"
#include "demos/frame_output.h"
#include "demos/heights.h"
#include "demos/memory.h"
#include "pipeline/maps.h"

namespace displace::app {

void run_demo(const DemoSettings& settings, std::ostream& out) {
  constexpr int demo_sectors = 4;
  const bake::Address address = bake::Address::wrap;  // an FFT ocean tiles
  make_output_directory(settings.output_directory);
  const std::filesystem::path height_file = settings.output_directory / "ocean_height.exr";
  const std::filesystem::path exr_file = settings.output_directory / "ocean_cone4.exr";
  const std::filesystem::path png_file = settings.output_directory / "ocean_cone4.png";

  // synthesize the default ocean frame
  pipeline::Scene source = pipeline::builtin_scene("ocean");
  source.map_size = settings.map_size;
  std::vector<render::Allocation> needs = synthesis_memory(source);
  for (render::Allocation& bake :
       bake_memory(source.map_size, source.map_size, demo_sectors, Baker::budgeted, ConeKind::center)) {
    needs.push_back(std::move(bake));
  }
  require_memory(needs, host_limits());
  const SceneHeights ocean = scene_heights(source, 0.0);
  write_height_exr(height_file, ocean);
  out << fmt::format(
      "displace demo: FFT ocean {} x {} ({:g} m patch, {} spectrum, wind {:g} m/s), t = 0 s, "
      "synthesized in {:.1f} ms\n",
      ocean.width, ocean.height, double(source.ocean.patch_size),
      pipeline::spectrum_word(source.ocean.spectrum), double(source.ocean.wind_speed), ocean.milliseconds);
  out << "  wrote " << height_file.string() << " (raw metres, channel height)\n";

  // mapped to [0, 1] with the spectrum's fixed mapping
  const std::vector<float>& heights = ocean.heights;
  out << "  mapped to [0, 1] as h = " << mapping_phrase(ocean.mapping) << " (+-3 sigma of the spectrum), "
      << ocean.clamped << " samples clamped\n";

  // bake and write the float cone map
  const Metadata metadata = source_attributes_for_cones(ocean.metadata);
  const double unlimited = std::numeric_limits<double>::infinity();
  const BakedCones baked =
      bake_cones(heights, ocean.width, ocean.height, demo_sectors, Baker::budgeted, address, unlimited);
  write_cone_exr(exr_file,
                 {ocean.width, ocean.height, demo_sectors, heights, baked.ratios, address, Baker::budgeted},
                 metadata);
  out << "  baked 4-sector cones (budgeted, unlimited budget, wrap): " << stats_phrase(baked.stats) << '\n';
  out << "  wrote " << exr_file.string() << " (channels height, cone0..cone3)\n";

  // bake the 8-bit heights again for the PNG, so its cones hold for the heights it stores
  std::vector<float> heights_8bit = heights;
  quantize_heights_8bit(heights_8bit);
  const BakedCones baked_8bit =
      bake_cones(heights_8bit, ocean.width, ocean.height, demo_sectors, Baker::budgeted, address, unlimited);
  Metadata png_metadata = metadata;
  png_metadata.push_back({"displace:heights_quantized_8bit", 1});
  write_cone_png(
      png_file,
      {ocean.width, ocean.height, demo_sectors, heights_8bit, baked_8bit.ratios, address, Baker::budgeted},
      png_metadata);
  out << "  baked the 8-bit heights again for the PNG: " << stats_phrase(baked_8bit.stats) << '\n';
  out << "  wrote " << png_file.string() << " (" << 2 * ocean.width << " x " << ocean.height
      << ": cone panel RGBA = sqrt(ratio) of sectors 0..3, then height panel R = height)\n";

  // render the frame with anisotropic cone mapping and with true displacement, and compare
  const render::View view;  // the default camera of render.h
  render::RendererOptions options;
  cli::finish_renderer(options);
  render::Renderer renderer(options);
  pipeline::MapMaker maps(renderer.device().max_image_dimension_3d);
  maps.set_heights({ocean.width, ocean.height, heights});
  const render::Frame acm4 = pipeline::render_with_maps(renderer, maps, view, {render::Method::acm4, 32, 0});
  const render::Frame reference =
      pipeline::render_with_maps(renderer, maps, view, {render::Method::reference, 1, 0});
  const std::filesystem::path acm4_file = settings.output_directory / "ocean_acm4.png";
  const std::filesystem::path reference_file = settings.output_directory / "ocean_reference.png";
  const std::filesystem::path iterations_file = settings.output_directory / "ocean_acm4_iterations.png";
  write_frame_image(acm4_file, acm4, metadata);
  write_frame_image(reference_file, reference, metadata);
  write_aov({Aov::iterations, iterations_file}, acm4, metadata);
  const FrameSummary summary = summarize(acm4);
  const render::ImageError error = render::compare(acm4, reference);
  out << fmt::format(
      "  rendered {} x {} on {}: acm4 (32 steps, on the renderer's own cone map for the bilinear surface) "
      "{:.1f} ms, {:.1f} fetches per pixel; reference (tessellated) {:.1f} ms; acm4 against it: rmse {:.2f}, "
      "{:.3f}% of pixels off by more than 10\n",
      acm4.width, acm4.height, renderer.device().name, acm4.gpu_milliseconds, summary.mean_fetches,
      reference.gpu_milliseconds, error.rmse, 100.0 * error.fraction_over_10);
  out << "  wrote " << acm4_file.string() << ", " << reference_file.string() << ", "
      << iterations_file.string() << " (iterations heatmap)\n";
}

Finish add_demo_command(CLI::App& command) {
  command.description("The default ocean end to end: synthesize, bake, export, render and compare.");
  auto settings = std::make_shared<DemoSettings>();
  auto directory = std::make_shared<std::string>(settings->output_directory.string());
  cli::add_value(command, "--map-size", settings->map_size, "ocean samples along u and v, even (default 512)",
                 "INT", cli::integer_in(2, sim::max_ocean_size));
  cli::add_value(command, "--output-dir", *directory, "where the files go (default out)", "DIR",
                 cli::not_empty());
  return [settings, directory] {
    if (settings->map_size % 2 != 0) {
      throw usage_error(
          fmt::format("--map-size for the ocean must be even (its FFT grid), got {}", settings->map_size));
    }
    DemoSettings parsed = *settings;
    parsed.output_directory = *directory;
    return ParsedCommand{"demo", parsed, [parsed](std::ostream& out) { run_demo(parsed, out); }};
  };
}

}  // namespace displace::app
