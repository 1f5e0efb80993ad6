// tests/bake/bake_checks.h - what the bakers' tests share: brute-force references written from the
// definition in bake/bake.h, the checks that compare a baker with them, and the maps they run on.
// Moved from tests/bake_test.cpp; functions are inline, in the anonymous namespace the tests use.
#pragma once

#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <numbers>
#include <numeric>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "bake/bake.h"
#include "bake/lane_sweep.h"
#include "tests/test_maps.h"

namespace displace::bake {
namespace {

using test::Map;

struct ConeMap {
  int width = 0, height = 0, sectors = 0;
  std::vector<float> ratios;
  ConeView view() { return {ratios.data(), width, height, sectors}; }
  float at(int i, int j, int k) const { return ratios[(std::size_t(i) * width + j) * sectors + k]; }
};

inline ConeMap make_cone_map(const Map& map, int sectors) {
  return {map.width, map.height, sectors, std::vector<float>(std::size_t(map.width) * map.height * sectors)};
}

inline HeightView view_of(const Map& map) { return {map.values.data(), map.width, map.height}; }

inline std::vector<Map> hard_maps() {
  return {test::make_spikes(24, 24),       test::make_terraces(20, 16),
          test::make_checkerboard(16, 16), test::make_fractal_cliff(32, 32),
          test::make_flat(12, 12),         test::make_near_flat_step(17, 13),
          test::make_flat(1, 1),           test::make_fractal_cliff(13, 7),
          test::make_bricks(30, 18),       test::make_spikes(1, 9)};
}

inline const char* address_name(Address a) { return a == Address::wrap ? "wrap" : "clamp"; }

inline ConeMap exact_of(const Map& map, int sectors, Address address) {
  ConeMap exact = make_cone_map(map, sectors);
  bake_exact(view_of(map), address, exact.view());
  return exact;
}

// Number of ratios above the exact ones (bit for bit) and the largest over-claim factor.
struct Violations {
  long long count = 0;
  double worst = 1.0;
};

inline Violations violations(const ConeMap& cones, const ConeMap& exact) {
  Violations v;
  for (std::size_t n = 0; n < cones.ratios.size(); ++n)
    if (cones.ratios[n] > exact.ratios[n]) {
      ++v.count;
      v.worst = std::max(v.worst, double(cones.ratios[n]) / double(exact.ratios[n]));
    }
  return v;
}

// A clock that advances by `step` milliseconds at every reading (thread safe).
struct FakeClock {
  std::shared_ptr<std::atomic<long long>> ticks = std::make_shared<std::atomic<long long>>(0);
  double step = 1.0;
  std::function<double()> function() const {
    auto t = ticks;
    const double s = step;
    return [t, s] { return double(t->fetch_add(1)) * s; };
  }
};

// Small non-square maps, wide and tall, one side a multiple of the other or not.
inline std::vector<Map> aspect_maps() {
  return {
      test::make_fractal_cliff(48, 24),  test::make_bricks(64, 16),           test::make_spikes(20, 40, 5),
      test::make_terraces(12, 36),       test::make_fractal_cliff(80, 5, 7),  test::make_spikes(6, 54, 9),
      test::make_near_flat_step(40, 20), test::make_fractal_cliff(33, 20, 4), test::make_checkerboard(8, 24)};
}

inline int address_texel(int index, int count, Address address) {
  if (address == Address::clamp) return std::clamp(index, 0, count - 1);
  return ((index % count) + count) % count;
}

// The bilinear surface s(u, v) of bake.h with the address mode, in double.
inline double surface(const Map& map, Address address, double u, double v) {
  const double x = u * map.width - 0.5, y = v * map.height - 0.5;
  const double fx = std::floor(x), fy = std::floor(y);
  const double tx = x - fx, ty = y - fy;
  const int j0 = address_texel(int(fx), map.width, address),
            j1 = address_texel(int(fx) + 1, map.width, address);
  const int i0 = address_texel(int(fy), map.height, address),
            i1 = address_texel(int(fy) + 1, map.height, address);
  auto h = [&](int i, int j) { return double(map.values[std::size_t(i) * map.width + j]); };
  return (h(i0, j0) * (1 - tx) + h(i0, j1) * tx) * (1 - ty) + (h(i1, j0) * (1 - tx) + h(i1, j1) * tx) * ty;
}

inline Map make_single_spike(int w, int h) {
  Map m = test::make_flat(w, h, 0.1f);
  m.name = "single-spike";
  m.at(h / 2, w / 2) = 0.95f;
  return m;
}

inline Map make_ramp(int w, int h) {
  Map m{"ramp", w, h, std::vector<float>(std::size_t(w) * h)};
  for (int i = 0; i < h; ++i)
    for (int j = 0; j < w; ++j) m.at(i, j) = w > 1 ? float(j) / float(w - 1) : 0.5f;
  return m;
}

inline Map make_noise(int w, int h) {
  Map m{"noise", w, h, std::vector<float>(std::size_t(w) * h)};
  for (int i = 0; i < h; ++i)
    for (int j = 0; j < w; ++j) m.at(i, j) = test::hash01(29, i, j);
  return m;
}

inline Map named_flat(int w, int h, float value) {
  Map m = test::make_flat(w, h, value);
  m.name = "flat-" + std::to_string(value).substr(0, 3);
  return m;
}

// ---- cone maps for the bilinear surface (bake_bilinear_cones)

struct BilinearCones {
  ConeMap cones;
  std::vector<float> apex;
  BakeStats stats;
};

inline BilinearCones bake_bilinear(const Map& map, int sectors, Address address,
                                   int window = BilinearConeSettings{}.slope_window) {
  BilinearCones b{make_cone_map(map, sectors), std::vector<float>(map.values.size()), {}};
  b.stats = bake_bilinear_cones(view_of(map), address, b.cones.view(), b.apex, {window});
  return b;
}

inline double mean_ratio(const ConeMap& cones) {
  return std::accumulate(cones.ratios.begin(), cones.ratios.end(), 0.0) / double(cones.ratios.size());
}

// Sample positions: `sample_units` per texel along each axis, position X along u at texel-centre
// coordinate X / sample_units (texel j's centre at X = sample_units * j), u = (X / units + 0.5) / W.
constexpr int sample_units = 32;

// Sectors (bit k) whose closed wedge holds the uv direction of a sample offset (dx, dy), from the
// definition: exact on the sector edges (multiples of 45 degrees, both sectors), atan2 elsewhere.
inline unsigned direction_sectors(long long dx, long long dy, int width, int height, int sectors) {
  if (sectors == 1) return 1u;
  const long long x = dx * height, y = dy * width;  // the uv offset times units * W * H
  const int octants = 8 / sectors;                  // octants per sector
  if (x == 0 || y == 0 || std::llabs(x) == std::llabs(y)) {
    const int m = y == 0   ? (x > 0 ? 0 : 4)
                  : x == 0 ? (y > 0 ? 2 : 6)
                  : x > 0  ? (y > 0 ? 1 : 7)
                           : (y > 0 ? 3 : 5);
    unsigned mask = 1u << (m / octants);
    if (m % octants == 0) mask |= 1u << ((m / octants + sectors - 1) % sectors);
    return mask;
  }
  double azimuth = std::atan2(double(y), double(x));
  if (azimuth < 0.0) azimuth += 2.0 * std::numbers::pi;
  return 1u << std::min(sectors - 1, int(azimuth / (2.0 * std::numbers::pi / sectors)));
}

struct BilinearCheck {
  long long pairs = 0;       // (p, x) pairs with x above the apex, checked
  long long violations = 0;  // pairs with s(x) > H_c + |x - p| / r_k + 1e-6 for a sector k of x - p
  double worst = 0.0;        // largest excess
  // per texel and sector: the smallest |x - p| / (s(x) - H_c) over the samples, clamped to 1 - an
  // upper bound of the best ratio any conservative baker could store for this H_c
  std::vector<double> sampled;
};

// Brute force: for texels c (every `stride`-th), points p in Q_c (its corners, edge midpoints, centre
// and two random points) and surface points x on a quarter-texel grid (cell corners, edge
// midpoints, quarter points) plus random points, over every x within uv distance 1 of p (wrap:
// periodic images; clamp: [0, 1]^2), s(x) <= H_c + |x - p| / r_k for each sector k holding x - p.
inline BilinearCheck check_bilinear(const Map& map, Address address, const ConeMap& cones,
                                    const std::vector<float>& apex, int stride = 1) {
  struct Point {
    int x, y;
    double s;
  };
  const int W = map.width, H = map.height, half = sample_units / 2;
  // x samples: u in [-1, 2] with wrap, [0, 1] with clamp
  const int lo_x = address == Address::wrap ? -half - sample_units * W : -half;
  const int hi_x = address == Address::wrap ? sample_units * 2 * W - half : sample_units * W - half;
  const int lo_y = address == Address::wrap ? -half - sample_units * H : -half;
  const int hi_y = address == Address::wrap ? sample_units * 2 * H - half : sample_units * H - half;
  std::vector<Point> points;
  auto add = [&](int x, int y) {
    const double u = (double(x) / sample_units + 0.5) / W, v = (double(y) / sample_units + 0.5) / H;
    points.push_back({x, y, surface(map, address, u, v)});
  };
  for (int y = lo_y; y <= hi_y; y += sample_units / 4)
    for (int x = lo_x; x <= hi_x; x += sample_units / 4) add(x, y);
  const int random_points = 8 * W * H;
  for (int n = 0; n < random_points; ++n)
    add(lo_x + int(test::hash01(5, n, 1) * (hi_x - lo_x)), lo_y + int(test::hash01(5, n, 2) * (hi_y - lo_y)));

  BilinearCheck check;
  const int sectors = cones.sectors;
  check.sampled.assign(cones.ratios.size(), 1.0);
  for (int i = 0; i < H; ++i)
    for (int j = 0; j < W; ++j) {
      if ((i * W + j) % stride != 0) continue;
      const double hc = apex[std::size_t(i) * W + j];
      std::vector<std::pair<int, int>> ps;
      for (int a = -1; a <= 1; ++a)
        for (int b = -1; b <= 1; ++b)
          ps.emplace_back(sample_units * j + a * half, sample_units * i + b * half);
      for (int n = 0; n < 2; ++n)
        ps.emplace_back(sample_units * j - half + int(test::hash01(9, i * W + j, n) * sample_units),
                        sample_units * i - half + int(test::hash01(9, i * W + j, n + 2) * sample_units));
      for (const auto& [px, py] : ps)
        for (const Point& x : points) {
          const double gap = x.s - hc;
          if (!(gap > 1e-6)) continue;
          const long long dx = x.x - px, dy = x.y - py;
          const double du = double(dx) / (sample_units * W), dv = double(dy) / (sample_units * H);
          const double distance = std::sqrt(du * du + dv * dv);
          if (distance >= 1.0) continue;  // ratios are at most 1 and gaps at most 1
          ++check.pairs;
          if (distance >= gap) continue;  // below H_c + distance, so below every cone
          const unsigned mask =
              dx == 0 && dy == 0 ? (1u << sectors) - 1u : direction_sectors(dx, dy, W, H, sectors);
          for (int k = 0; k < sectors; ++k) {
            if (!(mask >> k & 1u)) continue;
            double& sampled = check.sampled[(std::size_t(i) * W + j) * sectors + k];
            sampled = std::min(sampled, distance / gap);
            const double excess = x.s - (hc + distance / cones.at(i, j, k));
            if (excess > 1e-6) {
              ++check.violations;
              check.worst = std::max(check.worst, excess);
            }
          }
        }
    }
  return check;
}

inline std::vector<Map> bilinear_maps() {
  Map steep = make_noise(6, 6);
  steep.name = "noise-6x6";
  Map step = test::make_flat(9, 7, 0.2f);
  step.name = "step";
  for (int i = 0; i < 7; ++i)
    for (int j = 4; j < 9; ++j) step.at(i, j) = 0.9f;
  Map one = test::make_flat(1, 1, 0.3f);
  one.name = "one-texel";
  return {steep,
          make_noise(2, 3),
          make_noise(7, 4),
          make_noise(5, 1),
          test::make_spikes(9, 9),
          test::make_spikes(1, 6),
          make_single_spike(7, 5),
          step,
          test::make_checkerboard(8, 8),
          test::make_checkerboard(3, 5),
          test::make_fractal_cliff(10, 8),
          test::make_near_flat_step(9, 7),
          test::make_terraces(10, 8),
          test::make_bricks(12, 8),
          make_ramp(8, 6),
          named_flat(5, 4, 0.5f),
          one};
}

}  // namespace
}  // namespace displace::bake
