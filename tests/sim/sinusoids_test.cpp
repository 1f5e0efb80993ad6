// tests/sim/sinusoids_test.cpp - the sum of sinusoids (sim/sinusoids.cpp).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <numbers>
#include <stdexcept>
#include <thread>
#include <vector>

#include "sim/sim.h"

namespace displace::sim {
namespace {

using Complex = std::complex<double>;

// metres from the patch corner to the centre of texel `index` of `count`
float texel_centre(int index, int count, float patch) {
  return (static_cast<float>(index) + 0.5f) / static_cast<float>(count) * patch;
}

// ---------------------------------------------------------------------------------------------
// sinusoids

TEST(Sinusoids, DeterministicPerSeedAndDifferentAcrossSeeds) {
  SinusoidParams params;
  const std::vector<Wave> first = make_sinusoid_waves(params);
  const std::vector<Wave> again = make_sinusoid_waves(params);
  ASSERT_EQ(first.size(), static_cast<std::size_t>(params.wave_count));
  for (std::size_t i = 0; i < first.size(); ++i) {
    EXPECT_EQ(first[i].kx, again[i].kx);
    EXPECT_EQ(first[i].ky, again[i].ky);
    EXPECT_EQ(first[i].amplitude, again[i].amplitude);
    EXPECT_EQ(first[i].phase, again[i].phase);
  }
  params.seed = 2;
  const std::vector<Wave> other = make_sinusoid_waves(params);
  bool any_different = false;
  for (std::size_t i = 0; i < first.size(); ++i) any_different |= first[i].phase != other[i].phase;
  EXPECT_TRUE(any_different);
}

TEST(Sinusoids, SteepnessBoundAndDeepWaterDispersion) {
  for (bool tileable : {true, false}) {
    SinusoidParams params;
    params.wave_count = 64;
    params.tileable = tileable;
    params.seed = 11;
    double steepness = 0.0;
    for (const Wave& wave : make_sinusoid_waves(params)) {
      const double k = std::hypot(wave.kx, wave.ky);
      steepness += wave.amplitude * k;
      EXPECT_GT(wave.amplitude, 0.0f);
      EXPECT_NEAR(wave.omega * wave.omega, params.gravity * k, 1e-4 * params.gravity * k);
      if (!tileable) {
        const double wavelength = 2.0 * std::numbers::pi / k;
        EXPECT_GE(wavelength, params.wavelength_min * (1.0 - 1e-5));
        EXPECT_LE(wavelength, params.wavelength_max * (1.0 + 1e-5));
      }
    }
    EXPECT_LE(steepness, params.steepness * (1.0 + 1e-5));
  }
}

TEST(Sinusoids, TileableWavesSitOnTheLatticeAndTile) {
  SinusoidParams params;
  params.wave_count = 32;
  params.wavelength_min = 0.3f;
  params.wavelength_max = 5.0f;  // longer than the patch: snapped to the longest lattice wave
  const std::vector<Wave> waves = make_sinusoid_waves(params);
  const double step = 2.0 * std::numbers::pi / params.patch_size;
  for (const Wave& wave : waves) {
    const double m = wave.kx / step, n = wave.ky / step;
    EXPECT_NEAR(m, std::round(m), 1e-4);
    EXPECT_NEAR(n, std::round(n), 1e-4);
    EXPECT_GT(std::abs(std::round(m)) + std::abs(std::round(n)), 0.0);
  }
  const float size = params.patch_size;
  for (float t : {0.0f, 1.7f, 12.25f}) {
    for (float x : {0.0f, 0.37f, 2.9f}) {
      for (float y : {0.0f, 1.3f, 3.1f}) {
        const float h = sinusoid_height_at(waves, x, y, t);
        EXPECT_NEAR(sinusoid_height_at(waves, x + size, y, t), h, 2e-5f);
        EXPECT_NEAR(sinusoid_height_at(waves, x, y + size, t), h, 2e-5f);
      }
    }
  }
}

TEST(Sinusoids, GridMatchesClosedFormAtTexelCentres) {
  const std::vector<Wave> waves = make_sinusoid_waves(SinusoidParams{});
  const float patch = 4.0f;
  const int width = 48, height = 20;
  std::vector<float> grid(width * height);
  const float time = 3.25f;
  sinusoid_heights(waves, patch, time, width, height, grid);
  const float amplitude = 0.5f / sinusoid_mapping(waves).scale;
  for (int row = 0; row < height; ++row) {
    for (int column = 0; column < width; ++column) {
      const float x = texel_centre(column, width, patch), y = texel_centre(row, height, patch);
      EXPECT_NEAR(grid[row * width + column], sinusoid_height_at(waves, x, y, time), 1e-5f * amplitude);
    }
  }
  EXPECT_THROW(sinusoid_heights(waves, patch, time, width, height + 1, grid), std::invalid_argument);
}

TEST(Sinusoids, MappingNeverClamps) {
  SinusoidParams params;
  params.wave_count = 3;  // few waves line up most often
  const std::vector<Wave> waves = make_sinusoid_waves(params);
  const HeightMapping mapping = sinusoid_mapping(waves);
  EXPECT_EQ(mapping.bias, 0.5f);
  std::vector<float> raw(64 * 64), mapped(raw.size());
  for (int frame = 0; frame < 200; ++frame) {
    sinusoid_heights(waves, params.patch_size, 0.173f * static_cast<float>(frame), 64, 64, raw);
    EXPECT_EQ(apply_mapping(mapping, raw, mapped), 0u);
    for (float value : mapped) ASSERT_TRUE(value >= 0.0f && value <= 1.0f);
  }
}

TEST(Sinusoids, BadParamsThrow) {
  auto throws = [](auto change) {
    SinusoidParams params;
    change(params);
    EXPECT_THROW(make_sinusoid_waves(params), std::invalid_argument);
  };
  throws([](SinusoidParams& p) { p.wave_count = 0; });
  throws([](SinusoidParams& p) { p.wave_count = 5000; });
  throws([](SinusoidParams& p) { p.patch_size = -1.0f; });
  throws([](SinusoidParams& p) { p.patch_size = INFINITY; });
  throws([](SinusoidParams& p) { p.wavelength_min = 2.0f; });
  throws([](SinusoidParams& p) { p.wavelength_min = 0.0f; });
  throws([](SinusoidParams& p) { p.wavelength_max = NAN; });
  throws([](SinusoidParams& p) { p.steepness = 0.0f; });
  throws([](SinusoidParams& p) { p.steepness = 3.0f; });
  throws([](SinusoidParams& p) { p.direction_spread = -0.5f; });
  throws([](SinusoidParams& p) { p.gravity = 0.0f; });
  throws([](SinusoidParams& p) {
    p.wavelength_min = 5.0f;
    p.wavelength_max = 6.0f;
  });
}

}  // namespace
}  // namespace displace::sim
