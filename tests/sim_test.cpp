// tests/sim_test.cpp - properties of the sim stage: tiling, dispersion, Parseval, Hermitian spectra,
// determinism, work done only on request. Spectra of the outputs come from a naive DFT in double here,
// independent of FFTW.
#include "sim/sim.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <numbers>
#include <stdexcept>
#include <thread>
#include <vector>

namespace displace::sim {
namespace {

using Complex = std::complex<double>;

// H(k) = 1/N^2 sum_x h(x) exp(-i k.x) at texel centres x_j = (j + 1/2) L / N, so that h(x) = sum_k H(k) exp(i
// k.x).
std::vector<Complex> texel_centre_dft(const std::vector<float>& field, int n) {
  std::vector<Complex> twiddle(static_cast<std::size_t>(n) * n);
  for (int m = 0; m < n; ++m) {
    const int wave_number = m < n / 2 ? m : m - n;  // signed: the half-texel phase tells m from m - N
    for (int j = 0; j < n; ++j) {
      twiddle[static_cast<std::size_t>(m) * n + j] =
          std::polar(1.0, -2.0 * std::numbers::pi * wave_number * (j + 0.5) / n);
    }
  }
  std::vector<Complex> along_x(static_cast<std::size_t>(n) * n), result(static_cast<std::size_t>(n) * n);
  for (int row = 0; row < n; ++row) {
    for (int m = 0; m < n; ++m) {
      Complex sum = 0.0;
      for (int j = 0; j < n; ++j) sum += static_cast<double>(field[row * n + j]) * twiddle[m * n + j];
      along_x[row * n + m] = sum;
    }
  }
  for (int m_y = 0; m_y < n; ++m_y) {
    for (int m = 0; m < n; ++m) {
      Complex sum = 0.0;
      for (int row = 0; row < n; ++row) sum += along_x[row * n + m] * twiddle[m_y * n + row];
      result[m_y * n + m] = sum / static_cast<double>(n * n);
    }
  }
  return result;
}

double max_magnitude(const std::vector<Complex>& values) {
  double result = 0.0;
  for (const Complex& value : values) result = std::max(result, std::abs(value));
  return result;
}

// metres from the patch corner to the centre of texel `index` of `count`
float texel_centre(int index, int count, float patch) {
  return (static_cast<float>(index) + 0.5f) / static_cast<float>(count) * patch;
}

OceanParams small_ocean(Spectrum spectrum = Spectrum::phillips) {
  OceanParams params;
  params.size = 32;
  params.patch_size = 100.0f;
  params.spectrum = spectrum;
  params.wind_speed = 10.0f;
  params.seed = 7;
  return params;
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

TEST(HeightMapping, ClampsAndCounts) {
  const HeightMapping mapping{0.5f, 0.5f};
  const std::vector<float> raw = {-3.0f, -1.0f, 0.0f, 1.0f, 2.5f, NAN};
  std::vector<float> out(raw.size());
  EXPECT_EQ(apply_mapping(mapping, raw, out), 3u);
  EXPECT_EQ(out, (std::vector<float>{0.0f, 0.0f, 0.5f, 1.0f, 1.0f, 0.0f}));
  std::vector<float> short_out(2);
  EXPECT_THROW(apply_mapping(mapping, raw, short_out), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------
// FFT ocean

TEST(Ocean, SpectrumIsHermitianWithZeroNyquist) {
  for (Spectrum spectrum : {Spectrum::phillips, Spectrum::jonswap}) {
    const Ocean ocean(small_ocean(spectrum));
    const int n = ocean.size();
    const auto h = ocean.height_spectrum(2.5f);
    float largest = 0.0f;
    for (const auto& value : h) largest = std::max(largest, std::abs(value));
    ASSERT_GT(largest, 0.0f);
    for (int i = 0; i < n; ++i) {
      for (int j = 0; j < n; ++j) {
        const auto value = h[i * n + j];
        const auto mirror = h[((n - i) % n) * n + (n - j) % n];
        EXPECT_NEAR(std::abs(value - std::conj(mirror)), 0.0f, 1e-6f * largest);
        if (i == n / 2 || j == n / 2 || (i == 0 && j == 0)) {
          EXPECT_EQ(value, std::complex<float>(0.0f));
        }
      }
    }
  }
}

TEST(Ocean, OutputHeightsAreTheSpectrumSummedAtTexelCentres) {
  Ocean ocean(small_ocean());
  const int n = ocean.size();
  OceanFrame frame;
  // 3000 s exercises the fast phase reduction far from 0; 1e5 s the double-precision fallback
  for (float time : {0.0f, 1.75f, -4.0f, 3000.0f, 1.0e5f}) {
    ocean.evaluate(time, ocean_heights, frame);
    const std::vector<Complex> measured = texel_centre_dft(frame.height, n);
    const auto expected = ocean.height_spectrum(time);
    const double scale = max_magnitude(measured);
    ASSERT_GT(scale, 0.0);
    for (std::size_t k = 0; k < measured.size(); ++k) {
      ASSERT_NEAR(std::abs(measured[k] - Complex(expected[k])), 0.0, 2e-5 * scale)
          << "time " << time << " mode " << k;
    }
  }
}

TEST(Ocean, Parseval) {
  for (Spectrum spectrum : {Spectrum::phillips, Spectrum::jonswap}) {
    OceanParams params = small_ocean(spectrum);
    params.size = 64;
    Ocean ocean(params);
    OceanFrame frame;
    const float time = 6.5f;
    ocean.evaluate(time, ocean_heights, frame);
    double mean_square = 0.0;
    for (float h : frame.height) mean_square += static_cast<double>(h) * h;
    mean_square /= static_cast<double>(frame.height.size());
    double spectral = 0.0;
    for (const auto& value : ocean.height_spectrum(time)) spectral += std::norm(Complex(value));
    EXPECT_NEAR(mean_square, spectral, 1e-3 * spectral);
  }
}

TEST(Ocean, DispersionRelationHoldsInTheOutputs) {
  // h~(t + dt) + h~(t - dt) = 2 cos(w dt) h~(t) for every mode of the output heights
  for (Spectrum spectrum : {Spectrum::phillips, Spectrum::jonswap}) {
    Ocean ocean(small_ocean(spectrum));
    const int n = ocean.size();
    const float time = 5.0f, step = 0.7f;
    OceanFrame frame;
    std::vector<std::vector<Complex>> spectra;
    for (float t : {time - step, time, time + step}) {
      ocean.evaluate(t, ocean_heights, frame);
      spectra.push_back(texel_centre_dft(frame.height, n));
    }
    const double scale = max_magnitude(spectra[1]);
    double spread_of_cos = 0.0;
    for (int i = 0; i < n; ++i) {
      for (int j = 0; j < n; ++j) {
        const std::size_t k = static_cast<std::size_t>(i) * n + j;
        const double cos_w_dt = std::cos(static_cast<double>(ocean.omega(i, j)) * step);
        spread_of_cos = std::max(spread_of_cos, 1.0 - cos_w_dt);
        const Complex residual = spectra[2][k] + spectra[0][k] - 2.0 * cos_w_dt * spectra[1][k];
        EXPECT_LT(std::abs(residual), 5e-5 * scale) << "mode " << i << ", " << j;
      }
    }
    EXPECT_GT(spread_of_cos, 1.0);  // the frequencies cover more than a quarter turn in one step
  }
}

// Time is double from the API to the phases: at t = 1e9 s (where a float step is 64 s), frames
// 1/60 s apart still differ and obey the dispersion relation mode by mode.
TEST(Ocean, DispersionHoldsBetweenFramesASixtiethApartAtABillionSeconds) {
  Ocean ocean(small_ocean(Spectrum::phillips));
  const int n = ocean.size();
  const double time = 1e9, step = 1.0 / 60.0;
  OceanFrame frame;
  std::vector<std::vector<Complex>> spectra;
  std::vector<std::vector<float>> heights;
  for (double t : {time - step, time, time + step}) {
    ocean.evaluate(t, ocean_heights, frame);
    heights.push_back(frame.height);
    spectra.push_back(texel_centre_dft(frame.height, n));
  }
  EXPECT_NE(heights[0], heights[1]);
  EXPECT_NE(heights[1], heights[2]);
  const double scale = max_magnitude(spectra[1]);
  double largest_turn = 0.0;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const std::size_t k = static_cast<std::size_t>(i) * n + j;
      const double cos_w_dt = std::cos(static_cast<double>(ocean.omega(i, j)) * step);
      largest_turn = std::max(largest_turn, 1.0 - cos_w_dt);
      const Complex residual = spectra[2][k] + spectra[0][k] - 2.0 * cos_w_dt * spectra[1][k];
      EXPECT_LT(std::abs(residual), 5e-5 * scale) << "mode " << i << ", " << j;
    }
  }
  EXPECT_GT(largest_turn, 1e-3);  // frames far enough apart that a wrong time would show
}

TEST(Ocean, OmegaIsDeepWaterDispersion) {
  const OceanParams params = small_ocean();
  const Ocean ocean(params);
  const int n = ocean.size();
  const double dk = 2.0 * std::numbers::pi / params.patch_size;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const double k = dk * std::hypot(i < n / 2 ? i : i - n, j < n / 2 ? j : j - n);
      EXPECT_NEAR(ocean.omega(i, j), std::sqrt(params.gravity * k), 1e-5);
    }
  }
  EXPECT_THROW(static_cast<void>(ocean.omega(n, 0)), std::out_of_range);
}

TEST(Ocean, DeterministicPerSeed) {
  OceanFrame first, second, other;
  Ocean(small_ocean()).evaluate(3.0f, ocean_heights, first);
  Ocean(small_ocean()).evaluate(3.0f, ocean_heights, second);
  EXPECT_EQ(first.height, second.height);
  OceanParams params = small_ocean();
  params.seed = 8;
  Ocean(params).evaluate(3.0f, ocean_heights, other);
  EXPECT_NE(first.height, other.height);
}

TEST(Ocean, FramesAreIndependentOfHistory) {
  Ocean fresh(small_ocean()), used(small_ocean());
  OceanFrame a, b;
  used.evaluate(9.0f, ocean_heights | ocean_slopes, b);
  used.evaluate(-2.0f, ocean_foam, b);
  used.evaluate(1.5f, ocean_heights, b);
  fresh.evaluate(1.5f, ocean_heights, a);
  EXPECT_EQ(a.height, b.height);
}

TEST(Ocean, ComputesOnlyWhatIsRequested) {
  Ocean ocean(small_ocean());
  const std::size_t samples = 32 * 32;
  OceanFrame frame;
  struct Case {
    unsigned outputs;
    long long ffts;
  };
  for (const Case& c :
       {Case{0u, 0}, Case{ocean_heights, 1}, Case{ocean_slopes, 2}, Case{ocean_displacement, 2},
        Case{ocean_foam, 3}, Case{ocean_heights | ocean_slopes, 3},
        Case{ocean_heights | ocean_slopes | ocean_displacement | ocean_foam, 8}, Case{0u, 0}}) {
    const long long before = ocean.fft_count();
    ocean.evaluate(1.0f, c.outputs, frame);
    EXPECT_EQ(ocean.fft_count() - before, c.ffts) << "outputs " << c.outputs;
    EXPECT_EQ(frame.size, 32);
    auto expect_filled = [&](const std::vector<float>& values, unsigned bit) {
      EXPECT_EQ(values.size(), (c.outputs & bit) != 0 ? samples : 0u) << "outputs " << c.outputs;
    };
    expect_filled(frame.height, ocean_heights);
    expect_filled(frame.slope_x, ocean_slopes);
    expect_filled(frame.slope_y, ocean_slopes);
    expect_filled(frame.displacement_x, ocean_displacement);
    expect_filled(frame.displacement_y, ocean_displacement);
    expect_filled(frame.jacobian, ocean_foam);
  }
}

// Fourth-order central difference along x (columns) or y (rows) of a periodic field.
std::vector<float> periodic_derivative(const std::vector<float>& field, int n, double spacing, bool along_x) {
  std::vector<float> result(field.size());
  auto at = [&](int row, int column) {
    return static_cast<double>(field[((row + n) % n) * n + (column + n) % n]);
  };
  for (int row = 0; row < n; ++row) {
    for (int column = 0; column < n; ++column) {
      const int dr = along_x ? 0 : 1, dc = along_x ? 1 : 0;
      const double value = (8.0 * (at(row + dr, column + dc) - at(row - dr, column - dc)) -
                            (at(row + 2 * dr, column + 2 * dc) - at(row - 2 * dr, column - 2 * dc))) /
                           (12.0 * spacing);
      result[row * n + column] = static_cast<float>(value);
    }
  }
  return result;
}

OceanParams smooth_ocean() {
  OceanParams params;
  params.size = 64;
  params.patch_size = 40.0f;
  params.wind_speed = 4.0f;
  params.small_wave_cutoff = 1.5f;  // metres: damps everything near the grid's Nyquist
  params.seed = 3;
  return params;
}

float max_abs(const std::vector<float>& values) {
  float result = 0.0f;
  for (float value : values) result = std::max(result, std::abs(value));
  return result;
}

TEST(Ocean, SlopesMatchFiniteDifferences) {
  const OceanParams params = smooth_ocean();
  Ocean ocean(params);
  OceanFrame frame;
  ocean.evaluate(2.0f, ocean_heights | ocean_slopes, frame);
  const double spacing = static_cast<double>(params.patch_size) / params.size;
  const auto dx = periodic_derivative(frame.height, params.size, spacing, true);
  const auto dy = periodic_derivative(frame.height, params.size, spacing, false);
  const float scale = std::max(max_abs(frame.slope_x), max_abs(frame.slope_y));
  ASSERT_GT(scale, 0.0f);
  for (std::size_t i = 0; i < dx.size(); ++i) {
    EXPECT_NEAR(frame.slope_x[i], dx[i], 0.01f * scale);
    EXPECT_NEAR(frame.slope_y[i], dy[i], 0.01f * scale);
  }
}

TEST(Ocean, JacobianOfTheDisplacement) {
  OceanParams params = smooth_ocean();
  params.choppiness = 0.0f;
  OceanFrame frame;
  Ocean(params).evaluate(1.0f, ocean_heights | ocean_displacement | ocean_foam, frame);
  for (float value : frame.jacobian) ASSERT_EQ(value, 1.0f);
  for (float value : frame.displacement_x) ASSERT_EQ(value, 0.0f);

  params.choppiness = 6.0f;
  Ocean(params).evaluate(1.0f, ocean_heights | ocean_displacement | ocean_foam, frame);
  const int n = params.size;
  const double spacing = static_cast<double>(params.patch_size) / n;
  const auto xx = periodic_derivative(frame.displacement_x, n, spacing, true);
  const auto xy = periodic_derivative(frame.displacement_x, n, spacing, false);
  const auto yx = periodic_derivative(frame.displacement_y, n, spacing, true);
  const auto yy = periodic_derivative(frame.displacement_y, n, spacing, false);
  double spread = 0.0, error = 0.0, mean_height = 0.0, covariance = 0.0;
  for (float h : frame.height) mean_height += h / static_cast<double>(frame.height.size());
  for (std::size_t i = 0; i < frame.jacobian.size(); ++i) {
    const double expected = (1.0 + xx[i]) * (1.0 + yy[i]) - xy[i] * yx[i];
    error = std::max(error, std::abs(frame.jacobian[i] - expected));
    spread = std::max(spread, std::abs(frame.jacobian[i] - 1.0));
    covariance += (frame.jacobian[i] - 1.0) * (frame.height[i] - mean_height);
  }
  EXPECT_GT(spread, 0.02);
  EXPECT_LT(error, 0.02 * spread);
  EXPECT_LT(covariance, 0.0);  // positive choppiness pinches crests: J < 1 where the water is high
}

TEST(Ocean, BothSpectraGiveFiniteNonZeroFields) {
  for (Spectrum spectrum : {Spectrum::phillips, Spectrum::jonswap}) {
    OceanParams params = small_ocean(spectrum);
    params.size = 64;
    Ocean ocean(params);
    EXPECT_GT(ocean.height_variance(), 0.0);
    OceanFrame frame;
    ocean.evaluate(4.0f, ocean_heights | ocean_slopes | ocean_displacement | ocean_foam, frame);
    for (const auto* field : {&frame.height, &frame.slope_x, &frame.slope_y, &frame.displacement_x,
                              &frame.displacement_y, &frame.jacobian}) {
      for (float value : *field) ASSERT_TRUE(std::isfinite(value));
    }
    EXPECT_GT(max_abs(frame.height), 0.0f);
    EXPECT_GT(max_abs(frame.slope_x), 0.0f);
  }
}

TEST(Ocean, VarianceIsTheEnsembleMeanOfTheSpectrumEnergy) {
  OceanParams params = small_ocean(Spectrum::jonswap);
  params.patch_size = 1000.0f;  // many modes around the peak
  double mean_energy = 0.0, variance = 0.0;
  const int seeds = 32;
  for (int seed = 0; seed < seeds; ++seed) {
    params.seed = 100 + seed;
    const Ocean ocean(params);
    variance = ocean.height_variance();
    for (const auto& value : ocean.height_spectrum(0.0f)) mean_energy += std::norm(Complex(value)) / seeds;
  }
  EXPECT_NEAR(mean_energy, variance, 0.25 * variance);
}

TEST(Ocean, MappingIsFixedOverTimeAndRarelyClamps) {
  OceanParams params = small_ocean();
  params.size = 64;
  Ocean ocean(params);
  const HeightMapping mapping = ocean.mapping();
  EXPECT_EQ(mapping.bias, 0.5f);
  EXPECT_NEAR(mapping.scale, 1.0 / (6.0 * std::sqrt(ocean.height_variance())), 1e-6 * mapping.scale);
  OceanFrame frame;
  std::vector<float> mapped(64 * 64);
  std::size_t clamped = 0, total = 0;
  for (int i = 0; i < 20; ++i) {
    ocean.evaluate(1.3f * static_cast<float>(i), ocean_heights, frame);
    const HeightMapping now = ocean.mapping();
    EXPECT_EQ(now.scale, mapping.scale);
    EXPECT_EQ(now.bias, mapping.bias);
    clamped += apply_mapping(mapping, frame.height, mapped);
    total += mapped.size();
  }
  EXPECT_LT(static_cast<double>(clamped), 0.02 * static_cast<double>(total));
}

TEST(Ocean, BadParamsThrow) {
  auto throws = [](auto change) {
    OceanParams params = small_ocean();
    change(params);
    EXPECT_THROW(Ocean{params}, std::invalid_argument);
  };
  throws([](OceanParams& p) { p.size = 0; });
  throws([](OceanParams& p) { p.size = 33; });
  throws([](OceanParams& p) { p.size = 1 << 20; });
  throws([](OceanParams& p) { p.patch_size = 0.0f; });
  throws([](OceanParams& p) { p.wind_speed = NAN; });
  throws([](OceanParams& p) { p.wind_speed = -1.0f; });
  throws([](OceanParams& p) { p.fetch = 0.0f; });
  throws([](OceanParams& p) { p.peak_enhancement = 0.5f; });
  throws([](OceanParams& p) { p.spreading = -1.0f; });
  throws([](OceanParams& p) { p.phillips_amplitude = 0.0f; });
  throws([](OceanParams& p) { p.small_wave_cutoff = -1.0f; });
  throws([](OceanParams& p) { p.choppiness = INFINITY; });
  throws([](OceanParams& p) { p.gravity = 0.0f; });
  throws([](OceanParams& p) { p.spectrum = static_cast<Spectrum>(7); });
}

TEST(Ocean, MovesAndConcurrentConstruction) {
  std::vector<Ocean> oceans;
  std::vector<std::thread> threads;
  std::vector<std::vector<float>> heights(4);
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([t, &heights] {
      OceanParams params = small_ocean();
      params.size = 16 + 16 * (t % 2);
      Ocean ocean(params);
      Ocean moved(std::move(ocean));
      OceanFrame frame;
      moved.evaluate(0.5f, ocean_heights, frame);
      heights[t] = frame.height;
    });
  }
  for (auto& thread : threads) thread.join();
  EXPECT_EQ(heights[1], heights[3]);
  EXPECT_EQ(heights[1].size(), 32u * 32u);
}

}  // namespace
}  // namespace displace::sim

namespace displace::sim {

// The choppy surface back on the grid: a uniform displacement c moves the surface rigidly, so the
// height above x is h(x - c) (a whole-texel shift here, exact); on the choppy ocean the fixed point
// p + D(p) = x is found to a thousandth of a texel and the result is periodic and bounded by h.
TEST(Choppy, ResamplingInvertsTheDisplacement) {
  const int n = 16;
  const float patch = 8.0f;  // half a metre per texel
  std::vector<float> height(n * n), dx(n * n, 1.0f), dy(n * n, -1.5f), out(n * n);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) height[std::size_t(i) * n + j] = float(std::sin(0.7 * j) + 0.3 * i);
  const double residual = resample_displaced(n, patch, height, dx, dy, 4, out);
  EXPECT_LT(residual, 1e-5);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const int si = ((i + 3) % n + n) % n, sj = ((j - 2) % n + n) % n;  // x - c in texels: (j - 2, i + 3)
      EXPECT_NEAR(out[std::size_t(i) * n + j], height[std::size_t(si) * n + sj], 1e-5) << i << ", " << j;
    }

  OceanParams params;
  params.size = 64;
  params.choppiness = 1.0f;
  Ocean ocean(params);
  OceanFrame frame;
  ocean.evaluate(3.0, ocean_heights | ocean_displacement, frame);
  std::vector<float> choppy(frame.height.size());
  const double ocean_residual = resample_displaced(64, params.patch_size, frame.height, frame.displacement_x,
                                                   frame.displacement_y, 6, choppy);
  EXPECT_LT(ocean_residual, 1e-3 * params.patch_size / 64);
  const auto [lo, hi] = std::minmax_element(frame.height.begin(), frame.height.end());
  for (float h : choppy) EXPECT_TRUE(h >= *lo - 1e-4f && h <= *hi + 1e-4f);
  EXPECT_THROW(resample_displaced(64, params.patch_size, frame.height, frame.displacement_x,
                                  frame.displacement_y, 6, std::span<float>(choppy.data(), 10)),
               std::invalid_argument);
}

}  // namespace displace::sim

namespace displace::sim {
namespace {

// The resampling one texel at a time, with the scalar periodic bilinear sample and an integer
// modulo: Newton steps (the fixed-point step where det J < 0.2), each row of a group of 16 started
// from the row before's solution moved by J^-1 (0, 1). The library's blocked, vectorised version
// must give the same bits.
struct ScalarSample {
  float value, along_x, along_y;
};

ScalarSample scalar_bilinear(const std::vector<float>& grid, int size, float x, float y) {
  const float fx = std::floor(x), fy = std::floor(y);
  const float tx = x - fx, ty = y - fy;
  auto wrap = [size](int i) { return ((i % size) + size) % size; };
  const int x0 = wrap(int(fx)), x1 = wrap(int(fx) + 1), y0 = wrap(int(fy)), y1 = wrap(int(fy) + 1);
  const float* row0 = grid.data() + std::size_t(y0) * size;
  const float* row1 = grid.data() + std::size_t(y1) * size;
  const float top = row0[x0] + (row0[x1] - row0[x0]) * tx;
  const float bottom = row1[x0] + (row1[x1] - row1[x0]) * tx;
  return {top + (bottom - top) * ty,
          (row0[x1] - row0[x0]) + ((row1[x1] - row1[x0]) - (row0[x1] - row0[x0])) * ty, bottom - top};
}

double scalar_resample(int size, float patch_size, const std::vector<float>& height,
                       const std::vector<float>& dx, const std::vector<float>& dy, int iterations,
                       std::vector<float>& out, const std::vector<float>& extra,
                       std::vector<float>& extra_out) {
  const float texels_per_metre = float(size) / patch_size;
  auto tame = [](float v) { return std::max(-16777216.0f, std::min(16777216.0f, v)); };
  std::vector<float> last_x(size), last_y(size), move_x(size), move_y(size);
  double worst = 0.0;
  for (int i = 0; i < size; ++i)
    for (int j = 0; j < size; ++j) {
      const bool cold = i % 16 == 0;
      float px = cold ? float(j) : tame(last_x[j] + move_x[j]);
      float py = cold ? float(i) : tame(last_y[j] + move_y[j]);
      for (int step = 0;; ++step) {
        const ScalarSample sx = scalar_bilinear(dx, size, tame(px), tame(py));
        const ScalarSample sy = scalar_bilinear(dy, size, tame(px), tame(py));
        const float fx = px + sx.value * texels_per_metre - float(j);
        const float fy = py + sy.value * texels_per_metre - float(i);
        const float a = 1.0f + sx.along_x * texels_per_metre, c = sx.along_y * texels_per_metre;
        const float e = sy.along_x * texels_per_metre, d = 1.0f + sy.along_y * texels_per_metre;
        const float det = a * d - c * e;
        const bool newton = det >= 0.2f;
        const float inverse = 1.0f / (newton ? det : 1.0f);
        move_x[j] = newton ? -c * inverse : 0.0f;
        move_y[j] = newton ? a * inverse : 1.0f;
        if (step == iterations) {
          worst = std::max(worst, double(std::sqrt(fx * fx + fy * fy)) / texels_per_metre);
          break;
        }
        const float step_x = newton ? (d * fx - c * fy) * inverse : fx;
        const float step_y = newton ? (a * fy - e * fx) * inverse : fy;
        px = tame(px - step_x);
        py = tame(py - step_y);
      }
      last_x[j] = px;
      last_y[j] = py;
      out[std::size_t(i) * size + j] = scalar_bilinear(height, size, px, py).value;
      extra_out[std::size_t(i) * size + j] = scalar_bilinear(extra, size, px, py).value;
    }
  return worst;
}

// The water scene's choppy ocean (choppiness 1.5) at `time`: heights, displacements and Jacobian.
OceanFrame choppy_frame(int size, double time, OceanParams& params) {
  params.size = size;
  params.choppiness = 1.5f;
  Ocean ocean(params);
  OceanFrame frame;
  ocean.evaluate(time, ocean_heights | ocean_displacement | ocean_foam, frame);
  return frame;
}

}  // namespace

// On the choppy ocean (sizes that are not multiples of the 64-texel block or the 16-row group) and on
// displacements
// that reach many periods away in both directions, the library's resampling equals the scalar one.
TEST(Choppy, BlockedResamplingEqualsTheScalarOneBitForBit) {
  for (const int n : {2, 40, 96}) {
    OceanParams params;
    const OceanFrame frame = choppy_frame(n, 2.5, params);
    std::vector<std::vector<float>> dxs = {frame.displacement_x}, dys = {frame.displacement_y};
    // far: shifts of up to about 7 periods, either sign
    std::vector<float> far_x(frame.displacement_x.size()), far_y(far_x.size());
    for (std::size_t t = 0; t < far_x.size(); ++t) {
      far_x[t] = float(std::sin(0.37 * double(t))) * 7.0f * params.patch_size;
      far_y[t] = float(std::cos(0.23 * double(t))) * -6.5f * params.patch_size;
    }
    dxs.push_back(far_x);
    dys.push_back(far_y);
    for (std::size_t d = 0; d < dxs.size(); ++d) {
      std::vector<float> out(far_x.size()), extra_out(far_x.size()), want(far_x.size()),
          want_extra(far_x.size());
      const double residual = resample_displaced(n, params.patch_size, frame.height, dxs[d], dys[d], 6, out,
                                                 frame.jacobian, extra_out);
      const double want_residual = scalar_resample(n, params.patch_size, frame.height, dxs[d], dys[d], 6,
                                                   want, frame.jacobian, want_extra);
      EXPECT_EQ(out, want) << n << " texels, displacement " << d;
      EXPECT_EQ(extra_out, want_extra) << n << " texels, displacement " << d;
      EXPECT_NEAR(residual, want_residual, 1e-6 * std::max(1.0, want_residual)) << n << ", " << d;
    }
  }
}

// Settling: a block of texels stops once every texel's residual is within `settle` texels. On the
// water scene's ocean with the pipeline's settle (3e-4) the residual is then within it, some block
// stopped early, and the heights are within 1e-4 of the converged ones (the range's); with 0.003 they
// are not all (Newton's p is then up to J^-1 times the residual off); a settle of 0 runs every step;
// bad settle values are refused.
TEST(Choppy, SettledResamplingStopsNearTheFixedPoint) {
  for (const int n : {64, 160}) {
    OceanParams params;
    const OceanFrame frame = choppy_frame(n, 1.0, params);
    const std::size_t texels = frame.height.size();
    std::vector<float> converged(texels), settled(texels), fixed(texels), extra(texels),
        settled_extra(texels);
    resample_displaced(n, params.patch_size, frame.height, frame.displacement_x, frame.displacement_y, 40,
                       converged, frame.jacobian, extra);
    const double six = resample_displaced(n, params.patch_size, frame.height, frame.displacement_x,
                                          frame.displacement_y, 6, fixed, frame.jacobian, extra);
    const double residual =
        resample_displaced(n, params.patch_size, frame.height, frame.displacement_x, frame.displacement_y, 8,
                           settled, frame.jacobian, settled_extra, 3e-4f);
    EXPECT_LT(residual * n / params.patch_size, 3e-4) << n;  // texels: within the settle
    std::vector<float> eight(texels);
    const double eight_residual = resample_displaced(n, params.patch_size, frame.height, frame.displacement_x,
                                                     frame.displacement_y, 8, eight, frame.jacobian, extra);
    EXPECT_GT(residual, eight_residual) << n;  // some block stopped before its eighth step
    const auto [low, high] = std::minmax_element(converged.begin(), converged.end());
    const double range = double(*high) - double(*low);
    auto farthest = [&](const std::vector<float>& heights) {
      double worst = 0.0;
      for (std::size_t t = 0; t < texels; ++t)
        worst = std::max(worst, std::abs(double(heights[t]) - converged[t]));
      return worst;
    };
    EXPECT_LT(farthest(settled), 1e-4 * range) << n;
    std::vector<float> loose(texels);
    resample_displaced(n, params.patch_size, frame.height, frame.displacement_x, frame.displacement_y, 8,
                       loose, frame.jacobian, settled_extra, 0.003f);
    EXPECT_GT(farthest(loose), farthest(settled)) << n;
    // a settle of 0 runs every step
    const double all =
        resample_displaced(n, params.patch_size, frame.height, frame.displacement_x, frame.displacement_y, 6,
                           settled, frame.jacobian, settled_extra, 0.0f);
    EXPECT_EQ(all, six);
    EXPECT_EQ(settled, fixed);
  }
  std::vector<float> grid(16, 0.0f), out(16);
  for (const float bad : {-1.0f, std::numeric_limits<float>::quiet_NaN()}) {
    EXPECT_THROW(resample_displaced(4, 1.0f, grid, grid, grid, 4, out, {}, {}, bad), std::invalid_argument);
  }
}

// The steepest sea a scene may ask for (choppiness 4) and one between: Newton's steps, with the
// fixed-point step where the map nearly folds, stay finite and bounded by the heights, and within 8
// steps come much closer than the fixed point would: at 128 texels, t = 3, residuals 3.0e-4 / 2.9e-4
// texel at choppiness 2.5 / 4 (the settle), the fixed point's 3.3e-4 / 0.026 (it fails the bound,
// which leaves Newton 17x room for other FFT builds).
TEST(Choppy, SteepSeasStayFiniteAndConverge) {
  for (const float choppiness : {2.5f, 4.0f}) {
    OceanParams params;
    params.size = 128;
    params.choppiness = choppiness;
    Ocean ocean(params);
    OceanFrame frame;
    ocean.evaluate(3.0, ocean_heights | ocean_displacement | ocean_foam, frame);
    std::vector<float> out(frame.height.size()), extra(frame.height.size());
    const double residual =
        resample_displaced(params.size, params.patch_size, frame.height, frame.displacement_x,
                           frame.displacement_y, 8, out, frame.jacobian, extra, 3e-4f);
    const auto [lo, hi] = std::minmax_element(frame.height.begin(), frame.height.end());
    for (float h : out) ASSERT_TRUE(std::isfinite(h) && h >= *lo - 1e-4f && h <= *hi + 1e-4f) << choppiness;
    for (float j : extra) ASSERT_TRUE(std::isfinite(j)) << choppiness;
    EXPECT_LT(residual * params.size / params.patch_size, 0.005) << choppiness;  // texels
  }
}

}  // namespace displace::sim
