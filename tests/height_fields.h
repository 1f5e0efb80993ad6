// tests/height_fields.h - analytic height fields for the renderer tests, the built-in brick and
// ocean scenes at any size, and the finiteness check of every AOV. CPU only: no Vulkan instance.
#pragma once

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "render/render.h"
#include "sim/sim.h"

namespace displace::testing {

inline render::HeightField field_of(int width, int height, auto&& height_at) {
  render::HeightField field{width, height, std::vector<float>(std::size_t(width) * height)};
  for (int i = 0; i < height; ++i)
    for (int j = 0; j < width; ++j) field.heights[std::size_t(i) * width + j] = float(height_at(i, j));
  return field;
}

inline render::HeightField constant_field(int size, double value) {
  return field_of(size, size, [&](int, int) { return value; });
}
inline render::HeightField ramp_field(int size) {
  return field_of(size, size, [&](int, int j) { return 0.1 + 0.8 * (j + 0.5) / size; });
}
inline render::HeightField step_field(int size) {
  return field_of(size, size, [&](int, int j) { return j < size / 2 ? 0.2 : 0.8; });
}
inline render::HeightField waves_field(int size) {  // periodic: 3 waves across u, 2 along v
  return field_of(size, size, [&](int i, int j) {
    return 0.5 + 0.4 * std::sin(6.0 * std::numbers::pi * (j + 0.5) / size) *
                     std::cos(4.0 * std::numbers::pi * (i + 0.5) / size);
  });
}
inline render::HeightField spike_field(int size) {
  return field_of(size, size, [&](int i, int j) { return (i % 8 == 3 && j % 8 == 5) ? 1.0 : 0.1; });
}

// The built-in sweep scenes' sources at size x size: the brick relief and the ocean frame at t = 0.
inline std::vector<std::pair<std::string, render::HeightField>> bricks_and_ocean(int size) {
  std::vector<std::pair<std::string, render::HeightField>> scenes;
  render::HeightField bricks{size, size, std::vector<float>(std::size_t(size) * size)};
  sim::brick_heights(size, size, 1, bricks.heights);
  scenes.emplace_back("bricks", std::move(bricks));
  sim::OceanParams params;
  params.size = size;
  sim::Ocean ocean(params);
  sim::OceanFrame frame;
  ocean.evaluate(0.0f, sim::ocean_heights, frame);
  render::HeightField water{size, size, std::vector<float>(std::size_t(size) * size)};
  sim::apply_mapping(ocean.mapping(), frame.height, water.heights);
  scenes.emplace_back("ocean", std::move(water));
  return scenes;
}

inline bool all_finite(const render::Frame& frame) {
  auto finite = [](const std::vector<float>& values) {
    return std::all_of(values.begin(), values.end(), [](float v) { return std::isfinite(v); });
  };
  return finite(frame.uv) && finite(frame.depth) && finite(frame.iterations) && finite(frame.fetches);
}

}  // namespace displace::testing
