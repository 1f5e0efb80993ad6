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
float periodic_bilinear(std::span<const float> grid, int size, double x, double y) {
  const double fx = std::floor(x), fy = std::floor(y);
  const double tx = x - fx, ty = y - fy;
  auto wrap = [size](long long i) { return int(((i % size) + size) % size); };
  const int x0 = wrap((long long)fx), x1 = wrap((long long)fx + 1);
  const int y0 = wrap((long long)fy), y1 = wrap((long long)fy + 1);
  const double a = grid[std::size_t(y0) * size + x0], b = grid[std::size_t(y0) * size + x1];
  const double c = grid[std::size_t(y1) * size + x0], d = grid[std::size_t(y1) * size + x1];
  return float((a * (1 - tx) + b * tx) * (1 - ty) + (c * (1 - tx) + d * tx) * ty);
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
  const double texels_per_metre = double(size) / patch_size;
  return tbb::parallel_reduce(
      tbb::blocked_range<int>(0, size), 0.0,
      [&](const tbb::blocked_range<int>& rows, double worst) {
        for (int i = rows.begin(); i != rows.end(); ++i) {
          for (int j = 0; j < size; ++j) {
            // p <- x - D(p), in texels
            double px = j, py = i;
            for (int step = 0; step < iterations; ++step) {
              px = j - periodic_bilinear(displacement_x, size, px, py) * texels_per_metre;
              py = i - periodic_bilinear(displacement_y, size, px, py) * texels_per_metre;
            }
            const double rx = px + periodic_bilinear(displacement_x, size, px, py) * texels_per_metre - j;
            const double ry = py + periodic_bilinear(displacement_y, size, px, py) * texels_per_metre - i;
            worst = std::max(worst, std::hypot(rx, ry) / texels_per_metre);
            out[std::size_t(i) * size + j] = periodic_bilinear(height, size, px, py);
            if (!extra.empty()) extra_out[std::size_t(i) * size + j] = periodic_bilinear(extra, size, px, py);
          }
        }
        return worst;
      },
      [](double a, double b) { return std::max(a, b); });
}

}  // namespace displace::sim
