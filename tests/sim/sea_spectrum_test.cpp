// tests/sim/sea_spectrum_test.cpp - the sea spectra (sim/sea_spectrum.cpp): what the ocean synthesizes
// against the analytic spectrum, the literature's formulas for Hs and the peak, patch invariance, full
// development, depth, spreading normalisation.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <vector>

#include "sim/sim.h"

namespace displace::sim {
namespace {

constexpr double pi = std::numbers::pi;
constexpr double gravity = 9.81;

// Hs = 4 sigma of the synthesized heights over seeds and times, and the synthesized modes' energy
// |h~(k, t)|^2 summed into frequency bins [bin_edges[b], bin_edges[b + 1]).
struct Measured {
  double significant_height = 0.0;
  std::vector<double> bin_energy;
};

Measured measure(OceanParams params, int seeds, const std::vector<double>& times,
                 const std::vector<double>& bin_edges) {
  Measured result;
  result.bin_energy.assign(bin_edges.empty() ? 0 : bin_edges.size() - 1, 0.0);
  double variance = 0.0;
  int fields = 0;
  OceanFrame frame;
  for (int seed = 0; seed < seeds; ++seed) {
    params.seed = 1000 + std::uint64_t(seed);
    Ocean ocean(params);
    const int n = ocean.size();
    for (double time : times) {
      ocean.evaluate(time, ocean_heights, frame);
      double sum = 0.0, sum_squares = 0.0;
      for (float h : frame.height) {
        sum += h;
        sum_squares += double(h) * h;
      }
      const double count = double(frame.height.size());
      variance += sum_squares / count - (sum / count) * (sum / count);
      ++fields;
      if (bin_edges.empty()) continue;
      const std::vector<std::complex<float>> spectrum = ocean.height_spectrum(time);
      for (int i = 0; i < n; ++i) {
        for (int j = 0; j < n; ++j) {
          const double w = ocean.omega(i, j);
          const auto at = std::upper_bound(bin_edges.begin(), bin_edges.end(), w);
          if (at == bin_edges.begin() || at == bin_edges.end()) continue;
          result.bin_energy[std::size_t(at - bin_edges.begin() - 1)] +=
              std::norm(std::complex<double>(spectrum[std::size_t(i) * n + j]));
        }
      }
    }
  }
  result.significant_height = 4.0 * std::sqrt(variance / fields);
  for (double& energy : result.bin_energy) energy /= fields;
  return result;
}

// The analytic spectrum's variance over the wave numbers the lattice holds: E(k) D(theta; w) / k over
// the square of the lattice's cells less the k = 0 cell, each cell cut into subcells x subcells.
double band_variance(const OceanParams& params, int subcells) {
  const SeaSpectrum sea(params);
  const int n = params.size;
  const double dk = 2.0 * pi / params.patch_size;
  const double step = dk / subcells;
  const double half_side = (n / 2 - 0.5) * dk;
  const int count = int(std::lround(2.0 * half_side / step));
  double sum = 0.0;
  for (int a = 0; a < count; ++a) {
    const double ky = -half_side + (a + 0.5) * step;
    for (int b = 0; b < count; ++b) {
      const double kx = -half_side + (b + 0.5) * step;
      if (std::abs(kx) < 0.5 * dk && std::abs(ky) < 0.5 * dk) continue;
      const double k = std::hypot(kx, ky);
      // travelling along k, at angle atan2(ky, kx) - wind_direction from the wind
      const double theta = std::atan2(ky, kx) - params.wind_direction;
      sum += sea.wave_number(k) * sea.spreading(sea.omega(k), theta) / k;
    }
  }
  return sum * step * step;
}

// The peak of the measured bins: the analytic spectrum's peak times the frequency scale f that fits
// them best (least squares, the amplitude fitted too) with S(w / f), f on a grid 0.05% apart.
double fitted_peak(const SeaSpectrum& sea, double analytic_peak, const std::vector<double>& edges,
                   const std::vector<double>& energy) {
  double best_scale = 1.0, best_residual = std::numeric_limits<double>::infinity();
  for (double scale = 0.9; scale <= 1.1; scale += 0.0005) {
    std::vector<double> model(energy.size());
    double cross = 0.0, square = 0.0;
    for (std::size_t b = 0; b < energy.size(); ++b) {
      model[b] = sea.frequency(0.5 * (edges[b] + edges[b + 1]) / scale) * (edges[b + 1] - edges[b]);
      cross += model[b] * energy[b];
      square += model[b] * model[b];
    }
    const double amplitude = cross / square;
    double residual = 0.0;
    for (std::size_t b = 0; b < energy.size(); ++b)
      residual += std::pow(energy[b] - amplitude * model[b], 2.0);
    if (residual < best_residual) {
      best_residual = residual;
      best_scale = scale;
    }
  }
  return best_scale * analytic_peak;
}

// The w at the maximum of S(w), on a grid 0.01% apart.
double analytic_peak(const OceanParams& params, double guess) {
  const SeaSpectrum sea(params);
  double best = guess, best_value = 0.0;
  for (double w = 0.5 * guess; w < 2.0 * guess; w *= 1.0001) {
    const double value = sea.frequency(w);
    if (value > best_value) {
      best = w;
      best_value = value;
    }
  }
  return best;
}

// A sea of each spectrum with its peak about 8 wavelengths across a patch of 128 samples.
struct Case {
  const char* name;
  OceanParams params;
  double peak_omega;     // rad/s, the literature's formula (TMA: JONSWAP's, where the search starts)
  bool numeric = false;  // the peak is the maximum of S found numerically (TMA: S_J Phi)
};

std::vector<Case> cases() {
  std::vector<Case> result;
  OceanParams base;
  base.size = 128;
  base.wind_speed = 10.0f;
  base.wind_direction = 0.4f;
  base.choppiness = 0.0f;
  {
    OceanParams p = base;
    p.spectrum = Spectrum::phillips;
    p.small_wave_cutoff = 0.05f;  // metres: the damping would move the peak
    p.patch_size = 8.0f * float(2.0 * pi * p.wind_speed * p.wind_speed / gravity / std::sqrt(0.8));
    // Tessendorf's shape is S(w) ~ w^-5 exp(-(g / (U w))^4): its peak at (4/5)^(1/4) g / U
    result.push_back({"phillips", p, std::pow(0.8, 0.25) * gravity / p.wind_speed});
  }
  {
    OceanParams p = base;
    p.spectrum = Spectrum::pierson_moskowitz;
    const double peak = 0.8772 * gravity / (1.026 * p.wind_speed);  // 0.8772 g / U19.5
    p.patch_size = float(8.0 * 2.0 * pi * gravity / (peak * peak));
    result.push_back({"pierson-moskowitz", p, peak});
  }
  {
    OceanParams p = base;
    p.spectrum = Spectrum::jonswap;
    p.fetch = 50.0f;  // km
    const double peak = 22.0 * std::cbrt(gravity * gravity / (p.wind_speed * p.fetch * 1000.0));
    p.patch_size = float(8.0 * 2.0 * pi * gravity / (peak * peak));
    result.push_back({"jonswap", p, peak});
  }
  {
    OceanParams p = base;
    p.spectrum = Spectrum::tma;
    p.fetch = 50.0f;
    p.depth = 4.0f;  // k_p h about 0.7: shallow enough to slow the waves and take energy
    const double peak = 22.0 * std::cbrt(gravity * gravity / (p.wind_speed * p.fetch * 1000.0));
    const double k = dispersion_wave_number(peak, p.depth, gravity);
    p.patch_size = float(8.0 * 2.0 * pi / k);
    result.push_back({"tma", p, peak, true});
  }
  return result;
}

TEST(SeaSpectrum, SynthesizedHsMatchesTheBandIntegralAndThePeakTheFormula) {
  for (const Case& c : cases()) {
    SCOPED_TRACE(c.name);
    const double formula_peak = c.numeric ? analytic_peak(c.params, c.peak_omega) : c.peak_omega;
    // the analytic spectrum's own maximum where the literature puts it
    EXPECT_NEAR(analytic_peak(c.params, formula_peak), formula_peak, 0.005 * formula_peak);
    EXPECT_NEAR(2.0 * pi / describe_sea(c.params).peak_period, formula_peak, 0.005 * formula_peak);

    std::vector<double> edges;
    for (double w = 0.5 * formula_peak; w < 2.0 * formula_peak; w *= 1.02) edges.push_back(w);
    const Measured measured = measure(c.params, 16, {0.0, 37.0}, edges);
    const double band = 4.0 * std::sqrt(band_variance(c.params, 4));
    EXPECT_NEAR(measured.significant_height, band, 0.03 * band);

    // the measured spectrum's peak where the analytic one has it
    const double measured_peak = fitted_peak(SeaSpectrum(c.params), formula_peak, edges, measured.bin_energy);
    EXPECT_NEAR(measured_peak, formula_peak, 0.03 * formula_peak);
  }
}

TEST(SeaSpectrum, PiersonMoskowitzAndJonswapFollowTheirPapers) {
  const double u = 10.0;
  OceanParams params;
  params.wind_speed = float(u);
  params.spectrum = Spectrum::pierson_moskowitz;
  // Pierson & Moskowitz: S = 0.0081 g^2 w^-5 exp(-0.74 (g / (U19.5 w))^4), so m0 = 0.0081 U19.5^4 / (4 0.74
  // g^2)
  const double u19 = 1.026 * u;
  const double pm_hs = 4.0 * std::sqrt(0.0081 * std::pow(u19, 4.0) / (4.0 * 0.74 * gravity * gravity));
  const SeaState pm = describe_sea(params);
  EXPECT_NEAR(pm.significant_height, pm_hs, 0.005 * pm_hs);
  EXPECT_NEAR(pm.peak_period, 2.0 * pi / (0.8772 * gravity / u19), 0.005 * pm.peak_period);

  // JONSWAP's fetch laws below full development: g^2 m0 / U^4 = 1.6e-7 chi, w_p = 22 (g / U) chi^(-1/3)
  params.spectrum = Spectrum::jonswap;
  for (float fetch : {5.0f, 50.0f, 150.0f}) {
    params.fetch = fetch;
    const double chi = gravity * fetch * 1000.0 / (u * u);
    const SeaState sea = describe_sea(params);
    const double hs = 4.0 * std::sqrt(1.6e-7 * chi) * u * u / gravity;
    EXPECT_NEAR(sea.significant_height, hs, 0.005 * hs) << fetch;
    EXPECT_NEAR(2.0 * pi / sea.peak_period, 22.0 * gravity / u * std::cbrt(1.0 / chi),
                0.005 * 2.0 * pi / sea.peak_period)
        << fetch;
  }
}

TEST(SeaSpectrum, JonswapGrowsWithFetchUntilItIsPiersonMoskowitz) {
  OceanParams pm;
  pm.spectrum = Spectrum::pierson_moskowitz;
  pm.wind_speed = 10.0f;
  const SeaState developed = describe_sea(pm);
  OceanParams jonswap = pm;
  jonswap.spectrum = Spectrum::jonswap;
  double last_hs = 0.0, last_period = 0.0;
  for (float fetch : {1.0f, 10.0f, 100.0f, 300.0f, 1000.0f, 10000.0f}) {
    jonswap.fetch = fetch;
    const SeaState sea = describe_sea(jonswap);
    EXPECT_GE(sea.significant_height, last_hs) << fetch;
    EXPECT_GE(sea.peak_period, last_period) << fetch;
    EXPECT_LE(sea.significant_height, developed.significant_height * (1.0 + 1e-9)) << fetch;
    last_hs = sea.significant_height;
    last_period = sea.peak_period;
  }
  // 10,000 km: fully developed
  EXPECT_NEAR(last_hs, developed.significant_height, 0.05 * developed.significant_height);
  EXPECT_NEAR(last_period, developed.peak_period, 0.05 * developed.peak_period);
}

TEST(SeaSpectrum, HsDoesNotDependOnThePatch) {
  for (Spectrum spectrum : {Spectrum::phillips, Spectrum::pierson_moskowitz, Spectrum::jonswap}) {
    SCOPED_TRACE(int(spectrum));
    OceanParams params;
    params.spectrum = spectrum;
    params.wind_speed = 10.0f;
    params.fetch = 100.0f;
    double hs[2], analytic[2];
    int index = 0;
    for (const auto& [patch, size] : {std::pair{200.0f, 128}, std::pair{1600.0f, 1024}}) {
      params.patch_size = patch;
      params.size = size;  // the same texel: the same shortest waves
      const SeaState sea = describe_sea(params);
      EXPECT_LT(sea.below_patch + sea.above_map, 0.01) << patch;  // the band holds 99%
      analytic[index] = sea.significant_height;
      hs[index++] = sea.lattice_significant_height;
    }
    EXPECT_NEAR(hs[0], hs[1], 0.03 * hs[1]);
    EXPECT_NEAR(analytic[0], analytic[1], 1e-9 * analytic[1]);  // the sea itself: neither patch nor map
  }
}

TEST(SeaSpectrum, DescribedLatticeIsWhatTheOceanDraws) {
  for (Spectrum spectrum : {Spectrum::phillips, Spectrum::tma}) {
    OceanParams params;
    params.size = 64;
    params.spectrum = spectrum;
    params.depth = 6.0f;
    params.swell.significant_height = 0.8f;
    const Ocean ocean(params);
    const SeaState sea = describe_sea(params);
    const double hs = 4.0 * std::sqrt(ocean.height_variance());
    EXPECT_NEAR(sea.lattice_significant_height, hs, 1e-9 * hs);
  }
}

TEST(SeaSpectrum, SeaStateByHeightAndPeriod) {
  for (Spectrum spectrum : {Spectrum::pierson_moskowitz, Spectrum::jonswap, Spectrum::tma}) {
    SCOPED_TRACE(int(spectrum));
    OceanParams params;
    params.spectrum = spectrum;
    params.significant_height = 1.5f;
    params.peak_period = 7.0f;
    if (spectrum == Spectrum::tma) params.depth = 5.0f;
    const SeaState sea = describe_sea(params);
    EXPECT_NEAR(sea.significant_height, 1.5, 0.005 * 1.5);
    // TMA's depth factor moves the maximum of S_J Phi up a little
    const double tolerance = spectrum == Spectrum::tma ? 0.05 : 0.005;
    EXPECT_NEAR(sea.peak_period, 7.0, tolerance * 7.0);
  }
}

// TMA's spectrum is JONSWAP's times Kitaigorodskii's Phi(w_h), w_h = w sqrt(h / g):
// Phi = R^-2 / (1 + 2 w_h^2 R / sinh(2 w_h^2 R)) with R tanh(w_h^2 R) = 1 (Kitaigorodskii et al. 1975), which
// Thompson & Vincent's (1983) 0.5 w_h^2, 1 - 0.5 (2 - w_h)^2, 1 approximate within a few percent.
TEST(SeaSpectrum, TmaIsJonswapTimesKitaigorodskiisDepthFunction) {
  OceanParams jonswap;
  jonswap.spectrum = Spectrum::jonswap;
  jonswap.depth = 4.0f;
  OceanParams tma = jonswap;
  tma.spectrum = Spectrum::tma;
  const SeaSpectrum deep_energy(jonswap), shallow_energy(tma);
  const double h = jonswap.depth, g = jonswap.gravity;
  for (double omega_h : {0.3, 0.7, 1.0, 1.4, 1.9, 2.5}) {
    const double omega = omega_h * std::sqrt(g / h);
    const double x = omega_h * omega_h;
    double low = 1.0, high = 1.0 / std::tanh(x) + 1.0;  // R tanh(x R) = 1, bisection
    for (int i = 0; i < 200; ++i) {
      const double mid = 0.5 * (low + high);
      (mid * std::tanh(x * mid) < 1.0 ? low : high) = mid;
    }
    const double r = 0.5 * (low + high);
    const double phi = 1.0 / (r * r) / (1.0 + 2.0 * x * r / std::sinh(2.0 * x * r));
    const double ratio = shallow_energy.frequency(omega) / deep_energy.frequency(omega);
    EXPECT_NEAR(ratio, phi, 1e-9 * phi) << omega_h;
    const double approximate = omega_h <= 1.0   ? 0.5 * x
                               : omega_h <= 2.0 ? 1.0 - 0.5 * (2.0 - omega_h) * (2.0 - omega_h)
                                                : 1.0;
    EXPECT_NEAR(ratio, approximate, 0.06) << omega_h;
  }
}

TEST(SeaSpectrum, SwellAddsItsVariance) {
  OceanParams params;
  params.spectrum = Spectrum::pierson_moskowitz;
  params.wind_speed = 6.0f;
  const double sea_variance = std::pow(describe_sea(params).significant_height / 4.0, 2.0);
  params.swell = {1.2f, 11.0f, 0.7f, 30.0f};
  const SeaState with_swell = describe_sea(params);
  const double swell_variance = 1.2 * 1.2 / 16.0;
  EXPECT_NEAR(std::pow(with_swell.significant_height / 4.0, 2.0), sea_variance + swell_variance,
              0.005 * (sea_variance + swell_variance));
  // the swell's peak is the larger one here
  EXPECT_NEAR(with_swell.peak_period, 11.0, 0.01 * 11.0);
}

TEST(SeaSpectrum, SpreadingIntegratesToOneOverDirection) {
  for (Spreading model :
       {Spreading::cos2s, Spreading::mitsuyasu, Spreading::hasselmann, Spreading::donelan_banner}) {
    for (Spectrum spectrum : {Spectrum::phillips, Spectrum::jonswap}) {
      for (float wind : {3.0f, 30.0f}) {
        OceanParams params;
        params.spectrum = spectrum;
        params.spreading_model = model;
        params.wind_speed = wind;
        params.spreading = 7.5f;
        const SeaSpectrum sea(params);
        const double peak = 0.855 * gravity / wind;  // about the peak: the ratios span it either way
        for (double ratio : {0.3, 0.6, 0.9, 1.0, 1.3, 2.0, 5.0}) {
          const int steps = 8000;  // Simpson over [-pi, pi]
          double sum = 0.0;
          for (int i = 0; i <= steps; ++i) {
            const double theta = -pi + 2.0 * pi * i / steps;
            const double weight = i == 0 || i == steps ? 1.0 : (i % 2 == 1 ? 4.0 : 2.0);
            sum += weight * sea.spreading(ratio * peak, theta);
          }
          // (Simpson's error at a small s's cusp at theta = pi is about 3e-5)
          EXPECT_NEAR(sum * 2.0 * pi / steps / 3.0, 1.0, 1e-4)
              << "model " << int(model) << " wind " << wind << " w / w_p " << ratio;
        }
      }
    }
  }
}

TEST(SeaSpectrum, SpreadingFollowsTheWind) {
  // every model puts the most energy downwind and less across it
  for (Spreading model :
       {Spreading::cos2s, Spreading::mitsuyasu, Spreading::hasselmann, Spreading::donelan_banner}) {
    OceanParams params;
    params.spectrum = Spectrum::jonswap;
    params.spreading_model = model;
    const SeaSpectrum sea(params);
    const double peak = 2.0 * pi / describe_sea(params).peak_period;
    EXPECT_GT(sea.spreading(peak, 0.0), 2.0 * sea.spreading(peak, pi / 2.0)) << int(model);
  }
}

TEST(SeaSpectrum, BeaufortWindSpeeds) {
  EXPECT_FLOAT_EQ(beaufort_wind_speed(0), min_wind_speed);
  EXPECT_NEAR(beaufort_wind_speed(6), 12.3, 0.1);  // WMO: 10.8-13.8 m/s
  EXPECT_NEAR(beaufort_wind_speed(9), 22.6, 0.1);  // 20.8-24.4 m/s
  EXPECT_NEAR(beaufort_wind_speed(12), 34.8, 0.1);
  EXPECT_THROW(beaufort_wind_speed(13), std::invalid_argument);
  EXPECT_THROW(beaufort_wind_speed(-1), std::invalid_argument);
}

TEST(SeaSpectrum, DispersionAtAnyDepth) {
  for (double depth : {0.5, 3.0, 40.0, 1e4}) {
    for (double k : {0.01, 0.3, 2.0, 30.0}) {
      const double w = dispersion_omega(k, depth, gravity);
      EXPECT_NEAR(w * w, gravity * k * std::tanh(k * depth), 1e-12 * w * w);
      EXPECT_NEAR(dispersion_wave_number(w, depth, gravity), k, 1e-10 * k);
    }
  }
  EXPECT_EQ(dispersion_omega(0.5, std::numeric_limits<double>::infinity(), gravity),
            std::sqrt(gravity * 0.5));
}

TEST(SeaSpectrum, WarnsWhereThePatchOrTheMapLeavesTheSeaOut) {
  OceanParams params;
  params.spectrum = Spectrum::jonswap;
  params.wind_speed = 20.0f;
  params.fetch = 200.0f;
  params.size = 256;
  // 200 m: the 153 m peak wavelength on the patch's lowest modes
  const SeaState coarse_peak = describe_sea(params);
  EXPECT_TRUE(coarse_peak.patch_too_small);
  EXPECT_FALSE(coarse_peak.map_too_coarse);
  EXPECT_GT(std::abs(coarse_peak.lattice_error), left_out_allowance);
  EXPECT_LT(coarse_peak.below_patch, 0.5 * left_out_allowance);
  EXPECT_GE(coarse_peak.patch_needed, min_peak_wavelengths * coarse_peak.peak_wavelength);
  params.patch_size = float(coarse_peak.patch_needed);
  EXPECT_FALSE(describe_sea(params).patch_too_small);

  // 100 m: the longest waves left out
  params.patch_size = 100.0f;
  const SeaState small = describe_sea(params);
  EXPECT_TRUE(small.patch_too_small);
  EXPECT_GT(small.below_patch, left_out_allowance);

  // 32 samples over 1 km: the short waves left out
  params.patch_size = 1000.0f;
  params.size = 32;
  const SeaState coarse = describe_sea(params);
  EXPECT_TRUE(coarse.map_too_coarse);
  EXPECT_FALSE(coarse.patch_too_small);
  EXPECT_GT(coarse.above_map, left_out_allowance);
  params.size = coarse.size_needed;
  const SeaState fine = describe_sea(params);
  EXPECT_LE(fine.above_map, 0.5 * left_out_allowance);
  EXPECT_FALSE(fine.map_too_coarse);

  // Phillips' half-texel damping is the lattice's: 256 samples over 1600 m cut the sea's short waves
  OceanParams phillips;
  phillips.wind_speed = 10.0f;
  phillips.patch_size = 1600.0f;
  const SeaState damped = describe_sea(phillips);
  EXPECT_LT(damped.lattice_error, -left_out_allowance);
  EXPECT_TRUE(damped.map_too_coarse);
  EXPECT_FALSE(damped.patch_too_small);
}

TEST(SeaSpectrum, BadParamsThrow) {
  auto throws = [](auto change) {
    OceanParams params;
    change(params);
    EXPECT_THROW(SeaSpectrum{params}, std::invalid_argument);
    EXPECT_THROW(Ocean{params}, std::invalid_argument);
  };
  throws([](OceanParams& p) { p.depth = 0.0f; });
  throws([](OceanParams& p) { p.depth = NAN; });
  throws([](OceanParams& p) { p.depth = -3.0f; });
  throws([](OceanParams& p) { p.spreading_model = static_cast<Spreading>(9); });
  throws([](OceanParams& p) {  // phillips has no Hs / Tp form
    p.significant_height = 2.0f;
    p.peak_period = 8.0f;
  });
  throws([](OceanParams& p) {
    p.spectrum = Spectrum::jonswap;
    p.significant_height = 2.0f;  // without a period
  });
  throws([](OceanParams& p) { p.swell.significant_height = -1.0f; });
  throws([](OceanParams& p) {
    p.swell.significant_height = 1.0f;
    p.swell.peak_period = 0.0f;
  });
  throws([](OceanParams& p) { p.peak_enhancement = 50.0f; });
}

}  // namespace
}  // namespace displace::sim
