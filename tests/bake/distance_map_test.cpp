// tests/bake/distance_map_test.cpp - the distance map (bake/distance_map.cpp).
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
#include "tests/bake/bake_checks.h"
#include "tests/test_maps.h"

namespace displace::bake {
namespace {

using test::Map;

// ---- distance map (bake_distance_map) ----

struct DistanceMap {
  int width = 0, height = 0, depth = 0;
  std::vector<float> values;
  DistanceView view() { return {values.data(), width, height, depth}; }
  float at(int k, int i, int j) const { return values[(std::size_t(k) * height + i) * width + j]; }
};

DistanceMap make_distance_map(int width, int height, int depth) {
  return {width, height, depth, std::vector<float>(std::size_t(width) * height * depth, -1.0f)};
}

// The shader's sample: trilinear between voxel centres, clamp-to-edge in h, the address mode in u, v.
double sample_trilinear(const DistanceMap& map, Address address, double u, double v, double h) {
  auto taps = [](double coordinate, int count, Address mode, int& first, int& second, double& t) {
    const double x = coordinate * count - 0.5, fx = std::floor(x);
    t = x - fx;
    first = address_texel(int(fx), count, mode);
    second = address_texel(int(fx) + 1, count, mode);
  };
  int j0, j1, i0, i1, k0, k1;
  double tu, tv, th;
  taps(u, map.width, address, j0, j1, tu);
  taps(v, map.height, address, i0, i1, tv);
  taps(h, map.depth, Address::clamp, k0, k1, th);
  auto layer = [&](int k) {
    return (map.at(k, i0, j0) * (1 - tu) + map.at(k, i0, j1) * tu) * (1 - tv) +
           (map.at(k, i1, j0) * (1 - tu) + map.at(k, i1, j1) * tu) * tv;
  };
  return layer(k0) * (1 - th) + layer(k1) * th;
}

// Brute-force bracket of the true distance to the bilinear solid, on a fine uv lattice of
// fine_u x fine_v cells. upper: the nearest of the solid points (q, min(h, s(q))) over lattice points
// q (real solid points, so >= the truth). lower: the nearest of the boxes cell x (-inf, max of s at
// the cell's corners] (the cells nest in the bilinear patches, where s peaks at a corner, so the
// boxes hold the solid and this is <= the truth). The lattice also nests in the distance map's
// footprints, so its boxes lie inside the baker's boxes: a correct map is <= lower everywhere,
// with no tolerance but float rounding.
struct DistanceReference {
  int fine_u = 0, fine_v = 0;
  bool periodic = true;
  std::vector<double> point_height;  // (fine_v + 1) x (fine_u + 1) lattice points
  std::vector<double> cell_max;      // fine_v x fine_u cells

  // Cells per axis: a multiple of 2 * texels (texel centres on the lattice) and of voxels
  // (footprint edges on it), at least 4 times finer than the texels.
  static int cells_for(int texels, int voxels) {
    const int base = std::lcm(2 * texels, voxels);
    return base * std::max(1, (4 * texels + base - 1) / base);
  }

  DistanceReference(const Map& map, Address address, int map_width, int map_height)
      : fine_u(cells_for(map.width, map_width)),
        fine_v(cells_for(map.height, map_height)),
        periodic(address == Address::wrap) {
    point_height.resize(std::size_t(fine_v + 1) * (fine_u + 1));
    for (int b = 0; b <= fine_v; ++b)
      for (int a = 0; a <= fine_u; ++a)
        point_height[std::size_t(b) * (fine_u + 1) + a] =
            surface(map, address, double(a) / fine_u, double(b) / fine_v);
    cell_max.resize(std::size_t(fine_v) * fine_u);
    for (int b = 0; b < fine_v; ++b)
      for (int a = 0; a < fine_u; ++a) {
        auto p = [&](int db, int da) { return point_height[std::size_t(b + db) * (fine_u + 1) + a + da]; };
        cell_max[std::size_t(b) * fine_u + a] =
            std::max(std::max(p(0, 0), p(0, 1)), std::max(p(1, 0), p(1, 1)));
      }
  }

  // Signed offset from x to y along a unit-period axis: the nearest image with wrap.
  double offset(double x, double y) const {
    double d = y - x;
    if (periodic) d -= std::round(d);
    return d;
  }

  void bracket(double u, double v, double h, double& lower, double& upper) const {
    double lower2 = std::numeric_limits<double>::infinity(), upper2 = lower2;
    std::vector<double> cell_gap_u(fine_u), point_du(fine_u + 1);
    for (int a = 0; a < fine_u; ++a) {
      const double gap = std::max(0.0, std::abs(offset(u, (a + 0.5) / fine_u)) - 0.5 / fine_u);
      cell_gap_u[a] = gap * gap;
    }
    for (int a = 0; a <= fine_u; ++a)
      point_du[a] = offset(u, double(a) / fine_u) * offset(u, double(a) / fine_u);
    for (int b = 0; b < fine_v; ++b) {
      const double gap = std::max(0.0, std::abs(offset(v, (b + 0.5) / fine_v)) - 0.5 / fine_v);
      for (int a = 0; a < fine_u; ++a) {
        const double above = std::max(0.0, h - cell_max[std::size_t(b) * fine_u + a]);
        lower2 = std::min(lower2, cell_gap_u[a] + gap * gap + above * above);
      }
    }
    for (int b = 0; b <= fine_v; ++b) {
      const double dv = offset(v, double(b) / fine_v);
      for (int a = 0; a <= fine_u; ++a) {
        const double above = std::max(0.0, h - point_height[std::size_t(b) * (fine_u + 1) + a]);
        upper2 = std::min(upper2, point_du[a] + dv * dv + above * above);
      }
    }
    lower = std::sqrt(lower2);
    upper = std::sqrt(upper2);
  }
};

std::vector<Map> distance_maps(int w, int h) {
  return {named_flat(w, h, 0.0f),  named_flat(w, h, 1.0f), named_flat(w, h, 0.5f),
          make_single_spike(w, h), make_ramp(w, h),        test::make_checkerboard(w, h),
          make_noise(w, h)};
}

struct DistanceCheck {
  long long points = 0, violations = 0;
  long long inside_nonzero = 0;              // points inside the solid with a sample above the tolerance
  double worst_excess = 0.0;                 // largest sample - lower bound
  double stored_sum = 0.0, exact_sum = 0.0;  // over checked voxel centres: stored, and upper bound
  double tightness() const { return exact_sum > 0.0 ? stored_sum / exact_sum : 1.0; }
};

constexpr double distance_tolerance = 1e-5;  // uv: float rounding of the stored and sampled values

constexpr int centres_checked = 256;  // voxel centres checked per map (all if fewer)

constexpr int random_points_checked = 256;  // points between centres checked per map

// Every checked point: the trilinear sample of `map` is <= the reference's lower bound (+ rounding),
// and 0 inside the solid.
DistanceCheck check_distance_map(const Map& heights, Address address, const DistanceMap& map,
                                 const DistanceReference& reference) {
  DistanceCheck check;
  auto visit = [&](double u, double v, double h, const float* stored) {
    double lower, upper;
    reference.bracket(u, v, h, lower, upper);
    EXPECT_LE(lower, upper + 1e-12);
    const double value = stored ? double(*stored) : sample_trilinear(map, address, u, v, h);
    ++check.points;
    if (value > lower + distance_tolerance) ++check.violations;
    check.worst_excess = std::max(check.worst_excess, value - lower);
    if (h <= surface(heights, address, u, v) && value > distance_tolerance) ++check.inside_nonzero;
    if (stored) {
      check.stored_sum += value;
      check.exact_sum += upper;
    }
  };
  const long long voxels = (long long)map.width * map.height * map.depth;
  for (long long c = 0; c < std::min<long long>(voxels, centres_checked); ++c) {
    const long long n =
        voxels <= centres_checked ? c : (long long)(test::mix(c + 17) % std::uint64_t(voxels));
    const int j = int(n % map.width), i = int(n / map.width % map.height),
              k = int(n / map.width / map.height);
    const float& stored = map.values[std::size_t(n)];
    // the sample at a centre is the stored value itself
    EXPECT_NEAR(
        sample_trilinear(map, address, (j + 0.5) / map.width, (i + 0.5) / map.height, (k + 0.5) / map.depth),
        stored, 1e-6);
    visit((j + 0.5) / map.width, (i + 0.5) / map.height, (k + 0.5) / map.depth, &stored);
  }
  // between centres; with wrap also beyond [0, 1] in u and v; h a little outside [0, 1]
  const double lo = address == Address::wrap ? -0.25 : 0.0, span = address == Address::wrap ? 1.5 : 1.0;
  for (int n = 0; n < random_points_checked; ++n) {
    const double u = lo + span * test::hash01(101, n, 1), v = lo + span * test::hash01(101, n, 2);
    const double h = -0.05 + 1.1 * test::hash01(101, n, 3);
    visit(u, v, h, nullptr);
  }
  // the domain's corners and faces
  for (double u : {0.0, 1.0})
    for (double v : {0.0, 0.5, 1.0})
      for (double h : {0.0, 1.0 / 3.0, 1.0}) visit(u, v, h, nullptr), visit(v, u, h, nullptr);
  return check;
}

TEST(DistanceMap, TrilinearSamplesNeverExceedTheBruteForceDistance) {
  long long total_points = 0;
  for (const auto& [width, height] : {std::pair{1, 1}, std::pair{7, 5}, std::pair{16, 16}})
    for (const Map& heights : distance_maps(width, height))
      for (Address address : {Address::wrap, Address::clamp}) {
        const DistanceReference reference(heights, address, width, height);
        for (int depth : {8, 16}) {
          DistanceMap map = make_distance_map(width, height, depth);
          const BakeStats stats = bake_distance_map(view_of(heights), address, map.view());
          for (float value : map.values) ASSERT_TRUE(value >= 0.0f && std::isfinite(value));
          for (int i = 0; i < height; ++i)
            for (int j = 0; j < width; ++j)
              ASSERT_EQ(map.at(0, i, j), 0.0f) << "the bottom layer is in the solid";
          EXPECT_EQ(stats.width, width);
          EXPECT_EQ(stats.height, height);
          const DistanceCheck check = check_distance_map(heights, address, map, reference);
          std::printf(
              "distance %-13s %2dx%-2d depth %2d %-5s: %lld/%lld over the lower bound (worst %+.2g), "
              "tightness %.3f\n",
              heights.name.c_str(), width, height, depth, address_name(address), check.violations,
              check.points, check.worst_excess, check.tightness());
          ASSERT_EQ(check.violations, 0)
              << heights.name << " " << width << "x" << height << " depth " << depth << " "
              << address_name(address) << " worst " << check.worst_excess;
          ASSERT_EQ(check.inside_nonzero, 0) << heights.name << " " << address_name(address);
          total_points += check.points;
        }
      }
  EXPECT_GT(total_points, 10000);
}

// Distance maps coarser and finer than the height map (footprints spanning several texels or parts
// of one), checked the same way.
TEST(DistanceMap, ConservativeWhenTheMapAndHeightSizesDiffer) {
  struct Case {
    Map heights;
    int width, height, depth;
  };
  const Case cases[] = {{make_noise(16, 16), 8, 8, 8},
                        {test::make_checkerboard(16, 12), 5, 3, 16},
                        {make_single_spike(7, 5), 16, 16, 8},
                        {make_ramp(5, 9), 12, 4, 16},
                        {make_noise(9, 6), 1, 1, 8}};
  for (const Case& c : cases)
    for (Address address : {Address::wrap, Address::clamp}) {
      DistanceMap map = make_distance_map(c.width, c.height, c.depth);
      bake_distance_map(view_of(c.heights), address, map.view());
      const DistanceCheck check = check_distance_map(
          c.heights, address, map, DistanceReference(c.heights, address, c.width, c.height));
      ASSERT_EQ(check.violations, 0) << c.heights.name << " " << c.heights.width << "x" << c.heights.height
                                     << " into " << c.width << "x" << c.height << "x" << c.depth << " "
                                     << address_name(address) << " worst " << check.worst_excess;
      ASSERT_EQ(check.inside_nonzero, 0) << c.heights.name << " " << address_name(address);
    }
}

// The check has teeth: a map 10% above the truth (the reference's lower bound at the centres, so
// just under the truth, times 1.1) fails it wherever the distance is not tiny.
TEST(DistanceMap, CheckCatchesAMapTenPercentTooLarge) {
  for (const Map& heights : {make_noise(16, 16), make_single_spike(7, 5), named_flat(16, 16, 0.5f)})
    for (Address address : {Address::wrap, Address::clamp}) {
      const DistanceReference reference(heights, address, heights.width, heights.height);
      DistanceMap map = make_distance_map(heights.width, heights.height, 8);
      for (int k = 0; k < map.depth; ++k)
        for (int i = 0; i < map.height; ++i)
          for (int j = 0; j < map.width; ++j) {
            double lower, upper;
            reference.bracket((j + 0.5) / map.width, (i + 0.5) / map.height, (k + 0.5) / map.depth, lower,
                              upper);
            map.values[(std::size_t(k) * map.height + i) * map.width + j] = float(1.1 * lower);
          }
      const DistanceCheck check = check_distance_map(heights, address, map, reference);
      EXPECT_GT(check.violations, check.points / 4) << heights.name << " " << address_name(address);
    }
}

// Where the boxes are the solid - a flat floor - a voxel stores exactly the distance from the bottom
// of its support box, h - 1 / depth, and the mean is reported in the stats.
TEST(DistanceMap, FlatFloorIsTheDistanceFromTheSupportBoxBottom) {
  for (int depth : {1, 8, 16, 64})
    for (Address address : {Address::wrap, Address::clamp}) {
      const Map floor = named_flat(16, 16, 0.0f);
      DistanceMap map = make_distance_map(16, 16, depth);
      const BakeStats stats = bake_distance_map(view_of(floor), address, map.view());
      double sum = 0.0;
      for (int k = 0; k < depth; ++k)
        for (int i = 0; i < 16; ++i)
          for (int j = 0; j < 16; ++j) {
            ASSERT_NEAR(map.at(k, i, j), std::max(0.0, (k - 0.5) / depth), 2e-6) << k << " " << i << " " << j;
            sum += map.at(k, i, j);
          }
      EXPECT_NEAR(stats.mean_ratio, sum / map.values.size(), 1e-9);
      EXPECT_GE(stats.milliseconds, 0.0);
    }
}

// Not trivially zero: mean stored / mean brute-force distance over the checked centres stays above
// floors measured on these maps (measured values in parentheses, wrap / clamp). Rough maps at
// 16x16 (checkerboard, noise: tightness 0.02 - 0.05 at depth 16, printed above) get no floor: their
// mean distance, about 0.02 uv, is under a third of a voxel, and even the best map of this family,
// min over each support box of a fine-grid distance, reaches only 0.03 - 0.05 there.
TEST(DistanceMap, TightnessAboveTheMeasuredFloors) {
  struct Case {
    Map heights;
    int depth;
    double floor;
  };
  const Case cases[] = {{named_flat(16, 16, 0.0f), 16, 0.85},          // (0.880 / 0.880)
                        {named_flat(16, 16, 0.5f), 16, 0.73},          // (0.763 / 0.763)
                        {make_single_spike(16, 16), 16, 0.62},         // (0.647 / 0.647)
                        {make_ramp(16, 16), 16, 0.40},                 // (0.432 / 0.579)
                        {test::make_fractal_cliff(64, 64), 32, 0.75},  // (0.782 / 0.814)
                        {test::make_terraces(64, 48), 32, 0.70},       // (0.732 / 0.748)
                        {test::make_spikes(64, 64), 32, 0.62}};        // (0.646 / 0.668)
  for (const Case& c : cases)
    for (Address address : {Address::wrap, Address::clamp}) {
      const DistanceReference reference(c.heights, address, c.heights.width, c.heights.height);
      DistanceMap map = make_distance_map(c.heights.width, c.heights.height, c.depth);
      bake_distance_map(view_of(c.heights), address, map.view());
      const DistanceCheck check = check_distance_map(c.heights, address, map, reference);
      std::printf("distance %-13s %2dx%-2d depth %2d %-5s: tightness %.3f (floor %.2f)\n",
                  c.heights.name.c_str(), c.heights.width, c.heights.height, c.depth, address_name(address),
                  check.tightness(), c.floor);
      EXPECT_EQ(check.violations, 0) << c.heights.name << " " << address_name(address);
      EXPECT_GE(check.tightness(), c.floor) << c.heights.name << " " << address_name(address);
    }
}

TEST(DistanceMap, RejectsBadInput) {
  std::vector<float> voxels(4 * 4 * 4);
  const Map ok = test::make_flat(4, 4);
  Map nan_map = test::make_flat(4, 4);
  nan_map.at(1, 2) = std::nanf("");
  Map high = test::make_flat(4, 4);
  high.at(3, 0) = 1.01f;
  Map low = test::make_flat(4, 4);
  low.at(0, 3) = -0.01f;
  const DistanceView out{voxels.data(), 4, 4, 4};
  EXPECT_THROW(bake_distance_map(view_of(nan_map), Address::wrap, out), BakeError);
  EXPECT_THROW(bake_distance_map(view_of(high), Address::wrap, out), BakeError);
  EXPECT_THROW(bake_distance_map(view_of(low), Address::clamp, out), BakeError);
  EXPECT_THROW(bake_distance_map({nullptr, 4, 4}, Address::wrap, out), BakeError);
  EXPECT_THROW(bake_distance_map({ok.values.data(), 0, 4}, Address::wrap, out), BakeError);
  EXPECT_THROW(bake_distance_map(view_of(ok), Address::wrap, {nullptr, 4, 4, 4}), BakeError);
  EXPECT_THROW(bake_distance_map(view_of(ok), Address::wrap, {voxels.data(), 0, 4, 4}), BakeError);
  EXPECT_THROW(bake_distance_map(view_of(ok), Address::wrap, {voxels.data(), 4, -1, 4}), BakeError);
  EXPECT_THROW(bake_distance_map(view_of(ok), Address::wrap, {voxels.data(), 4, 4, 0}), BakeError);
  EXPECT_THROW(bake_distance_map(view_of(ok), Address::wrap, {voxels.data(), 1, 1, 1025}), BakeError);
  EXPECT_THROW(bake_distance_map(view_of(ok), Address::wrap, {voxels.data(), 40000, 1, 1}), BakeError);
  EXPECT_THROW(bake_distance_map(view_of(ok), Address::wrap, {voxels.data(), 32768, 32768, 2}), BakeError);
  EXPECT_NO_THROW(bake_distance_map(view_of(ok), Address::wrap, out));
}

}  // namespace
}  // namespace displace::bake
