// demos/commands.cpp - the `displace` subcommands: sim (synthesize and write raw heights), bake
// (heights from a file or a source to a cone map), demo (the default ocean scene end to end).
//
// The one fact to know: a PNG cone map is baked from the heights quantized to 8 bits, the heights
// it stores, so its cones are conservative for what an engine reads back (see cone_export.h).
#include "demos/commands.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <ostream>
#include <sstream>
#include <stdexcept>

#include "demos/memory.h"
#include "demos/obj_io.h"
#include "demos/play.h"
#include "demos/progress.h"
#include "pipeline/maps.h"
#include "pipeline/scene.h"

namespace displace::app {
namespace {

using Clock = std::chrono::steady_clock;

double milliseconds_since(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

const char* source_name(SourceKind kind) {
  switch (kind) {
    case SourceKind::ocean: return "ocean";
    case SourceKind::sinusoids: return "sinusoids";
    case SourceKind::bricks: return "bricks";
    case SourceKind::cliff: return "cliff";
  }
  return "unknown";
}
const char* spectrum_name(sim::Spectrum spectrum) {
  return spectrum == sim::Spectrum::phillips ? "phillips" : "jonswap";
}

Metadata synthesis_metadata(const SourceSettings& source, const sim::HeightMapping& mapping) {
  Metadata metadata = {
      {"displace:units", std::string("metres")}, {"displace:source", std::string(source_name(source.kind))},
      {"displace:time", float(source.time)},     {"displace:height_scale", mapping.scale},
      {"displace:height_bias", mapping.bias},
  };
  if (source.kind == SourceKind::ocean) {
    const sim::OceanParams& ocean = source.ocean;
    const Metadata ocean_metadata = {
        {"displace:seed", std::to_string(ocean.seed)},
        {"displace:patch_size", ocean.patch_size},
        {"displace:spectrum", std::string(spectrum_name(ocean.spectrum))},
        {"displace:wind_speed", ocean.wind_speed},
        {"displace:wind_direction", ocean.wind_direction},
        {"displace:fetch", ocean.fetch},
        {"displace:peak_enhancement", ocean.peak_enhancement},
        {"displace:spreading", ocean.spreading},
        {"displace:phillips_amplitude", ocean.phillips_amplitude},
        {"displace:small_wave_cutoff", ocean.small_wave_cutoff},
        {"displace:choppiness", ocean.choppiness},
        {"displace:gravity", ocean.gravity},
    };
    metadata.insert(metadata.end(), ocean_metadata.begin(), ocean_metadata.end());
  } else if (source.kind == SourceKind::bricks || source.kind == SourceKind::cliff) {
    metadata[0].value = std::string("[0, 1]");
    metadata.push_back({"displace:seed", std::to_string(source.seed)});
  } else {
    const sim::SinusoidParams& waves = source.sinusoids;
    const Metadata wave_metadata = {
        {"displace:seed", std::to_string(waves.seed)},
        {"displace:patch_size", waves.patch_size},
        {"displace:wave_count", waves.wave_count},
        {"displace:wavelength_min", waves.wavelength_min},
        {"displace:wavelength_max", waves.wavelength_max},
        {"displace:steepness", waves.steepness},
        {"displace:wind_direction", waves.wind_direction},
        {"displace:direction_spread", waves.direction_spread},
        {"displace:tileable", waves.tileable ? 1 : 0},
        {"displace:gravity", waves.gravity},
    };
    metadata.insert(metadata.end(), wave_metadata.begin(), wave_metadata.end());
  }
  return metadata;
}

// The attributes of the heights, renamed for a cone map whose own `height` channel is in [0, 1].
Metadata source_attributes_for_cones(const Metadata& metadata) {
  Metadata renamed;
  for (Attribute attribute : metadata) {
    if (attribute.name == "displace:height_scale") attribute.name = "displace:source_height_scale";
    if (attribute.name == "displace:height_bias") attribute.name = "displace:source_height_bias";
    if (attribute.name == "displace:units") continue;
    renamed.push_back(std::move(attribute));
  }
  return renamed;
}

std::string mapping_phrase(const sim::HeightMapping& mapping) {
  return fmt::format("raw * {:.6g} {} {:.6g}", double(mapping.scale), mapping.bias < 0.0f ? '-' : '+',
                     std::abs(double(mapping.bias)));
}

std::string clamped_phrase(std::size_t clamped) {
  return clamped ? fmt::format(", {} clamped", clamped) : std::string();
}

std::string budget_phrase(double milliseconds) {
  return std::isinf(milliseconds) ? std::string("unlimited budget")
                                  : fmt::format("{:.6g} ms budget", milliseconds);
}

// "within a 0 ms budget", "with an unlimited budget"
std::string baked_within(double milliseconds) {
  return std::isinf(milliseconds) ? std::string("with an unlimited budget")
                                  : "within a " + budget_phrase(milliseconds);
}

std::string stats_phrase(const bake::BakeStats& stats) {
  return fmt::format("{:.1f} ms, mean ratio {:.4f}, {} texels refined, {} fallback", stats.milliseconds,
                     stats.mean_ratio, stats.texels_refined, stats.texels_fallback);
}

void make_output_directory(const std::filesystem::path& directory) {
  std::error_code error;
  std::filesystem::create_directories(directory, error);
  if (error || !std::filesystem::is_directory(directory)) {
    throw runtime_error("cannot create the directory '" + directory.string() +
                        "': " + (error ? error.message() : std::string("not a directory")));
  }
}

}  // namespace

SynthesizedHeights synthesize(const SourceSettings& source) {
  const auto start = Clock::now();
  SynthesizedHeights result;
  result.width = source.size;
  result.height = source.size;
  try {
    if (source.kind == SourceKind::ocean) {
      sim::OceanParams params = source.ocean;
      params.size = source.size;
      sim::Ocean ocean(params);
      sim::OceanFrame frame;
      ocean.evaluate(source.time, sim::ocean_heights, frame);
      result.raw = std::move(frame.height);
      result.mapping = ocean.mapping();
    } else if (source.kind == SourceKind::bricks || source.kind == SourceKind::cliff) {
      result.raw.resize(std::size_t(source.size) * std::size_t(source.size));
      (source.kind == SourceKind::bricks ? sim::brick_heights : sim::cliff_heights)(source.size, source.size,
                                                                                    source.seed, result.raw);
      result.mapping = sim::HeightMapping{1.0f, 0.0f};
    } else {
      const std::vector<sim::Wave> waves = sim::make_sinusoid_waves(source.sinusoids);
      result.raw.resize(std::size_t(source.size) * std::size_t(source.size));
      sim::sinusoid_heights(waves, source.sinusoids.patch_size, source.time, source.size, source.size,
                            result.raw);
      result.mapping = sim::sinusoid_mapping(waves);
    }
  } catch (const std::invalid_argument& error) {
    throw usage_error(std::string("bad ") + source_name(source.kind) + " parameters: " + error.what());
  }
  result.milliseconds = milliseconds_since(start);

  if (result.raw.size() != std::size_t(result.width) * std::size_t(result.height)) {
    throw runtime_error(std::string("the ") + source_name(source.kind) + " source returned " +
                        std::to_string(result.raw.size()) + " heights for a " + std::to_string(source.size) +
                        " x " + std::to_string(source.size) + " grid");
  }
  for (float h : result.raw) {
    if (!std::isfinite(h))
      throw runtime_error(std::string("the ") + source_name(source.kind) +
                          " source produced a non-finite height");
  }
  if (!std::isfinite(result.mapping.scale) || !std::isfinite(result.mapping.bias)) {
    throw runtime_error(std::string("the ") + source_name(source.kind) +
                        " source has no finite height mapping");
  }
  result.metadata = synthesis_metadata(source, result.mapping);
  return result;
}

void write_height_exr(const std::filesystem::path& file, const SynthesizedHeights& heights) {
  const ExrChannel channel{"height", heights.raw};
  write_exr(file, heights.width, heights.height, std::span(&channel, 1), heights.metadata);
}

BakeInput prepare_bake_input(const std::variant<FileInput, SourceSettings>& input) {
  BakeInput prepared;
  if (const auto* file = std::get_if<FileInput>(&input)) {
    LoadedHeights loaded = load_heights(file->path, file->load);
    prepared.width = loaded.width;
    prepared.height = loaded.height;
    prepared.heights = std::move(loaded.heights);
    const char* format_name = loaded.format == SampleFormat::uint8    ? "8-bit"
                              : loaded.format == SampleFormat::uint16 ? "16-bit"
                                                                      : "float";
    prepared.description = std::string("'") + file->path.string() + "' (" + format_name + " channel '" +
                           loaded.channel_name + "', h = " + mapping_phrase(loaded.mapping) +
                           (loaded.inverted ? ", inverted" : "") + clamped_phrase(loaded.clamped) + ")";
    prepared.metadata = {
        {"displace:input", file->path.string()},
        {"displace:input_channel", loaded.channel_name},
        {"displace:source_height_scale", loaded.mapping.scale},
        {"displace:source_height_bias", loaded.mapping.bias},
        {"displace:source_inverted", loaded.inverted ? 1 : 0},
    };
  } else {
    const SourceSettings& source = std::get<SourceSettings>(input);
    SynthesizedHeights synthesized = synthesize(source);
    prepared.width = synthesized.width;
    prepared.height = synthesized.height;
    prepared.heights.resize(synthesized.raw.size());
    const std::size_t clamped = sim::apply_mapping(synthesized.mapping, synthesized.raw, prepared.heights);
    prepared.description = std::string(source_name(source.kind)) +
                           fmt::format(" at t = {:g} s (h = ", double(source.time)) +
                           mapping_phrase(synthesized.mapping) + clamped_phrase(clamped) + ")";
    prepared.metadata = source_attributes_for_cones(synthesized.metadata);
  }
  return prepared;
}

BakedCones bake_cones(std::span<const float> heights, int width, int height, int sector_count, Baker baker,
                      bake::Address address, double budget_milliseconds, float tolerance,
                      const bake::Progress& progress) {
  if (baker == Baker::relaxed && sector_count != 1 && sector_count != 4) {
    throw usage_error("the relaxed baker supports 1 or 4 sectors, not " + std::to_string(sector_count));
  }
  BakedCones baked;
  baked.ratios.assign(std::size_t(width) * std::size_t(height) * std::size_t(sector_count), 0.0f);
  const bake::HeightView view{heights.data(), width, height};
  const bake::ConeView cones{baked.ratios.data(), width, height, sector_count};

  const auto start = Clock::now();
  switch (baker) {
    case Baker::exact: baked.stats = bake::bake_exact(view, address, cones, progress); break;
    case Baker::original: baked.stats = bake::bake_original(view, address, cones, progress); break;
    case Baker::paper_adaptive:
      baked.stats = bake::bake_paper_adaptive(view, address, bake::PaperAdaptiveSettings{}, cones);
      break;
    case Baker::budgeted: {
      bake::Budget budget;
      budget.milliseconds = budget_milliseconds;
      budget.tolerance = tolerance;
      baked.stats = bake::bake_budgeted(view, address, budget, cones);
      break;
    }
    case Baker::relaxed: baked.stats = bake::bake_relaxed(view, address, cones, progress); break;
    case Baker::full: throw usage_error("--mode full bakes bilinear cones only (--cones bilinear)");
  }
  const double elapsed = milliseconds_since(start);
  if (!(baked.stats.milliseconds > 0.0) || !std::isfinite(baked.stats.milliseconds)) {
    baked.stats.milliseconds = elapsed;
  }
  baked.stats.width = width;
  baked.stats.height = height;
  baked.stats.sector_count = sector_count;
  return baked;
}

BakedCones bake_bilinear(std::span<const float> heights, int width, int height, int sector_count, Baker baker,
                         bake::Address address, double budget_milliseconds, float tolerance,
                         const bake::Progress& progress) {
  if (baker != Baker::budgeted && baker != Baker::full) {
    throw usage_error(std::string("bilinear cones bake with the budgeted or the full baker, not ") +
                      baker_name(baker));
  }
  BakedCones baked;
  const std::size_t texels = std::size_t(width) * std::size_t(height);
  baked.ratios.assign(texels * std::size_t(sector_count), 0.0f);
  baked.apex.assign(texels, 0.0f);
  const bake::HeightView view{heights.data(), width, height};
  const bake::ConeView cones{baked.ratios.data(), width, height, sector_count};
  if (baker == Baker::full) {
    bake::BilinearConeSettings settings;
    settings.progress = progress;
    baked.stats = bake::bake_bilinear_cones(view, address, cones, baked.apex, settings);
  } else {
    bake::Budget budget;
    budget.milliseconds = budget_milliseconds;
    budget.tolerance = tolerance;
    budget.progress = progress;
    bake::BilinearBaker bilinear_baker(width, height, sector_count, address);
    baked.stats = bilinear_baker.bake(view, budget, cones, baked.apex);
  }
  return baked;
}

std::string stats_json(const bake::BakeStats& stats, Baker baker, bake::Address address, ConeKind kind) {
  const auto finite = [](double value) { return std::isfinite(value) ? value : 0.0; };
  const nlohmann::ordered_json line = {
      {"mode", baker_name(baker)},
      {"cones", cone_kind_name(kind)},
      {"width", stats.width},
      {"height", stats.height},
      {"sectors", stats.sector_count},
      {"address", address_name(address)},
      {"milliseconds", finite(stats.milliseconds)},
      {"texels_refined", stats.texels_refined},
      {"texels_fallback", stats.texels_fallback},
      {"work", stats.work},
      {"mean_ratio", finite(stats.mean_ratio)},
  };
  return line.dump();
}

void run_sim(const SimSettings& settings, std::ostream& out) {
  require_memory(synthesis_memory(settings.source), host_limits());
  const SynthesizedHeights heights = synthesize(settings.source);
  write_height_exr(settings.output, heights);
  out << "displace: synthesized " << source_name(settings.source.kind) << " heights " << heights.width
      << " x " << heights.height
      << fmt::format(" at t = {:g} s in {:.1f} ms (h01 = ", double(settings.source.time),
                     heights.milliseconds)
      << mapping_phrase(heights.mapping) << "); wrote raw metres to '" << settings.output.string() << "'\n";
}

void run_bake(const BakeSettings& settings, std::ostream& out) {
  // refused before the work when it cannot fit: a source before it is synthesized, a file once its
  // size is known
  const render::MemoryLimits limits = host_limits();
  if (const auto* source = std::get_if<SourceSettings>(&settings.input)) {
    std::vector<render::Allocation> needs = synthesis_memory(*source);
    for (render::Allocation& bake :
         bake_memory(source->size, source->size, settings.sector_count, settings.baker, settings.cones)) {
      needs.push_back(std::move(bake));
    }
    require_memory(needs, limits);
  }
  BakeInput input = prepare_bake_input(settings.input);
  if (std::holds_alternative<FileInput>(settings.input)) {
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
  const BakedCones baked = (bilinear ? bake_bilinear : bake_cones)(
      input.heights, input.width, input.height, settings.sector_count, settings.baker, settings.address,
      settings.budget_milliseconds, settings.tolerance, progress.callback());
  progress.finish();
  const ConeMapExport cones{input.width,    input.height,   settings.sector_count,
                            input.heights,  baked.ratios,   settings.address,
                            settings.baker, settings.cones, baked.apex};
  Metadata metadata = input.metadata;
  metadata.push_back({"displace:heights_quantized_8bit", png ? 1 : 0});
  if (png) {
    write_cone_png(settings.output, cones, metadata);
  } else {
    write_cone_exr(settings.output, cones, metadata);
  }

  if (settings.stats) {
    out << stats_json(baked.stats, settings.baker, settings.address, settings.cones) << '\n';
  } else {
    out << "displace: baked " << settings.sector_count
        << (bilinear ? "-sector bilinear cones (with apex heights) for " : "-sector cones for ")
        << input.width << " x " << input.height << " heights from " << input.description << " with the "
        << baker_name(settings.baker) << " baker (" << address_name(settings.address)
        << (settings.baker == Baker::budgeted ? ", " + budget_phrase(settings.budget_milliseconds) : "")
        << "): " << stats_phrase(baked.stats) << "; wrote '" << settings.output.string() << "'"
        << (png ? " (heights quantized to 8 bits before baking)" : "") << '\n';
  }
}

namespace {

// Blue -> cyan -> green -> yellow -> red over [0, maximum]: the iterations heatmap (as in Figure 5 of
// Risser et al.'s interval mapping paper). Pixels off the relief stay black.
std::vector<std::uint8_t> heatmap(std::span<const float> values, std::span<const float> uv_hit,
                                  float maximum) {
  constexpr float stops[5][3] = {{0, 0, 1}, {0, 1, 1}, {0, 1, 0}, {1, 1, 0}, {1, 0, 0}};
  std::vector<std::uint8_t> rgba(values.size() * 4, 0);
  for (std::size_t p = 0; p < values.size(); ++p) {
    rgba[p * 4 + 3] = 255;
    if (uv_hit[p * 3 + 2] < 0.5f) continue;
    const float x = std::clamp(maximum > 0.0f ? values[p] / maximum : 0.0f, 0.0f, 1.0f) * 4.0f;
    const int stop = std::min(int(x), 3);
    const float f = x - float(stop);
    for (int c = 0; c < 3; ++c) {
      rgba[p * 4 + c] =
          std::uint8_t(std::lround(255.0f * (stops[stop][c] * (1 - f) + stops[stop + 1][c] * f)));
    }
  }
  return rgba;
}

}  // namespace

FrameSummary summarize(const render::Frame& frame) {
  FrameSummary summary;
  std::vector<float> fetches;
  for (std::size_t p = 0; p < frame.fetches.size(); ++p) {
    if (frame.uv[p * 3 + 2] < 0.5f) continue;
    summary.mean_iterations += frame.iterations[p];
    summary.mean_fetches += frame.fetches[p];
    summary.max_iterations = std::max(summary.max_iterations, double(frame.iterations[p]));
    fetches.push_back(frame.fetches[p]);
  }
  summary.hit_pixels = (long long)fetches.size();
  if (!fetches.empty()) {
    summary.mean_iterations /= double(fetches.size());
    summary.mean_fetches /= double(fetches.size());
    const std::size_t rank = std::min(fetches.size() - 1, std::size_t(0.99 * double(fetches.size())));
    std::nth_element(fetches.begin(), fetches.begin() + std::ptrdiff_t(rank), fetches.end());
    summary.p99_fetches = fetches[rank];
  }
  return summary;
}

MethodRun measure_method(render::Renderer& renderer, pipeline::MapMaker& maps, const render::View& view,
                         const render::MethodSettings& method, int repeat, const render::Frame& reference,
                         render::Frame& frame) {
  std::vector<double> times;
  renderer.set_maps(maps.maps_for(method.method, view));
  for (int r = 0; r < repeat; ++r) {
    renderer.render(view, method, frame);
    times.push_back(frame.gpu_milliseconds);
  }
  std::sort(times.begin(), times.end());
  MethodRun run;
  run.median_ms = times[times.size() / 2];
  run.error = render::compare(frame, reference);
  run.summary = summarize(frame);
  return run;
}

void write_frame_image(const std::filesystem::path& file, const render::Frame& frame,
                       const Metadata& metadata) {
  if (lower_extension(file) == ".png") {
    write_png_rgba8(file, frame.width, frame.height, frame.color, metadata);
    return;
  }
  const std::size_t pixels = std::size_t(frame.width) * frame.height;
  std::vector<float> channels[4];
  for (auto& channel : channels) channel.resize(pixels);
  for (std::size_t p = 0; p < pixels; ++p) {
    for (int c = 0; c < 4; ++c) channels[c][p] = float(frame.color[p * 4 + c]) / 255.0f;
  }
  const ExrChannel exr[] = {{"R", channels[0]}, {"G", channels[1]}, {"B", channels[2]}, {"A", channels[3]}};
  write_exr(file, frame.width, frame.height, exr, metadata);
}

void write_aov(const AovOutput& aov, const render::Frame& frame, const Metadata& metadata) {
  const std::size_t pixels = std::size_t(frame.width) * frame.height;
  if (aov.aov == Aov::uv) {
    std::vector<float> u(pixels), v(pixels), hit(pixels);
    for (std::size_t p = 0; p < pixels; ++p) {
      u[p] = frame.uv[p * 3 + 0];
      v[p] = frame.uv[p * 3 + 1];
      hit[p] = frame.uv[p * 3 + 2];
    }
    const ExrChannel exr[] = {{"u", u}, {"v", v}, {"hit", hit}};
    write_exr(aov.file, frame.width, frame.height, exr, metadata);
    return;
  }
  if (aov.aov == Aov::depth) {
    const ExrChannel exr[] = {{"depth", frame.depth}};
    write_exr(aov.file, frame.width, frame.height, exr, metadata);
    return;
  }
  const bool iterations = aov.aov == Aov::iterations;
  const std::vector<float>& values = iterations ? frame.iterations : frame.fetches;
  if (lower_extension(aov.file) == ".png") {
    const float maximum = values.empty() ? 0.0f : *std::max_element(values.begin(), values.end());
    Metadata heat_metadata = metadata;
    heat_metadata.push_back({"displace:heatmap_maximum", maximum});
    write_png_rgba8(aov.file, frame.width, frame.height, heatmap(values, frame.uv, maximum), heat_metadata);
    return;
  }
  const ExrChannel exr[] = {{iterations ? "iterations" : "fetches", values}};
  write_exr(aov.file, frame.width, frame.height, exr, metadata);
}

namespace {

void set_albedo_from(render::Renderer& renderer, const std::filesystem::path& file) {
  Rgba8Image image = read_color_image(file);
  renderer.set_albedo({image.width, image.height, std::move(image.pixels)});
}

}  // namespace

void run_render(const RenderSettings& settings, std::ostream& out) {
  // the device first: what it offers decides what fits, before anything is synthesized or baked
  render::Renderer renderer(settings.renderer);
  const render::MemoryLimits limits = renderer.memory_limits();
  if (const auto* source = std::get_if<SourceSettings>(&settings.input)) {
    require_memory(render_memory(settings, source->size, source->size), limits);
  }
  BakeInput input = prepare_bake_input(settings.input);
  if (std::holds_alternative<FileInput>(settings.input)) {
    require_memory(render_memory(settings, input.width, input.height), limits);
  }
  pipeline::MapMaker maps(renderer.device().max_image_dimension_3d);
  maps.set_cone_budget(settings.cone_budget);
  maps.set_heights({input.width, input.height, std::move(input.heights)});
  if (!settings.albedo.empty()) set_albedo_from(renderer, settings.albedo);
  if (!settings.mesh.empty()) renderer.set_mesh(read_obj(settings.mesh));
  const render::MethodInfo& info = render::method_info(settings.method.method);
  const render::Frame frame = pipeline::render_with_maps(renderer, maps, settings.view, settings.method);
  Metadata metadata = input.metadata;
  metadata.push_back({"displace:method", std::string(info.name)});
  metadata.push_back({"displace:steps", settings.method.steps});
  metadata.push_back({"displace:refine", settings.method.refine});
  const bake::Budget& cone_budget = settings.cone_budget;
  const bool default_tolerance = cone_budget.tolerance == bake::Budget{}.tolerance;
  if (std::isfinite(cone_budget.milliseconds))
    metadata.push_back({"displace:bake_budget_ms", float(cone_budget.milliseconds)});
  if (!default_tolerance) metadata.push_back({"displace:bake_tolerance", cone_budget.tolerance});
  if (settings.view.surface != render::Surface::plane) {
    metadata.push_back({"displace:surface", std::string(render::surface_name(settings.view.surface))});
    metadata.push_back({"displace:radius", settings.view.radius});
  }
  write_frame_image(settings.output, frame, metadata);
  for (const AovOutput& aov : settings.aovs) write_aov(aov, frame, metadata);
  const FrameSummary summary = summarize(frame);
  out << fmt::format(
      "displace render: {}, {} steps, {} refine, on {} ({}): {} x {}, {} pixels hit, "
      "{:.2f} ms on the device; per pixel: {:.1f} iterations, {:.1f} fetches (p99 {:.0f})\n",
      info.name, settings.method.steps, settings.method.refine, renderer.device().name,
      renderer.device().type, frame.width, frame.height, summary.hit_pixels, frame.gpu_milliseconds,
      summary.mean_iterations, summary.mean_fetches, summary.p99_fetches);
  if (info.cone_sectors != 0) {  // what the cone maps cost and claim
    out << "  cone maps baked by the budgeted bilinear baker " << baked_within(cone_budget.milliseconds)
        << (default_tolerance ? std::string() : fmt::format(" at tolerance {:g}", cone_budget.tolerance));
    const bake::BakeStats& stats = maps.cone_stats(info.cone_sectors);
    if (stats.sector_count != 0) {
      out << fmt::format(": {:.1f} ms, mean ratio {:.4f}, {} of {} texels searched", stats.milliseconds,
                         stats.mean_ratio, stats.texels_refined, (long long)stats.width * stats.height);
    }
    out << " (conservative at any budget)\n";
  }
  out << "  wrote " << settings.output.string();
  for (const AovOutput& aov : settings.aovs) out << ", " << aov.file.string();
  out << '\n';
  if (settings.compare_reference) {
    const render::Frame reference =
        pipeline::render_with_maps(renderer, maps, settings.view, {render::Method::reference, 1, 0});
    const render::ImageError error = render::compare(frame, reference);
    out << fmt::format(
        "  compare reference: rmse {:.3f}, max error {:.0f}, {:.3f}% of {} pixels off by more than 10 "
        "(8-bit units)\n",
        error.rmse, error.max_error, 100.0 * error.fraction_over_10, error.pixels);
  }
  if (settings.renderer.validate && renderer.validation_messages() > 0) {
    throw runtime_error(std::to_string(renderer.validation_messages()) +
                        " Vulkan validation messages (printed above)");
  }
}

void load_scene(render::Renderer& renderer, pipeline::MapMaker& maps, const SceneSettings& scene) {
  BakeInput input = prepare_bake_input(scene.input);
  maps.set_heights({input.width, input.height, std::move(input.heights)});
  if (!scene.mesh.empty()) renderer.set_mesh(read_obj(scene.mesh));
  if (scene.albedo.empty()) {
    renderer.clear_albedo();
  } else {
    set_albedo_from(renderer, scene.albedo);
  }
}

void run_sweep(const SweepSettings& settings, std::ostream& out) {
  render::Renderer renderer(settings.renderer);
  pipeline::MapMaker maps(renderer.device().max_image_dimension_3d);
  maps.set_cone_budget(settings.cone_budget);
  std::ofstream csv(settings.output);
  if (!csv) throw runtime_error("cannot write " + settings.output.string());
  csv << "scene,method,steps,refine,rmse,max_error,fraction_over_10,mean_fetches,p99_fetches,mean_iterations,"
         "median_ms,device\n";
  out << "displace sweep on " << renderer.device().name << " (" << renderer.device().type << "), "
      << settings.repeat << " renders per row, median device time; cone maps baked "
      << baked_within(settings.cone_budget.milliseconds)
      << fmt::format(" at tolerance {:g}\n", settings.cone_budget.tolerance);
  for (const SceneSettings& scene : settings.scenes) {
    load_scene(renderer, maps, scene);
    const render::Frame reference =
        pipeline::render_with_maps(renderer, maps, scene.view, {render::Method::reference, 1, 0});
    out << fmt::format("scene {}: {} x {} map, {} x {} pixels\n", scene.name, maps.heights().width,
                       maps.heights().height, scene.view.camera.width, scene.view.camera.height);
    out << "  method            fetches/pixel for rmse <= 3 (steps)   rmse at the most steps\n";
    std::array<bool, 3> cones_used{};  // by render::cone_slot
    for (render::Method method : settings.methods) {
      const render::MethodInfo& info = render::method_info(method);
      if (!render::supports_surface(method, scene.view.surface)) {
        out << fmt::format("  {:<17} skipped: no {} support\n", info.name,
                           render::surface_name(scene.view.surface));
        continue;
      }
      if (info.cone_sectors != 0) cones_used[std::size_t(render::cone_slot(info.cone_sectors))] = true;
      double best_fetches = -1.0;
      int best_steps = 0;
      double last_rmse = 0.0;
      render::Frame frame;
      for (int steps : settings.steps) {
        const MethodRun run = measure_method(renderer, maps, scene.view, {method, steps, settings.refine},
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
  }
  out << "  wrote " << settings.output.string() << '\n';
  if (settings.renderer.validate && renderer.validation_messages() > 0) {
    throw runtime_error(std::to_string(renderer.validation_messages()) +
                        " Vulkan validation messages (printed above)");
  }
}

void run_demo(const DemoSettings& settings, std::ostream& out) {
  constexpr int demo_sectors = 4;
  const bake::Address address = bake::Address::wrap;  // an FFT ocean tiles
  make_output_directory(settings.output_directory);
  const std::filesystem::path height_file = settings.output_directory / "ocean_height.exr";
  const std::filesystem::path exr_file = settings.output_directory / "ocean_cone4.exr";
  const std::filesystem::path png_file = settings.output_directory / "ocean_cone4.png";

  // synthesize the default ocean frame
  SourceSettings source;
  source.kind = SourceKind::ocean;
  source.size = settings.map_size;
  source.time = 0.0f;
  source.ocean.size = settings.map_size;
  std::vector<render::Allocation> needs = synthesis_memory(source);
  for (render::Allocation& bake :
       bake_memory(source.size, source.size, demo_sectors, Baker::budgeted, ConeKind::center)) {
    needs.push_back(std::move(bake));
  }
  require_memory(needs, host_limits());
  const SynthesizedHeights ocean = synthesize(source);
  write_height_exr(height_file, ocean);
  out << fmt::format(
      "displace demo: FFT ocean {} x {} ({:g} m patch, {} spectrum, wind {:g} m/s), t = 0 s, "
      "synthesized in {:.1f} ms\n",
      ocean.width, ocean.height, double(source.ocean.patch_size), spectrum_name(source.ocean.spectrum),
      double(source.ocean.wind_speed), ocean.milliseconds);
  out << "  wrote " << height_file.string() << " (raw metres, channel height)\n";

  // map to [0, 1] with the spectrum's fixed mapping
  std::vector<float> heights(ocean.raw.size());
  const std::size_t clamped = sim::apply_mapping(ocean.mapping, ocean.raw, heights);
  out << "  mapped to [0, 1] as h = " << mapping_phrase(ocean.mapping) << " (+-3 sigma of the spectrum), "
      << clamped << " samples clamped\n";

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
  RenderSettings render_settings;
  render_settings.view = render::View{};  // the default camera of render.h
  render_settings.method = {render::Method::acm4, 32, 0};
  render::Renderer renderer(render_settings.renderer);
  pipeline::MapMaker maps(renderer.device().max_image_dimension_3d);
  maps.set_heights({ocean.width, ocean.height, heights});
  const render::Frame acm4 =
      pipeline::render_with_maps(renderer, maps, render_settings.view, render_settings.method);
  const render::Frame reference =
      pipeline::render_with_maps(renderer, maps, render_settings.view, {render::Method::reference, 1, 0});
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

void run_print_scene(const PrintSceneSettings& settings, std::ostream& out) {
  out << pipeline::scene_toml(pipeline::builtin_scene(settings.name));
}

std::string usage_text() {
  std::string methods;
  for (const render::MethodInfo& info : render::method_table()) {
    if (!methods.empty()) methods += ", ";
    methods += info.name;
  }
  std::string text = R"(displace - height fields, cone maps and their export

usage:
  displace sim --source ocean|sinusoids|bricks|cliff --map-size N --time T [synthesis options] --output F.exr
      Synthesize heights and write raw metres to channel `height`, with the source parameters and
      the [0, 1] mapping (displace:height_scale, displace:height_bias) as EXR attributes.

  displace bake (--input H.png|H.exr [--channel C] [--invert] [--height-range LO,HI]
                | --source ocean|sinusoids|bricks|cliff --map-size N --time T [synthesis options])
                --sectors 1|4|8 (--mode exact|original|paper-adaptive|budgeted [--budget-ms X] [--tolerance T]
                                 | --relaxed
                                 | --cones bilinear --mode budgeted|full [--budget-ms X] [--tolerance T])
                [--address wrap|clamp] --output C.exr|C.png [--stats]
      Bake a cone map. --input: 8/16-bit images map as value / maximum; float images map their
      min..max to 0..1 unless --height-range LO,HI is given or the file was written by
      `displace sim`. --channel takes a name or an index (default: `height`, or the only grey
      channel). --invert: the image stores depth (1 = deepest). --relaxed bakes relaxed cones
      (sectors 1 or 4). A .png output quantizes the heights to 8 bits before baking so that its
      cones are conservative for the heights it stores. --budget-ms: refinement time per frame
      (the conservative fallback is always completed). --tolerance T (default 0.25): refine only
      while a ratio may be more than T below exact; 0 refines to the exact map. --stats prints one
      JSON line.
      --cones center (the default): cones between texel centres, as above. --cones bilinear: the
      renderer's cone maps, safe for the bilinear surface from anywhere in a texel's square, with an
      apex height per texel; --mode full bakes them whole, --mode budgeted with the budgeted bilinear
      baker within --budget-ms (0 allowed: conservative at any budget). Their .exr has channels
      height, apex, cone0..cone{n-1}; their .png adds an apex panel after the height panel, rounded
      up (ratios are rounded down), so the decoded maps stay conservative.
      On a terminal, a bake that runs for more than a second shows its progress on stderr.

  displace render (--input H.png|H.exr [load options] | --source NAME --map-size N --time T [...])
                  --method NAME [--steps S] [--refine R] [--address wrap|clamp] [--tile K]
                  [--depth-scale D] [--eye X,Y,Z] [--look-at X,Y,Z] [--up X,Y,Z] [--fov-y DEG]
                  [--light X,Y,Z] [--shadows] [--albedo IMAGE] [--size WxH] [--bake-budget-ms B]
                  [--bake-tolerance T] [--surface plane|sphere|cylinder|cone|mesh:FILE.obj] [--radius R]
                  --output F.png|F.exr [--aov NAME=FILE ...] [--compare reference] [--device N|NAME]
                  [--validate]
      Render the height field on the plane x, y in [0, 1] (z up; height 1 on the plane z = 0, height 0
      at z = -D) with one per-pixel method, baking the maps it needs (cone maps for the bilinear
      surface, relaxed cones, the dual max pyramid or the distance map).
      Methods: METHODS.
      --surface sphere|cylinder|cone (Patterson et al.'s inverse displacement mapping): a quadric
      of radius R (--radius, default 0.25, D at most R/2) around the vertical axis x = y = 0.5: the
      sphere centred at z = 0, the cylinder over z in [-R, R], the cone (apex z = 1.5 R, slope 1/2)
      over z in [-R/2, R/2]; u = longitude / 2 pi, v along the axis (sphere: angle from the south
      pole / pi). Height 1 is the outer surface, height 0 lies D inward along the normal. Methods
      there: bump, pom, relief, interval, csm, acm4, acm8, acm4-interval, reference.
      --steps: linear-search steps or maximum cone steps (default 32); --refine: binary or secant
      steps (default 8). AOVs: uv=F.exr (u, v, hit), depth=F.exr, iterations=F.exr|F.png (a .png
      is a heatmap), fetches=F.exr|F.png. --compare reference also renders the reference (the
      tessellated height field, its hit snapped to the exact bilinear crossing on the plane) and
      prints RMSE, maximum error and the share of pixels off by more than 10 (8-bit).
      --surface mesh:FILE.obj: any OBJ mesh with texture coordinates as the top of the relief
      (height 0 lies D inside along the normal); every method; silhouettes from the mesh's curvature.
      --bake-budget-ms B (cone methods: csm, acm4, acm8, acm4-interval, relaxed): bake their cone
      maps with the budgeted bilinear baker within B ms (default unlimited; 0 allowed). The maps are
      conservative at any budget: a starved bake costs cone steps, never a wrong hit.
      --bake-tolerance T (the same methods, default 0.25): refine a texel only while one of its
      ratios may be more than T below the best the contract allows. An unlimited bake then searches
      fewer texels (2048 ocean: about 25 s at 0.25, 10 s at 0.45 for 0.96 of the mean ratio).
      --shadows traces from each hit towards the light with the same method (self-shadowing).
      --albedo shades with an image (1-4 channels, used as stored) instead of the procedural grid.
      --device picks a Vulkan device (default: the best GPU, else lavapipe); --validate turns on the
      Khronos validation layer and fails on any message. --pipeline-cache DIR|off: where compiled
      pipelines are kept between runs (default $DISPLACE_PIPELINE_CACHE, else
      $XDG_CACHE_HOME/displace, else ~/.cache/displace).

  displace sweep [--scene bricks|ocean|cliff|FILE ...] [--methods all|NAME,NAME...]
                 [--steps 4,8,16,32,64] [--refine R] [--repeat N] [--size WxH] [--bake-budget-ms B]
                 [--bake-tolerance T] [--device D] [--validate] --output sweep.csv
      What accuracy costs: every method at every step count on each scene, against the reference.
      One CSV row per scene, method and steps: rmse, max error, share of pixels off by more than 10,
      mean and p99 fetches per pixel, mean iterations, median device milliseconds. Prints, per
      method, the fewest fetches per pixel that reach rmse <= 3. Default scenes: the three built-in
      ones (256 x 256 maps, the default camera). A scene FILE holds render flags, one per line
      (--source/--input and their options, --map-size, --eye, --look-at, --up, --fov-y, --size,
      --tile, --depth-scale, --address, --light, --shadows, --albedo, --surface, --radius); '#' starts a
      comment. --bake-budget-ms and --bake-tolerance bake the cone methods' maps as render does.

  displace report [--scene bricks|ocean|cliff|IMAGE|FILE.txt ...] [--invert] [--quick] [--size N]
                  [--output DIR] [--no-plots]
      What accuracy costs in time, measured on this machine: every method's rmse against fetches and
      device ms (steps 4..1024), grazing views (2..80 degrees), the bakers' budgets and tolerances
      against their tightness and the acm4 fetches it buys, the water frame loop's budget against
      its error, and iteration heatmaps. Writes the CSV/JSON behind each figure, the figures (PNG,
      demos/report/plot_report.py with Debian's python3-matplotlib) and DIR/README.md (default
      docs/report). --quick: fewer runs at 128 x 128 (under a minute); the full report takes about
      6 minutes on 2 cores. An IMAGE scene is a height map (--invert: a depth map), clamped at its edges.

  displace demo [--map-size N] [--output-dir DIR]
      Default ocean (512 x 512, t = 0) to out/ocean_height.exr, out/ocean_cone4.exr and
      out/ocean_cone4.png, baked with the budgeted baker and an unlimited budget; then renders it
      with acm4 and with the tessellated reference (out/ocean_acm4.png, out/ocean_reference.png,
      out/ocean_acm4_iterations.png) and compares them.

  displace scene --print NAME
      Write a built-in scene of the frame pipeline (NAMES) as a TOML scene file to stdout.

  displace play [--scene NAME|FILE.toml] [--size WxH] [--map-size N] [--frames N [--screenshot F.png]] [--vsync]
      The frame pipeline's scene (default water) animated in a window: M cycles methods, Up/Down
      steps, Right/Left the frame budget, Space pauses, N steps, S screenshots, the mouse orbits
      (`displace play --help` lists the keys). --frames N renders exactly frames 0..N-1 and exits.
      Needs a display: 'xvfb-run -a displace play ...' without one.

  displace help | --help
      This overview. `displace COMMAND --help` lists the flags of one command with their limits.

--map-size is always the height map's samples a side, --size always the image's pixels (WxH).

synthesis options:
  --seed S               random seed (non-negative integer); bricks and cliff take only --seed
  --time T               seconds (ocean, sinusoids)
  --patch-size M         metres covered by the map (ocean 200, sinusoids 4)
  --wind-direction DEG   azimuth of the wind / mean wave direction, degrees
  --wind-speed V         ocean: m/s at 10 m (default 12)
  --spectrum S           ocean: phillips (default) or jonswap
  --fetch KM             ocean, jonswap only: fetch in km (default 200)
  --spreading S          ocean: directional spreading exponent (default 2)
  --choppiness L         ocean: horizontal displacement scale, recorded only (default 1)
  --waves K              sinusoids: number of waves (default 12)

exit status: 0 success; 2 when the command line is wrong (a flag, a value, its limits, flags that do
not go together, a flag that does not fit its input); 1 when the problem lies outside it (a missing,
truncated or malformed file, an output that cannot be written, no Vulkan device, not enough memory).
DISPLACE_MEMORY_LIMIT_MB=N holds the memory guards to N megabytes.
)";
  text.replace(text.find("METHODS"), 7, methods);
  std::string names;
  for (const std::string& name : pipeline::builtin_scene_names()) names += (names.empty() ? "" : ", ") + name;
  text.replace(text.find("NAMES"), 5, names);
  return text;
}

int run_command(const CommandSettings& settings, std::ostream& out) {
  if (const auto* help = std::get_if<HelpSettings>(&settings)) {
    out << (help->text.empty() ? usage_text() : help->text);
  } else if (const auto* print = std::get_if<PrintSceneSettings>(&settings)) {
    run_print_scene(*print, out);
  } else if (const auto* sim_settings = std::get_if<SimSettings>(&settings)) {
    run_sim(*sim_settings, out);
  } else if (const auto* bake_settings = std::get_if<BakeSettings>(&settings)) {
    run_bake(*bake_settings, out);
  } else if (const auto* render_settings = std::get_if<RenderSettings>(&settings)) {
    run_render(*render_settings, out);
  } else if (const auto* sweep_settings = std::get_if<SweepSettings>(&settings)) {
    run_sweep(*sweep_settings, out);
  } else if (const auto* sequence_settings = std::get_if<SequenceSettings>(&settings)) {
    run_sequence(*sequence_settings, out);
  } else if (const auto* bench_settings = std::get_if<BenchFrameSettings>(&settings)) {
    run_bench_frame(*bench_settings, out);
  } else if (const auto* play_settings = std::get_if<PlaySettings>(&settings)) {
    run_play(*play_settings, out);
  } else if (const auto* report_settings = std::get_if<ReportSettings>(&settings)) {
    run_report(*report_settings, out);
  } else {
    run_demo(std::get<DemoSettings>(settings), out);
  }
  out.flush();
  return 0;
}

}  // namespace displace::app
