// sim/choppy.cpp - the choppy (horizontally displaced) ocean surface resampled onto the regular grid
// (Tessendorf, "Simulating Ocean Water", sec. 4.6 displaces the grid; a height field wants the
// inverse map). sim.h has the contract.
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include "sim/sim.h"

namespace displace::sim {
namespace {

// Bilinear sample of a periodic size x size grid at (x, y) in texels (texel centres at integers).
inline float periodic_bilinear(const float* grid, int size, float x, float y) {
  const float fx = std::floor(x), fy = std::floor(y);
  const float tx = x - fx, ty = y - fy;
  auto wrap = [size](int i) {
    if (unsigned(i) < unsigned(size)) return i;  // the common case: no division
    i %= size;
    return i < 0 ? i + size : i;
  };
  const int x0 = wrap(int(fx)), x1 = wrap(int(fx) + 1);
  const int y0 = wrap(int(fy)), y1 = wrap(int(fy) + 1);
  const float* row0 = grid + std::size_t(y0) * size;
  const float* row1 = grid + std::size_t(y1) * size;
  const float top = row0[x0] + (row0[x1] - row0[x0]) * tx;
  const float bottom = row1[x0] + (row1[x1] - row1[x0]) * tx;
  return top + (bottom - top) * ty;
}

}  // namespace

double resample_displaced(int size, float patch_size, std::span<const float> height,
                          std::span<const float> displacement_x, std::span<const float> displacement_y,
                          int iterations, std::span<float> out, std::span<const float> extra,
                          std::span<float> extra_out) {
  const std::size_t texels = std::size_t(size) * std::size_t(size);
  if (size < 2 || !(patch_size > 0.0f) || height.size() != texels || displacement_x.size() != texels ||
      displacement_y.size() != texels || out.size() != texels || iterations < 0 || extra.size() != extra_out.size() ||
      !(extra.empty() || extra.size() == texels)) {
    throw std::invalid_argument("resample_displaced: size x size heights, displacements and output, patch_size > 0");
  }
  const float texels_per_metre = float(size) / patch_size;
  const float* dx = displacement_x.data();
  const float* dy = displacement_y.data();
  return tbb::parallel_reduce(
      tbb::blocked_range<int>(0, size), 0.0,
      [&](const tbb::blocked_range<int>& rows, double worst) {
        for (int i = rows.begin(); i != rows.end(); ++i) {
          for (int j = 0; j < size; ++j) {
            // p <- x - D(p), in texels, from p = x
            float px = float(j), py = float(i);
            for (int step = 0; step < iterations; ++step) {
              const float next_x = float(j) - periodic_bilinear(dx, size, px, py) * texels_per_metre;
              const float next_y = float(i) - periodic_bilinear(dy, size, px, py) * texels_per_metre;
              px = next_x;
              py = next_y;
            }
            const float rx = px + periodic_bilinear(dx, size, px, py) * texels_per_metre - float(j);
            const float ry = py + periodic_bilinear(dy, size, px, py) * texels_per_metre - float(i);
            worst = std::max(worst, double(std::hypot(rx, ry)) / texels_per_metre);
            out[std::size_t(i) * size + j] = periodic_bilinear(height.data(), size, px, py);
            if (!extra.empty()) extra_out[std::size_t(i) * size + j] = periodic_bilinear(extra.data(), size, px, py);
          }
        }
        return worst;
      },
      [](double a, double b) { return std::max(a, b); });
}

}  // namespace displace::sim
