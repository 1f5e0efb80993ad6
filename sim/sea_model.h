// sim/sea_model.h - internal to sim/: the sea behind sim.h's Ocean, frequency_spectrum, directional_spreading
// and describe_sea (sim/sea_spectrum.cpp). Not installed.
#pragma once

#include "sim/sim.h"

namespace displace::sim::detail {

// Throws std::invalid_argument ("OceanParams: ...") on parameters the ocean cannot make a sea of.
void validate_ocean(const OceanParams& params);

// S(w) = scale w^-5 exp(-5/4 (w_p / w)^4) gamma^r(w), r = exp(-(w - w_p)^2 / (2 sigma^2 w_p^2)) (sigma 0.07
// below the peak, 0.09 above): Pierson-Moskowitz's shape for gamma = 1, JONSWAP's otherwise; times
// Kitaigorodskii's depth function when depth_limited (TMA).
struct PeakedSpectrum {
  double scale = 0.0;       // alpha g^2, m^2 s^-4
  double peak_omega = 0.0;  // w_p, rad/s
  double gamma = 1.0;
  bool depth_limited = false;
  // S(w) in m^2 s / rad, given the depth factor phi (1 in deep water or without depth_limited)
  double value(double omega, double phi) const;
};

class SeaModel {
 public:
  // Expects validated parameters.
  explicit SeaModel(const OceanParams& params);

  const OceanParams& params() const { return params_; }
  bool deep() const { return deep_; }
  // w(k) = sqrt(g k tanh(k h)), sqrt(g k) in deep water, rad/s
  double omega(double wave_number) const;
  // the group speed dw/dk, m/s
  double group_speed(double wave_number, double omega) const;
  // Kitaigorodskii's Phi(w, h) at the wave number k of w: tanh^2(k h) / (1 + 2 k h / sinh(2 k h))
  double depth_factor(double wave_number) const;

  // The one-dimensional wave-number spectrum E(k) of sea and swell, m^2 per rad/m: its integral over
  // k > 0 is the height variance m0.
  double wave_number_spectrum(double wave_number) const;
  // S(w), m^2 s / rad, of sea and swell.
  double frequency_spectrum(double omega) const;
  // The sea's D(theta; w) about the wind, 1/rad; cos_theta = cos(theta), passed to keep cos2s exact.
  double sea_spreading(double omega, double cos_theta) const;
  // Per-mode variance P(k) = E|h0(k)|^2 of the lattice mode of wave number `wave_number` travelling along
  // the unit vector (dir_x, dir_y): half the variance density E D / k times the mode area.
  double mode_variance(double dir_x, double dir_y, double wave_number) const;
  // The sea's peak w_p (rad/s) that the frequency-dependent spreadings scale with.
  double sea_peak_omega() const { return sea_peak_omega_; }
  // The lowest and highest peak wave numbers of sea and swell (rad/m): where describe_sea integrates.
  double lowest_peak_wave_number() const;
  double highest_peak_wave_number() const;

 private:
  double phillips_spectrum(double wave_number) const;           // E(k) of the Phillips sea
  double sea_spectrum(double omega, double wave_number) const;  // S(w) of the sea (not Phillips)

  OceanParams params_;
  bool deep_ = true;
  double gravity_ = 9.81;
  double depth_ = 0.0;
  double mode_area_ = 0.0;  // dk^2, (rad/m)^2
  double wind_x_ = 1.0, wind_y_ = 0.0;
  double spreading_norm_ = 0.0;  // cos2s: G(s)
  // phillips
  double phillips_amplitude_ = 0.0;  // A (L_ref / L)^2, per mode
  double phillips_length_ = 0.0;     // L_w = U^2 / g, metres
  double damping_length_ = 0.0;      // l of the lattice's modes, metres (small_wave_cutoff, or half a texel)
  double spectrum_damping_ = 0.0;    // l of the analytic spectrum: small_wave_cutoff only, metres
  // the other spectra
  PeakedSpectrum sea_;
  double sea_peak_omega_ = 0.0;
  double wave_age_wind_ = 0.0;  // U10 (m/s) the spreadings' wave age U w_p / g takes
  // swell
  bool has_swell_ = false;
  PeakedSpectrum swell_;
  double swell_x_ = 1.0, swell_y_ = 0.0;
  double swell_norm_ = 0.0;
};

}  // namespace displace::sim::detail
