// sim/choppy.cpp - the choppy (horizontally displaced) ocean surface resampled onto the regular grid
// (Tessendorf, "Simulating Ocean Water", sec. 4.6 displaces the grid; a height field wants the
// inverse map). sim.h has the contract.
#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <stdexcept>

#include "displace/simd_clones.h"
#include "sim/sim.h"

namespace displace::sim {
namespace {

// Texels are resampled in blocks of one row's `block` neighbours, each Newton step over the
// whole block: the steps of one texel depend on each other, those of neighbours do not, so the
// block's loop vectorises (one clone per x86-64 level, as in fft_ocean.cpp; the loads per lane,
// which GCC's tuning prefers to gathers here) where a texel at a time waits on each step's loads.
// GCC vectorises these loops only as written: floors by truncation, maxima of non-negative floats
// taken on their bits, samples stored to a local array, and no trapping math (sim/CMakeLists.txt);
// one thing missing and the loop stays scalar (-fopt-info-vec shows it). The arithmetic is the
// scalar bilinear sample's, in the same order, so the heights and the extra channel are the same
// bit for bit (tests/sim/choppy_test.cpp checks them against one); the residual is the largest in float.
constexpr int block = 64;
constexpr int row_group = 16;  // rows resampled in order, the first from x, the others warm

// floor(x) for |x| < 2^30 through a truncating conversion, exact there as std::floor. GCC vectorises
// neither std::floor nor a select between float expressions while trapping math is on (the default):
// only selects between values, and arithmetic done either way.
inline float floor_of(float x) {
  const float t = float(int(x));
  return t - float(t > x);
}

// Coordinates clamped to +-2^24 texels (NaN to the upper end: no real ocean moves a texel that
// far), so that every conversion below stays defined; selects between values only.
inline float tame(float x) { return std::max(-16777216.0f, std::min(16777216.0f, x)); }

// The lattice index of the floor fx (an integer-valued float, |fx| < 2^24) wrapped into [0, size),
// without a branch or an integer division (so that it vectorises): the float quotient can be one
// off, which the two selects put right. The last select keeps any index inside the grid.
inline int wrap_index(float fx, int size, float inverse_size) {
  int i = int(fx - floor_of(fx * inverse_size) * float(size));
  i += i < 0 ? size : 0;
  i -= i >= size ? size : 0;
  return unsigned(i) < unsigned(size) ? i : 0;
}

// Where a bilinear sample at (x, y) in texels (texel centres at integers) reads in a periodic
// size x size grid, and with which weights.
struct Tap {
  int i00, i01, i10, i11;
  float tx, ty;
};

inline Tap tap_at(float x, float y, int size, float inverse_size) {
  x = tame(x);
  y = tame(y);
  const float fx = floor_of(x), fy = floor_of(y);
  const int x0 = wrap_index(fx, size, inverse_size), y0 = wrap_index(fy, size, inverse_size);
  const int x1 = x0 + 1 == size ? 0 : x0 + 1, y1 = y0 + 1 == size ? 0 : y0 + 1;
  return {y0 * size + x0, y0 * size + x1, y1 * size + x0, y1 * size + x1, x - fx, y - fy};
}

inline float sample(const float* grid, const Tap& t) {
  const float top = grid[t.i00] + (grid[t.i01] - grid[t.i00]) * t.tx;
  const float bottom = grid[t.i10] + (grid[t.i11] - grid[t.i10]) * t.tx;
  return top + (bottom - top) * t.ty;
}

// The bilinear sample and its two partial derivatives (per texel) on the tap's cell.
struct Sampled {
  float value, along_x, along_y;
};

inline Sampled sample_with_slopes(const float* grid, const Tap& t) {
  const float a = grid[t.i00], b = grid[t.i01], c = grid[t.i10], d = grid[t.i11];
  const float top = a + (b - a) * t.tx;
  const float bottom = c + (d - c) * t.tx;
  return {top + (bottom - top) * t.ty, (b - a) + ((d - c) - (b - a)) * t.ty, bottom - top};
}

struct BlockJob {
  int size = 0;
  float texels_per_metre = 0.0f;
  int iterations = 0;
  float settle = 0.0f;  // texels: a block stops once every texel's residual is within this (0: never)
  const float* dx = nullptr;
  const float* dy = nullptr;
  const float* height = nullptr;
  const float* extra = nullptr;  // may be null
  float* out = nullptr;          // the block's first output texel
  float* extra_out = nullptr;    // the same in extra_out, when extra is given
};

// Where each texel of a block ended, and how its solution moves one row on (J^-1 (0, 1), or (0, 1)
// where the fixed-point step was taken): the next row's block starts there.
struct Warm {
  float px[block], py[block], ox[block], oy[block];
};

// Texels j0 .. j0 + count - 1 of row i, started from x (cold) or from the row before's solutions
// moved by their predicted change (warm); returns the largest squared residual in texels.
//
// Newton's method on F(p) = p + D(p) - x (texels): D is bilinear on each cell, so its Jacobian on p's
// cell comes from the same four texels as D(p), and J = I + grad D. Where det J is at least
// `newton_floor` the step is J^-1 F; below it (a folding crest, or near one) the fixed-point step F
// (p <- x - D(p)), which was the whole iteration before. Measured on the water scene's ocean (512,
// choppiness 1.5, three times, settle 0.003 texels): the fixed point needed all 8 steps somewhere;
// Newton from x measures F 3.4 times a block, from the row before's solution alone 2.4 times, and
// with its predicted change 2.1 times (2 is the least: a step, then the check); 2.5 times at the
// pipeline's settle of 3e-4 texels.
DISPLACE_SIMD_CLONES
float resample_block(const BlockJob& job, int i, int j0, int count, bool cold, Warm& warm) {
  constexpr float newton_floor = 0.2f;
  const int size = job.size;
  const float inverse_size = 1.0f / float(size);
  const float scale = job.texels_per_metre;
  const float settle_squared = job.settle * job.settle;
  float px[block], py[block], nx[block], ny[block], ox[block], oy[block];
  for (int b = 0; b < count; ++b) {
    px[b] = cold ? float(j0 + b) : tame(warm.px[b] + warm.ox[b]);
    py[b] = cold ? float(i) : tame(warm.py[b] + warm.oy[b]);
  }
  // evaluations 0 .. iterations: each measures F at p and, unless it is the last or the whole block
  // is within the settle, steps
  int worst = 0;  // the bits of the largest squared residual: non-negative floats order as their bits do
  for (int step = 0;; ++step) {
    worst = 0;
    for (int b = 0; b < count; ++b) {
      const Tap t = tap_at(px[b], py[b], size, inverse_size);
      const Sampled sx = sample_with_slopes(job.dx, t), sy = sample_with_slopes(job.dy, t);
      const float fx = px[b] + sx.value * scale - float(j0 + b);
      const float fy = py[b] + sy.value * scale - float(i);
      worst = std::max(worst, std::bit_cast<int>(fx * fx + fy * fy));
      const float a = 1.0f + sx.along_x * scale, c = sx.along_y * scale;
      const float e = sy.along_x * scale, d = 1.0f + sy.along_y * scale;
      const float det = a * d - c * e;
      const bool newton = det >= newton_floor;
      const float inverse = 1.0f / (newton ? det : 1.0f);
      const float step_x = newton ? (d * fx - c * fy) * inverse : fx;
      const float step_y = newton ? (a * fy - e * fx) * inverse : fy;
      nx[b] = tame(px[b] - step_x);
      ny[b] = tame(py[b] - step_y);
      ox[b] = newton ? -c * inverse : 0.0f;
      oy[b] = newton ? a * inverse : 1.0f;
    }
    if (step == job.iterations || std::bit_cast<float>(worst) <= settle_squared) break;
    std::copy_n(nx, count, px);
    std::copy_n(ny, count, py);
  }
  // stores through `warm` inside the loop would stop it vectorising as `out` would (below)
  std::copy_n(px, count, warm.px);
  std::copy_n(py, count, warm.py);
  std::copy_n(ox, count, warm.ox);
  std::copy_n(oy, count, warm.oy);
  // the samples go to a local array first: a store through `out` could alias the gathered loads
  // as far as the compiler knows, and the loops would not vectorise
  float sampled[block];
  for (int b = 0; b < count; ++b) sampled[b] = sample(job.height, tap_at(px[b], py[b], size, inverse_size));
  std::copy_n(sampled, count, job.out);
  if (job.extra) {
    for (int b = 0; b < count; ++b) sampled[b] = sample(job.extra, tap_at(px[b], py[b], size, inverse_size));
    std::copy_n(sampled, count, job.extra_out);
  }
  return std::bit_cast<float>(worst);
}

}  // namespace

double resample_displaced(int size, float patch_size, std::span<const float> height,
                          std::span<const float> displacement_x, std::span<const float> displacement_y,
                          int iterations, std::span<float> out, std::span<const float> extra,
                          std::span<float> extra_out, float settle) {
  const std::size_t texels = std::size_t(size) * std::size_t(size);
  if (size < 2 || !(patch_size > 0.0f) || height.size() != texels || displacement_x.size() != texels ||
      displacement_y.size() != texels || out.size() != texels || iterations < 0 ||
      extra.size() != extra_out.size() || !(extra.empty() || extra.size() == texels) || !(settle >= 0.0f)) {
    throw std::invalid_argument(
        "resample_displaced: size x size heights, displacements and output, patch_size > 0, settle >= 0");
  }
  // the taps index size^2 texels with int (and the coordinates stay exact floats, below 2^24)
  if (size > 46340)
    throw std::invalid_argument("resample_displaced: size at most 46340 (size^2 texels indexed with int)");
  BlockJob job;
  job.size = size;
  job.texels_per_metre = float(size) / patch_size;
  job.iterations = iterations;
  job.settle = settle;
  job.dx = displacement_x.data();
  job.dy = displacement_y.data();
  job.height = height.data();
  job.extra = extra.empty() ? nullptr : extra.data();
  // Rows in groups of `row_group`, each started cold and then warm row by row, a strip of `block`
  // columns at a time: the groups are fixed, so the result does not depend on the threads.
  const int groups = (size + row_group - 1) / row_group;
  const float worst_squared = tbb::parallel_reduce(
      tbb::blocked_range<int>(0, groups), 0.0f,
      [&](const tbb::blocked_range<int>& range, float worst) {
        BlockJob mine = job;
        Warm warm;
        for (int g = range.begin(); g != range.end(); ++g) {
          const int first_row = g * row_group, end_row = std::min(size, first_row + row_group);
          for (int j0 = 0; j0 < size; j0 += block) {
            for (int i = first_row; i < end_row; ++i) {
              const std::size_t first = std::size_t(i) * std::size_t(size) + std::size_t(j0);
              mine.out = out.data() + first;
              mine.extra_out = extra.empty() ? nullptr : extra_out.data() + first;
              worst = std::max(worst,
                               resample_block(mine, i, j0, std::min(block, size - j0), i == first_row, warm));
            }
          }
        }
        return worst;
      },
      [](float a, float b) { return std::max(a, b); });
  return std::sqrt(double(worst_squared)) / job.texels_per_metre;
}

}  // namespace displace::sim
