// sim/sea_spectrum.cpp - the sea spectra of oceanography behind the FFT ocean: Pierson & Moskowitz (1964),
// JONSWAP (Hasselmann et al. 1973) with its growth capped at full development, TMA (Bouws et al. 1985,
// Kitaigorodskii et al. 1975), Tessendorf's Phillips spectrum per unit area; directional spreading after
// Mitsuyasu et al. (1975), Hasselmann et al. (1980), Donelan et al. (1985) and Banner (1990); linear
// dispersion at any depth. After Horvath, "Empirical directional wave spectra for computer graphics"
// (DigiPro 2015). Formulas and sources: docs/design/sim.md#sea-spectra-simsea_spectrumcpp
//
// The one fact to know: everything is a variance density E(k) D(theta) / k over the wave-number plane
// (E the one-dimensional wave-number spectrum, E(k) = S(w) dw/dk, D integrating to 1 over direction),
// and a lattice mode of area dk^2 holds half of it times dk^2: the other half comes with its mirror mode.
#include <math.h>  // lgamma_r
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "sim/sea_model.h"
#include "sim/sim.h"

namespace displace::sim {
namespace {

constexpr double pm_alpha = 0.0081;  // Phillips' constant of the fully developed sea (Pierson & Moskowitz)
constexpr double pm_peak =
    0.855;  // w_p U10 / g of the fully developed sea (0.877 g / U19.5, U19.5 = 1.026 U10)
constexpr double pm_energy = pm_alpha / (5.0 * pm_peak * pm_peak * pm_peak * pm_peak);  // g^2 m0 / U10^4
constexpr double jonswap_energy_coefficient = 1.6e-7;  // g^2 m0 / U^4 = 1.6e-7 g F / U^2 (Hasselmann 1973)
constexpr double jonswap_peak_coefficient = 22.0;      // w_p U / g = 22 (g F / U^2)^(-1/3) (Hasselmann 1973)
constexpr double jonswap_sigma_below_peak = 0.07;      // peak width for w <= w_p
constexpr double jonswap_sigma_above_peak = 0.09;      // peak width for w > w_p
constexpr double swell_peak_enhancement =
    7.0;  // gamma of a swell's JONSWAP shape (a modelling choice: narrow)
constexpr double phillips_peak = 0.9457416090031758;  // w_p U / g of Phillips' shape: (4/5)^(1/4)
constexpr double mitsuyasu_peak_spreading = 11.5;     // s_p = 11.5 (U w_p / g)^-2.5 (Mitsuyasu et al. 1975)
constexpr double mitsuyasu_wave_age_exponent = -2.5;
constexpr double mitsuyasu_exponent_below = 5.0;  // s = s_p (w / w_p)^5 below the peak
constexpr double mitsuyasu_exponent_above = -2.5;
constexpr double hasselmann_below = 6.97;  // s = 6.97 (w / w_p)^4.06 below the peak (Hasselmann et al. 1980)
constexpr double hasselmann_exponent_below = 4.06;
constexpr double hasselmann_above = 9.77;  // s = 9.77 (w / w_p)^mu above, mu = -2.33 - 1.45 (U / c_p - 1.17)
constexpr double hasselmann_mu = -2.33;
constexpr double hasselmann_mu_slope = -1.45;
constexpr double hasselmann_mu_age = 1.17;
constexpr double donelan_low = 0.56;  // beta = 2.61 (w / w_p)^1.3 on [0.56, 0.95) (Donelan et al. 1985)
constexpr double donelan_mid = 0.95;  // beta = 2.28 (w / w_p)^-1.3 on [0.95, 1.6)
constexpr double donelan_high = 1.6;  // above: Banner (1990), 10^(-0.4 + 0.8393 exp(-0.567 ln (w / w_p)^2))
constexpr double donelan_rising = 2.61;
constexpr double donelan_falling = 2.28;
constexpr double donelan_exponent = 1.3;
constexpr double banner_offset = -0.4;
constexpr double banner_scale = 0.8393;
constexpr double banner_decay = -0.567;
constexpr double metres_per_kilometre = 1000.0;
constexpr double wmo_beaufort = 0.836;        // v = 0.836 B^(3/2) m/s (WMO)
constexpr int integral_steps_per_unit = 400;  // steps per unit of ln k (or ln w) in the integrals below

bool positive_finite(float value) { return std::isfinite(value) && value > 0.0f; }

std::string range_text(float low, float high) {
  char text[64];
  std::snprintf(text, sizeof text, "[%g, %g]", double(low), double(high));
  return text;
}
std::string range_text(float value) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", double(value));
  return text;
}

bool in_range(float value, float low, float high) { return value >= low && value <= high; }

// Normalisation G(s) of cos^{2s}(theta / 2) over [-pi, pi]: Gamma(s+1) / (2 sqrt(pi) Gamma(s+1/2)).
double spreading_normalisation(double s) {
  return std::tgamma(s + 1.0) / (2.0 * std::sqrt(std::numbers::pi) * std::tgamma(s + 0.5));
}
// The same through log-gamma, for the frequency-dependent exponents. lgamma_r, not std::lgamma: the
// latter stores the sign in the global signgam, a data race when TBB's workers describe a sea (the
// arguments here are positive, so the sign is not needed).
double log_gamma(double x) {
  int sign = 0;
  return ::lgamma_r(x, &sign);
}
double spreading_normalisation_log(double s) {
  return std::exp(log_gamma(s + 1.0) - log_gamma(s + 0.5)) / (2.0 * std::sqrt(std::numbers::pi));
}

// Simpson's rule for the integral of f(x) dx over [low, high] in u = ln x: intervals per unit of ln x.
template <typename Function>
double integrate_log(Function f, double low, double high) {
  const double span = std::log(high / low);
  int intervals = std::max(2, int(std::ceil(span * integral_steps_per_unit)));
  intervals += intervals % 2;
  const double step = span / intervals;
  double sum = 0.0;
  for (int i = 0; i <= intervals; ++i) {
    const double x = low * std::exp(i * step);
    const double weight = i == 0 || i == intervals ? 1.0 : (i % 2 == 1 ? 4.0 : 2.0);
    sum += weight * f(x) * x;
  }
  return sum * step / 3.0;
}

// J(gamma) = integral of x^-5 exp(-5/4 x^-4) gamma^r(x) dx over x = w / w_p: m0 = scale J / w_p^4.
double peak_integral(double gamma) {
  const detail::PeakedSpectrum shape{1.0, 1.0, gamma, false};
  if (gamma == 1.0) return 0.2;
  return integrate_log([&](double x) { return shape.value(x, 1.0); }, 0.3, 1000.0);
}

}  // namespace

namespace detail {

void validate_ocean(const OceanParams& params) {
  auto fail = [](const std::string& message) { throw std::invalid_argument("OceanParams: " + message); };
  if (params.size < min_ocean_size || params.size > max_ocean_size || params.size % 2 != 0) {
    fail("size must be even and in [" + std::to_string(min_ocean_size) + ", " +
         std::to_string(max_ocean_size) + "], got " + std::to_string(params.size));
  }
  if (!in_range(params.patch_size, min_patch_size, max_patch_size))
    fail("patch_size must be in " + range_text(min_patch_size, max_patch_size) + " metres");
  switch (params.spectrum) {
    case Spectrum::phillips:
    case Spectrum::jonswap:
    case Spectrum::pierson_moskowitz:
    case Spectrum::tma: break;
    default: fail("unknown spectrum");
  }
  switch (params.spreading_model) {
    case Spreading::cos2s:
    case Spreading::mitsuyasu:
    case Spreading::hasselmann:
    case Spreading::donelan_banner: break;
    default: fail("unknown spreading model");
  }
  if (!in_range(params.wind_speed, min_wind_speed, max_wind_speed))
    fail("wind_speed must be in " + range_text(min_wind_speed, max_wind_speed) + " m/s");
  if (!std::isfinite(params.wind_direction)) fail("wind_direction must be finite");
  if (!in_range(params.fetch, min_fetch, max_fetch))
    fail("fetch must be in " + range_text(min_fetch, max_fetch) + " km");
  if (!in_range(params.peak_enhancement, min_peak_enhancement, max_peak_enhancement)) {
    fail("peak_enhancement (JONSWAP gamma) must be in " +
         range_text(min_peak_enhancement, max_peak_enhancement));
  }
  if (!in_range(params.spreading, 0.0f, max_spreading))
    fail("spreading must be in " + range_text(0.0f, max_spreading));
  if (!positive_finite(params.phillips_amplitude)) fail("phillips_amplitude must be positive and finite");
  if (!std::isfinite(params.small_wave_cutoff) || params.small_wave_cutoff < 0.0f) {
    fail("small_wave_cutoff must be finite and >= 0 (metres)");
  }
  if (!in_range(params.choppiness, 0.0f, max_choppiness))
    fail("choppiness must be in " + range_text(0.0f, max_choppiness));
  if (!positive_finite(params.gravity)) fail("gravity must be positive and finite");
  if (!(params.loop_seconds == 0.0 ||
        (params.loop_seconds >= min_loop_seconds && params.loop_seconds <= max_loop_seconds))) {
    fail("loop_seconds must be 0 (no loop) or in [" + range_text(float(min_loop_seconds)) + ", " +
         range_text(float(max_loop_seconds)) + "]");
  }
  if (!(params.depth == std::numeric_limits<float>::infinity() ||
        in_range(params.depth, min_depth, max_depth)))
    fail("depth must be infinite (deep water) or in " + range_text(min_depth, max_depth) + " metres");
  const bool by_height = params.significant_height != 0.0f || params.peak_period != 0.0f;
  if (by_height) {
    if (!in_range(params.significant_height, min_significant_height, max_significant_height))
      fail("significant_height must be in " + range_text(min_significant_height, max_significant_height) +
           " metres (with peak_period)");
    if (!in_range(params.peak_period, min_peak_period, max_peak_period))
      fail("peak_period must be in " + range_text(min_peak_period, max_peak_period) +
           " seconds (with significant_height)");
    if (params.spectrum == Spectrum::phillips)
      fail("significant_height and peak_period make a pierson_moskowitz, jonswap or tma sea, not phillips");
  }
  const SwellParams& swell = params.swell;
  if (swell.significant_height != 0.0f) {
    if (!in_range(swell.significant_height, min_significant_height, max_significant_height))
      fail("swell significant_height must be 0 (none) or in " +
           range_text(min_significant_height, max_significant_height) + " metres");
    if (!in_range(swell.peak_period, min_peak_period, max_peak_period))
      fail("swell peak_period must be in " + range_text(min_peak_period, max_peak_period) + " seconds");
    if (!std::isfinite(swell.direction)) fail("swell direction must be finite");
    if (!in_range(swell.spreading, 0.0f, max_spreading))
      fail("swell spreading must be in " + range_text(0.0f, max_spreading));
  }
}

double PeakedSpectrum::value(double omega, double phi) const {
  if (!(omega > 0.0)) return 0.0;
  const double ratio = peak_omega / omega;
  const double ratio_squared = ratio * ratio;
  double s =
      scale / (omega * omega * omega * omega * omega) * std::exp(-1.25 * ratio_squared * ratio_squared);
  if (gamma != 1.0) {
    const double sigma = omega <= peak_omega ? jonswap_sigma_below_peak : jonswap_sigma_above_peak;
    const double offset = (omega - peak_omega) / (sigma * peak_omega);
    s *= std::pow(gamma, std::exp(-0.5 * offset * offset));
  }
  return s * phi;
}

SeaModel::SeaModel(const OceanParams& params) : params_(params) {
  const double g = params.gravity;
  gravity_ = g;
  deep_ = !std::isfinite(params.depth);
  depth_ = deep_ ? 0.0 : double(params.depth);
  const double dk = 2.0 * std::numbers::pi / params.patch_size;
  mode_area_ = dk * dk;
  wind_x_ = std::cos(static_cast<double>(params.wind_direction));
  wind_y_ = std::sin(static_cast<double>(params.wind_direction));
  spreading_norm_ = spreading_normalisation(params.spreading);
  const double u = params.wind_speed;
  wave_age_wind_ = u;

  // Phillips: A per mode of the reference patch; exactly A at that patch
  const double reference_ratio = double(phillips_reference_patch) / double(params.patch_size);
  phillips_amplitude_ = params.phillips_amplitude * (reference_ratio * reference_ratio);
  phillips_length_ = u * u / g;
  damping_length_ =
      params.small_wave_cutoff > 0.0f ? params.small_wave_cutoff : 0.5 * params.patch_size / params.size;
  // half a texel is the lattice's filter, not the sea's: the analytic spectrum keeps the short waves
  spectrum_damping_ = params.small_wave_cutoff;

  const bool by_height = params.significant_height > 0.0f;
  const double target_variance =
      by_height ? double(params.significant_height) * params.significant_height / 16.0 : 0.0;
  const double period_peak = by_height ? 2.0 * std::numbers::pi / params.peak_period : 0.0;
  switch (params.spectrum) {
    case Spectrum::phillips: sea_peak_omega_ = phillips_peak * g / u; break;
    case Spectrum::pierson_moskowitz:
      if (by_height) {
        sea_ = {target_variance * 5.0 * std::pow(period_peak, 4.0), period_peak, 1.0, false};
      } else {
        sea_ = {pm_alpha * g * g, pm_peak * g / u, 1.0, false};
      }
      break;
    case Spectrum::jonswap:
    case Spectrum::tma: {
      // the fetch laws of energy and peak, each capped at the fully developed sea's value
      double variance = target_variance, peak = period_peak;
      if (!by_height) {
        const double fetch = params.fetch * metres_per_kilometre;
        const double dimensionless_fetch = g * fetch / (u * u);
        const double u4_g2 = u * u * u * u / (g * g);
        variance = std::min(jonswap_energy_coefficient * dimensionless_fetch, pm_energy) * u4_g2;
        peak = std::max(jonswap_peak_coefficient * std::cbrt(1.0 / dimensionless_fetch), pm_peak) * g / u;
      }
      const double gamma = params.peak_enhancement;
      sea_ = {1.0, peak, gamma, params.spectrum == Spectrum::tma && !deep_};
      if (sea_.depth_limited && by_height) {
        // Hs at the depth: normalised with the depth factor
        const double shape = integrate_log(
            [&](double omega) {
              return sea_.value(omega, depth_factor(dispersion_wave_number(omega, depth_, gravity_)));
            },
            0.3 * peak, 1000.0 * peak);
        sea_.scale = variance / shape;
      } else {
        sea_.scale = variance * std::pow(peak, 4.0) / peak_integral(gamma);
      }
      break;
    }
  }
  if (params.spectrum != Spectrum::phillips) {
    sea_peak_omega_ = sea_.peak_omega;
    if (by_height) wave_age_wind_ = pm_peak * g / sea_peak_omega_;  // taken as fully developed
  }

  const SwellParams& swell = params.swell;
  has_swell_ = swell.significant_height > 0.0f;
  if (has_swell_) {
    const double peak = 2.0 * std::numbers::pi / swell.peak_period;
    const double variance = double(swell.significant_height) * swell.significant_height / 16.0;
    swell_ = {variance * std::pow(peak, 4.0) / peak_integral(swell_peak_enhancement), peak,
              swell_peak_enhancement, false};
    swell_x_ = std::cos(double(swell.direction));
    swell_y_ = std::sin(double(swell.direction));
    swell_norm_ = spreading_normalisation_log(swell.spreading);
  }
}

double SeaModel::omega(double wave_number) const {
  if (deep_) return std::sqrt(params_.gravity * wave_number);
  return std::sqrt(gravity_ * wave_number * std::tanh(wave_number * depth_));
}

double SeaModel::group_speed(double wave_number, double omega) const {
  if (deep_) return 0.5 * gravity_ / omega;
  const double kh = wave_number * depth_;
  const double t = std::tanh(kh);
  return 0.5 * gravity_ * (t + kh * (1.0 - t * t)) / omega;
}

double SeaModel::depth_factor(double wave_number) const {
  if (deep_) return 1.0;
  const double kh = wave_number * depth_;
  const double t = std::tanh(kh);
  return t * t / (1.0 + 2.0 * kh / std::sinh(2.0 * kh));
}

double SeaModel::phillips_spectrum(double wave_number) const {
  // E(k) = 2 pi A (L_ref / L)^2 / dk^2 k^-3 exp(-1 / (k L_w)^2) exp(-k^2 l^2): the per-mode P integrated over
  // directions (pi D_s integrates to pi), doubled for the mirror mode, per unit area
  const double kl = wave_number * phillips_length_;
  return 2.0 * std::numbers::pi * phillips_amplitude_ / mode_area_ * std::exp(-1.0 / (kl * kl)) /
         (wave_number * wave_number * wave_number) *
         std::exp(-wave_number * wave_number * spectrum_damping_ * spectrum_damping_);
}

double SeaModel::sea_spectrum(double omega, double wave_number) const {
  return sea_.value(omega, sea_.depth_limited ? depth_factor(wave_number) : 1.0);
}

double SeaModel::wave_number_spectrum(double wave_number) const {
  if (!(wave_number > 0.0)) return 0.0;
  const double w = omega(wave_number);
  const double speed = group_speed(wave_number, w);
  double e = params_.spectrum == Spectrum::phillips ? phillips_spectrum(wave_number)
                                                    : sea_spectrum(w, wave_number) * speed;
  if (has_swell_) e += swell_.value(w, 1.0) * speed;
  return e;
}

double SeaModel::frequency_spectrum(double omega) const {
  if (!(omega > 0.0)) return 0.0;
  const double k =
      dispersion_wave_number(omega, deep_ ? std::numeric_limits<double>::infinity() : depth_, gravity_);
  return wave_number_spectrum(k) / group_speed(k, this->omega(k));
}

double SeaModel::sea_spreading(double omega, double cos_theta) const {
  const double cos_half_squared = std::max(0.0, 0.5 * (1.0 + cos_theta));
  const double ratio = omega / sea_peak_omega_;
  const double wave_age = wave_age_wind_ * sea_peak_omega_ / gravity_;  // U / c_p
  switch (params_.spreading_model) {
    case Spreading::cos2s:
      return spreading_norm_ * std::pow(cos_half_squared, static_cast<double>(params_.spreading));
    case Spreading::mitsuyasu:
    case Spreading::hasselmann: {
      double s = 0.0;
      if (params_.spreading_model == Spreading::mitsuyasu) {
        const double peak_s = mitsuyasu_peak_spreading * std::pow(wave_age, mitsuyasu_wave_age_exponent);
        s = peak_s * std::pow(ratio, ratio <= 1.0 ? mitsuyasu_exponent_below : mitsuyasu_exponent_above);
      } else if (ratio < 1.0) {
        s = hasselmann_below * std::pow(ratio, hasselmann_exponent_below);
      } else {
        s = hasselmann_above *
            std::pow(ratio, hasselmann_mu + hasselmann_mu_slope * (wave_age - hasselmann_mu_age));
      }
      return spreading_normalisation_log(s) * std::pow(cos_half_squared, s);
    }
    case Spreading::donelan_banner: {
      const double r = std::max(ratio, donelan_low);
      const double beta =
          r < donelan_mid ? donelan_rising * std::pow(r, donelan_exponent)
          : r < donelan_high
              ? donelan_falling * std::pow(r, -donelan_exponent)
              : std::pow(10.0, banner_offset + banner_scale * std::exp(banner_decay * std::log(r * r)));
      const double theta = std::acos(std::clamp(cos_theta, -1.0, 1.0));
      const double sech = 1.0 / std::cosh(beta * theta);
      return beta / (2.0 * std::tanh(beta * std::numbers::pi)) * sech * sech;
    }
  }
  return 0.0;
}

double SeaModel::mode_variance(double dir_x, double dir_y, double wave_number) const {
  const double k = wave_number;
  const double cos_theta = dir_x * wind_x_ + dir_y * wind_y_;
  double variance = 0.0;
  if (params_.spectrum == Spectrum::phillips) {
    // Tessendorf's P(k) = A exp(-1 / (k L_w)^2) / k^4 exp(-k^2 l^2) pi D(theta), A per unit area
    const double spread = params_.spreading_model == Spreading::cos2s
                              ? spreading_norm_ * std::pow(std::max(0.0, 0.5 * (1.0 + cos_theta)),
                                                           static_cast<double>(params_.spreading))
                              : sea_spreading(omega(k), cos_theta);
    const double kl = k * phillips_length_;
    variance = phillips_amplitude_ * std::exp(-1.0 / (kl * kl)) / (k * k * k * k) *
               std::exp(-k * k * damping_length_ * damping_length_) * std::numbers::pi * spread;
    if (!has_swell_) return variance;
  }
  const double w = omega(k);
  const double speed = group_speed(k, w);
  if (params_.spectrum != Spectrum::phillips) {
    variance = 0.5 * sea_spectrum(w, k) * speed * sea_spreading(w, cos_theta) / k * mode_area_;
  }
  if (has_swell_) {
    const double cos_swell = dir_x * swell_x_ + dir_y * swell_y_;
    const double spread = swell_norm_ * std::pow(std::max(0.0, 0.5 * (1.0 + cos_swell)),
                                                 static_cast<double>(params_.swell.spreading));
    variance += 0.5 * swell_.value(w, 1.0) * speed * spread / k * mode_area_;
  }
  return variance;
}

double SeaModel::lowest_peak_wave_number() const {
  const double infinite = std::numeric_limits<double>::infinity();
  const double h = deep_ ? infinite : depth_;
  double k = dispersion_wave_number(sea_peak_omega_, h, gravity_);
  if (has_swell_) k = std::min(k, dispersion_wave_number(swell_.peak_omega, h, gravity_));
  return k;
}

double SeaModel::highest_peak_wave_number() const {
  const double h = deep_ ? std::numeric_limits<double>::infinity() : depth_;
  double k = dispersion_wave_number(sea_peak_omega_, h, gravity_);
  if (has_swell_) k = std::max(k, dispersion_wave_number(swell_.peak_omega, h, gravity_));
  return k;
}

}  // namespace detail

float beaufort_wind_speed(int force) {
  if (force < 0 || force > max_beaufort)
    throw std::invalid_argument("Beaufort force must be in [0, " + std::to_string(max_beaufort) + "]");
  if (force == 0) return min_wind_speed;
  return float(wmo_beaufort * std::pow(double(force), 1.5));
}

double dispersion_omega(double wave_number, double depth, double gravity) {
  if (!std::isfinite(depth)) return std::sqrt(gravity * wave_number);
  return std::sqrt(gravity * wave_number * std::tanh(wave_number * depth));
}

double dispersion_wave_number(double omega, double depth, double gravity) {
  const double deep = omega * omega / gravity;
  if (!std::isfinite(depth) || !(omega > 0.0)) return deep;
  // Eckart's estimate k h = y / sqrt(tanh y), y = w^2 h / g, then Newton on g k tanh(k h) - w^2
  const double y = deep * depth;
  double k = y / std::sqrt(std::tanh(y)) / depth;
  for (int iteration = 0; iteration < 50; ++iteration) {
    const double t = std::tanh(k * depth);
    const double residual = gravity * k * t - omega * omega;
    const double slope = gravity * (t + k * depth * (1.0 - t * t));
    const double step = residual / slope;
    k -= step;
    if (std::abs(step) <= 1e-15 * k) break;
  }
  return k;
}

SeaSpectrum::SeaSpectrum(const OceanParams& params) {
  detail::validate_ocean(params);
  model_ = std::make_unique<detail::SeaModel>(params);
}
SeaSpectrum::~SeaSpectrum() = default;
SeaSpectrum::SeaSpectrum(SeaSpectrum&&) noexcept = default;
SeaSpectrum& SeaSpectrum::operator=(SeaSpectrum&&) noexcept = default;

double SeaSpectrum::frequency(double omega) const { return model_->frequency_spectrum(omega); }
double SeaSpectrum::wave_number(double wave_number) const {
  return model_->wave_number_spectrum(wave_number);
}
double SeaSpectrum::spreading(double omega, double theta) const {
  return model_->sea_spreading(omega, std::cos(theta));
}
double SeaSpectrum::omega(double wave_number) const { return model_->omega(wave_number); }

SeaState describe_sea(const OceanParams& params) {
  detail::validate_ocean(params);
  const detail::SeaModel model(params);
  const double infinite = std::numeric_limits<double>::infinity();
  const double depth = std::isfinite(params.depth) ? double(params.depth) : infinite;
  const double g = params.gravity;

  // E(k) on a grid in ln k, and its running integral (trapezoids)
  const double low = 1e-3 * model.lowest_peak_wave_number();
  const double high = 1e4 * model.highest_peak_wave_number();
  const double span = std::log(high / low);
  const int steps = std::max(2, int(std::ceil(span * integral_steps_per_unit)));
  const double step = span / steps;
  std::vector<double> log_k(steps + 1), cumulative(steps + 1, 0.0), spectrum(steps + 1);
  for (int i = 0; i <= steps; ++i) {
    log_k[i] = std::log(low) + i * step;
    const double k = std::exp(log_k[i]);
    spectrum[i] = model.wave_number_spectrum(k) * k;  // per unit of ln k
    if (i > 0) cumulative[i] = cumulative[i - 1] + 0.5 * step * (spectrum[i] + spectrum[i - 1]);
  }
  const double m0 = cumulative.back();
  auto below = [&](double k) {  // integral of E over (0, k)
    const double at = (std::log(k) - log_k[0]) / step;
    if (at <= 0.0) return 0.0;
    if (at >= steps) return m0;
    const int i = int(at);
    return cumulative[i] + (at - i) * (cumulative[i + 1] - cumulative[i]);
  };
  auto wave_number_at = [&](double share) {  // the k below which `share` of m0 lies
    const auto it = std::lower_bound(cumulative.begin(), cumulative.end(), share * m0);
    const int i = std::clamp(int(it - cumulative.begin()), 1, steps);
    const double part =
        (share * m0 - cumulative[i - 1]) / std::max(cumulative[i] - cumulative[i - 1], 1e-300);
    return std::exp(log_k[i - 1] + std::clamp(part, 0.0, 1.0) * step);
  };

  SeaState state;
  state.significant_height = 4.0 * std::sqrt(m0);
  // the peak of S(w) = E(k) / c_g, refined by a parabola in ln w
  std::vector<double> s_of_w(steps + 1), log_w(steps + 1);
  int peak = 0;
  for (int i = 0; i <= steps; ++i) {
    const double k = std::exp(log_k[i]);
    const double w = model.omega(k);
    log_w[i] = std::log(w);
    s_of_w[i] = spectrum[i] / k / model.group_speed(k, w);
    if (s_of_w[i] > s_of_w[peak]) peak = i;
  }
  double peak_log_w = log_w[peak];
  if (peak > 0 && peak < steps) {
    const double a = s_of_w[peak - 1], b = s_of_w[peak], c = s_of_w[peak + 1];
    const double curvature = a - 2.0 * b + c;
    if (curvature < 0.0) {
      const double shift = std::clamp(0.5 * (a - c) / curvature, -1.0, 1.0);
      peak_log_w += shift * (shift > 0.0 ? log_w[peak + 1] - log_w[peak] : log_w[peak] - log_w[peak - 1]);
    }
  }
  const double peak_omega = std::exp(peak_log_w);
  state.peak_period = 2.0 * std::numbers::pi / peak_omega;
  state.peak_wavelength = 2.0 * std::numbers::pi / dispersion_wave_number(peak_omega, depth, g);

  // what the lattice holds
  const double root_pi = std::sqrt(std::numbers::pi);
  const int n = params.size;
  const double patch = params.patch_size;
  auto below_share = [&](double patch_size) {
    return m0 > 0.0 ? below(2.0 * root_pi / patch_size) / m0 : 0.0;
  };
  auto above_share = [&](double patch_size, int size) {
    return m0 > 0.0 ? 1.0 - below(2.0 * root_pi * (size - 1) / patch_size) / m0 : 0.0;
  };
  // the lattice's variance over the spectrum's between its bounds, less 1; the lattice's variance
  auto lattice_error = [&](double patch_size, int size, double* variance) {
    OceanParams lattice_params = params;
    lattice_params.patch_size = float(patch_size);
    lattice_params.size = size;
    const detail::SeaModel lattice_model(lattice_params);  // its modes' areas
    const double dk = 2.0 * std::numbers::pi / patch_size;
    std::vector<double> rows(std::size_t(size), 0.0);
    tbb::parallel_for(tbb::blocked_range<int>(0, size), [&](const tbb::blocked_range<int>& range) {
      for (int i = range.begin(); i != range.end(); ++i) {
        if (i == size / 2) continue;
        const int lattice_y = i < size / 2 ? i : i - size;
        double sum = 0.0;
        for (int j = 0; j < size; ++j) {
          if (j == size / 2) continue;
          const int lattice_x = j < size / 2 ? j : j - size;
          const double kx = lattice_x * dk, ky = lattice_y * dk;
          const double k = std::hypot(kx, ky);
          if (k == 0.0) continue;
          sum += lattice_model.mode_variance(-kx / k, -ky / k, k);
        }
        rows[std::size_t(i)] = sum;
      }
    });
    double lattice = 0.0;  // summed in order: the same on any number of threads
    for (double row : rows) lattice += row;
    lattice *= 2.0;  // each mode's mirror
    if (variance) *variance = lattice;
    const double band = m0 * (1.0 - below_share(patch_size) - above_share(patch_size, size));
    return band > 0.0 ? lattice / band - 1.0 : 0.0;
  };
  state.below_patch = below_share(patch);
  state.above_map = above_share(patch, n);
  double lattice = 0.0;
  state.lattice_error = lattice_error(patch, n, &lattice);
  state.lattice_significant_height = 4.0 * std::sqrt(lattice);

  // the patch that would do: half the allowance below, min_peak_wavelengths peak wavelengths, and a
  // lattice within half the allowance (checked on at most probe_size samples: the error is the peak's)
  constexpr int probe_size = 256;
  constexpr double patch_step = 1.25;
  constexpr int patch_tries = 16;
  state.patch_needed = std::max(2.0 * root_pi / wave_number_at(0.5 * left_out_allowance),
                                min_peak_wavelengths * state.peak_wavelength);
  for (int attempt = 0; attempt < patch_tries; ++attempt) {
    const int size = std::min(n, probe_size);
    if (std::abs(lattice_error(state.patch_needed, size, nullptr)) <= 0.5 * left_out_allowance) break;
    state.patch_needed *= patch_step;
  }

  // the verdicts, and the map that would do at the patch that would
  const double left_out = state.below_patch + state.above_map;
  const bool lattice_off = std::abs(state.lattice_error) > left_out_allowance;
  state.patch_too_small = (left_out > left_out_allowance && state.below_patch > 0.5 * left_out_allowance) ||
                          (lattice_off && patch < state.patch_needed);
  state.map_too_coarse = (left_out > left_out_allowance && state.above_map > 0.5 * left_out_allowance) ||
                         (lattice_off && patch >= state.patch_needed);
  const double patch_then = state.patch_too_small ? state.patch_needed : patch;
  const double size = 1.0 + wave_number_at(1.0 - 0.5 * left_out_allowance) * patch_then / (2.0 * root_pi);
  const double even_size = 2.0 * std::ceil(std::min(size, 1e9) / 2.0);
  state.size_needed = int(std::max(even_size, double(min_ocean_size)));
  return state;
}

}  // namespace displace::sim
