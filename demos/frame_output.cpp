// demos/frame_output.cpp - pictures, AOVs and statistics of rendered frames (demos/frame_output.h).
#include "demos/frame_output.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <span>

#include "demos/error.h"
#include "pipeline/height_source.h"

namespace displace::app {

std::string lower_extension(const std::filesystem::path& path) {
  std::string extension = path.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  return extension;
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

unsigned frame_outputs(const std::vector<AovOutput>& aovs) {
  unsigned outputs = render::output_color;
  for (const AovOutput& aov : aovs) {
    outputs |= aov.aov == Aov::uv           ? render::output_uv
               : aov.aov == Aov::depth      ? render::output_depth
               : aov.aov == Aov::iterations ? render::output_uv | render::output_iterations
                                            : render::output_uv | render::output_fetches;
  }
  return outputs;
}

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

files::WrittenFile write_frame_image(const std::filesystem::path& file, const render::Frame& frame,
                                     const Metadata& metadata) {
  if (lower_extension(file) == ".png") {
    return write_png_rgba8(file, frame.width, frame.height, frame.color, metadata);
  }
  const std::size_t pixels = std::size_t(frame.width) * frame.height;
  std::vector<float> channels[4];
  for (auto& channel : channels) channel.resize(pixels);
  for (std::size_t p = 0; p < pixels; ++p) {
    for (int c = 0; c < 4; ++c) channels[c][p] = float(frame.color[p * 4 + c]) / 255.0f;
  }
  const ExrChannel exr[] = {{"R", channels[0]}, {"G", channels[1]}, {"B", channels[2]}, {"A", channels[3]}};
  return write_exr(file, frame.width, frame.height, exr, metadata);
}

files::WrittenFile write_aov(const AovOutput& aov, const render::Frame& frame, const Metadata& metadata) {
  const std::size_t pixels = std::size_t(frame.width) * frame.height;
  if (aov.aov == Aov::uv) {
    std::vector<float> u(pixels), v(pixels), hit(pixels);
    for (std::size_t p = 0; p < pixels; ++p) {
      u[p] = frame.uv[p * 3 + 0];
      v[p] = frame.uv[p * 3 + 1];
      hit[p] = frame.uv[p * 3 + 2];
    }
    const ExrChannel exr[] = {{"u", u}, {"v", v}, {"hit", hit}};
    return write_exr(aov.file, frame.width, frame.height, exr, metadata);
  }
  if (aov.aov == Aov::depth) {
    const ExrChannel exr[] = {{"depth", frame.depth}};
    return write_exr(aov.file, frame.width, frame.height, exr, metadata);
  }
  const bool iterations = aov.aov == Aov::iterations;
  const std::vector<float>& values = iterations ? frame.iterations : frame.fetches;
  if (lower_extension(aov.file) == ".png") {
    const float maximum = values.empty() ? 0.0f : *std::max_element(values.begin(), values.end());
    Metadata heat_metadata = metadata;
    heat_metadata.push_back({"displace:heatmap_maximum", maximum});
    return write_png_rgba8(aov.file, frame.width, frame.height, heatmap(values, frame.uv, maximum),
                           heat_metadata);
  }
  const ExrChannel exr[] = {{iterations ? "iterations" : "fetches", values}};
  return write_exr(aov.file, frame.width, frame.height, exr, metadata);
}

std::vector<std::string> effect_names(unsigned effects) {
  std::vector<std::string> names;
  if (effects & pipeline::effect_heights) names.emplace_back("heights");
  if (effects & pipeline::effect_choppy) names.emplace_back("choppy");
  if (effects & pipeline::effect_foam) names.emplace_back("foam");
  return names;
}

}  // namespace displace::app
