// demos/commands/sim.cpp - `displace sim`: a scene's heights at one time, as the renderer samples them
// (choppy crests resampled onto the grid), in raw metres to channel `height` of an EXR with the
// source's parameters and its [0, 1] mapping as attributes. For the ocean: what sea it made (the
// spectrum's Hs, Tp and peak wavelength, the Hs synthesized, the share of the variance the patch and the
// map hold; a warning on stderr when they leave out more than sim::left_out_allowance of it).
#include <fmt/format.h>

#include <cmath>
#include <iostream>
#include <numbers>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "demos/cli/command.h"
#include "demos/cli/flags.h"
#include "demos/cli/scene_flags.h"
#include "demos/commands/settings.h"
#include "demos/error.h"
#include "demos/heights.h"
#include "demos/memory.h"
#include "demos/text_file.h"

namespace displace::app {

namespace {

// 4 x the standard deviation of `heights`, metres
double significant_height(const std::vector<float>& heights) {
  double sum = 0.0, sum_squares = 0.0;
  for (float h : heights) {
    sum += h;
    sum_squares += double(h) * h;
  }
  const double count = double(heights.size());
  const double mean = sum / count;
  return 4.0 * std::sqrt(std::max(0.0, sum_squares / count - mean * mean));
}

std::string percent(double share) { return fmt::format("{:.1f}%", 100.0 * share); }

// "pierson-moskowitz, Hs 2.72 m, Tp 8.2 s, peak wavelength 106 m, deep water; ..."
std::string sea_phrase(const sim::OceanParams& params, const sim::SeaState& sea, double frame_hs) {
  const std::string depth =
      std::isfinite(params.depth) ? fmt::format("{:g} m deep", double(params.depth)) : "deep water";
  const std::string swell =
      params.swell.significant_height > 0.0f
          ? fmt::format(" with a swell (Hs {:g} m, Tp {:g} s)", double(params.swell.significant_height),
                        double(params.swell.peak_period))
          : std::string();
  return fmt::format(
      "displace: the sea: {}{}, Hs {:.3g} m, Tp {:.3g} s, peak wavelength {:.4g} m, {}; synthesized Hs "
      "{:.3g} m (the mean over seeds), {:.3g} m in these heights; the {:g} m patch and {} samples hold {} of "
      "its variance ({} in longer waves, {} in shorter)\n",
      pipeline::spectrum_word(params.spectrum), swell, sea.significant_height, sea.peak_period,
      sea.peak_wavelength, depth, sea.lattice_significant_height, frame_hs, double(params.patch_size),
      params.size, percent(1.0 - sea.below_patch - sea.above_map), percent(sea.below_patch),
      percent(sea.above_map));
}

// One line each: "patch too small: ..." / "map too coarse: ...".
std::vector<std::string> sea_warnings(const sim::OceanParams& params, const sim::SeaState& sea) {
  std::vector<std::string> warnings;
  if (sea.patch_too_small) {
    const std::string why =
        sea.below_patch > 0.5 * sim::left_out_allowance
            ? fmt::format("{} of the variance is in waves longer than the {:g} m patch holds",
                          percent(sea.below_patch), double(params.patch_size))
            : fmt::format(
                  "the {:g} m patch holds {:.1f} peak wavelengths, so coarsely that its modes hold {} {} "
                  "variance than the spectrum",
                  double(params.patch_size), params.patch_size / sea.peak_wavelength,
                  percent(std::abs(sea.lattice_error)), sea.lattice_error > 0.0 ? "more" : "less");
    warnings.push_back(fmt::format("patch too small: {}; a patch of {:.0f} m would do (patch_size)", why,
                                   std::ceil(sea.patch_needed)));
  }
  if (sea.map_too_coarse) {
    const std::string why =
        sea.above_map > 0.5 * sim::left_out_allowance
            ? fmt::format("{} of the variance is in waves shorter than {} samples over {:g} m hold",
                          percent(sea.above_map), params.size, double(params.patch_size))
            : fmt::format("its {} samples hold {} {} variance than the spectrum", params.size,
                          percent(std::abs(sea.lattice_error)), sea.lattice_error > 0.0 ? "more" : "less");
    warnings.push_back(fmt::format("map too coarse: {}; a map of {} would do{} (map_size)", why,
                                   sea.size_needed, sea.patch_too_small ? " with that patch" : ""));
  }
  return warnings;
}

// The synthesized heights' frequency spectrum at `time` (|h~|^2 of the ocean's modes summed into bins 3%
// wide, per hertz) beside the analytic S(f), one row a bin that holds modes, up to the frequency of the
// highest wave number the lattice holds in every direction.
void write_frequency_spectrum(const std::filesystem::path& file, const sim::OceanParams& params,
                              double time) {
  const sim::Ocean ocean(params);
  const sim::SeaSpectrum sea(params);
  const int n = ocean.size();
  const std::vector<std::complex<float>> spectrum = ocean.height_spectrum(time);
  constexpr double bin_ratio = 1.03;  // the bins' upper over lower frequency
  double lowest = std::numeric_limits<double>::infinity(), highest = 0.0;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const double f = ocean.omega(i, j) / (2.0 * std::numbers::pi);
      if (f > 0.0) {
        lowest = std::min(lowest, f);
        highest = std::max(highest, f);
      }
    }
  }
  const int bins = int(std::ceil(std::log(highest / lowest) / std::log(bin_ratio))) + 1;
  std::vector<double> energy(std::size_t(bins), 0.0);
  std::vector<int> modes(std::size_t(bins), 0);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const double f = ocean.omega(i, j) / (2.0 * std::numbers::pi);
      if (!(f > 0.0)) continue;
      const int bin = std::min(bins - 1, int(std::log(f / lowest) / std::log(bin_ratio)));
      energy[std::size_t(bin)] += std::norm(std::complex<double>(spectrum[std::size_t(i) * n + j]));
      ++modes[std::size_t(bin)];
    }
  }
  // up to the wave number the lattice holds in every direction, (N/2 - 1) dk
  const double covered = ocean.omega(0, n / 2 - 1) / (2.0 * std::numbers::pi);
  TextFile csv(file, "frequency_hz,synthesized_m2_per_hz,analytic_m2_per_hz,modes");
  for (int bin = 0; bin < bins; ++bin) {
    const double low = lowest * std::pow(bin_ratio, bin), high = low * bin_ratio;
    if (modes[std::size_t(bin)] == 0 || high > covered) continue;
    const double centre = std::sqrt(low * high);
    csv << fmt::format("{:.6g},{:.6g},{:.6g},{}\n", centre, energy[std::size_t(bin)] / (high - low),
                       2.0 * std::numbers::pi * sea.frequency(2.0 * std::numbers::pi * centre),
                       modes[std::size_t(bin)]);
  }
  csv.save();
}

}  // namespace

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
  if (settings.scene.source != pipeline::SourceKind::ocean) return;
  sim::OceanParams params = settings.scene.ocean;
  params.size = settings.scene.map_size;
  const sim::SeaState sea = sim::describe_sea(params);
  out << sea_phrase(params, sea, significant_height(heights.raw));
  for (const std::string& warning : sea_warnings(params, sea))
    std::cerr << "displace sim: warning: " << warning << '\n';
  if (!settings.frequency_spectrum.empty()) {
    write_frequency_spectrum(settings.frequency_spectrum, params, time);
    out << "displace: wrote the synthesized and the analytic frequency spectrum to '"
        << settings.frequency_spectrum.string() << "'\n";
  }
}

Finish add_sim_command(CLI::App& command) {
  command.description(
      "Write a scene's heights at one time (--time, [time] start), as the renderer samples them, in raw "
      "metres to channel `height`, with the source's parameters and the [0, 1] mapping as EXR attributes. "
      "For the ocean, say what sea it made: the spectrum's Hs, Tp and peak wavelength, the Hs synthesized, "
      "and the share of the variance the patch and the map hold, with a warning (patch too small, map too "
      "coarse, and what size would do) when they leave out more than 5% of it.");
  auto flags = std::make_shared<cli::SceneFlags>();
  auto output = std::make_shared<std::string>();
  cli::add_scene_flags(command, *flags, cli::scene_source, "ocean");
  command.option_defaults()->group("Options");
  auto spectrum = std::make_shared<std::string>();
  cli::add_value(command, "--output", *output, "the heights", "FILE.exr", cli::output_file({".exr"}))
      ->required();
  cli::add_value(
      command, "--frequency-spectrum", *spectrum,
      "the ocean's synthesized frequency spectrum beside the analytic one: frequency_hz, "
      "synthesized_m2_per_hz, analytic_m2_per_hz, modes (bins 3% wide, up to the lattice's inscribed circle)",
      "FILE.csv", cli::output_file({".csv"}));
  return [&command, flags, output, spectrum] {
    SimSettings settings{cli::finish_scene(command, *flags), *output, *spectrum};
    if (!settings.frequency_spectrum.empty() && settings.scene.source != pipeline::SourceKind::ocean)
      throw usage_error("'displace sim --frequency-spectrum' needs the ocean source");
    if (settings.scene.source == pipeline::SourceKind::image)
      throw usage_error("'displace sim' synthesizes heights: not from a height image (--input)");
    return ParsedCommand{"sim", settings, [settings](std::ostream& out) { run_sim(settings, out); }};
  };
}

}  // namespace displace::app
