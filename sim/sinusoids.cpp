// sim/sinusoids.cpp - sinusoid water, the dynamic displacement example of Chen & Chuang
// ("Anisotropic Cone Mapping"): h(x, t) = sum_i a_i sin(k_i . x - w_i t + phi_i), w_i^2 = g |k_i|.
// Every draw comes from a splitmix64 stream turned into uniforms by hand, so the waves for a seed
// are the same with every standard library. A grid is filled separably:
// sin(kx x + ky y + c) = sin(kx x) cos(ky y + c) + cos(kx x) sin(ky y + c).
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <stdexcept>
#include <string>

#include "sim/sim.h"

namespace displace::sim {
namespace {

// relative spread of the per-wave steepness shares: each share is drawn from [1 - x, 1]
constexpr double steepness_share_spread = 0.5;

class SplitMix64 {
 public:
  explicit SplitMix64(std::uint64_t seed) : state_(seed) {}
  std::uint64_t next() {
    std::uint64_t z = (state_ += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
  }
  // uniform in [0, 1) from the top 53 bits
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }

 private:
  std::uint64_t state_;
};

bool positive_finite(float value) { return std::isfinite(value) && value > 0.0f; }

void validate(const SinusoidParams& params) {
  auto fail = [](const std::string& message) { throw std::invalid_argument("SinusoidParams: " + message); };
  if (params.wave_count < 1 || params.wave_count > max_wave_count) {
    fail("wave_count must be in [1, " + std::to_string(max_wave_count) + "], got " +
         std::to_string(params.wave_count));
  }
  if (!(params.patch_size >= min_patch_size && params.patch_size <= max_patch_size)) {
    char text[96];
    std::snprintf(text, sizeof text, "patch_size must be in [%g, %g] metres", double(min_patch_size),
                  double(max_patch_size));
    fail(text);
  }
  if (!positive_finite(params.wavelength_min) || !positive_finite(params.wavelength_max)) {
    fail("wavelength_min and wavelength_max must be positive finite lengths in metres");
  }
  if (params.wavelength_min > params.wavelength_max) fail("wavelength_min exceeds wavelength_max");
  if (params.tileable && params.wavelength_min > params.patch_size) {
    fail("tileable waves cannot be longer than the patch, but wavelength_min exceeds patch_size");
  }
  if (!positive_finite(params.steepness) || params.steepness > max_steepness) {
    char text[64];
    std::snprintf(text, sizeof text, "steepness must be in (0, %g] (sum of a_i |k_i|)",
                  double(max_steepness));
    fail(text);
  }
  if (!std::isfinite(params.wind_direction)) fail("wind_direction must be finite");
  if (!std::isfinite(params.direction_spread) || params.direction_spread < 0.0f ||
      params.direction_spread > std::numbers::pi_v<float>) {
    fail("direction_spread must be in [0, pi] radians");
  }
  if (!positive_finite(params.gravity)) fail("gravity must be positive and finite");
}

// sin and cos of start + i * step for i in [0, count), scaled, by rotating in double
void fill_rotation(double start, double step, double scale, int count, float* sin_out, float* cos_out) {
  const double step_cos = std::cos(step);
  const double step_sin = std::sin(step);
  double c = std::cos(start);
  double s = std::sin(start);
  for (int index = 0; index < count; ++index) {
    sin_out[index] = static_cast<float>(scale * s);
    cos_out[index] = static_cast<float>(scale * c);
    const double next_c = c * step_cos - s * step_sin;
    s = s * step_cos + c * step_sin;
    c = next_c;
  }
}

}  // namespace

std::vector<Wave> make_sinusoid_waves(const SinusoidParams& params) {
  validate(params);
  constexpr double two_pi = 2.0 * std::numbers::pi;
  SplitMix64 random(params.seed);
  const double lattice_step = two_pi / params.patch_size;
  const double log_min = std::log(static_cast<double>(params.wavelength_min));
  const double log_max = std::log(static_cast<double>(params.wavelength_max));

  struct Draw {
    double kx, ky, share, phase;
  };
  std::vector<Draw> draws(params.wave_count);
  double share_sum = 0.0;
  for (Draw& draw : draws) {
    // log-uniform wavelength, uniform direction in the spread, then snap to the lattice
    const double wavelength = std::exp(log_min + (log_max - log_min) * random.uniform());
    const double direction = params.wind_direction + params.direction_spread * (2.0 * random.uniform() - 1.0);
    draw.kx = two_pi / wavelength * std::cos(direction);
    draw.ky = two_pi / wavelength * std::sin(direction);
    if (params.tileable) {
      double m = std::round(draw.kx / lattice_step);
      double n = std::round(draw.ky / lattice_step);
      if (m == 0.0 && n == 0.0) {
        (std::abs(draw.kx) >= std::abs(draw.ky) ? m : n) = 1.0;
        m = std::copysign(m, draw.kx);
        n = std::copysign(n, draw.ky);
      }
      draw.kx = m * lattice_step;
      draw.ky = n * lattice_step;
    }
    draw.share = 1.0 - steepness_share_spread * random.uniform();
    draw.phase = two_pi * random.uniform();
    share_sum += draw.share;
  }

  std::vector<Wave> waves;
  waves.reserve(draws.size());
  for (const Draw& draw : draws) {
    const double k = std::hypot(draw.kx, draw.ky);
    Wave wave;
    wave.kx = static_cast<float>(draw.kx);
    wave.ky = static_cast<float>(draw.ky);
    wave.amplitude = static_cast<float>(params.steepness * draw.share / (share_sum * k));
    wave.omega = static_cast<float>(std::sqrt(params.gravity * k));
    wave.phase = static_cast<float>(draw.phase);
    waves.push_back(wave);
  }
  return waves;
}

float sinusoid_height_at(std::span<const Wave> waves, float x, float y, double time) {
  double height = 0.0;
  for (const Wave& wave : waves) {
    const double phase = static_cast<double>(wave.kx) * x + static_cast<double>(wave.ky) * y -
                         static_cast<double>(wave.omega) * time + wave.phase;
    height += wave.amplitude * std::sin(phase);
  }
  return static_cast<float>(height);
}

void sinusoid_heights(std::span<const Wave> waves, float patch_size, double time, int width, int height,
                      std::span<float> out) {
  if (width < 1 || height < 1) throw std::invalid_argument("sinusoid_heights: width and height must be >= 1");
  if (!positive_finite(patch_size)) {
    throw std::invalid_argument("sinusoid_heights: patch_size must be positive");
  }
  if (out.size() != static_cast<std::size_t>(width) * static_cast<std::size_t>(height)) {
    throw std::invalid_argument("sinusoid_heights: out must hold width * height samples");
  }
  // per-wave sin and cos tables along x (amplitude folded in) and along y (time and phase folded in)
  const std::size_t wave_count = waves.size();
  std::vector<float> sin_x(wave_count * width), cos_x(wave_count * width);
  std::vector<float> sin_y(wave_count * height), cos_y(wave_count * height);
  const double texel_u = static_cast<double>(patch_size) / width;
  const double texel_v = static_cast<double>(patch_size) / height;
  for (std::size_t index = 0; index < wave_count; ++index) {
    const Wave& wave = waves[index];
    const double offset = static_cast<double>(wave.phase) - static_cast<double>(wave.omega) * time;
    fill_rotation(0.5 * wave.kx * texel_u, wave.kx * texel_u, wave.amplitude, width, &sin_x[index * width],
                  &cos_x[index * width]);
    fill_rotation(0.5 * wave.ky * texel_v + offset, wave.ky * texel_v, 1.0, height, &sin_y[index * height],
                  &cos_y[index * height]);
  }
  // accumulate the separable products row by row
  tbb::parallel_for(0, height, [&](int row) {
    float* line = out.data() + static_cast<std::size_t>(row) * width;
    std::fill(line, line + width, 0.0f);
    for (std::size_t index = 0; index < wave_count; ++index) {
      const float* wave_sin = sin_x.data() + index * width;
      const float* wave_cos = cos_x.data() + index * width;
      const float c = cos_y[index * height + row];
      const float s = sin_y[index * height + row];
      for (int column = 0; column < width; ++column)
        line[column] += wave_sin[column] * c + wave_cos[column] * s;
    }
  });
}

HeightMapping sinusoid_mapping(std::span<const Wave> waves) {
  double amplitude_sum = 0.0;
  for (const Wave& wave : waves) amplitude_sum += std::abs(wave.amplitude);
  HeightMapping mapping;
  mapping.bias = 0.5f;
  mapping.scale = amplitude_sum > 0.0 ? static_cast<float>(0.5 / amplitude_sum) : 1.0f;
  return mapping;
}

}  // namespace displace::sim
