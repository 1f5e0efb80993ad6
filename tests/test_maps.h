// tests/test_maps.h - hard height maps for the bakers' tests and benchmarks, made in code.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "sim/sim.h"

namespace displace::test {

struct Map {
  std::string name;
  int width = 0, height = 0;
  std::vector<float> values;
  float& at(int i, int j) { return values[std::size_t(i) * width + j]; }
};

inline std::uint64_t mix(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}
inline float hash01(std::uint64_t seed, int i, int j) {
  return float(mix(seed ^ mix(std::uint64_t(i) * 73856093ull ^ std::uint64_t(j) * 19349663ull)) >> 40) /
         float(1u << 24);
}

inline Map make_flat(int w, int h, float value = 0.5f) {
  return {"flat", w, h, std::vector<float>(std::size_t(w) * h, value)};
}

inline Map make_spikes(int w, int h, std::uint64_t seed = 7) {
  Map m = make_flat(w, h, 0.1f);
  m.name = "spikes";
  const int count = std::max(1, w * h / 97);
  for (int s = 0; s < count; ++s) {
    const int i = int(hash01(seed, s, 1) * h) % h, j = int(hash01(seed, s, 2) * w) % w;
    m.at(i, j) = 0.5f + 0.5f * hash01(seed, s, 3);
  }
  return m;
}

inline Map make_terraces(int w, int h) {
  Map m{"terraces", w, h, std::vector<float>(std::size_t(w) * h)};
  for (int i = 0; i < h; ++i)
    for (int j = 0; j < w; ++j) {
      const float r = std::sqrt(float((i - h / 2) * (i - h / 2) + (j - w / 3) * (j - w / 3)));
      m.at(i, j) = std::floor(6.0f * std::max(0.0f, 1.0f - r / float(std::max(w, h)))) / 6.0f;
    }
  return m;
}

inline Map make_checkerboard(int w, int h) {
  Map m{"checkerboard", w, h, std::vector<float>(std::size_t(w) * h)};
  for (int i = 0; i < h; ++i)
    for (int j = 0; j < w; ++j) m.at(i, j) = ((i + j) & 1) ? 0.9f : 0.2f;
  return m;
}

// Value-noise fBm with a cliff along a column: a sharp step of 0.4.
inline Map make_fractal_cliff(int w, int h, std::uint64_t seed = 3) {
  Map m{"fractal-cliff", w, h, std::vector<float>(std::size_t(w) * h)};
  for (int i = 0; i < h; ++i)
    for (int j = 0; j < w; ++j) {
      float sum = 0.0f, amplitude = 0.5f;
      for (int octave = 0, cell = std::max(2, std::max(w, h) / 2); octave < 5 && cell >= 1;
           ++octave, cell /= 2) {
        const float fi = float(i) / cell, fj = float(j) / cell;
        const int i0 = int(fi), j0 = int(fj);
        const float ti = fi - i0, tj = fj - j0;
        const float a = hash01(seed + octave, i0, j0), b = hash01(seed + octave, i0, j0 + 1);
        const float c = hash01(seed + octave, i0 + 1, j0), d = hash01(seed + octave, i0 + 1, j0 + 1);
        sum += amplitude * ((a * (1 - tj) + b * tj) * (1 - ti) + (c * (1 - tj) + d * tj) * ti);
        amplitude *= 0.5f;
      }
      m.at(i, j) = std::min(1.0f, 0.55f * sum + (j >= w / 2 ? 0.4f : 0.0f));
    }
  return m;
}

inline Map make_near_flat_step(int w, int h) {
  Map m = make_flat(w, h, 0.5f);
  m.name = "near-flat-16bit-step";
  for (int i = h / 4; i < h / 2 + 1; ++i)
    for (int j = w / 3; j < w; ++j) m.at(i, j) = 0.5f + 1.0f / 65535.0f;
  return m;
}

// Brick-like: rows of bricks with bevelled edges and mortar grooves.
inline Map make_bricks(int w, int h) {
  Map m{"bricks", w, h, std::vector<float>(std::size_t(w) * h)};
  const float rows = 8.0f, cols = 4.0f, mortar = 0.06f;
  for (int i = 0; i < h; ++i)
    for (int j = 0; j < w; ++j) {
      const float v = (i + 0.5f) / h * rows;
      const int row = int(v);
      const float u = (j + 0.5f) / w * cols + (row % 2 ? 0.5f : 0.0f);
      const float fu = u - std::floor(u), fv = v - std::floor(v);
      const float edge = std::min(std::min(fu, 1 - fu) * 2.0f / cols * rows, std::min(fv, 1 - fv));
      float value = edge < mortar ? 0.15f : std::min(1.0f, 0.75f + 2.0f * (edge - mortar));
      value -= 0.05f * hash01(11, i, j);
      m.at(i, j) = std::max(0.0f, std::min(1.0f, value));
    }
  return m;
}

// Deep rectangular pockets with steep walls (a toy box's face, depth inverted): a grid of 4 x 4
// cells, each a pocket of its own size and depth (0.35 to 0.85 below the top) sunk into a frame at
// 0.95, the walls one texel wide, rough tops and floors. The pockets scale with the map.
inline Map make_pockets(int w, int h, std::uint64_t seed = 5) {
  Map m{"pockets", w, h, std::vector<float>(std::size_t(w) * h)};
  const int cells = 4;
  for (int i = 0; i < h; ++i)
    for (int j = 0; j < w; ++j) {
      const float u = (j + 0.5f) / w * cells, v = (i + 0.5f) / h * cells;
      const int cell_x = std::min(int(u), cells - 1), cell_y = std::min(int(v), cells - 1);
      const float fu = u - cell_x, fv = v - cell_y;
      auto margin = [&](int side) { return 0.06f + 0.14f * hash01(seed, cell_y, cell_x * 5 + side); };
      const bool inside = fu > margin(0) && fu < 1.0f - margin(1) && fv > margin(2) && fv < 1.0f - margin(3);
      const float depth = 0.35f + 0.5f * hash01(seed, cell_y, cell_x * 5 + 4);
      m.at(i, j) = (inside ? 0.95f - depth : 0.95f) - 0.003f * hash01(seed + 1, i, j);
    }
  return m;
}

// An FFT ocean frame (the default sim::Ocean at t = 0, mapped onto [0, 1]) of the longer side N,
// sampled every N / w columns and N / h rows: the same periodic surface, coarser along the shorter
// side of a non-square map. N must be a multiple of both sides.
inline Map make_ocean(int w, int h) {
  const int n = std::max(w, h);
  sim::OceanParams params;
  params.size = n;
  sim::Ocean ocean(params);
  sim::OceanFrame frame;
  ocean.evaluate(0.0f, sim::ocean_heights, frame);
  std::vector<float> square(std::size_t(n) * n);
  sim::apply_mapping(ocean.mapping(), frame.height, square);
  Map m{"ocean", w, h, std::vector<float>(std::size_t(w) * h)};
  for (int i = 0; i < h; ++i)
    for (int j = 0; j < w; ++j) m.at(i, j) = square[std::size_t(i) * (n / h) * n + std::size_t(j) * (n / w)];
  return m;
}

}  // namespace displace::test
