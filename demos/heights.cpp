// demos/heights.cpp - a scene's heights for the one-off commands, and the scene files' readers.
#include "demos/heights.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <stdexcept>

#include "demos/error.h"
#include "demos/obj_io.h"
#include "pipeline/height_source.h"

namespace displace::app {
namespace {

using Clock = std::chrono::steady_clock;

Metadata synthesis_metadata(const pipeline::Scene& source, double time, const sim::HeightMapping& mapping) {
  Metadata metadata = {
      {"displace:units", std::string("metres")},
      {"displace:source", std::string(source_name(source.source))},
      {"displace:time", float(time)},
      {"displace:height_scale", mapping.scale},
      {"displace:height_bias", mapping.bias},
  };
  if (source.source == pipeline::SourceKind::ocean) {
    const sim::OceanParams& ocean = source.ocean;
    const Metadata ocean_metadata = {
        {"displace:seed", std::to_string(ocean.seed)},
        {"displace:patch_size", ocean.patch_size},
        {"displace:spectrum", std::string(pipeline::spectrum_word(ocean.spectrum))},
        {"displace:spreading_model", std::string(pipeline::spreading_word(ocean.spreading_model))},
        {"displace:depth", ocean.depth},
        {"displace:significant_height", ocean.significant_height},
        {"displace:peak_period", ocean.peak_period},
        {"displace:swell_significant_height", ocean.swell.significant_height},
        {"displace:swell_peak_period", ocean.swell.peak_period},
        {"displace:swell_direction", ocean.swell.direction},
        {"displace:swell_spreading", ocean.swell.spreading},
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
  } else if (source.source == pipeline::SourceKind::bricks || source.source == pipeline::SourceKind::cliff) {
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

// A height image: frame 0 of a numbered sequence, read with the scene's settings.
SceneHeights image_heights(const pipeline::Scene& scene) {
  const std::filesystem::path file =
      pipeline::is_image_sequence(scene.image) ? pipeline::image_for_frame(scene.image, 0) : scene.image;
  LoadedHeights loaded = load_heights(file, load_settings(scene.image_read));
  SceneHeights result;
  result.width = loaded.width;
  result.height = loaded.height;
  result.raw = loaded.heights;
  result.heights = std::move(loaded.heights);
  result.mapping = loaded.mapping;
  result.clamped = loaded.clamped;
  const char* format_name = loaded.format == SampleFormat::uint8    ? "8-bit"
                            : loaded.format == SampleFormat::uint16 ? "16-bit"
                                                                    : "float";
  result.description = fmt::format("'{}' ({} channel '{}', h = {}{}{})", file.string(), format_name,
                                   loaded.channel_name, mapping_phrase(loaded.mapping),
                                   loaded.inverted ? ", inverted" : "", clamped_phrase(loaded.clamped));
  result.metadata = {
      {"displace:input", file.string()},
      {"displace:input_channel", loaded.channel_name},
      {"displace:source_height_scale", loaded.mapping.scale},
      {"displace:source_height_bias", loaded.mapping.bias},
      {"displace:source_inverted", loaded.inverted ? 1 : 0},
  };
  return result;
}

}  // namespace

std::string source_name(pipeline::SourceKind kind) {
  switch (kind) {
    case pipeline::SourceKind::ocean: return "ocean";
    case pipeline::SourceKind::sinusoids: return "sinusoids";
    case pipeline::SourceKind::bricks: return "bricks";
    case pipeline::SourceKind::cliff: return "cliff";
    case pipeline::SourceKind::image: return "image";
  }
  return "unknown";
}

bool sim_wants_device(const pipeline::Scene& scene) {
  return pipeline::simulates_on_device(scene.source) && pipeline::runs_on_default_device(scene.sim_backend);
}

SceneHeights scene_heights(const pipeline::Scene& scene, double time, render::Renderer* device) {
  if (scene.source == pipeline::SourceKind::image) return image_heights(scene);
  const auto start = Clock::now();
  SceneHeights result;
  try {
    if (device && pipeline::simulates_on_device(scene.source)) {
      // on the device: the same effects, read back
      pipeline::DeviceSimInfo info;
      const pipeline::SourceSettings settings = pipeline::source_settings(scene);
      const std::unique_ptr<sim::DeviceSim> made = pipeline::make_device_sim(
          *device, settings, pipeline::scene_effects(scene) & ~unsigned(pipeline::effect_foam), &info);
      const sim::HeightMapping mapping = info.mapping;
      result.loop_error = info.loop_error;
      made->simulate(pipeline::source_time(settings, time));
      made->read_back(&result.heights, &result.raw, nullptr);
      result.width = result.height = made->size();
      result.mapping = mapping;
      result.clamped = std::size_t(std::count_if(result.raw.begin(), result.raw.end(), [&](float h) {
        const float mapped = h * mapping.scale + mapping.bias;
        return !(mapped >= 0.0f && mapped <= 1.0f);
      }));
    } else {
      // the heights the renderer samples: choppy crests resampled onto the grid; no foam (nothing reads it)
      pipeline::HeightSource source(pipeline::source_settings(scene),
                                    pipeline::scene_effects(scene) & ~unsigned(pipeline::effect_foam));
      pipeline::HeightFrame frame;
      source.make(time, 0, frame);
      result.width = frame.field.width;
      result.height = frame.field.height;
      result.raw.assign(frame.raw.begin(), frame.raw.end());
      result.heights = frame.field.heights;
      result.mapping = source.mapping();
      result.loop_error = source.loop_error();
      result.clamped = frame.clamped;
    }
  } catch (const pipeline::SceneError& error) {
    throw usage_error(error.what());
  } catch (const std::invalid_argument& error) {
    throw usage_error(fmt::format("bad {} parameters: {}", source_name(scene.source), error.what()));
  }
  result.milliseconds = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
  for (const float h : result.raw) {
    if (!std::isfinite(h))
      throw runtime_error("the " + source_name(scene.source) + " source produced a non-finite height");
  }
  result.description =
      fmt::format("{} at t = {:g} s{} (h = {}{})", source_name(scene.source), time,
                  device && pipeline::simulates_on_device(scene.source) ? " on the device" : "",
                  mapping_phrase(result.mapping), clamped_phrase(result.clamped));
  result.metadata = synthesis_metadata(scene, time, result.mapping);
  return result;
}

void write_height_exr(const std::filesystem::path& file, const SceneHeights& heights) {
  const ExrChannel channel{"height", heights.raw};
  write_exr(file, heights.width, heights.height, std::span(&channel, 1), heights.metadata);
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

HeightLoadSettings load_settings(const pipeline::ImageRead& read) {
  HeightLoadSettings settings;
  if (!read.channel.empty()) {
    if (read.channel.find_first_not_of("0123456789") == std::string::npos) {
      settings.channel.index = std::stoi(read.channel);
    } else {
      settings.channel.name = read.channel;
    }
  }
  settings.invert = read.invert;
  if (read.height_range) settings.range = HeightRange{(*read.height_range)[0], (*read.height_range)[1]};
  return settings;
}

pipeline::HeightLoader height_loader(const pipeline::ImageRead& read) {
  return [settings = load_settings(read)](const std::filesystem::path& file) {
    LoadedHeights loaded = load_heights(file, settings);
    return render::HeightField{loaded.width, loaded.height, std::move(loaded.heights)};
  };
}

pipeline::AlbedoLoader albedo_loader() {
  return [](const std::filesystem::path& file) {
    Rgba8Image image = read_color_image(file);
    return render::Albedo{image.width, image.height, std::move(image.pixels)};
  };
}

void load_scene_mesh(render::Renderer& renderer, const pipeline::Scene& scene) {
  if (scene.surface == render::Surface::mesh) renderer.set_mesh(read_obj(scene.mesh));
}

void load_scene_files(render::Renderer& renderer, const pipeline::Scene& scene) {
  load_scene_mesh(renderer, scene);
  if (scene.albedo.empty()) {
    renderer.clear_albedo();
  } else {
    renderer.set_albedo(albedo_loader()(scene.albedo));
  }
}

render::View start_view(const pipeline::Scene& scene) {
  render::View view = pipeline::scene_view(scene, scene.start);
  view.unbounded = false;  // accuracy is measured on the patch, which the reference tessellates
  return view;
}

void load_scene(render::Renderer& renderer, pipeline::MapMaker& maps, const pipeline::Scene& scene) {
  SceneHeights heights = scene_heights(scene, scene.start);
  maps.set_heights({heights.width, heights.height, std::move(heights.heights)});
  load_scene_files(renderer, scene);
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

}  // namespace displace::app
