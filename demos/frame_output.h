// demos/frame_output.h - what a rendered frame becomes: its picture (.png 8-bit, .exr float), its
// AOVs (uv, depth, iterations, fetches), its per-pixel statistics and its error against a reference;
// files written by the checked writer (render/files.h), so an interrupted run leaves no half file.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "demos/image_io.h"
#include "pipeline/maps.h"
#include "render/render.h"

namespace displace::app {

// An arbitrary output variable written next to the picture: uv, depth, iterations or fetches.
enum class Aov { uv, depth, iterations, fetches };
struct AovOutput {
  Aov aov = Aov::uv;
  std::filesystem::path file;  // uv and depth: .exr; iterations and fetches: .exr (raw) or .png (heatmap)
};
// The render outputs (render::Output bits) the colour and these AOVs read back.
unsigned frame_outputs(const std::vector<AovOutput>& aovs);

// The extension of a path, lower-cased (".png"): what chooses an output's format.
std::string lower_extension(const std::filesystem::path& path);

// A rendered frame's colour to .png (8-bit) or .exr (float RGBA), and one AOV (AovOutput's formats).
files::WrittenFile write_frame_image(const std::filesystem::path& file, const render::Frame& frame,
                                     const Metadata& metadata);
files::WrittenFile write_aov(const AovOutput& aov, const render::Frame& frame, const Metadata& metadata);

// The error target of `sweep` and `report`: rmse against the reference, 8-bit units.
inline constexpr double sweep_target_rmse = 3.0;

// Per-pixel statistics of a frame (read back with output_all) over the pixels that hit the relief.
struct FrameSummary {
  double mean_iterations = 0.0, mean_fetches = 0.0, p99_fetches = 0.0, max_iterations = 0.0;
  long long hit_pixels = 0;
};
FrameSummary summarize(const render::Frame& frame);

// One method at one step count against a reference frame: its error and what it cost.
struct MethodRun {
  render::ImageError error;
  FrameSummary summary;
  double median_ms = 0.0;  // the median device time of the renders
};
// Renders `method` `repeat` times from the maps `maps` makes for it; `frame` keeps the last one.
MethodRun measure_method(render::Renderer& renderer, pipeline::MapMaker& maps, const render::View& view,
                         const render::MethodSettings& method, int repeat, const render::Frame& reference,
                         render::Frame& frame);

// The names of pipeline::Effect bits ("heights", "choppy", "foam").
std::vector<std::string> effect_names(unsigned effects);

}  // namespace displace::app
