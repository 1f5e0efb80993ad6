// sim/procedural.cpp - procedural test reliefs made directly in [0, 1]: a brick wall (flat brick
// tops with bevelled edges, mortar grooves, a little seeded roughness) and a cliff with spikes
// (a smooth slope, a vertical cliff, and isolated single-texel spikes) - the hard cases of the
// renderer's accuracy sweep. Both tile.
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "sim/sim.h"

namespace displace::sim {
namespace {

constexpr int bricks_per_row = 4;                       // bricks across the map
constexpr int brick_rows = 8;                           // rows of bricks down the map
constexpr float mortar_width = 0.06f;                   // fraction of a brick's height
constexpr float bevel_width = 0.10f;                    // fraction of a brick's height
constexpr float brick_top = 0.92f;                      // height of a brick's flat top
constexpr float mortar_depth = 0.25f;                   // height of the mortar
constexpr float brick_roughness = 0.05f;                // amplitude of the per-texel roughness
constexpr float cliff_low = 0.15f, cliff_high = 0.75f;  // heights below and above the cliff
constexpr int spike_spacing = 16;                       // texels between spikes

std::uint64_t hash(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}
float random01(std::uint64_t seed, long long a, long long b) {
  return float(hash(seed ^ hash(std::uint64_t(a) * 73856093ull ^ std::uint64_t(b) * 19349663ull)) >> 40) /
         float(1u << 24);
}

void check(int width, int height, std::span<float> out) {
  if (width < 1 || height < 1 || out.size() != std::size_t(width) * std::size_t(height)) {
    throw std::invalid_argument("procedural relief: the output must hold width x height >= 1 samples");
  }
}

}  // namespace

void brick_heights(int width, int height, std::uint64_t seed, std::span<float> out) {
  check(width, height, out);
  for (int i = 0; i < height; ++i) {
    for (int j = 0; j < width; ++j) {
      const float v = (i + 0.5f) / height * brick_rows;
      const int row = int(v);
      const float u = (j + 0.5f) / width * bricks_per_row + (row % 2 ? 0.5f : 0.0f);
      // distance to the nearest mortar line, in units of a brick's height
      const float across = v - std::floor(v);
      const float along = (u - std::floor(u)) * float(brick_rows) / float(bricks_per_row) * 2.0f;
      const float along_length = float(brick_rows) / float(bricks_per_row) * 2.0f;
      const float edge = std::min({across, 1.0f - across, along, along_length - along});
      float h = mortar_depth;
      if (edge > mortar_width) {
        const float bevel = std::clamp((edge - mortar_width) / bevel_width, 0.0f, 1.0f);
        h = mortar_depth + (brick_top - mortar_depth) * bevel;
        h -= brick_roughness * random01(seed, i, j);
      }
      out[std::size_t(i) * width + j] = std::clamp(h, 0.0f, 1.0f);
    }
  }
}

void cliff_heights(int width, int height, std::uint64_t seed, std::span<float> out) {
  check(width, height, out);
  for (int i = 0; i < height; ++i) {
    for (int j = 0; j < width; ++j) {
      const float u = (j + 0.5f) / width, v = (i + 0.5f) / height;
      // a gentle periodic slope with a vertical cliff where it wraps
      float h = cliff_low + (cliff_high - cliff_low) * (u < 0.5f ? 2.0f * u : 2.0f - 2.0f * u);
      h += 0.05f * std::sin(6.2831853f * 2.0f * v);
      if (u >= 0.25f && u < 0.75f && v >= 0.25f && v < 0.75f) h = std::min(h + 0.2f, 1.0f);  // the cliff
      if (i % spike_spacing == spike_spacing / 2 && j % spike_spacing == spike_spacing / 3) {
        h = 0.9f + 0.1f * random01(seed, i, j);  // a single-texel spike
      }
      out[std::size_t(i) * width + j] = std::clamp(h, 0.0f, 1.0f);
    }
  }
}

}  // namespace displace::sim
