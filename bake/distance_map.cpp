// bake/distance_map.cpp - Donnelly, "Per-Pixel Displacement Mapping with Distance Functions" (GPU
// Gems 2, ch. 8): a 3D distance map for sphere tracing, computed with Felzenszwalb & Huttenlocher's
// separable exact Euclidean distance transform ("Distance Transforms of Sampled Functions"), one
// lower envelope of parabolas per line, and made conservative for TRILINEAR filtering.
//
// The one fact: a trilinear sample at p reads voxels whose centres c have p in their support box
// B(c) (c plus or minus one spacing per axis), so storing a lower bound of min over B(c) of the
// distance d to the solid makes every sample a convex combination of values <= d(p). That bound is
// the distance from B(c) to the boxes F x (-inf, S_F] over the map's cells F (S_F the bilinear
// surface's maximum over F), rounded down: h is never voxelised, only uv is.
//
// Proof: docs/design/bakers.md#bakedistance_mapcpp-the-distance-map-conservative-for-trilinear-filtering
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <vector>

#include "bake/geometry.h"

namespace displace::bake {
namespace {

// uv: covers the float rounding of squared distances (<= 3) stored between the two passes, < 1e-7.
constexpr double rounding_margin = 1e-6;

long long floor_div_ll(long long a, long long b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }

int address_index(long long index, int count, Address address) {
  if (address == Address::clamp) return int(std::clamp<long long>(index, 0, count - 1));
  const long long wrapped = index % count;
  return int(wrapped < 0 ? wrapped + count : wrapped);
}

// A point along an axis in texel-centre coordinates (texel t's centre at t, unwrapped): between
// centres `first` and first + 1, at `weight` in [0, 1).
struct AxisPoint {
  long long first = 0;
  double weight = 0.0;
};

// Where the bilinear s, restricted to footprint cell `cell` of `cells` along an axis of `texels`
// texels, can peak along that axis: the cell's two ends and the texel centres strictly inside
// (s is linear between centres). The cell is [a, b] in texel-centre coordinates,
// a = cell * texels / cells - 1/2, b = (cell + 1) * texels / cells - 1/2.
std::vector<AxisPoint> peak_candidates(int cell, int cells, int texels) {
  const long long denominator = 2ll * cells;
  // a and b times the denominator
  const long long a = 2ll * cell * texels - cells, b = 2ll * (cell + 1) * texels - cells;
  auto point = [&](long long numerator) {
    const long long first = floor_div_ll(numerator, denominator);
    return AxisPoint{first, double(numerator - first * denominator) / double(denominator)};
  };
  std::vector<AxisPoint> points{point(a)};
  for (long long t = floor_div_ll(a, denominator) + 1; t * denominator < b; ++t) points.push_back({t, 0.0});
  points.push_back(point(b));
  return points;
}

// S_F for every footprint cell of a width x height map: the maximum of the bilinear s over the cell
// (step 2), exact up to rounding. s is bilinear on each piece of the cell cut by the texel-centre
// lines, so it peaks at a corner of a piece: a candidate along u times a candidate along v. Interior
// v candidates are texel rows, whose peak over the u candidates is shared (row_peak); the two ends
// along v are evaluated directly.
std::vector<float> footprint_maxima(HeightView heights, Address address, int width, int height) {
  std::vector<std::vector<AxisPoint>> along_u(width);
  for (int j = 0; j < width; ++j) along_u[j] = peak_candidates(j, width, heights.width);
  // s along texel row r at a u candidate
  auto row_value = [&](int r, const AxisPoint& x) {
    const float* row = heights.data + std::size_t(r) * heights.width;
    const double left = row[address_index(x.first, heights.width, address)];
    if (x.weight == 0.0) return left;
    return left + (double(row[address_index(x.first + 1, heights.width, address)]) - left) * x.weight;
  };
  std::vector<double> row_peak(std::size_t(heights.height) * width);
  tbb::parallel_for(tbb::blocked_range<int>(0, heights.height), [&](const tbb::blocked_range<int>& rows) {
    for (int r = rows.begin(); r < rows.end(); ++r)
      for (int j = 0; j < width; ++j) {
        double m = 0.0;
        for (const AxisPoint& x : along_u[j]) m = std::max(m, row_value(r, x));
        row_peak[std::size_t(r) * width + j] = m;
      }
  });
  std::vector<float> maxima(std::size_t(height) * width);
  tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& cells) {
    for (int i = cells.begin(); i < cells.end(); ++i) {
      const std::vector<AxisPoint> along_v = peak_candidates(i, height, heights.height);
      for (int j = 0; j < width; ++j) {
        double m = 0.0;
        for (std::size_t n = 0; n < along_v.size(); ++n) {
          const AxisPoint& y = along_v[n];
          const int r0 = address_index(y.first, heights.height, address);
          if (n > 0 && n + 1 < along_v.size()) {  // a texel row inside the cell
            m = std::max(m, row_peak[std::size_t(r0) * width + j]);
            continue;
          }
          const int r1 = address_index(y.first + 1, heights.height, address);
          for (const AxisPoint& x : along_u[j]) {
            const double bottom = row_value(r0, x);
            m = std::max(m, bottom + (row_value(r1, x) - bottom) * y.weight);
          }
        }
        // rounded up, so that it stays an upper bound of s
        maxima[std::size_t(i) * width + j] = detail::float_at_least(m);
      }
    }
  });
  return maxima;
}

// One line of the transform (step 3) along an axis of `count` cells of `spacing`: output[q] = min
// over cells c of gap(q, c)^2 + input[c], gap from the interval spanning q's neighbours' centres
// (q's own centre when count is 1) to the box of c. Scratch is kept between lines.
struct LineTransform {
  std::vector<double> input, output;
  std::vector<double> nearest;                  // centre-to-cell transform, before the neighbour min
  std::vector<double> position, value, breaks;  // parabolas rooted at cell edges; envelope breaks
  std::vector<int> hull;                        // parabolas on the lower envelope, left to right

  void run(int count, double spacing, bool periodic) {
    output.resize(count);
    if (std::all_of(input.begin(), input.begin() + count, [](double x) { return x == 0.0; })) {
      std::fill(output.begin(), output.end(), 0.0);  // inside the solid's boxes: nothing to transform
      return;
    }
    nearest.resize(count);
    centre_to_cell(count, spacing, periodic);
    // min over the neighbours q - 1, q, q + 1
    for (int q = 0; q < count; ++q) {
      double m = nearest[q];
      if (periodic) {
        m = std::min({m, nearest[(q + count - 1) % count], nearest[(q + 1) % count]});
      } else {
        if (q > 0) m = std::min(m, nearest[q - 1]);
        if (q + 1 < count) m = std::min(m, nearest[q + 1]);
      }
      output[q] = m;
    }
  }

  // nearest[q] = min over cells c of (gap from q's centre to the box of c)^2 + input[c]
  void centre_to_cell(int count, double spacing, bool periodic) {
    position.clear();
    value.clear();
    // edge e lies between cells e - 1 and e, at e * spacing; cell q's centre at (q + 0.5) * spacing
    if (periodic) {  // the images within half a period of [0, count): positions in [-count / 2, 3 count / 2]
      for (int period = -1; period <= 1; ++period)
        for (int e = 0; e < count; ++e) {
          if ((period < 0 && 2 * e < count) || (period > 0 && 2 * e > count)) continue;
          position.push_back(double(e + period * count) * spacing);
          value.push_back(std::min(input[(e + count - 1) % count], input[e]));
        }
    } else {
      for (int e = 1; e < count; ++e) {
        position.push_back(double(e) * spacing);
        value.push_back(std::min(input[e - 1], input[e]));
      }
    }
    const int sources = int(position.size());
    if (sources == 0) {
      std::copy(input.begin(), input.begin() + count, nearest.begin());
      return;
    }
    // lower envelope (Felzenszwalb & Huttenlocher, Algorithm 1)
    hull.resize(sources);
    breaks.resize(sources + 1);
    int k = 0;
    hull[0] = 0;
    breaks[0] = -std::numeric_limits<double>::infinity();
    breaks[1] = std::numeric_limits<double>::infinity();
    for (int s = 1; s < sources; ++s) {
      double crossing;
      for (;;) {
        const int r = hull[k];
        crossing = ((value[s] + position[s] * position[s]) - (value[r] + position[r] * position[r])) /
                   (2.0 * (position[s] - position[r]));
        if (crossing > breaks[k]) break;
        --k;  // stops at k = 0, whose break is -infinity
      }
      ++k;
      hull[k] = s;
      breaks[k] = crossing;
      breaks[k + 1] = std::numeric_limits<double>::infinity();
    }
    // evaluate at the cell centres, left to right
    k = 0;
    for (int q = 0; q < count; ++q) {
      const double x = (double(q) + 0.5) * spacing;
      while (breaks[k + 1] < x) ++k;
      const double offset = x - position[hull[k]];
      nearest[q] = std::min(input[q], offset * offset + value[hull[k]]);
    }
  }
};

// Step 1: half the extent of a voxel's support box along an axis of `count` voxels.
double tap_reach(int count) { return (count == 1 ? 0.5 : 1.0) / count; }

}  // namespace

BakeStats bake_distance_map(HeightView heights, Address address, DistanceView out) {
  validate(heights, out);
  const auto start = std::chrono::steady_clock::now();
  const int width = out.width, height = out.height, depth = out.depth;
  const bool periodic = address == Address::wrap;
  const double spacing_u = 1.0 / width, spacing_v = 1.0 / height, spacing_h = 1.0 / depth;
  const double reach_h = tap_reach(depth);
  const std::vector<float> maxima = footprint_maxima(heights, address, width, height);

  // along u: from the analytic h part (B's bottom against the footprint's top) to squared
  // distances, kept in `out` between the passes
  tbb::parallel_for(tbb::blocked_range<int>(0, depth * height), [&](const tbb::blocked_range<int>& lines) {
    LineTransform line;
    line.input.resize(width);
    for (int n = lines.begin(); n < lines.end(); ++n) {
      const int k = n / height, i = n % height;
      const double bottom = (double(k) + 0.5) * spacing_h - reach_h;
      const float* row_max = maxima.data() + std::size_t(i) * width;
      for (int j = 0; j < width; ++j) {
        const double gap = std::max(0.0, bottom - double(row_max[j]));
        line.input[j] = gap * gap;
      }
      line.run(width, spacing_u, periodic);
      float* row = out.data + std::size_t(n) * width;
      for (int j = 0; j < width; ++j) row[j] = float(line.output[j]);
    }
  });

  // along v, then the distance, rounded down
  tbb::parallel_for(tbb::blocked_range<int>(0, depth * width), [&](const tbb::blocked_range<int>& lines) {
    LineTransform line;
    line.input.resize(height);
    for (int n = lines.begin(); n < lines.end(); ++n) {
      const int k = n / width, j = n % width;
      float* column = out.data + std::size_t(k) * height * width + j;
      for (int i = 0; i < height; ++i) line.input[i] = column[std::size_t(i) * width];
      line.run(height, spacing_v, periodic);
      for (int i = 0; i < height; ++i)
        column[std::size_t(i) * width] = detail::float_at_most(std::sqrt(line.output[i]) - rounding_margin);
    }
  });

  BakeStats stats;
  stats.mode = Mode::exact;
  stats.width = width;
  stats.height = height;
  stats.milliseconds =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  stats.mean_ratio = detail::mean_of(out.data, std::size_t(width) * height * depth);
  return stats;
}

}  // namespace displace::bake
