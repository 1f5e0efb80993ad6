// tests/sim/fft_ocean_test.cpp - the FFT ocean (sim/fft_ocean.cpp): spectra of the outputs from a naive DFT
// in double, independent of FFTW.
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

TEST(Ocean, OmegaIsDeepWaterDispersionByDefault) {
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

// Finite depth: every mode turns at w = sqrt(g k tanh(k h)), i.e. travels at the phase speed
// sqrt(g / k tanh(k h)), in the output heights at t = 1e6 s (phases reduced in double) and at 5000 s (the
// fast phase reduction), for every spectrum.
TEST(Ocean, FiniteDepthPhaseSpeedAtAMillionSeconds) {
  for (Spectrum spectrum :
       {Spectrum::phillips, Spectrum::pierson_moskowitz, Spectrum::jonswap, Spectrum::tma}) {
    SCOPED_TRACE(int(spectrum));
    OceanParams params = small_ocean(spectrum);
    params.depth = 3.0f;  // k h from 0.19 to 3
    Ocean ocean(params);
    const int n = ocean.size();
    const double dk = 2.0 * std::numbers::pi / params.patch_size;
    for (double time : {5000.0, 1e6}) {
      const double step = 0.3;
      OceanFrame frame;
      std::vector<std::vector<Complex>> spectra;
      for (double t : {time - step, time, time + step}) {
        ocean.evaluate(t, ocean_heights, frame);
        spectra.push_back(texel_centre_dft(frame.height, n));
      }
      const double scale = max_magnitude(spectra[1]);
      ASSERT_GT(scale, 0.0);
      for (int i = 0; i < n; ++i) {
        for (int j = 0; j < n; ++j) {
          const double k = dk * std::hypot(i < n / 2 ? i : i - n, j < n / 2 ? j : j - n);
          if (k == 0.0) continue;
          const double speed = std::sqrt(params.gravity / k * std::tanh(k * params.depth));
          EXPECT_NEAR(ocean.omega(i, j) / k, speed, 1e-6 * speed);
          const std::size_t index = static_cast<std::size_t>(i) * n + j;
          const double cos_w_dt = std::cos(speed * k * step);
          const Complex residual = spectra[2][index] + spectra[0][index] - 2.0 * cos_w_dt * spectra[1][index];
          EXPECT_LT(std::abs(residual), 5e-5 * scale) << "time " << time << " mode " << i << ", " << j;
        }
      }
    }
  }
}

// Depth absent is deep water as before, bit for bit: w = sqrt(g k) in every mode, and the same heights as
// water so deep that tanh(k h) is 1 in double for every mode.
TEST(Ocean, NoDepthIsDeepWaterBitForBit) {
  for (Spectrum spectrum : {Spectrum::phillips, Spectrum::pierson_moskowitz}) {
    OceanParams params = small_ocean(spectrum);
    ASSERT_FALSE(std::isfinite(params.depth));
    Ocean deep(params);
    const int n = deep.size();
    const double dk = 2.0 * std::numbers::pi / params.patch_size;
    for (int i = 0; i < n; ++i) {
      for (int j = 0; j < n; ++j) {
        const double k = dk * std::hypot(i < n / 2 ? i : i - n, j < n / 2 ? j : j - n);
        ASSERT_EQ(deep.omega(i, j), static_cast<float>(std::sqrt(params.gravity * k)));
      }
    }
    params.depth = max_depth;  // k h >= 628
    Ocean very_deep(params);
    OceanFrame a, b;
    deep.evaluate(12.5, ocean_heights | ocean_displacement, a);
    very_deep.evaluate(12.5, ocean_heights | ocean_displacement, b);
    EXPECT_EQ(a.height, b.height);
    EXPECT_EQ(a.displacement_x, b.displacement_x);
  }
}

TEST(Ocean, LoopsInShallowWaterBitForBit) {
  OceanParams params = small_ocean(Spectrum::tma);
  params.depth = 2.0f;
  params.loop_seconds = 9.0;
  Ocean ocean(params);
  OceanFrame first, later;
  for (double start : {0.0, 3.3, 1e9}) {
    ocean.evaluate(start, ocean_heights, first);
    ocean.evaluate(start + params.loop_seconds, ocean_heights, later);
    EXPECT_EQ(first.height, later.height) << start;
  }
  EXPECT_GT(ocean.loop_error(), 0.0);
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

TEST(Ocean, EverySpectrumGivesFiniteNonZeroFields) {
  for (Spectrum spectrum :
       {Spectrum::phillips, Spectrum::pierson_moskowitz, Spectrum::jonswap, Spectrum::tma}) {
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
  throws([](OceanParams& p) { p.loop_seconds = 0.05; });
  throws([](OceanParams& p) { p.loop_seconds = -1.0; });
  throws([](OceanParams& p) { p.loop_seconds = NAN; });
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

TEST(Ocean, LoopsSeamlesslyBitForBit) {
  OceanParams params;
  params.size = 64;
  params.choppiness = 1.5f;
  params.loop_seconds = 12.5;
  Ocean ocean(params);
  const unsigned outputs = ocean_heights | ocean_displacement | ocean_foam;
  const double step = 2.0 * std::numbers::pi / params.loop_seconds;
  // every frequency a multiple of 2 pi / T, and the error reported is the largest change
  double largest_change = 0.0;
  Ocean unlooped([&] {
    OceanParams plain = params;
    plain.loop_seconds = 0.0;
    return plain;
  }());
  for (int i = 0; i < params.size; ++i) {
    for (int j = 0; j < params.size; ++j) {
      const double multiple = double(ocean.omega(i, j)) / step;
      EXPECT_NEAR(multiple, std::round(multiple), 1e-5);
      if (i == params.size / 2 || j == params.size / 2 || (i == 0 && j == 0)) continue;
      largest_change =
          std::max(largest_change, std::abs(double(ocean.omega(i, j)) - double(unlooped.omega(i, j))) /
                                       double(unlooped.omega(i, j)));
    }
  }
  EXPECT_GT(ocean.loop_error(), 0.0);
  EXPECT_NEAR(ocean.loop_error(), largest_change, 1e-6);
  EXPECT_EQ(unlooped.loop_error(), 0.0);
  for (double start : {0.0, 1.25, 1e9}) {
    SCOPED_TRACE(start);
    OceanFrame first, later, halfway;
    ocean.evaluate(start, outputs, first);
    ocean.evaluate(start + params.loop_seconds, outputs, later);
    ocean.evaluate(start + 0.5 * params.loop_seconds, outputs, halfway);
    EXPECT_EQ(first.height, later.height);
    EXPECT_EQ(first.displacement_x, later.displacement_x);
    EXPECT_EQ(first.jacobian, later.jacobian);
    EXPECT_NE(first.height, halfway.height);
  }
}

}  // namespace
}  // namespace displace::sim
