// sim/fft_ocean.cpp - FFT ocean after Tessendorf, "Simulating Ocean Water" (SIGGRAPH course notes):
// h(x, t) = sum_k h~(k, t) exp(i k.x), h~(k, t) = h0(k) e^{i w t} + conj(h0(-k)) e^{-i w t}.
// The one fact to know: the sum is taken at the texel centres x_j = (j + 1/2) L / N, so the FFT input is
// h~ times the half-texel phase exp(i pi (m + n) / N); h~ itself (height_spectrum) is in world positions.
//
// - Each grid is the Hermitian half spectrum N x (N/2 + 1), inverted by FFTW plans made once per Ocean and
//   executed on several buffers (new-array execute): c2c along y, then c2r along x. The Nyquist row and
//   column and k = 0 are zero, so the field is exactly real and the plain sum over the grid holds.
// - h0(k) e^{i(k.x + w t)} travels towards -k, so h0(k) takes its variance from the spectrum at -k; with
//   the one-sided spreading cos^{2s}(theta / 2) the waves then run with the wind.
// - Choppy displacement is D = lambda sum i k/|k| h~ exp(i k.x): Tessendorf's -i k/|k| with the sign of
//   lambda flipped, so that a positive choppiness sharpens crests as Gerstner waves do (and the Jacobian
//   drops below 1 at crests, where foam belongs).
// - Spectra are per-mode variances P(k) = E|h0(k)|^2 drawn from the sea of sim/sea_spectrum.cpp (Phillips,
//   Pierson-Moskowitz, JONSWAP, TMA; a swell), w^2 = g |k| tanh(|k| h): docs/design/sim.md
#include <fftw3.h>
#include <tbb/blocked_range.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <complex>
#include <cstring>
#include <mutex>
#include <new>
#include <numbers>
#include <stdexcept>

#include "displace/simd_clones.h"
#include "sim/sea_model.h"
#include "sim/sim.h"

namespace displace::sim {
namespace {

constexpr float fast_phase_limit = 1.0e5f;    // radians; above, phases are reduced in double
constexpr int spectrum_rows_per_task = 8;     // rows of the half spectrum per TBB task
constexpr int max_fft_chunks = 16;            // most pieces each FFT pass is cut into for TBB
constexpr std::size_t buffer_alignment = 64;  // bytes, FFTW SIMD alignment and a cache line

// FFTW's planner is not thread safe; plans are only made and destroyed under this lock.
std::mutex& fftw_planner_mutex() {
  static std::mutex mutex;
  return mutex;
}

struct AlignedDeleter {
  void operator()(void* memory) const { ::operator delete(memory, std::align_val_t(buffer_alignment)); }
};
template <typename T>
using AlignedArray = std::unique_ptr<T[], AlignedDeleter>;

template <typename T>
AlignedArray<T> make_aligned(std::size_t count) {
  return AlignedArray<T>(
      static_cast<T*>(::operator new(count * sizeof(T), std::align_val_t(buffer_alignment))));
}

std::uint64_t mix64(std::uint64_t z) {
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

// Two independent standard normals for the mode with signed wave numbers (m, n): splitmix64 keyed
// by (seed, m, n), then Box-Muller, so a mode's draw depends on neither N nor the order of evaluation.
std::complex<double> gaussian_pair(std::uint64_t seed, int m, int n) {
  const std::uint64_t key =
      (static_cast<std::uint64_t>(static_cast<std::uint32_t>(m)) << 32) | static_cast<std::uint32_t>(n);
  std::uint64_t state = mix64(seed + 0x9e3779b97f4a7c15ull) ^ key;
  auto uniform = [&state] {
    state += 0x9e3779b97f4a7c15ull;
    return static_cast<double>(mix64(state) >> 11) * 0x1.0p-53;
  };
  const double radius = std::sqrt(-2.0 * std::log(1.0 - uniform()));
  const double angle = 2.0 * std::numbers::pi * uniform();
  return std::polar(radius, angle);
}

// A float split into a high part with 12 significant bits and the exact remainder, so that the product
// of two high parts is exact in float. Bit masking keeps it exact under any contraction setting.
struct SplitFloat {
  float high, low;
};
inline SplitFloat split_float(float value) {
  constexpr std::uint32_t keep_high_bits = 0xfffff000u;  // sign, exponent, 11 of 23 mantissa bits
  const float high = std::bit_cast<float>(std::bit_cast<std::uint32_t>(value) & keep_high_bits);
  return {high, value - high};
}
// A double time the same way: the high part's 12 bits, then the rest of the double rounded to float
// (about 36 significant bits in all, so that a frame time like 100 + 1/60 s keeps its fraction).
inline SplitFloat split_time(double value) {
  const SplitFloat high = split_float(static_cast<float>(value));
  return {high.high, static_cast<float>(value - static_cast<double>(high.high))};
}

// sin and cos of w t for |w t| <= fast_phase_limit. The product is formed from split halves (its high part
// exact), reduced by pi/2 in three Cody-Waite steps, and fed to Cephes' minimax polynomials (about 1 ulp on
// [-pi/4, pi/4]); the phase error stays near 1e-6 rad where a plain float product would be off by
// ulp(w t) / 2. Branch-free, so the calling loop vectorises.
inline void phase_sincos(float omega_high, float omega_low, SplitFloat time, float& sin_out, float& cos_out) {
  constexpr float two_over_pi = 0.636619772367581343f;
  constexpr float round_magic = 12582912.0f;  // 1.5 * 2^23: adding and subtracting rounds to an integer
  constexpr float pi_half_1 = 1.5703125f;     // 8 significant bits: exact times quadrants < 2^16
  constexpr float pi_half_2 = 4.837512969970703125e-4f;
  constexpr float pi_half_3 = 7.54978995489188216e-8f;
  const float phase_high = omega_high * time.high;
  const float phase_low = omega_high * time.low + omega_low * time.high + omega_low * time.low;
  const float nearest = ((phase_high + phase_low) * two_over_pi + round_magic) - round_magic;
  const int quadrant = static_cast<int>(nearest);
  const float r =
      (((phase_high - nearest * pi_half_1) - nearest * pi_half_2) - nearest * pi_half_3) + phase_low;
  const float z = r * r;
  const float sin_r = ((-1.9515295891e-4f * z + 8.3321608736e-3f) * z - 1.6666654611e-1f) * z * r + r;
  const float cos_r =
      ((2.443315711809948e-5f * z - 1.388731625493765e-3f) * z + 4.166664568298827e-2f) * z * z - 0.5f * z +
      1.0f;
  const bool swap = (quadrant & 1) != 0;
  const float sin_v = swap ? cos_r : sin_r;
  const float cos_v = swap ? sin_r : cos_r;
  sin_out = (quadrant & 2) != 0 ? -sin_v : sin_v;
  cos_out = ((quadrant + 1) & 2) != 0 ? -cos_v : cos_v;
}

// Coefficients of one row of the shifted half spectrum: h~ = (p cos + q sin) + i (r cos + u sin) of w t.
struct RowCoefficients {
  const float* p;
  const float* q;
  const float* r;
  const float* u;
  const float* omega;
  const float* omega_high;
  const float* omega_low;
};

// One clone per x86-64 level (AVX-512, AVX2, SSE2), picked at load time: the sincos is the cost here.

DISPLACE_SIMD_CLONES
void build_row_fast(const RowCoefficients& row, SplitFloat split_time, int count, float* __restrict out) {
  const float* __restrict p = row.p;
  const float* __restrict q = row.q;
  const float* __restrict r = row.r;
  const float* __restrict u = row.u;
  const float* __restrict omega_high = row.omega_high;
  const float* __restrict omega_low = row.omega_low;
  for (int j = 0; j < count; ++j) {
    float s, c;
    phase_sincos(omega_high[j], omega_low[j], split_time, s, c);
    out[2 * j] = p[j] * c + q[j] * s;
    out[2 * j + 1] = r[j] * c + u[j] * s;
  }
}

void build_row_precise(const RowCoefficients& row, double time, int count, float* out) {
  for (int j = 0; j < count; ++j) {
    const double phase = std::fmod(static_cast<double>(row.omega[j]) * time, 2.0 * std::numbers::pi);
    const float s = static_cast<float>(std::sin(phase));
    const float c = static_cast<float>(std::cos(phase));
    out[2 * j] = row.p[j] * c + row.q[j] * s;
    out[2 * j + 1] = row.r[j] * c + row.u[j] * s;
  }
}

// spectrum buffers: h~ and the spectra derived from it, one c2r FFT each
enum Grid : int {
  grid_height,
  grid_slope_x,
  grid_slope_y,
  grid_displacement_x,
  grid_displacement_y,
  grid_jacobian_xx,
  grid_jacobian_yy,
  grid_jacobian_xy,
  grid_count
};

}  // namespace

struct Ocean::Impl {
  OceanParams params;
  int n = 0;
  int half = 0;  // N/2 + 1 columns of the half spectrum
  double variance = 0.0;
  double loop_error = 0.0;  // the loop's largest relative change to a mode's w
  float omega_max = 0.0f;
  long long fft_count = 0;

  std::vector<std::complex<float>> h0;                   // N x N, world positions, unshifted FFTW order
  std::vector<float> omega_full;                         // N x N
  std::vector<float> coef_p, coef_q, coef_r, coef_u;     // N x half, half-texel shift folded in
  std::vector<float> omega_half, omega_high, omega_low;  // N x half
  std::vector<float> wave_x;                             // kx per column of the half spectrum, rad/m
  std::vector<float> wave_y;                             // ky per row, rad/m
  std::vector<float> inverse_wave_number;                // N x half, 1 / |k| in metres (0 at k = 0)

  // The 2D inverse FFT as its two passes, each cut into chunks that TBB runs side by side: c2c along y on
  // a range of the half spectrum's columns, then c2r along x on a range of rows. Chunks start at even
  // indices, so every chunk keeps the alignment its plan was made with in any 64-byte aligned buffer.
  std::vector<int> column_starts, row_starts;  // chunk boundaries, last = half or N
  std::vector<fftwf_plan> column_plans, row_plans;
  AlignedArray<fftwf_complex> spectra[grid_count];
  AlignedArray<float> scratch[grid_count];  // real outputs that do not go straight into the frame

  std::size_t spectrum_size() const { return static_cast<std::size_t>(n) * half; }
  std::size_t grid_size() const { return static_cast<std::size_t>(n) * n; }
  int signed_index(int index) const { return index < n / 2 ? index : index - n; }

  void make_plans();
  void draw_spectrum();
  void build_spectra(double time, unsigned grids);
  void build_row(int i, double time, bool fast, unsigned grids);
  float* output_for(int grid, std::vector<float>* target);

  ~Impl() {
    std::lock_guard lock(fftw_planner_mutex());
    for (fftwf_plan plan : column_plans) fftwf_destroy_plan(plan);
    for (fftwf_plan plan : row_plans) fftwf_destroy_plan(plan);
  }
};

namespace {

// Boundaries of `chunks` ranges over [0, count), every start even.
std::vector<int> even_chunk_starts(int count, int chunks) {
  const int pairs = (count + 1) / 2;
  chunks = std::clamp(chunks, 1, pairs);
  std::vector<int> starts;
  for (int chunk = 0; chunk < chunks; ++chunk) starts.push_back(2 * (chunk * pairs / chunks));
  starts.push_back(count);
  return starts;
}

}  // namespace

// FFTW_ESTIMATE, not FFTW_MEASURE: measured plans are picked by timing, so the same seed could give
// heights that differ in the last bit from one run (or machine load) to the next.
constexpr unsigned plan_rigor = FFTW_ESTIMATE;

void Ocean::Impl::make_plans() {
  const int chunks = std::min(tbb::info::default_concurrency(), max_fft_chunks);
  column_starts = even_chunk_starts(half, chunks);
  row_starts = even_chunk_starts(n, chunks);
  fftwf_complex* spectrum = spectra[grid_height].get();
  float* real = scratch[grid_height].get();
  // planning may overwrite the arrays, so this runs before anything is stored in them
  std::lock_guard lock(fftw_planner_mutex());
  for (std::size_t chunk = 0; chunk + 1 < column_starts.size(); ++chunk) {
    const int start = column_starts[chunk];
    fftwf_complex* first = spectrum + start;
    column_plans.push_back(fftwf_plan_many_dft(1, &n, column_starts[chunk + 1] - start, first, nullptr, half,
                                               1, first, nullptr, half, 1, FFTW_BACKWARD, plan_rigor));
  }
  for (std::size_t chunk = 0; chunk + 1 < row_starts.size(); ++chunk) {
    const int start = row_starts[chunk];
    row_plans.push_back(fftwf_plan_many_dft_c2r(
        1, &n, row_starts[chunk + 1] - start, spectrum + static_cast<std::size_t>(start) * half, nullptr, 1,
        half, real + static_cast<std::size_t>(start) * n, nullptr, 1, n, plan_rigor));
  }
  for (fftwf_plan plan : column_plans) {
    if (plan == nullptr) throw std::runtime_error("Ocean: FFTW could not plan the inverse FFT along y");
  }
  for (fftwf_plan plan : row_plans) {
    if (plan == nullptr) throw std::runtime_error("Ocean: FFTW could not plan the inverse FFT along x");
  }
}

void Ocean::Impl::draw_spectrum() {
  const detail::SeaModel model(params);
  const double dk = 2.0 * std::numbers::pi / params.patch_size;
  h0.assign(grid_size(), {});
  omega_full.assign(grid_size(), 0.0f);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const int lattice_x = signed_index(j);
      const int lattice_y = signed_index(i);
      const double kx = lattice_x * dk;
      const double ky = lattice_y * dk;
      const double k = std::hypot(kx, ky);
      const std::size_t index = static_cast<std::size_t>(i) * n + j;
      const double omega = model.omega(k);
      // a loop of T seconds: w rounded to a multiple of 2 pi / T
      const double loop_step = params.loop_seconds > 0.0 ? 2.0 * std::numbers::pi / params.loop_seconds : 0.0;
      const double quantised = loop_step > 0.0 ? std::round(omega / loop_step) * loop_step : omega;
      omega_full[index] = static_cast<float>(quantised);
      const bool nyquist = i == n / 2 || j == n / 2;
      if (k == 0.0 || nyquist) continue;
      loop_error = std::max(loop_error, std::abs(quantised - omega) / omega);
      // travel direction of h0(k) is -k
      const double mode_variance = model.mode_variance(-kx / k, -ky / k, k);
      const std::complex<double> xi = gaussian_pair(params.seed, lattice_x, lattice_y);
      h0[index] = std::complex<float>(xi * std::sqrt(0.5 * mode_variance));
      variance += mode_variance;
    }
  }
  // E|h~(k)|^2 = P(k) + P(-k); summed over the symmetric set of modes that is twice sum P
  variance *= 2.0;
  omega_max = *std::max_element(omega_full.begin(), omega_full.end());

  // shifted half-spectrum coefficients
  coef_p.assign(spectrum_size(), 0.0f);
  coef_q.assign(spectrum_size(), 0.0f);
  coef_r.assign(spectrum_size(), 0.0f);
  coef_u.assign(spectrum_size(), 0.0f);
  omega_half.assign(spectrum_size(), 0.0f);
  omega_high.assign(spectrum_size(), 0.0f);
  omega_low.assign(spectrum_size(), 0.0f);
  inverse_wave_number.assign(spectrum_size(), 0.0f);
  wave_x.assign(half, 0.0f);
  wave_y.assign(n, 0.0f);
  for (int j = 0; j < half; ++j) wave_x[j] = static_cast<float>(signed_index(j) * dk);
  for (int i = 0; i < n; ++i) wave_y[i] = static_cast<float>(signed_index(i) * dk);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < half; ++j) {
      const std::size_t full = static_cast<std::size_t>(i) * n + j;
      const std::size_t mirror = static_cast<std::size_t>((n - i) % n) * n + (n - j) % n;
      const std::size_t slot = static_cast<std::size_t>(i) * half + j;
      omega_half[slot] = omega_full[full];
      const SplitFloat split = split_float(omega_full[full]);
      omega_high[slot] = split.high;
      omega_low[slot] = split.low;
      const double k = dk * std::hypot(signed_index(i), signed_index(j));
      inverse_wave_number[slot] = k > 0.0 ? static_cast<float>(1.0 / k) : 0.0f;
      // h~ = (a + ib)(c + is) + (d + ie)(c - is) with a + ib = h0(k), d + ie = conj(h0(-k))
      const double a = h0[full].real(), b = h0[full].imag();
      const double d = h0[mirror].real(), e = -h0[mirror].imag();
      const double p = a + d, q = e - b, r = b + e, u = a - d;
      const double shift = std::numbers::pi * (signed_index(i) + signed_index(j)) / n;
      const double alpha = std::cos(shift), beta = std::sin(shift);
      coef_p[slot] = static_cast<float>(alpha * p - beta * r);
      coef_q[slot] = static_cast<float>(alpha * q - beta * u);
      coef_r[slot] = static_cast<float>(beta * p + alpha * r);
      coef_u[slot] = static_cast<float>(beta * q + alpha * u);
    }
  }
}

void Ocean::Impl::build_spectra(double time, unsigned grids) {
  for (int grid = 0; grid < grid_count; ++grid) {
    if ((grids & (1u << grid)) != 0 && !spectra[grid]) {
      spectra[grid] = make_aligned<fftwf_complex>(spectrum_size());
    }
  }
  const bool fast = std::abs(time) * omega_max <= fast_phase_limit;
  tbb::parallel_for(tbb::blocked_range<int>(0, n, spectrum_rows_per_task),
                    [&](const tbb::blocked_range<int>& rows) {
                      for (int i = rows.begin(); i != rows.end(); ++i) build_row(i, time, fast, grids);
                    });
}

void Ocean::Impl::build_row(int i, double time, bool fast, unsigned grids) {
  const std::size_t offset = static_cast<std::size_t>(i) * half;
  float* height = reinterpret_cast<float*>(spectra[grid_height].get() + offset);
  const RowCoefficients row{coef_p.data() + offset,   coef_q.data() + offset,     coef_r.data() + offset,
                            coef_u.data() + offset,   omega_half.data() + offset, omega_high.data() + offset,
                            omega_low.data() + offset};
  if (fast) {
    build_row_fast(row, split_time(time), half, height);
  } else {
    build_row_precise(row, time, half, height);
  }
  if (grids == (1u << grid_height)) return;

  // derived spectra: h~ times i k (slopes), i lambda k/|k| (displacement), -lambda k k^T/|k| (Jacobian)
  const float lambda = params.choppiness;
  const float ky = wave_y[i];
  const float* inverse_k = inverse_wave_number.data() + offset;
  auto derive = [&](int grid, auto factor_of) {
    if ((grids & (1u << grid)) == 0) return;
    float* out = reinterpret_cast<float*>(spectra[grid].get() + offset);
    for (int j = 0; j < half; ++j) {
      const std::complex<float> factor = factor_of(wave_x[j], inverse_k[j]);
      const float re = height[2 * j], im = height[2 * j + 1];
      out[2 * j] = factor.real() * re - factor.imag() * im;
      out[2 * j + 1] = factor.real() * im + factor.imag() * re;
    }
  };
  using Factor = std::complex<float>;
  derive(grid_slope_x, [](float kx, float) { return Factor(0.0f, kx); });
  derive(grid_slope_y, [ky](float, float) { return Factor(0.0f, ky); });
  derive(grid_displacement_x, [lambda](float kx, float inv_k) { return Factor(0.0f, lambda * kx * inv_k); });
  derive(grid_displacement_y, [lambda, ky](float, float inv_k) { return Factor(0.0f, lambda * ky * inv_k); });
  derive(grid_jacobian_xx,
         [lambda](float kx, float inv_k) { return Factor(-lambda * kx * kx * inv_k, 0.0f); });
  derive(grid_jacobian_yy,
         [lambda, ky](float, float inv_k) { return Factor(-lambda * ky * ky * inv_k, 0.0f); });
  derive(grid_jacobian_xy,
         [lambda, ky](float kx, float inv_k) { return Factor(-lambda * kx * ky * inv_k, 0.0f); });
}

// Where the FFT of `grid` writes: straight into the frame's vector when its alignment matches the plan's.
float* Ocean::Impl::output_for(int grid, std::vector<float>* target) {
  if (target != nullptr &&
      fftwf_alignment_of(target->data()) == fftwf_alignment_of(scratch[grid_height].get())) {
    return target->data();
  }
  if (!scratch[grid]) scratch[grid] = make_aligned<float>(grid_size());
  return scratch[grid].get();
}

Ocean::Ocean(const OceanParams& params) : impl_(std::make_unique<Impl>()) {
  detail::validate_ocean(params);
  Impl& impl = *impl_;
  impl.params = params;
  impl.n = params.size;
  impl.half = params.size / 2 + 1;
  impl.spectra[grid_height] = make_aligned<fftwf_complex>(impl.spectrum_size());
  impl.scratch[grid_height] = make_aligned<float>(impl.grid_size());
  impl.make_plans();
  impl.draw_spectrum();
}

Ocean::~Ocean() = default;
Ocean::Ocean(Ocean&&) noexcept = default;
Ocean& Ocean::operator=(Ocean&&) noexcept = default;

double Ocean::loop_time(double time) const {
  const double loop = impl_->params.loop_seconds;
  return loop > 0.0 ? time - loop * std::floor(time / loop) : time;
}

double Ocean::loop_error() const { return impl_->loop_error; }

void Ocean::evaluate(double time, unsigned outputs, OceanFrame& frame) {
  Impl& impl = *impl_;
  time = loop_time(time);
  frame.size = impl.n;
  const std::size_t samples = impl.grid_size();
  auto prepare = [&](unsigned output, std::vector<float>& target) {
    if ((outputs & output) != 0) {
      target.resize(samples);
    } else {
      target.clear();
    }
  };
  prepare(ocean_heights, frame.height);
  prepare(ocean_slopes, frame.slope_x);
  prepare(ocean_slopes, frame.slope_y);
  prepare(ocean_displacement, frame.displacement_x);
  prepare(ocean_displacement, frame.displacement_y);
  prepare(ocean_foam, frame.jacobian);

  unsigned grids = 0;
  if ((outputs & ocean_heights) != 0) grids |= 1u << grid_height;
  if ((outputs & ocean_slopes) != 0) grids |= (1u << grid_slope_x) | (1u << grid_slope_y);
  if ((outputs & ocean_displacement) != 0) grids |= (1u << grid_displacement_x) | (1u << grid_displacement_y);
  if ((outputs & ocean_foam) != 0) {
    grids |= (1u << grid_jacobian_xx) | (1u << grid_jacobian_yy) | (1u << grid_jacobian_xy);
  }
  if (grids == 0) return;
  // h~ always lands in the height buffer; its FFT runs only when heights are asked for
  impl.build_spectra(time, grids | (1u << grid_height));

  struct Job {
    int grid;
    float* out;
  };
  std::vector<float>* targets[grid_count] = {
      &frame.height,         &frame.slope_x, &frame.slope_y, &frame.displacement_x,
      &frame.displacement_y, nullptr,        nullptr,        nullptr};
  Job jobs[grid_count];
  int job_count = 0;
  for (int grid = 0; grid < grid_count; ++grid) {
    if ((grids & (1u << grid)) != 0) jobs[job_count++] = {grid, impl.output_for(grid, targets[grid])};
  }
  // pass 1: along y, every (job, column chunk) in parallel
  const int column_chunks = static_cast<int>(impl.column_plans.size());
  tbb::parallel_for(0, job_count * column_chunks, [&](int task) {
    const int chunk = task % column_chunks;
    fftwf_complex* first = impl.spectra[jobs[task / column_chunks].grid].get() + impl.column_starts[chunk];
    fftwf_execute_dft(impl.column_plans[chunk], first, first);
  });
  // pass 2: along x into the outputs, every (job, row chunk) in parallel
  const int row_chunks = static_cast<int>(impl.row_plans.size());
  tbb::parallel_for(0, job_count * row_chunks, [&](int task) {
    const int chunk = task % row_chunks;
    const Job& job = jobs[task / row_chunks];
    const std::size_t start = impl.row_starts[chunk];
    const std::size_t end = impl.row_starts[chunk + 1];
    const int n = impl.n;
    fftwf_execute_dft_c2r(impl.row_plans[chunk], impl.spectra[job.grid].get() + start * impl.half,
                          job.out + start * n);
    std::vector<float>* target = targets[job.grid];
    if (target != nullptr && job.out != target->data()) {
      std::memcpy(target->data() + start * n, job.out + start * n, (end - start) * n * sizeof(float));
    }
  });
  impl.fft_count += job_count;

  if ((outputs & ocean_foam) != 0) {
    // J = (1 + dDx/dx)(1 + dDy/dy) - dDx/dy dDy/dx, with dDx/dy = dDy/dx
    const float* xx = impl.scratch[grid_jacobian_xx].get();
    const float* yy = impl.scratch[grid_jacobian_yy].get();
    const float* xy = impl.scratch[grid_jacobian_xy].get();
    float* jacobian = frame.jacobian.data();
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, samples),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                        for (std::size_t index = range.begin(); index != range.end(); ++index) {
                          jacobian[index] = (1.0f + xx[index]) * (1.0f + yy[index]) - xy[index] * xy[index];
                        }
                      });
  }
}

int Ocean::size() const { return impl_->n; }
float Ocean::patch_size() const { return impl_->params.patch_size; }
const OceanParams& Ocean::params() const { return impl_->params; }
double Ocean::height_variance() const { return impl_->variance; }

HeightMapping Ocean::mapping() const {
  const double sigma = std::sqrt(impl_->variance);
  HeightMapping mapping;
  mapping.bias = 0.5f;
  mapping.scale = sigma > 0.0 ? static_cast<float>(1.0 / (6.0 * sigma)) : 1.0f;
  return mapping;
}

std::vector<std::complex<float>> Ocean::height_spectrum(double time) const {
  const Impl& impl = *impl_;
  time = loop_time(time);
  const int n = impl.n;
  std::vector<std::complex<float>> spectrum(impl.grid_size());
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const std::size_t index = static_cast<std::size_t>(i) * n + j;
      const std::size_t mirror = static_cast<std::size_t>((n - i) % n) * n + (n - j) % n;
      const double phase =
          std::fmod(static_cast<double>(impl.omega_full[index]) * time, 2.0 * std::numbers::pi);
      const std::complex<double> rotation = std::polar(1.0, phase);
      const std::complex<double> forward(impl.h0[index]);
      const std::complex<double> backward = std::conj(std::complex<double>(impl.h0[mirror]));
      spectrum[index] = std::complex<float>(forward * rotation + backward * std::conj(rotation));
    }
  }
  return spectrum;
}

float Ocean::omega(int i, int j) const {
  const int n = impl_->n;
  if (i < 0 || i >= n || j < 0 || j >= n)
    throw std::out_of_range("Ocean::omega: mode index outside the grid");
  return impl_->omega_full[static_cast<std::size_t>(i) * n + j];
}

Ocean::HalfSpectrum Ocean::half_spectrum() const {
  const Impl& impl = *impl_;
  HalfSpectrum spectrum;
  const std::size_t modes = impl.spectrum_size();
  spectrum.coefficients.resize(4 * modes);
  for (std::size_t mode = 0; mode < modes; ++mode) {
    spectrum.coefficients[4 * mode] = impl.coef_p[mode];
    spectrum.coefficients[4 * mode + 1] = impl.coef_q[mode];
    spectrum.coefficients[4 * mode + 2] = impl.coef_r[mode];
    spectrum.coefficients[4 * mode + 3] = impl.coef_u[mode];
  }
  spectrum.omega = impl.omega_half;
  return spectrum;
}

long long Ocean::fft_count() const { return impl_->fft_count; }

}  // namespace displace::sim
