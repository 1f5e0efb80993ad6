// sim/choppy.cpp - the choppy (horizontally displaced) ocean surface resampled onto the regular grid
// (Tessendorf, "Simulating Ocean Water", sec. 4.6 displaces the grid; a height field wants the
// inverse map). sim.h has the contract.
#include <algorithm>
#include <bit>
#include <cmath>
#include <stdexcept>

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include "displace/simd_clones.h"
#include "sim/sim.h"

namespace displace::sim {
namespace {

// Texels are resampled in blocks of one row's `block` neighbours, each fixed-point step over the
// whole block: the steps of one texel depend on each other, those of neighbours do not, so the
// block's loop vectorises (one clone per x86-64 level, as in fft_ocean.cpp; the loads per lane,
// which GCC's tuning prefers to gathers here) where a texel at a time waits on each step's loads.
// GCC vectorises these loops only as written: floors by truncation, maxima of non-negative floats
// taken on their bits, samples stored to a local array, and no trapping math (sim/CMakeLists.txt);
// one thing missing and the loop stays scalar (-fopt-info-vec shows it). The arithmetic is the
// scalar bilinear sample's, in the same order, so the heights and the extra channel are the same
// bit for bit (tests/sim_test.cpp checks them against one); the residual is the largest in float.
constexpr int block = 64;


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

struct BlockJob {
  int size = 0;
  float texels_per_metre = 0.0f;
  int iterations = 0;
  float settle = 0.0f;  // texels: a block stops once no texel moved more than this in a step (0: never)
  const float* dx = nullptr;
  const float* dy = nullptr;
  const float* height = nullptr;
  const float* extra = nullptr;  // may be null
  float* out = nullptr;          // the block's first output texel
  float* extra_out = nullptr;    // the same in extra_out, when extra is given
};

// Texels j0 .. j0 + count - 1 of row i; returns the largest squared residual in texels.
DISPLACE_SIMD_CLONES
float resample_block(const BlockJob& job, int i, int j0, int count) {
  const int size = job.size;
  const float inverse_size = 1.0f / float(size);
  const float scale = job.texels_per_metre;
  float px[block], py[block];
  for (int b = 0; b < count; ++b) {
    px[b] = float(j0 + b);
    py[b] = float(i);
  }
  // p <- x - D(p), in texels, from p = x
  for (int step = 0; step < job.iterations; ++step) {
    int moved = 0;  // the bits of the largest move: non-negative floats order as their bits do
    for (int b = 0; b < count; ++b) {
      const Tap t = tap_at(px[b], py[b], size, inverse_size);
      const float next_x = float(j0 + b) - sample(job.dx, t) * scale;
      const float next_y = float(i) - sample(job.dy, t) * scale;
      moved = std::max(moved, std::bit_cast<int>(std::max(std::abs(next_x - px[b]), std::abs(next_y - py[b]))));
      px[b] = next_x;
      py[b] = next_y;
    }
    if (std::bit_cast<float>(moved) <= job.settle) break;
  }
  // the samples go to a local array first: a store through `out` could alias the gathered loads
  // as far as the compiler knows, and the loops would not vectorise
  float sampled[block];
  int worst = 0;  // bits, as `moved`
  for (int b = 0; b < count; ++b) {
    const Tap t = tap_at(px[b], py[b], size, inverse_size);
    const float rx = px[b] + sample(job.dx, t) * scale - float(j0 + b);
    const float ry = py[b] + sample(job.dy, t) * scale - float(i);
    worst = std::max(worst, std::bit_cast<int>(rx * rx + ry * ry));
    sampled[b] = sample(job.height, t);
  }
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
      displacement_y.size() != texels || out.size() != texels || iterations < 0 || extra.size() != extra_out.size() ||
      !(extra.empty() || extra.size() == texels) || !(settle >= 0.0f)) {
    throw std::invalid_argument(
        "resample_displaced: size x size heights, displacements and output, patch_size > 0, settle >= 0");
  }
  // the taps index size^2 texels with int (and the coordinates stay exact floats, below 2^24)
  if (size > 46340) throw std::invalid_argument("resample_displaced: size at most 46340 (size^2 texels indexed with int)");
  BlockJob job;
  job.size = size;
  job.texels_per_metre = float(size) / patch_size;
  job.iterations = iterations;
  job.settle = settle;
  job.dx = displacement_x.data();
  job.dy = displacement_y.data();
  job.height = height.data();
  job.extra = extra.empty() ? nullptr : extra.data();
  const float worst_squared = tbb::parallel_reduce(
      tbb::blocked_range<int>(0, size), 0.0f,
      [&](const tbb::blocked_range<int>& rows, float worst) {
        BlockJob mine = job;
        for (int i = rows.begin(); i != rows.end(); ++i) {
          for (int j0 = 0; j0 < size; j0 += block) {
            const std::size_t first = std::size_t(i) * std::size_t(size) + std::size_t(j0);
            mine.out = out.data() + first;
            mine.extra_out = extra.empty() ? nullptr : extra_out.data() + first;
            worst = std::max(worst, resample_block(mine, i, j0, std::min(block, size - j0)));
          }
        }
        return worst;
      },
      [](float a, float b) { return std::max(a, b); });
  return std::sqrt(double(worst_squared)) / job.texels_per_metre;
}

}  // namespace displace::sim
