// sim/sim.h - height-field synthesis. The whole public API of the sim stage.
//
// No file I/O and no Vulkan: callers pass output memory and the functions fill it.
//
// Units and conventions
// - A height field is a W x H grid stored row-major: sample (i, j) is row i, column j, at
//   data[i * W + j]. Row i runs along v, column j along u; the sample sits at the texel centre
//   u = (j + 0.5) / W, v = (i + 0.5) / H of a patch that is `patch_size` metres wide in both u and v.
// - Raw heights are in metres, positive up.
// - The baker and the renderer want heights in [0, 1] with 1 = top. HeightMapping turns raw
//   heights into that range; for animated sources the mapping is derived from the source's
//   parameters (spectrum, amplitudes), never from one frame, so that it is fixed over time.
#pragma once

#include <complex>
#include <cstdint>
#include <limits>
#include <memory>
#include <span>
#include <vector>

namespace displace::sim {

// h01 = clamp(raw * scale + bias, 0, 1). Records how a source range became [0, 1] (the SCALE/BIAS of
// Premecz's iterative parallax mapping, inverted).
struct HeightMapping {
  float scale = 1.0f;
  float bias = 0.0f;
};

// Applies the mapping to `raw` in place of `out` (same length). Returns how many samples were clamped.
std::size_t apply_mapping(const HeightMapping& mapping, std::span<const float> raw, std::span<float> out);

// Limits the parameter checks below hold every caller to (a front end bounds its input with them too).
inline constexpr float min_patch_size = 0.01f;  // metres, SinusoidParams and OceanParams::patch_size
inline constexpr float max_patch_size = 1e5f;   // metres

// ---------------------------------------------------------------------------------------------
// Sinusoid water (Chen & Chuang's dynamic displacement example): a seeded sum of directional
// sinusoids h(x, t) = sum_i a_i sin(k_i . x - w_i t + phi_i), deep-water dispersion w_i^2 = g |k_i|.
inline constexpr int max_wave_count = 4096;   // SinusoidParams::wave_count, from 1
inline constexpr float max_steepness = 1.0f;  // SinusoidParams::steepness, in (0, max_steepness]

struct SinusoidParams {
  int wave_count = 12;
  float patch_size = 4.0f;        // metres covered by the map along u and along v
  float wavelength_min = 0.25f;   // metres
  float wavelength_max = 1.5f;    // metres
  float steepness = 0.4f;         // a_i * |k_i| summed over waves stays below this (no overhangs)
  float wind_direction = 0.0f;    // radians, azimuth of the mean travel direction in (u, v)
  float direction_spread = 1.0f;  // radians, half-width of the uniform spread around wind_direction
  std::uint64_t seed = 1;
  bool tileable = true;   // snap wave vectors to the patch lattice so the field tiles
  float gravity = 9.81f;  // m/s^2
};

struct Wave {
  float kx, ky;     // wave vector, radians per metre
  float amplitude;  // metres
  float omega;      // radians per second
  float phase;      // radians
};

// Deterministic for a given seed. Throws std::invalid_argument on absurd parameters.
std::vector<Wave> make_sinusoid_waves(const SinusoidParams& params);

// Closed-form height in metres at a point (x, y in metres) and time t (seconds).
float sinusoid_height_at(std::span<const Wave> waves, float x, float y, double time);

// Fills out (width * height) with raw heights at the texel centres of a patch `patch_size` wide.
void sinusoid_heights(std::span<const Wave> waves, float patch_size, double time, int width, int height,
                      std::span<float> out);

// bias 0.5, scale 0.5 / sum(amplitudes): never clamps, fixed over time.
HeightMapping sinusoid_mapping(std::span<const Wave> waves);

// ---------------------------------------------------------------------------------------------
// FFT ocean (Tessendorf, "Simulating Ocean Water") with the sea spectra of oceanography
// (sim/sea_spectrum.cpp; sources and formulas in docs/design/sim.md):
// - phillips: Tessendorf's shape, its amplitude per unit area (Hs does not depend on the patch);
// - pierson_moskowitz: the fully developed sea of a wind (Pierson & Moskowitz 1964);
// - jonswap: the fetch-limited sea (Hasselmann et al. 1973), its growth capped where it is fully developed;
// - tma: jonswap times Kitaigorodskii's depth function (Bouws et al. 1985), for finite depth.
enum class Spectrum { phillips, jonswap, pierson_moskowitz, tma };

// Directional spreading D(theta; w) about the mean direction, each integrating to 1 over theta:
// cos2s: cos^(2s)(theta / 2) with a fixed s (OceanParams::spreading); mitsuyasu (Mitsuyasu et al. 1975) and
// hasselmann (Hasselmann et al. 1980): cos^(2s)(theta / 2) with s following w / w_p and the wave age;
// donelan_banner: sech^2(beta theta) (Donelan et al. 1985, Banner 1990 above 1.6 w_p).
enum class Spreading { cos2s, mitsuyasu, hasselmann, donelan_banner };

inline constexpr int min_ocean_size = 2;             // OceanParams::size, samples a side, even
inline constexpr int max_ocean_size = 8192;          // samples a side
inline constexpr float min_wind_speed = 0.1f;        // m/s, OceanParams::wind_speed
inline constexpr float max_wind_speed = 100.0f;      // m/s
inline constexpr float min_fetch = 0.1f;             // km, OceanParams::fetch
inline constexpr float max_fetch = 1e5f;             // km
inline constexpr float max_spreading = 100.0f;       // OceanParams::spreading, exponent s, from 0
inline constexpr float max_choppiness = 10.0f;       // OceanParams::choppiness, lambda, from 0
inline constexpr float min_peak_enhancement = 1.0f;  // OceanParams::peak_enhancement, JONSWAP gamma
inline constexpr float max_peak_enhancement = 20.0f;
inline constexpr double min_loop_seconds = 0.1;         // OceanParams::loop_seconds, when not 0
inline constexpr double max_loop_seconds = 1e6;         // seconds
inline constexpr float min_depth = 0.1f;                // metres, OceanParams::depth when finite
inline constexpr float max_depth = 1e4f;                // metres (deeper: leave it infinite)
inline constexpr float min_significant_height = 1e-3f;  // metres, OceanParams and SwellParams, when set
inline constexpr float max_significant_height = 50.0f;  // metres
inline constexpr float min_peak_period = 0.1f;          // seconds, OceanParams and SwellParams, when set
inline constexpr float max_peak_period = 60.0f;         // seconds
inline constexpr int max_beaufort = 12;                 // Beaufort force, from 0
// Tessendorf's amplitude A is the per-mode variance scale of a patch this wide (metres); other patches
// scale it by their mode area, so that the spectral density, and with it Hs, stays the same.
inline constexpr float phillips_reference_patch = 200.0f;

// A swell: a narrow, long-period sea made elsewhere (a JONSWAP shape with a sharp peak, cos^(2s)
// spreading about its own direction), added to the local sea. Only computed when present.
struct SwellParams {
  float significant_height = 0.0f;  // metres, Hs of the swell alone; 0: no swell
  float peak_period = 12.0f;        // seconds
  float direction = 0.0f;           // radians, azimuth in (u, v) the swell travels towards
  float spreading = 24.0f;          // exponent s of cos^(2s)(theta / 2), in [0, max_spreading]
};

struct OceanParams {
  int size = 256;             // N x N grid, N even in [min_ocean_size, max_ocean_size]
  float patch_size = 200.0f;  // metres
  Spectrum spectrum = Spectrum::phillips;
  float wind_speed = 12.0f;       // m/s at 10 m
  float wind_direction = 0.0f;    // radians, azimuth in (u, v): the sea's mean direction
  float fetch = 200.0f;           // km, jonswap and tma
  float peak_enhancement = 3.3f;  // JONSWAP gamma (jonswap, tma)
  float spreading = 2.0f;         // directional spreading exponent s of cos^(2s)(theta / 2) (cos2s)
  Spreading spreading_model = Spreading::cos2s;
  float phillips_amplitude = 3e-7f;  // Tessendorf's A for a patch of phillips_reference_patch metres
  float small_wave_cutoff = 0.0f;    // metres; Phillips damping length l (0 = patch/N/2, a filter of the
                                     // lattice's shortest waves that SeaSpectrum and describe_sea leave out)
  float choppiness = 1.0f;           // lambda, scales the horizontal displacement; > 0 sharpens crests
  std::uint64_t seed = 1;
  float gravity = 9.81f;  // m/s^2
  // Water depth in metres (finite: [min_depth, max_depth]); infinity: deep water. Every spectrum's
  // modes follow w^2 = g k tanh(k h); tma also takes its energy from it.
  float depth = std::numeric_limits<float>::infinity();
  // pierson_moskowitz, jonswap, tma: the sea by its significant height (m) and peak period (s) instead of
  // wind_speed and fetch; both 0 (the wind's sea) or both set.
  float significant_height = 0.0f;
  float peak_period = 0.0f;
  SwellParams swell;
  // A seamless loop of this many seconds (0: none): every mode's angular frequency is rounded to the
  // nearest multiple of 2 pi / loop_seconds (Ocean::loop_error says how far that moved them), and
  // time is taken modulo loop_seconds, so heights at t and t + loop_seconds are equal bit for bit.
  double loop_seconds = 0.0;
};

// The wind speed (m/s at 10 m) of Beaufort force 0-12: the WMO's v = 0.836 B^(3/2) (force 0: the
// least wind speed). Throws std::invalid_argument outside [0, max_beaufort].
float beaufort_wind_speed(int force);

// Linear dispersion in water `depth` metres deep (infinity: deep water): w(k) = sqrt(g k tanh(k h)) in
// rad/s for a wave number k in rad/m, and its inverse k(w) (Newton's method, to double precision).
double dispersion_omega(double wave_number, double depth, double gravity);
double dispersion_wave_number(double omega, double depth, double gravity);

namespace detail {
class SeaModel;
}

// The analytic sea an Ocean of the same parameters draws its modes from (sea and swell).
class SeaSpectrum {
 public:
  // Validates the parameters as Ocean does (throws std::invalid_argument).
  explicit SeaSpectrum(const OceanParams& params);
  ~SeaSpectrum();
  SeaSpectrum(SeaSpectrum&&) noexcept;
  SeaSpectrum& operator=(SeaSpectrum&&) noexcept;

  // The one-sided frequency spectrum S(w), m^2 s / rad: its integral over w > 0 is the height variance m0.
  double frequency(double omega) const;
  // The wave-number spectrum E(k) = S(w) dw/dk, m^2 per rad/m, k in rad/m.
  double wave_number(double wave_number) const;
  // The sea's directional spreading D(theta; w), 1/rad, theta from wind_direction (the swell's spreading
  // is its own cos^(2s) about its direction).
  double spreading(double omega, double theta) const;
  // w(k) at the depth, rad/s.
  double omega(double wave_number) const;

 private:
  std::unique_ptr<detail::SeaModel> model_;
};

// What sea the parameters make, and how much of it the patch and the map hold. The lattice of a patch L
// with N samples a side holds wave numbers between 2 sqrt(pi) / L and 2 sqrt(pi) (N - 1) / L (the radii of
// circles with the areas of the missing k = 0 cell and of the lattice's square); a patch a few peak
// wavelengths wide samples the peak so coarsely that its modes hold more or less than the spectrum has.
struct SeaState {
  double significant_height = 0.0;          // metres, 4 sqrt(m0) of the analytic spectrum (sea and swell)
  double peak_period = 0.0;                 // seconds, 2 pi / w at the maximum of S(w)
  double peak_wavelength = 0.0;             // metres, 2 pi / k at that w and the depth
  double lattice_significant_height = 0.0;  // metres, 4 sqrt of the variance the lattice's modes hold (the
                                            // mean over seeds of what the ocean synthesizes)
  double below_patch = 0.0;                 // share of m0 in waves longer than the patch holds
  double above_map = 0.0;                   // share of m0 in waves shorter than the map holds
  double lattice_error = 0.0;  // the lattice's variance over the spectrum's between those bounds, less 1
  // below_patch + above_map > left_out_allowance with below_patch (above_map) more than half of it, or
  // |lattice_error| > left_out_allowance: the patch's when it is narrower than patch_needed, else the map's
  bool patch_too_small = false;
  bool map_too_coarse = false;
  // metres: a patch that leaves at most half the allowance below, is min_peak_wavelengths peak
  // wavelengths wide and whose lattice is within half the allowance (1.25 times wider until it is)
  double patch_needed = 0.0;
  int size_needed = 0;  // samples a side (even) that leave at most half the allowance above, at
                        // patch_needed when patch_too_small, else at patch_size
};
inline constexpr double left_out_allowance = 0.05;  // share of m0 a patch and map may leave out together
inline constexpr double min_peak_wavelengths =
    4.0;  // the least patch describe_sea suggests, in peak wavelengths
SeaState describe_sea(const OceanParams& params);

// Outputs beyond heights are computed only when requested; requesting none costs nothing.
enum OceanOutput : unsigned {
  ocean_heights = 1u << 0,
  ocean_slopes = 1u << 1,        // dh/dx, dh/dy (spectral derivatives)
  ocean_displacement = 1u << 2,  // choppy horizontal displacement dx, dy (metres):
                                 // D = lambda sum_k i k/|k| h~(k, t) exp(i k.x), Gerstner-like
  ocean_foam = 1u << 3,          // Jacobian determinant of the choppy map (foam where < threshold)
};

struct OceanFrame {
  int size = 0;
  std::vector<float> height;                          // metres, size*size, when ocean_heights requested
  std::vector<float> slope_x, slope_y;                // when ocean_slopes requested
  std::vector<float> displacement_x, displacement_y;  // when ocean_displacement requested
  std::vector<float> jacobian;                        // when ocean_foam requested
};

class Ocean {
 public:
  // Validates the parameters (throws std::invalid_argument with a clear message), draws the
  // Gaussian spectrum amplitudes h0 from the seed and creates single-precision FFTW plans once.
  explicit Ocean(const OceanParams& params);
  ~Ocean();
  Ocean(Ocean&&) noexcept;
  Ocean& operator=(Ocean&&) noexcept;
  Ocean(const Ocean&) = delete;
  Ocean& operator=(const Ocean&) = delete;

  // Computes the requested outputs at time t (seconds, double: phases w t are formed in double, so
  // frames 1/60 s apart stay distinct and correct at t = 1e9 s), independently of any other frame.
  void evaluate(double time, unsigned outputs, OceanFrame& frame);

  int size() const;
  float patch_size() const;
  const OceanParams& params() const;

  // Expected height variance (m^2) over the ensemble, from the spectrum amplitudes.
  double height_variance() const;
  // Maps +-3 standard deviations of the spectrum's height onto [0, 1]; fixed over time.
  HeightMapping mapping() const;

  // Fourier coefficients h~(k, t) of the height at time t, N*N complex values in FFTW's
  // unshifted order (index (i, j) holds wave numbers (ky, kx) = 2 pi / L * (i', j') with
  // i' = i < N/2 ? i : i - N). height(x) = sum_k h~(k, t) exp(i k.x) with x in metres from the patch
  // corner, so output sample (i, j) is this sum at its texel centre x = ((j + 0.5) L / N, (i + 0.5) L / N).
  // The Nyquist row and column (i or j = N/2) and k = 0 are zero, so the sum is real.
  std::vector<std::complex<float>> height_spectrum(double time) const;
  // Angular frequency w(k) = sqrt(g |k| tanh(|k| h)) of the mode at index (i, j) (sqrt(g |k|) in deep water).
  float omega(int i, int j) const;

  // The half spectrum evaluate() transforms, for a caller that evaluates it elsewhere (the device
  // ocean, sim/device/device_sim.h): N x (N/2 + 1) modes, row i (wave numbers along y, unshifted order),
  // column j (along x), h~(t) = (p c + q s) + i (r c + u s) with (c, s) = (cos, sin)(w t) and the
  // half-texel shift folded in, so that the inverse FFT gives the heights at the texel centres.
  struct HalfSpectrum {
    std::vector<float> coefficients;  // (p, q, r, u) per mode
    std::vector<float> omega;         // w per mode, rad/s
  };
  HalfSpectrum half_spectrum() const;

  // Work counter: inverse FFTs executed since construction.
  long long fft_count() const;
  // With params().loop_seconds: the largest relative change |w_q - w| / w the loop's quantisation made
  // to a mode that carries energy (0 without a loop).
  double loop_error() const;
  // The time the spectrum is evaluated at: `time` modulo loop_seconds (in [0, loop_seconds)), or
  // `time` itself without a loop.
  double loop_time(double time) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// ---------------------------------------------------------------------------------------------
// Procedural test reliefs, made directly in [0, 1] (their mapping is the identity): a brick wall
// and a cliff with single-texel spikes. Both tile; seeded roughness. Throw std::invalid_argument
// when out does not hold width x height samples.
void brick_heights(int width, int height, std::uint64_t seed, std::span<float> out);
void cliff_heights(int width, int height, std::uint64_t seed, std::span<float> out);

// ---------------------------------------------------------------------------------------------
// Choppy waves back onto the grid (sim/choppy.cpp). The choppy ocean moves the surface point of
// grid position p to p + D(p) (D = OceanFrame::displacement, metres) at height h(p); a height field
// needs the height above each grid position x instead: h(p) for the p with p + D(p) = x. Found per
// texel centre by Newton's method on p + D(p) - x (D bilinear, periodic; its Jacobian from the same
// four texels), with the fixed-point step p <- x - D(p) where the map's Jacobian determinant is below
// 0.2 (a folding crest, or near one; where it folds, the last p is used). Rows go in fixed groups
// of 16: the first row starts from p = x, each next one from the row before's p moved by its
// predicted change (J^-1 (0, 1)). At most `iterations` steps; with `settle` > 0 (texels) a block of
// neighbouring texels stops once every texel's residual |p + D(p) - x| is within `settle` (on the
// water scene's ocean most blocks after one step); 0 runs every step. Deterministic either way (the
// groups do not depend on the threads); the result stays periodic. Returns the largest residual in
// metres at the p used.
// `extra` (optional, e.g. the Jacobian for foam) is resampled through the same p into `extra_out`.
double resample_displaced(int size, float patch_size, std::span<const float> height,
                          std::span<const float> displacement_x, std::span<const float> displacement_y,
                          int iterations, std::span<float> out, std::span<const float> extra = {},
                          std::span<float> extra_out = {}, float settle = 0.0f);

}  // namespace displace::sim
