// tests/bake_test.cpp - every baker against the definition in bake/bake.h.
#include "bake/bake.h"

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

ConeMap make_cone_map(const Map& map, int sectors) {
  return {map.width, map.height, sectors, std::vector<float>(std::size_t(map.width) * map.height * sectors)};
}
HeightView view_of(const Map& map) { return {map.values.data(), map.width, map.height}; }

// All pairs, written straight from the definition with its own arithmetic (double, atan2).
ConeMap brute_force(const Map& map, int sectors, Address address) {
  ConeMap cones = make_cone_map(map, sectors);
  const double two_pi = 2.0 * std::numbers::pi;
  const int tiles = address == Address::wrap ? 1 : 0;
  for (int ci = 0; ci < map.height; ++ci)
    for (int cj = 0; cj < map.width; ++cj) {
      const double hc = map.values[std::size_t(ci) * map.width + cj];
      std::vector<double> best(sectors, 1.0);
      for (int qi = 0; qi < map.height; ++qi)
        for (int qj = 0; qj < map.width; ++qj) {
          const double hq = map.values[std::size_t(qi) * map.width + qj];
          if (!(hq > hc)) continue;
          for (int ty = -tiles; ty <= tiles; ++ty)
            for (int tx = -tiles; tx <= tiles; ++tx) {
              const double du = double(qj + tx * map.width - cj) / map.width;
              const double dv = double(qi + ty * map.height - ci) / map.height;
              const double ratio = std::sqrt(du * du + dv * dv) / (hq - hc);
              double azimuth = std::atan2(dv, du);
              if (azimuth < 0) azimuth += two_pi;
              const double sector_width = two_pi / sectors;
              for (int k = 0; k < sectors; ++k) {
                const double lo = k * sector_width, hi = (k + 1) * sector_width;
                const double eps = 1e-10;
                const bool inside = (azimuth >= lo - eps && azimuth <= hi + eps) ||
                                    (k == sectors - 1 && azimuth <= eps) ||
                                    (k == 0 && azimuth >= two_pi - eps);
                if (inside && ratio < best[k]) best[k] = ratio;
              }
            }
        }
      for (int k = 0; k < sectors; ++k)
        cones.ratios[(std::size_t(ci) * map.width + cj) * sectors + k] = float(best[k]);
    }
  return cones;
}

std::vector<Map> hard_maps() {
  return {test::make_spikes(24, 24),       test::make_terraces(20, 16),
          test::make_checkerboard(16, 16), test::make_fractal_cliff(32, 32),
          test::make_flat(12, 12),         test::make_near_flat_step(17, 13),
          test::make_flat(1, 1),           test::make_fractal_cliff(13, 7),
          test::make_bricks(30, 18),       test::make_spikes(1, 9)};
}

const char* address_name(Address a) { return a == Address::wrap ? "wrap" : "clamp"; }

TEST(ExactBaker, MatchesAllPairsOnHardMaps) {
  for (const Map& map : hard_maps())
    for (int sectors : {1, 4, 8})
      for (Address address : {Address::wrap, Address::clamp}) {
        const ConeMap reference = brute_force(map, sectors, address);
        ConeMap exact = make_cone_map(map, sectors);
        bake_exact(view_of(map), address, exact.view());
        for (std::size_t n = 0; n < exact.ratios.size(); ++n)
          ASSERT_NEAR(exact.ratios[n], reference.ratios[n], 1e-5f * reference.ratios[n] + 1e-7f)
              << map.name << " " << map.width << "x" << map.height << " sectors " << sectors << " "
              << address_name(address) << " texel " << n / sectors << " sector " << n % sectors;
      }
}

TEST(OriginalBaker, EqualsExactBitForBit) {
  for (const Map& map : hard_maps())
    for (int sectors : {1, 4, 8})
      for (Address address : {Address::wrap, Address::clamp}) {
        ConeMap exact = make_cone_map(map, sectors), original = make_cone_map(map, sectors);
        bake_exact(view_of(map), address, exact.view());
        bake_original(view_of(map), address, original.view());
        ASSERT_EQ(exact.ratios, original.ratios)
            << map.name << " sectors " << sectors << " " << address_name(address);
      }
}

ConeMap exact_of(const Map& map, int sectors, Address address) {
  ConeMap exact = make_cone_map(map, sectors);
  bake_exact(view_of(map), address, exact.view());
  return exact;
}

// Number of ratios above the exact ones (bit for bit) and the largest over-claim factor.
struct Violations {
  long long count = 0;
  double worst = 1.0;
};
Violations violations(const ConeMap& cones, const ConeMap& exact) {
  Violations v;
  for (std::size_t n = 0; n < cones.ratios.size(); ++n)
    if (cones.ratios[n] > exact.ratios[n]) {
      ++v.count;
      v.worst = std::max(v.worst, double(cones.ratios[n]) / double(exact.ratios[n]));
    }
  return v;
}

TEST(MaxPyramid, ParentsAreMaximaOfChildrenForOddSizes) {
  const Map map = test::make_fractal_cliff(13, 7);
  const MaxPyramid pyramid = build_max_pyramid(view_of(map));
  ASSERT_EQ(pyramid.widths.back(), 1);
  ASSERT_EQ(pyramid.heights.back(), 1);
  for (std::size_t level = 1; level < pyramid.levels.size(); ++level) {
    const int w = pyramid.widths[level], h = pyramid.heights[level];
    const int fw = pyramid.widths[level - 1], fh = pyramid.heights[level - 1];
    EXPECT_EQ(w, (fw + 1) / 2);
    EXPECT_EQ(h, (fh + 1) / 2);
    for (int i = 0; i < h; ++i)
      for (int j = 0; j < w; ++j) {
        float m = 0.0f;
        for (int di = 0; di < 2; ++di)
          for (int dj = 0; dj < 2; ++dj)
            if (2 * i + di < fh && 2 * j + dj < fw)
              m = std::max(m, pyramid.levels[level - 1][std::size_t(2 * i + di) * fw + 2 * j + dj]);
        EXPECT_EQ(pyramid.levels[level][std::size_t(i) * w + j], m);
      }
  }
  EXPECT_EQ(pyramid.levels.back()[0], *std::max_element(map.values.begin(), map.values.end()));
}

// Built into a kept pyramid (the bakers' frame loop), the pyramid is the fresh one, whatever size the
// kept one had before.
TEST(MaxPyramid, RebuiltIntoAKeptPyramidEqualsAFreshOne) {
  MaxPyramid kept;
  for (const auto& [w, h] : {std::pair{13, 7}, std::pair{33, 20}, std::pair{5, 9}, std::pair{5, 9}}) {
    const Map map = test::make_fractal_cliff(w, h);
    build_max_pyramid(view_of(map), kept);
    const MaxPyramid fresh = build_max_pyramid(view_of(map));
    EXPECT_EQ(kept.widths, fresh.widths) << w << " x " << h;
    EXPECT_EQ(kept.heights, fresh.heights) << w << " x " << h;
    EXPECT_EQ(kept.levels, fresh.levels) << w << " x " << h;
  }
}

// The bilinear surface, written here from the convention in bake.h (texel centres at (j + 0.5) / W,
// wrap or clamp addressing), in double: x = u W - 0.5, y = v H - 0.5.
double bilinear_at(const Map& map, Address address, double x, double y) {
  auto texel = [&](long long i, long long j) {
    if (address == Address::wrap) {
      i = ((i % map.height) + map.height) % map.height;
      j = ((j % map.width) + map.width) % map.width;
    } else {
      i = std::clamp<long long>(i, 0, map.height - 1);
      j = std::clamp<long long>(j, 0, map.width - 1);
    }
    return double(map.values[std::size_t(i) * map.width + j]);
  };
  const double x0 = std::floor(x), y0 = std::floor(y), fx = x - x0, fy = y - y0;
  const auto j = (long long)x0, i = (long long)y0;
  return (texel(i, j) * (1 - fx) + texel(i, j + 1) * fx) * (1 - fy) +
         (texel(i + 1, j) * (1 - fx) + texel(i + 1, j + 1) * fx) * fy;
}

std::vector<Map> dual_pyramid_maps() {
  std::vector<Map> maps;
  std::uint64_t seed = 11;
  for (auto [w, h] :
       {std::pair{1, 1}, {1, 5}, {5, 1}, {2, 3}, {7, 13}, {16, 16}, {17, 9}, {32, 20}, {37, 29}}) {
    Map map{"random", w, h, std::vector<float>(std::size_t(w) * h)};
    for (int i = 0; i < h; ++i)
      for (int j = 0; j < w; ++j) map.at(i, j) = test::hash01(seed, i, j);
    maps.push_back(std::move(map));
    ++seed;
  }
  maps.push_back(test::make_spikes(23, 17));
  maps.push_back(test::make_fractal_cliff(19, 33));
  return maps;
}

// Every node against brute force: the bilinear surface sampled on a grid of quarter cells over the
// node's footprint (which includes every texel centre in it). A node never under-bounds the surface
// and equals its max (the max sits at a texel centre).
TEST(DualMaxPyramid, EveryNodeIsTheBilinearMaxOverItsFootprint) {
  constexpr int samples_per_cell = 4;
  for (const Map& map : dual_pyramid_maps()) {
    for (const Address address : {Address::wrap, Address::clamp}) {
      SCOPED_TRACE(map.name + " " + std::to_string(map.width) + "x" + std::to_string(map.height) +
                   (address == Address::wrap ? " wrap" : " clamp"));
      const DualMaxPyramid pyramid = build_dual_max_pyramid(view_of(map), address);
      const int cells_x = pyramid.widths[0], cells_y = pyramid.heights[0];
      ASSERT_EQ(pyramid.origin, address == Address::wrap ? 0 : -1);
      ASSERT_EQ(cells_x, address == Address::wrap ? map.width : map.width + 1);
      ASSERT_EQ(cells_y, address == Address::wrap ? map.height : map.height + 1);
      ASSERT_EQ(pyramid.widths.back(), 1);
      ASSERT_EQ(pyramid.heights.back(), 1);
      ASSERT_EQ(pyramid.offsets.back() + 1, pyramid.values.size());
      for (std::size_t level = 0; level < pyramid.widths.size(); ++level) {
        const int w = pyramid.widths[level], h = pyramid.heights[level], span = 1 << level;
        if (level > 0) {
          EXPECT_EQ(w, (pyramid.widths[level - 1] + 1) / 2);
          EXPECT_EQ(h, (pyramid.heights[level - 1] + 1) / 2);
        }
        for (int b = 0; b < h; ++b)
          for (int a = 0; a < w; ++a) {
            // footprint in cells, truncated at the grid's end
            const int x_lo = a * span, x_hi = std::min((a + 1) * span, cells_x);
            const int y_lo = b * span, y_hi = std::min((b + 1) * span, cells_y);
            double sampled = 0.0, at_centres = 0.0;
            for (int sy = y_lo * samples_per_cell; sy <= y_hi * samples_per_cell; ++sy)
              for (int sx = x_lo * samples_per_cell; sx <= x_hi * samples_per_cell; ++sx) {
                const double x = double(sx) / samples_per_cell + pyramid.origin;
                const double y = double(sy) / samples_per_cell + pyramid.origin;
                const double value = bilinear_at(map, address, x, y);
                sampled = std::max(sampled, value);
                if (sx % samples_per_cell == 0 && sy % samples_per_cell == 0)
                  at_centres = std::max(at_centres, value);
              }
            const float node = pyramid.values[pyramid.offsets[level] + std::size_t(b) * w + a];
            ASSERT_GE(double(node), sampled - 1e-12) << "level " << level << " node " << a << "," << b;
            ASSERT_EQ(double(node), at_centres) << "level " << level << " node " << a << "," << b;
          }
      }
    }
  }
}

// The lookup the renderer makes: a surface point at texture coordinates (u, v) (anywhere on a 3 x 3
// tiling with wrap, on the patch with clamp) falls in the node floor((u W - 0.5 - origin) / 2^L)
// (its period's with wrap) of every level, and that node is at least the surface there.
TEST(DualMaxPyramid, TheNodeUnderEverySurfacePointBoundsIt) {
  for (const Map& map : dual_pyramid_maps()) {
    for (const Address address : {Address::wrap, Address::clamp}) {
      const DualMaxPyramid pyramid = build_dual_max_pyramid(view_of(map), address);
      const double extent = address == Address::wrap ? 3.0 : 1.0;
      const int cells_x = pyramid.widths[0], cells_y = pyramid.heights[0];
      for (int sample = 0; sample < 2000; ++sample) {
        const double u = extent * test::hash01(97, sample, 1), v = extent * test::hash01(97, sample, 2);
        const double x = u * map.width - 0.5, y = v * map.height - 0.5;
        const double surface = bilinear_at(map, address, x, y);
        auto cell = [&](double coordinate, int cells) {
          const auto c = (long long)std::floor(coordinate - pyramid.origin);
          return int(address == Address::wrap ? ((c % cells) + cells) % cells : c);
        };
        const int cx = cell(x, cells_x), cy = cell(y, cells_y);
        ASSERT_TRUE(cx >= 0 && cx < cells_x && cy >= 0 && cy < cells_y) << u << "," << v;
        for (std::size_t level = 0; level < pyramid.widths.size(); ++level) {
          const float node =
              pyramid.values[pyramid.offsets[level] + std::size_t(cy >> level) * pyramid.widths[level] +
                             std::size_t(cx >> level)];
          ASSERT_GE(double(node), surface - 1e-12)
              << map.name << " at " << u << "," << v << " level " << level;
        }
      }
    }
  }
}

TEST(DualMaxPyramid, RejectsBadInput) {
  const float nan_height = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(build_dual_max_pyramid({nullptr, 0, 0}, Address::wrap), BakeError);
  EXPECT_THROW(build_dual_max_pyramid({&nan_height, 1, 1}, Address::clamp), BakeError);
}

TEST(PaperAdaptiveBaker, IsNotConservativeAndTheViolationsAreCounted) {
  // Equal heights only (similarity 0): the copy rule still over-claims, because a child can sit
  // half a coarse texel closer to a blocker than its parent's centre.
  long long equal_height_violations = 0;
  double equal_height_worst = 1.0, loose_worst = 1.0;
  for (const Map& map : hard_maps())
    for (int sectors : {1, 4, 8}) {
      const ConeMap exact = exact_of(map, sectors, Address::wrap);
      ConeMap strict = make_cone_map(map, sectors), loose = make_cone_map(map, sectors);
      bake_paper_adaptive(view_of(map), Address::wrap, {3, 0.0f}, strict.view());
      bake_paper_adaptive(view_of(map), Address::wrap, {3, 0.25f}, loose.view());
      const Violations vs = violations(strict, exact), vl = violations(loose, exact);
      std::printf(
          "paper-adaptive %-22s %2dx%-2d n=%d: similarity 0: %lld violations (worst x%.2f); "
          "similarity 0.25: %lld violations (worst x%.2f)\n",
          map.name.c_str(), map.width, map.height, sectors, vs.count, vs.worst, vl.count, vl.worst);
      equal_height_violations += vs.count;
      equal_height_worst = std::max(equal_height_worst, vs.worst);
      loose_worst = std::max(loose_worst, vl.worst);
    }
  EXPECT_GT(equal_height_violations, 0);
  EXPECT_GE(equal_height_worst, 1.5);
  EXPECT_GE(loose_worst, 5.0);
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

TEST(BudgetedBaker, ConservativeAtEveryBudget) {
  for (const Map& map : hard_maps())
    for (int sectors : {1, 4, 8})
      for (Address address : {Address::wrap, Address::clamp}) {
        const ConeMap exact = exact_of(map, sectors, address);
        for (int budget_kind = 0; budget_kind < 4; ++budget_kind) {
          Budget budget;
          if (budget_kind == 0) budget.milliseconds = 0.0;  // zero: fallback only
          if (budget_kind == 1) budget.max_work = 50;       // tiny
          if (budget_kind == 2) budget.clock = FakeClock{}.function(), budget.milliseconds = 3.0;
          ConeMap cones = make_cone_map(map, sectors);
          const BakeStats stats = bake_budgeted(view_of(map), address, budget, cones.view());
          const Violations v = violations(cones, exact);
          ASSERT_EQ(v.count, 0) << map.name << " " << map.width << "x" << map.height << " sectors " << sectors
                                << " " << address_name(address) << " budget kind " << budget_kind;
          for (float r : cones.ratios) ASSERT_GT(r, 0.0f) << "a zero ratio would stall a cone stepper";
          EXPECT_EQ(stats.texels_refined + stats.texels_fallback <= (long long)map.width * map.height, true);
          if (budget_kind == 3) {  // unlimited: within the tolerance of exact everywhere
            EXPECT_EQ(stats.texels_fallback, 0);
            for (std::size_t n = 0; n < cones.ratios.size(); ++n)
              ASSERT_GE(cones.ratios[n], (1.0f - budget.tolerance) * exact.ratios[n] * (1.0f - 1e-6f))
                  << map.name << " texel " << n / sectors;
          }
        }
      }
}

// The O(N) floor's rings on bigger, odd-sized maps (more pyramid levels, partial blocks at the seams).
TEST(BudgetedBaker, ZeroBudgetFloorIsConservativeOnLargerOddMaps) {
  for (const Map& map :
       {test::make_fractal_cliff(100, 60, 5), test::make_spikes(77, 129, 3), test::make_bricks(96, 96)})
    for (int sectors : {1, 4, 8})
      for (Address address : {Address::wrap, Address::clamp}) {
        Budget budget;
        budget.milliseconds = 0.0;
        ConeMap cones = make_cone_map(map, sectors);
        const BakeStats stats = bake_budgeted(view_of(map), address, budget, cones.view());
        EXPECT_EQ(stats.texels_refined, 0);
        const Violations v = violations(cones, exact_of(map, sectors, address));
        ASSERT_EQ(v.count, 0) << map.name << " " << map.width << "x" << map.height << " sectors " << sectors
                              << " " << address_name(address) << " worst x" << v.worst;
        for (float r : cones.ratios) ASSERT_GT(r, 0.0f);
      }
}

// Stage L on its own (bake/lane_sweep.cpp): per quadrant, the lane count of every texel gives a
// ratio at or below the exact 4-sector ratio of that quadrant, bit for bit, and the first lane that
// fails bounds the exact ratio from above - on every hard map, square or not, wrap or clamp, with and
// without the knight moves.
struct LaneRun {
  detail::LanePlan plan;
  std::vector<std::uint32_t> masks;
  std::vector<float> out;  // the 4-sector output
  detail::LaneSweepTotals totals;
  long long work = 0;
  std::uint32_t* plane(int q) { return masks.data() + std::size_t(q) * plan.width * plan.height; }
};

LaneRun run_lanes(const Map& map, Address address, bool knights, const detail::LaneSweepOptions& options = {},
                  float lowest = 0.02f) {
  LaneRun run;
  detail::make_lane_plan(map.values.data(), map.width, map.height, address == Address::wrap, lowest, knights,
                         false, run.plan);
  run.masks.assign(map.values.size() * 4, 0xdeadbeef);
  std::uint32_t* const planes[4] = {run.plane(0), run.plane(1), run.plane(2), run.plane(3)};
  // flag the counts whose ratio is below half of their upper bound (below the lowest lane, the
  // floor's), to check the pending sum
  std::uint8_t pending[detail::lane_count + 1];
  for (int c = 0; c <= detail::lane_count; ++c)
    pending[c] = run.plan.lane_ratio[c] < 0.5f * run.plan.lane_upper[c];
  detail::LaneSweepOptions half = options;
  half.floor_keep = 0.5f;
  run.out.assign(map.values.size() * 4, -1.0f);
  run.totals = detail::sweep_sectors(run.plan, map.values.data(), 4, planes, run.out.data(), pending, half);
  run.work = run.totals.work;
  return run;
}

TEST(LaneSweep, BoundsTheExactQuadrantRatioFromBothSides) {
  std::vector<Map> maps = hard_maps();
  maps.push_back(test::make_fractal_cliff(100, 60, 5));
  maps.push_back(test::make_bricks(64, 48));
  maps.push_back(test::make_spikes(77, 41, 3));
  for (const Map& map : maps)
    for (Address address : {Address::wrap, Address::clamp})
      for (bool knights : {true, false}) {
        const ConeMap exact = exact_of(map, 4, address);
        LaneRun run = run_lanes(map, address, knights);
        double swept_sum = 0.0, exact_sum = 0.0;
        long long pending = 0;
        for (int q = 0; q < 4; ++q)
          for (int i = 0; i < map.height; ++i)
            for (int j = 0; j < map.width; ++j) {
              const std::uint32_t mask = run.plane(q)[std::size_t(i) * map.width + j];
              const int count = detail::lanes_passed(mask);
              // lanes pass from the lowest up
              ASSERT_EQ(mask, count == 32 ? 0xffffffffu : (1u << count) - 1u);
              const detail::LaneFloor floor =
                  detail::lane_floor(run.plan, map.values.data(), std::size_t(i) * map.width + j, q, 4);
              const float ratio = count == 0 ? floor.floor : run.plan.lane_ratio[count];
              ASSERT_LE(exact.at(i, j, q), floor.upper);
              const std::string where =
                  map.name + " " + std::to_string(map.width) + "x" + std::to_string(map.height) + " " +
                  address_name(address) + " knights " + std::to_string(knights) + " quadrant " +
                  std::to_string(q) + " texel " + std::to_string(i) + "," + std::to_string(j);
              ASSERT_GT(ratio, 0.0f) << where;
              ASSERT_EQ(run.out[(std::size_t(i) * map.width + j) * 4 + q], ratio) << where;
              ASSERT_LE(ratio, exact.at(i, j, q)) << where;
              ASSERT_LE(exact.at(i, j, q), run.plan.lane_upper[count]) << where << " count " << count;
              swept_sum += ratio;
              exact_sum += exact.at(i, j, q);
              pending += count == 0 ? floor.floor / std::min(run.plan.lane_upper[0], floor.upper) < 0.5f
                                    : run.plan.lane_ratio[count] < 0.5f * run.plan.lane_upper[count];
            }
        EXPECT_EQ(run.totals.pending, pending) << map.name;
        EXPECT_NEAR(run.totals.ratio_sum, swept_sum, 1e-5 * swept_sum) << map.name;
        if (map.name == "fractal-cliff" && map.width == 100) {
          std::printf("lane sweep on %s %s, knights %d: tightness %.3f\n", map.name.c_str(),
                      address_name(address), int(knights), swept_sum / exact_sum);
          EXPECT_GT(swept_sum, 0.85 * exact_sum);
        }
      }
}

// Octant sweeps (8 sectors on square maps): the same two-sided bounds against the exact 8-sector
// ratio, and every instruction set agrees.
TEST(LaneSweep, OctantsBoundTheExactOctantRatioFromBothSides) {
  std::vector<Map> maps;
  for (const Map& map : hard_maps())
    if (map.width == map.height) maps.push_back(map);
  maps.push_back(test::make_fractal_cliff(64, 64, 5));
  maps.push_back(test::make_bricks(48, 48));
  maps.push_back(test::make_spikes(50, 50, 3));
  ASSERT_GE(maps.size(), 6u);
  for (const Map& map : maps)
    for (Address address : {Address::wrap, Address::clamp})
      for (bool knights : {true, false}) {
        const ConeMap exact = exact_of(map, 8, address);
        detail::LanePlan plan;
        detail::make_lane_plan(map.values.data(), map.width, map.height, address == Address::wrap, 0.02f,
                               knights, true, plan);
        const std::size_t count = map.values.size();
        std::vector<std::uint32_t> masks(count * 8, 0xdeadbeef);
        std::uint32_t* planes[8];
        for (int k = 0; k < 8; ++k) planes[k] = masks.data() + k * count;
        detail::sweep_sectors(plan, map.values.data(), 8, planes, nullptr, nullptr);
        double swept_sum = 0.0, exact_sum = 0.0;
        for (int k = 0; k < 8; ++k)
          for (std::size_t t = 0; t < count; ++t) {
            const int c = detail::lanes_passed(planes[k][t]);
            ASSERT_EQ(planes[k][t], c == 32 ? 0xffffffffu : (1u << c) - 1u) << map.name;
            const detail::LaneFloor floor = detail::lane_floor(plan, map.values.data(), t, k, 8);
            const float ratio = c == 0 ? floor.floor : plan.lane_ratio[c];
            ASSERT_LE(exact.ratios[t * 8 + k], floor.upper);
            const float truth = exact.ratios[t * 8 + k];
            ASSERT_LE(ratio, truth) << map.name << " " << map.width << " " << address_name(address)
                                    << " knights " << knights << " octant " << k << " texel " << t;
            ASSERT_LE(truth, plan.lane_upper[c])
                << map.name << " octant " << k << " texel " << t << " count " << c;
            swept_sum += ratio;
            exact_sum += truth;
          }
        if (map.name == "fractal-cliff" && map.width == 64) {
          std::printf("octant sweep on %s %s, knights %d: tightness %.3f\n", map.name.c_str(),
                      address_name(address), int(knights), swept_sum / exact_sum);
          EXPECT_GT(swept_sum, 0.85 * exact_sum);
        }
        for (int level : {0, 3}) {
          if (level > detail::lane_sweep_best_level()) continue;
          std::vector<std::uint32_t> other(count * 8);
          std::uint32_t* other_planes[8];
          for (int k = 0; k < 8; ++k) other_planes[k] = other.data() + k * count;
          detail::sweep_sectors(plan, map.values.data(), 8, other_planes, nullptr, nullptr, {level, true});
          EXPECT_EQ(other, masks) << map.name << " level " << level;
        }
      }
}

// Many small random maps - noise, heights on the 16-bit grid, 0/1 spikes, gaps of one 16-bit step,
// 1 x n strips, and from seed 121 on one side a multiple (2 to 6) of the other, so that 8 sectors
// get octant sweeps - in every sector count and address mode: stage L never claims more than exact,
// and its certified bounds hold.
TEST(LaneSweep, RandomMapsNeverOverclaim) {
  int checked = 0, octant_maps = 0;
  for (std::uint64_t seed = 1; seed <= 180; ++seed) {
    int w = 1 + int(test::hash01(seed, 0, 1) * 24), h = 1 + int(test::hash01(seed, 0, 2) * 24);
    if (seed > 120) {
      const int side = 1 + int(test::hash01(seed, 0, 3) * 9),
                multiple = 2 + int(test::hash01(seed, 0, 4) * 5);
      w = seed % 3 == 0 ? side : side * multiple;
      h = seed % 3 == 0 ? side * multiple : side;
    }
    Map map{"random", w, h, std::vector<float>(std::size_t(w) * h)};
    const int kind = int(seed % 4);
    for (int i = 0; i < h; ++i)
      for (int j = 0; j < w; ++j) {
        const float u = test::hash01(seed, i, j);
        float v = u;
        if (kind == 1) v = std::round(u * 65535.0f) / 65535.0f;         // on the 16-bit grid
        if (kind == 2) v = u > 0.9f ? 1.0f : 0.0f;                      // spikes of the full range
        if (kind == 3) v = 0.5f + (u > 0.5f ? 1.0f : 0.0f) / 65535.0f;  // one 16-bit step
        map.at(i, j) = v;
      }
    for (Address address : {Address::wrap, Address::clamp})
      for (int sectors : {4, 8}) {
        detail::LanePlan plan;
        detail::make_lane_plan(map.values.data(), w, h, address == Address::wrap, 0.02f, seed % 2 == 0,
                               sectors == 8, plan);
        if (sectors == 8 && plan.octant_split == 0) continue;  // the baker takes quadrants there
        octant_maps += sectors == 8 && w != h;
        const ConeMap exact = exact_of(map, sectors, address);
        const std::size_t count = map.values.size();
        std::vector<std::uint32_t> masks(count * sectors);
        std::uint32_t* planes[8];
        for (int k = 0; k < sectors; ++k) planes[k] = masks.data() + k * count;
        detail::sweep_sectors(plan, map.values.data(), sectors, planes, nullptr, nullptr);
        for (int k = 0; k < sectors; ++k)
          for (std::size_t t = 0; t < count; ++t) {
            const int c = detail::lanes_passed(planes[k][t]);
            const detail::LaneFloor floor = detail::lane_floor(plan, map.values.data(), t, k, sectors);
            const float ratio = c == 0 ? floor.floor : plan.lane_ratio[c];
            const float truth = exact.ratios[t * sectors + k];
            ASSERT_LE(ratio, truth) << "seed " << seed << " " << w << "x" << h << " " << address_name(address)
                                    << " sectors " << sectors << " sector " << k << " texel " << t;
            ASSERT_LE(truth, c == 0 ? std::min(plan.lane_upper[0], floor.upper) : plan.lane_upper[c])
                << "seed " << seed << " sector " << k << " texel " << t;
            ++checked;
          }
        // and the whole baker with no budget, 1, 4 or 8 sectors
        for (int n : {1, sectors}) {
          ConeMap cones = make_cone_map(map, n);
          Budget none;
          none.milliseconds = 0.0;
          bake_budgeted(view_of(map), address, none, cones.view());
          ASSERT_EQ(violations(cones, exact_of(map, n, address)).count, 0)
              << "seed " << seed << " sectors " << n;
        }
      }
  }
  EXPECT_GT(checked, 100000);
  EXPECT_GT(octant_maps, 40);
}

// The AVX2 and AVX-512 kernels (where this CPU has them) give the generic kernel's masks exactly.
TEST(LaneSweep, EveryInstructionSetGivesTheSameCounts) {
  const int best = detail::lane_sweep_best_level();
  std::printf("lane sweep: best instruction set level here %d\n", best);
  for (const Map& map : {test::make_fractal_cliff(100, 60, 5), test::make_bricks(64, 48),
                         test::make_spikes(13, 1, 2), test::make_flat(1, 1)})
    for (Address address : {Address::wrap, Address::clamp})
      for (bool knights : {true, false}) {
        const LaneRun generic = run_lanes(map, address, knights, {0, true});
        for (int level : {3, 4}) {
          if (level > best) continue;
          const LaneRun other = run_lanes(map, address, knights, {level, true});
          EXPECT_EQ(other.masks, generic.masks) << map.name << " level " << level;
          EXPECT_EQ(other.work, generic.work) << map.name << " level " << level;
          EXPECT_EQ(other.out, generic.out) << map.name << " level " << level;
          EXPECT_EQ(other.totals.pending, generic.totals.pending) << map.name << " level " << level;
          EXPECT_NEAR(other.totals.ratio_sum, generic.totals.ratio_sum, 1e-5 * generic.totals.ratio_sum);
        }
      }
}

// $DISPLACE_BAKE_ISA picks a lower instruction set for benchmarks, never one the CPU lacks, and any
// other word is refused.
TEST(LaneSweep, BakeIsaSettingPicksALevelTheCpuRuns) {
  EXPECT_EQ(detail::lane_sweep_level_for(nullptr, 4), 4);
  EXPECT_EQ(detail::lane_sweep_level_for("", 3), 3);
  EXPECT_EQ(detail::lane_sweep_level_for("avx2", 4), 3);
  EXPECT_EQ(detail::lane_sweep_level_for("generic", 4), 0);
  EXPECT_EQ(detail::lane_sweep_level_for("avx512", 4), 4);
  EXPECT_EQ(detail::lane_sweep_level_for("avx512", 3), 3);  // not above the CPU
  EXPECT_EQ(detail::lane_sweep_level_for("avx2", 0), 0);
  EXPECT_THROW(detail::lane_sweep_level_for("AVX2", 4), std::invalid_argument);
  EXPECT_THROW(detail::lane_sweep_level_for("sse9", 4), std::invalid_argument);
}

// The bilinear baker's near-field kernel (16-bit lanes): every instruction set gives the generic
// kernel's bounds bit for bit, and those are the definition's (computed here in double from the same
// 16-bit values, one offset at a time: a sub-cell counts where its maximum exceeds the apex less one
// unit, the gap term is floor(rise * inverse_gap / 65536) + 1) shrunk by no more than a relative
// 1e-5, on rows narrower than a block, a whole block, and with a partial last block; apexes of 0
// and maxima of 65535 included.
TEST(LaneSweep, NearRowKernelsAgreeWithTheDefinition) {
  const int best = detail::lane_sweep_best_level();
  int counted = 0;                                // gap terms of sub-cells above the apex
  for (int width : {1, 5, 16, 21, 32, 37, 70}) {  // blocks are 16 texels (AVX2, generic) or 32 (AVX-512)
    const int columns = std::max(width, detail::near_block) + 8;
    std::vector<std::vector<std::uint16_t>> planes;
    std::vector<detail::NearOffset> offsets;
    detail::NearRowJob job;
    std::vector<int> group_of;
    for (int g = 0; g < detail::near_groups; ++g) {
      job.group_counts[g] = 1 + (g * 7 + width) % 4;
      for (int n = 0; n < job.group_counts[g]; ++n) {
        for (int f = 0; f < 3; ++f) {
          std::vector<std::uint16_t> plane(columns);
          for (int j = 0; j < columns; ++j) {
            const float r = test::hash01(61, std::uint64_t(planes.size()), std::uint64_t(j));
            plane[j] = f == 0 ? (r > 0.97f ? 65535 : std::uint16_t(r * 65535.0f))
                              : std::uint16_t(1.0f + 60000.0f * r * r);
          }
          planes.push_back(std::move(plane));
        }
        detail::NearOffset offset;
        const bool touching = g < 3;
        offset.inverse_gap =
            touching
                ? 0
                : std::uint16_t(20000.0f + 45535.0f * test::hash01(67, std::uint64_t(offsets.size()), 0));
        offsets.push_back(offset);
        group_of.push_back(g);
      }
    }
    for (std::size_t o = 0; o < offsets.size(); ++o) {
      offsets[o].top = planes[3 * o].data();
      offsets[o].along_u = planes[3 * o + 1].data();
      offsets[o].along_v = planes[3 * o + 2].data();
    }
    std::vector<std::uint16_t> apex(width);
    for (int j = 0; j < width; ++j) {
      const float r = test::hash01(71, std::uint64_t(width), std::uint64_t(j));
      apex[j] = r < 0.05f ? 0 : std::uint16_t((0.55f + 0.45f * r) * 65535.0f);
    }
    job.offsets = offsets.data();
    job.apex = apex.data();
    job.width = width;
    job.rate_unit = 1.7e-3f;
    job.steep_unit = 3.1e-5f;
    auto run = [&](int level) {
      std::vector<float> near(width), slope3(width);
      job.near = near.data();
      job.slope3 = slope3.data();
      if (level == 0) detail::near_row_generic(job);
      if (level == 3) detail::near_row_avx2(job);
      if (level == 4) detail::near_row_avx512(job);
      return std::pair{near, slope3};
    };
    const auto generic = run(0);
    for (int level : {3, 4})
      if (level <= best) {
        const auto other = run(level);
        for (int j = 0; j < width; ++j)  // bit for bit: bake/ is built without fused multiply-adds
          for (const auto& [got, want] :
               {std::pair{other.first[j], generic.first[j]}, std::pair{other.second[j], generic.second[j]}}) {
            EXPECT_EQ(std::bit_cast<std::uint32_t>(got), std::bit_cast<std::uint32_t>(want))
                << "width " << width << " level " << level << " texel " << j << ": " << got << " against "
                << want;
          }
      }
    const double infinite = std::numeric_limits<double>::infinity();
    for (int j = 0; j < width; ++j) {
      const int below = apex[j] > 0 ? apex[j] - 1 : 0;
      double ru = 0, rv = 0, ru3 = 0, rv3 = 0, steep = 0;
      bool touch = false, any = false, any3 = false;
      for (std::size_t o = 0; o < offsets.size(); ++o) {
        const int g = group_of[o];
        const int top = offsets[o].top[j];
        if (!(top > below)) continue;
        const bool box2 = g < 6, along_u = g % 3 != 1, along_v = g % 3 != 0;
        any3 = true;
        if (along_u) ru3 = std::max(ru3, double(offsets[o].along_u[j]));
        if (along_v) rv3 = std::max(rv3, double(offsets[o].along_v[j]));
        if (!box2) continue;
        any = true;
        if (along_u) ru = std::max(ru, double(offsets[o].along_u[j]));
        if (along_v) rv = std::max(rv, double(offsets[o].along_v[j]));
        if (g < 3) {
          touch = true;
        } else {
          const long long term = (static_cast<long long>(top - below) * offsets[o].inverse_gap >> 16) + 1;
          steep = std::max(steep, double(term));
          ++counted;
        }
      }
      const double unit = job.rate_unit, far = steep > 0 ? 1.0 / (steep * job.steep_unit) : infinite;
      const double slope3 = any3 ? 1.0 / (std::hypot(ru3, rv3) * unit) : infinite;
      const double near = any ? std::max(touch ? 0.0 : far, 1.0 / (std::hypot(ru, rv) * unit)) : infinite;
      for (const auto& [got, want] :
           {std::pair{double(generic.first[j]), near}, std::pair{double(generic.second[j]), slope3}}) {
        if (std::isinf(want)) {
          EXPECT_TRUE(std::isinf(got)) << "width " << width << " texel " << j;
        } else {
          EXPECT_LE(got, want) << "width " << width << " texel " << j;
          EXPECT_GE(got, want * (1.0 - 1e-5)) << "width " << width << " texel " << j;
        }
      }
    }
  }
  EXPECT_GT(counted, 50);
}

// The second lap stops where its rows meet the first lap's; what it leaves is what a whole second
// lap gives, and on a smooth periodic map it does stop early.
// The apex kernels of every instruction set the CPU runs give bake_bilinear_cones' apexes bit for
// bit (rounded up to float) and their 16-bit floors, on rows of every length that fills 0 to 3
// blocks with a remainder, with heights whose samples round in both directions.
TEST(LaneSweep, ApexKernelsGiveTheFullBakesApexes) {
  const int best = detail::lane_sweep_best_level();
  long long compared = 0;
  for (int width = 3; width <= 30; ++width) {
    std::vector<float> heights(std::size_t(width) * 3);
    for (std::size_t n = 0; n < heights.size(); ++n) heights[n] = test::hash01(71, n, std::uint64_t(width));
    heights[std::size_t(width) + 1] = 1.0f;  // a peak: the apex at its largest
    std::vector<float> cones(heights.size() * 4), expected(heights.size());
    bake_bilinear_cones({heights.data(), width, 3}, Address::clamp, {cones.data(), width, 3, 4}, expected);
    const float* const rows[3] = {heights.data(), heights.data() + width, heights.data() + 2 * width};
    for (int level : {0, 3, 4}) {
      if (level > best) continue;
      const int block = detail::apex_block_texels(level), blocks = (width - 2) / block;
      std::vector<float> apex(std::size_t(width), -1.0f);
      std::vector<std::uint16_t> bottom(std::size_t(width), 7);
      switch (level) {
        case 0: detail::apex_blocks_generic(rows, 1, blocks, apex.data(), bottom.data()); break;
        case 3: detail::apex_blocks_avx2(rows, 1, blocks, apex.data(), bottom.data()); break;
        default: detail::apex_blocks_avx512(rows, 1, blocks, apex.data(), bottom.data()); break;
      }
      for (int j = 0; j < width; ++j) {
        const bool written = j >= 1 && j < 1 + blocks * block;
        if (!written) {  // nothing outside the blocks
          EXPECT_EQ(apex[std::size_t(j)], -1.0f) << width << " " << j;
          continue;
        }
        const float want = expected[std::size_t(width) + std::size_t(j)];
        EXPECT_EQ(apex[std::size_t(j)], want) << "level " << level << " width " << width << " texel " << j;
        const int floor_scaled = std::clamp(int(want * 65535.0f - 0x1p-7f), 0, 65535);
        EXPECT_EQ(bottom[std::size_t(j)], floor_scaled)
            << "level " << level << " width " << width << " texel " << j;
        ++compared;
      }
    }
  }
  EXPECT_GT(compared, 300);
}

// Stage L's last step gives the same bits in every instruction set the CPU runs: rows of 1 to 40
// texels (the vector blocks and the scalar rest), every lane count 0 to 32, apexes at, below and far
// below the highest cell, near and slope bounds from 0 to infinity.
TEST(LaneSweep, StageLCombineKernelsAgree) {
  const int best = detail::lane_sweep_best_level();
  float lane_ratio[detail::lane_count + 1];
  for (int l = 0; l <= detail::lane_count; ++l) lane_ratio[l] = 0.01f * std::pow(1.15f, float(l));
  long long compared = 0;
  for (int width = 1; width <= 40; ++width) {
    std::vector<float> apex(static_cast<std::size_t>(width)), near(static_cast<std::size_t>(width) * 4),
        slope3(near.size());
    std::vector<std::uint8_t> passed(near.size()), passed3(near.size());
    for (int j = 0; j < width; ++j) {
      const float r = test::hash01(73, std::uint64_t(width), std::uint64_t(j));
      apex[std::size_t(j)] = j % 7 == 0 ? 0.75f : 0.75f * r;  // some at the highest cell
    }
    for (std::size_t n = 0; n < near.size(); ++n) {
      const float a = test::hash01(79, std::uint64_t(width), n),
                  b = test::hash01(83, std::uint64_t(width), n);
      near[n] = n % 5 == 0 ? std::numeric_limits<float>::infinity() : 2.0f * a;
      slope3[n] = n % 3 == 0 ? std::numeric_limits<float>::infinity() : (n % 11 == 0 ? 0.0f : b);
      passed[n] = std::uint8_t((n * 7 + std::size_t(width)) % 33);
      passed3[n] = std::uint8_t((n * 13 + 5) % 33);
    }
    detail::StageLCombineJob job;
    job.width = width;
    job.apex = apex.data();
    job.highest = 0.75f;
    job.half_texel = 0.5 / 512.0;
    job.lane_ratio = lane_ratio;
    job.lipschitz = 0.03f;
    for (int q = 0; q < 4; ++q) {
      job.passed[q] = passed.data() + std::size_t(q) * width;
      job.passed3[q] = passed3.data() + std::size_t(q) * width;
      job.near[q] = near.data() + std::size_t(q) * width;
      job.slope3[q] = slope3.data() + std::size_t(q) * width;
    }
    std::vector<float> expected(std::size_t(width) * 4, -1.0f);
    job.out = expected.data();
    detail::stage_l_combine_generic(job);
    for (int level : {3, 4}) {
      if (level > best) continue;
      std::vector<float> out(expected.size(), -2.0f);
      job.out = out.data();
      if (level == 3)
        detail::stage_l_combine_avx2(job);
      else
        detail::stage_l_combine_avx512(job);
      for (std::size_t n = 0; n < out.size(); ++n) {
        EXPECT_EQ(std::bit_cast<std::uint32_t>(out[n]), std::bit_cast<std::uint32_t>(expected[n]))
            << "level " << level << " width " << width << " value " << n << ": " << out[n] << " against "
            << expected[n];
        ++compared;
      }
    }
    // and the definition, for one texel and quadrant
    const int j = width - 1, q = width % 4;
    const float floor = apex[std::size_t(j)] < 0.75f
                            ? float(0.5 / 512.0 / (0.75 - double(apex[std::size_t(j)])) * (1.0 - 1e-6))
                            : 1.0f;
    const float beyond2 = std::max(floor, lane_ratio[job.passed[q][j]]),
                beyond3 = std::max(floor, lane_ratio[job.passed3[q][j]]);
    const float want =
        std::max(std::min({beyond3, std::max(beyond2, job.slope3[q][j]), job.near[q][j], 1.0f}), 0.03f);
    EXPECT_EQ(expected[std::size_t(j) * 4 + std::size_t(q)], want) << width;
  }
  if (best >= 3) {
    EXPECT_GT(compared, 1000);
  }
}

// The sub-cell rows of every instruction set the CPU runs are the generic build's bit for bit, for
// counts that fill the vectors and leave rests, and the generic build's values are the definition:
// a sub-cell's largest corner plus the slack, its rates the corner differences raised.
TEST(LaneSweep, SubCellKernelsAgree) {
  const int best = detail::lane_sweep_best_level();
  long long compared = 0;
  for (int count = 1; count <= 45; count += 4) {
    std::vector<float> samples[4];
    for (int r = 0; r < 4; ++r) {
      samples[r].resize(std::size_t(count) + 2);
      for (std::size_t k = 0; k < samples[r].size(); ++k)
        samples[r][k] = test::hash01(89, std::uint64_t(r), k);
    }
    samples[0][0] = 1.0f;  // a maximum above 1 by its slack: stored as 65535
    detail::SubCellRowJob job;
    job.even0 = samples[0].data();
    job.odd0 = samples[1].data();
    job.even1 = samples[2].data();
    job.odd1 = samples[3].data();
    job.count = count;
    job.per_u = 1024.0f;
    job.per_v = 512.0f;
    job.slack_u = 4e-4f;
    job.slack_v = 2e-4f;
    job.top_slack = 2.4e-7f;
    job.rate_scale = 60.0f;  // rates up to 1024 (a whole height over half a texel) below 65535 units
    auto run = [&](int level) {
      std::vector<std::uint16_t> out(std::size_t(count) * 10, 7);
      for (int f = 0; f < 5; ++f)
        for (int p = 0; p < 2; ++p) job.out[f][p] = out.data() + std::size_t(f * 2 + p) * count;
      if (level == 0) detail::sub_cell_row_generic(job);
      if (level == 3) detail::sub_cell_row_avx2(job);
      if (level == 4) detail::sub_cell_row_avx512(job);
      return out;
    };
    const std::vector<std::uint16_t> expected = run(0);
    // the definition at the last even sub-cell: corners even0[k], odd0[k], even1[k], odd1[k], each
    // value above its exact 16-bit scaling and by less than 3 units
    const int k = count - 1;
    const float a = samples[0][std::size_t(k)], b = samples[1][std::size_t(k)],
                c = samples[2][std::size_t(k)], d = samples[3][std::size_t(k)];
    const double top = double(std::max({a, b, c, d}) + 2.4e-7f) * 65535.0;
    if (top < 65533.0) {
      EXPECT_GT(double(expected[std::size_t(k)]), top);
      EXPECT_LT(double(expected[std::size_t(k)]), top + 3.0);
    }
    const double rate =
        double(std::max({0.0f, (b - a) * 1024.0f, (d - c) * 1024.0f}) * (1.0f + 0x1p-20f) + 4e-4f) * 60.0;
    EXPECT_GT(double(expected[std::size_t(2 * count + k)]), rate);
    EXPECT_LT(double(expected[std::size_t(2 * count + k)]), rate + 3.0);
    EXPECT_EQ(expected[0], 65535);
    for (int level : {3, 4}) {
      if (level > best) continue;
      const std::vector<std::uint16_t> out = run(level);
      for (std::size_t n = 0; n < out.size(); ++n) {
        EXPECT_EQ(out[n], expected[n]) << "level " << level << " count " << count << " value " << n;
        ++compared;
      }
    }
  }
  if (best >= 3) {
    EXPECT_GT(compared, 1000);
  }
}

TEST(LaneSweep, SecondLapStopsOnlyWhereNothingWouldChange) {
  Map waves{"waves", 96, 80, std::vector<float>(96 * 80)};
  for (int i = 0; i < waves.height; ++i)
    for (int j = 0; j < waves.width; ++j)
      waves.at(i, j) =
          0.5f + 0.25f * std::sin(2.0f * std::numbers::pi_v<float> * (3.0f * j / 96.0f + 2.0f * i / 80.0f)) +
          0.2f * std::cos(2.0f * std::numbers::pi_v<float> * (5.0f * i / 80.0f - j / 96.0f));
  std::vector<Map> maps = {waves, test::make_fractal_cliff(100, 60, 5)};
  for (std::uint64_t seed = 1; seed <= 40; ++seed) {
    maps.push_back(test::make_spikes(20 + int(seed % 7), 9 + int(seed % 5), seed));
    maps.push_back(test::make_fractal_cliff(12 + int(seed % 9), 7 + int(seed % 4), seed));
  }
  for (const Map& map : maps) {
    const LaneRun early = run_lanes(map, Address::wrap, true, {-1, true});
    const LaneRun whole = run_lanes(map, Address::wrap, true, {-1, false});
    EXPECT_EQ(early.masks, whole.masks) << map.name;
    EXPECT_LE(early.work, whole.work) << map.name;
    if (map.name == "waves") {
      EXPECT_LT(early.work, whole.work * 3 / 4) << "the second lap should stop early";
    }
  }
}

// The same for the bilinear sweeps (their box tests read the three rows swept before the tested
// one): on maps with tall cells next to the seam rows and on random maps, the counts of passing lanes
// of both boxes with the second lap stopping early are those of a whole second lap (and a third).
// Stopping after `depth` equal rows, as the centre-to-centre sweeps may, failed this on 13 of the
// 120 maps, always with more lanes passing than the whole sweep gives (not conservative). The same
// with the first lap leaving any number of rows' tests to the second (its guess from the last sweep).
TEST(LaneSweep, BilinearSecondLapStopsOnlyWhereNothingWouldChange) {
  int mismatches = 0, maps = 0;
  for (std::uint64_t seed = 1; seed <= 120; ++seed) {
    const int W = 6 + int(seed % 11), H = 7 + int((seed * 7) % 13);
    std::vector<float> cells(std::size_t(W) * H, 0.0f);
    const int kind = int(seed % 3);
    for (int i = 0; i < H; ++i)
      for (int j = 0; j < W; ++j) {
        const float r = test::hash01(131, seed * 101 + std::uint64_t(i), std::uint64_t(j));
        cells[std::size_t(i) * W + j] = kind == 0   ? 0.05f * r
                                        : kind == 1 ? (r > 0.9f ? r : 0.0f)
                                                    : 0.5f * r * r;
      }
    // tall cells in the first and last rows and next to them, where the laps meet
    for (int s = 0; s < 3; ++s) {
      const int rows[4] = {0, 1, H - 1, H - 2};
      const int i = rows[int(test::hash01(137, seed, std::uint64_t(s)) * 4.0f) % 4];
      const int j = int(test::hash01(139, seed, std::uint64_t(s)) * float(W)) % W;
      cells[std::size_t(i) * W + j] = 0.6f + 0.4f * test::hash01(149, seed, std::uint64_t(s));
    }
    detail::LanePlan plan;
    detail::make_lane_plan(cells.data(), W, H, true, 0.02f, true, false, plan);
    std::vector<std::uint16_t> bottom(std::size_t(W) * H);
    for (std::size_t t = 0; t < bottom.size(); ++t)
      bottom[t] = std::uint16_t(65535.0f * (0.2f + 0.8f * test::hash01(151, seed, t)));
    alignas(64) std::uint16_t bonus[detail::lane_count], bonus3[detail::lane_count];
    for (int l = 0; l < detail::lane_count; ++l) {
      bonus[l] = std::uint16_t(300 + 20 * l);
      bonus3[l] = std::uint16_t(900 + 60 * l);
    }
    auto run = [&](bool stop_early) {
      std::vector<std::uint8_t> counts(std::size_t(W) * H * 8);
      std::uint8_t* passed[4];
      std::uint8_t* passed3[4];
      for (int q = 0; q < 4; ++q) {
        passed[q] = counts.data() + std::size_t(q) * W * H;
        passed3[q] = counts.data() + std::size_t(4 + q) * W * H;
      }
      detail::sweep_bilinear_quadrants(plan, W, H, bottom.data(), bonus, passed, bonus3, passed3, -1,
                                       stop_early);
      return counts;
    };
    const std::vector<std::uint8_t> early = run(true);
    // the first lap leaves the box tests of as many rows to the second as it took the last time:
    // any number of rows (a guess too small, too large, past what the second lap can track)
    for (int q = 0; q < 4; ++q)
      plan.scratch[std::size_t(q)].second_lap_rows =
          int(test::hash01(157, seed, std::uint64_t(q)) * float(H + 2));
    const std::vector<std::uint8_t> guessed = run(true);
    const std::vector<std::uint8_t> whole = run(false);
    ++maps;
    if (early != whole || guessed != whole) ++mismatches;
    EXPECT_EQ(early, whole) << "seed " << seed << ", " << W << " x " << H;
    EXPECT_EQ(guessed, whole) << "seed " << seed << ", " << W << " x " << H << ", guessed second laps";
  }
  EXPECT_EQ(mismatches, 0) << "of " << maps;
}

// Non-square maps. The chamfer of stage L (lane_sweep.cpp) for every aspect make_lane_plan sees:
// the cheapest path of moves to every lattice point of the quadrant within uv distance 1 - each move
// costing scale times its uv length - is no longer than the straight line; scale stays the square
// map's (cos 13.3 deg) up to 32:1; and where there are octant sweeps (one side a multiple n <= 64 of
// the other), the moves of each reach exactly the lattice points of its octant (the move sets as
// sweep_sectors takes them).
TEST(LaneSweep, ChamferPathsAreNeverLongerThanTheStraightLine) {
  struct Move {
    int da, db;
  };
  const std::pair<int, int> sizes[] = {{16, 16}, {32, 16},     {16, 32},     {24, 16}, {16, 24},
                                       {70, 30}, {30, 70},     {64, 4},      {4, 64},  {5, 1},
                                       {1, 5},   {1024, 1023}, {1023, 1024}, {256, 2}, {2, 256}};
  for (const auto& [w, h] : sizes) {
    const std::vector<float> flat(std::size_t(w) * h, 0.5f);
    detail::LanePlan plan;
    detail::make_lane_plan(flat.data(), w, h, true, 0.02f, true, true, plan);
    const std::string where = std::to_string(w) + "x" + std::to_string(h);
    if (std::max(w, h) <= 32 * std::min(w, h)) {
      EXPECT_GT(plan.scale, 0.97) << where;
    }
    // octants where one side is a multiple n of the other and the move (1, n) or (n, 1) exists
    const int multiple = w % h == 0 ? w / h : h % w == 0 ? h / w : 0;
    EXPECT_EQ(plan.octant_split, multiple <= detail::lane_reach_limit ? multiple : 0) << where;
    auto moves = [&](int row_first, int row_last, int column_first, int column_last, bool carry) {
      std::vector<Move> set;
      for (int k = row_first; k <= row_last; ++k) set.push_back({1, k});
      for (int k = column_first; k <= column_last; ++k) set.push_back({k, 1});
      if (carry) set.push_back({0, 1});
      return set;
    };
    const int rows = plan.row_reach, columns = plan.column_reach, n = plan.octant_split;
    const bool tall = h > w;
    std::vector<std::vector<Move>> sets = {moves(0, rows, 2, columns, true)};
    if (n > 0) {
      sets.push_back(tall ? moves(0, 0, n, columns, false) : moves(0, n, 2, columns, false));  // next to v
      sets.push_back(tall ? moves(1, rows, 2, n, true) : moves(n, rows, 2, 1, true));          // next to u
    }
    auto length = [&](int da, int db) { return std::hypot(double(db) / w, double(da) / h); };
    const int last_a = std::min(h, 300), last_b = std::min(w, 300);  // uv distance 1 (or as far as that)
    for (std::size_t set = 0; set < sets.size(); ++set) {
      // cheapest paths over the lattice points (a rows, b columns) of the quadrant
      std::vector<double> cost(std::size_t(last_a + 1) * (last_b + 1),
                               std::numeric_limits<double>::infinity());
      cost[0] = 0.0;
      for (int a = 0; a <= last_a; ++a)
        for (int b = 0; b <= last_b; ++b)
          for (const Move& m : sets[set])
            if (m.da <= a && m.db <= b)
              cost[std::size_t(a) * (last_b + 1) + b] = std::min(
                  cost[std::size_t(a) * (last_b + 1) + b],
                  cost[std::size_t(a - m.da) * (last_b + 1) + (b - m.db)] + plan.scale * length(m.da, m.db));
      for (int a = 0; a <= last_a; ++a)
        for (int b = 0; b <= last_b; ++b) {
          const double straight = length(a, b);
          if ((a == 0 && b == 0) || !(straight < 1.0)) continue;
          const double path = cost[std::size_t(a) * (last_b + 1) + b];
          // in the octant next to v when its direction is at least 45 deg from u (both on the diagonal)
          const bool next_to_v = std::int64_t(b) * h <= std::int64_t(a) * w;
          const bool next_to_u = std::int64_t(a) * w <= std::int64_t(b) * h;
          const bool in_set = set == 0 || (set == 1 ? next_to_v : next_to_u);
          ASSERT_EQ(path < std::numeric_limits<double>::infinity(), in_set)
              << where << " move set " << set << " point " << a << "," << b;
          if (in_set) {
            ASSERT_LE(path, straight * (1.0 + 1e-12))
                << where << " move set " << set << " point " << a << "," << b;
          }
        }
    }
  }
}

// Small non-square maps, wide and tall, one side a multiple of the other or not.
std::vector<Map> aspect_maps() {
  return {
      test::make_fractal_cliff(48, 24),  test::make_bricks(64, 16),           test::make_spikes(20, 40, 5),
      test::make_terraces(12, 36),       test::make_fractal_cliff(80, 5, 7),  test::make_spikes(6, 54, 9),
      test::make_near_flat_step(40, 20), test::make_fractal_cliff(33, 20, 4), test::make_checkerboard(8, 24)};
}

// Stage L on non-square maps, 4 and 8 sectors: every ratio at or below the exact one bit for bit, the
// first failing lane above it, and every instruction set the same masks (the longer move sets loop).
TEST(LaneSweep, NonSquareSweepsBoundTheExactRatiosFromBothSides) {
  for (const Map& map : aspect_maps())
    for (Address address : {Address::wrap, Address::clamp})
      for (int sectors : {4, 8}) {
        detail::LanePlan plan;
        detail::make_lane_plan(map.values.data(), map.width, map.height, address == Address::wrap, 0.02f,
                               true, sectors == 8, plan);
        const std::string where = map.name + " " + std::to_string(map.width) + "x" +
                                  std::to_string(map.height) + " " + address_name(address) + " sectors " +
                                  std::to_string(sectors);
        EXPECT_GT(plan.scale, 0.97) << where;
        if (sectors == 8 && plan.octant_split == 0) {
          EXPECT_FALSE(map.width % map.height == 0 || map.height % map.width == 0) << where;
          continue;
        }
        const ConeMap exact = exact_of(map, sectors, address);
        const std::size_t count = map.values.size();
        std::vector<std::uint32_t> masks(count * sectors, 0xdeadbeef);
        std::uint32_t* planes[8];
        for (int k = 0; k < sectors; ++k) planes[k] = masks.data() + k * count;
        detail::sweep_sectors(plan, map.values.data(), sectors, planes, nullptr, nullptr);
        double swept_sum = 0.0, exact_sum = 0.0;
        for (int k = 0; k < sectors; ++k)
          for (std::size_t t = 0; t < count; ++t) {
            const int c = detail::lanes_passed(planes[k][t]);
            ASSERT_EQ(planes[k][t], c == 32 ? 0xffffffffu : (1u << c) - 1u) << where;
            const detail::LaneFloor floor = detail::lane_floor(plan, map.values.data(), t, k, sectors);
            const float ratio = c == 0 ? floor.floor : plan.lane_ratio[c];
            const float truth = exact.ratios[t * sectors + k];
            ASSERT_GT(ratio, 0.0f) << where;
            ASSERT_LE(ratio, truth) << where << " sector " << k << " texel " << t;
            ASSERT_LE(truth, c == 0 ? std::min(plan.lane_upper[0], floor.upper) : plan.lane_upper[c])
                << where << " sector " << k << " texel " << t << " count " << c;
            swept_sum += ratio;
            exact_sum += truth;
          }
        EXPECT_GT(swept_sum, 0.8 * exact_sum) << where;
        for (int level : {0, 3}) {
          if (level > detail::lane_sweep_best_level()) continue;
          std::vector<std::uint32_t> other(count * sectors);
          std::uint32_t* other_planes[8];
          for (int k = 0; k < sectors; ++k) other_planes[k] = other.data() + k * count;
          detail::sweep_sectors(plan, map.values.data(), sectors, other_planes, nullptr, nullptr,
                                {level, true});
          EXPECT_EQ(other, masks) << where << " level " << level;
        }
      }
}

// The whole baker on non-square maps, 1, 4 and 8 sectors: never above exact at any budget, within the
// tolerance with no limit, and exact with tolerance 0.
TEST(BudgetedBaker, NonSquareMapsConservativeAtEveryBudget) {
  for (const Map& map : aspect_maps())
    for (int sectors : {1, 4, 8})
      for (Address address : {Address::wrap, Address::clamp}) {
        const ConeMap exact = exact_of(map, sectors, address);
        const std::string where = map.name + " " + std::to_string(map.width) + "x" +
                                  std::to_string(map.height) + " " + address_name(address) + " sectors " +
                                  std::to_string(sectors);
        for (int budget_kind = 0; budget_kind < 4; ++budget_kind) {
          Budget budget;
          if (budget_kind == 0) budget.milliseconds = 0.0;
          if (budget_kind == 1) budget.max_work = 50;
          if (budget_kind == 3) budget.tolerance = 0.0f;
          ConeMap cones = make_cone_map(map, sectors);
          const BakeStats stats = bake_budgeted(view_of(map), address, budget, cones.view());
          ASSERT_EQ(violations(cones, exact).count, 0) << where << " budget kind " << budget_kind;
          for (float r : cones.ratios) ASSERT_GT(r, 0.0f) << where;
          if (budget_kind == 2) {
            EXPECT_EQ(stats.texels_fallback, 0) << where;
            for (std::size_t n = 0; n < cones.ratios.size(); ++n) {
              ASSERT_GE(cones.ratios[n], (1.0f - budget.tolerance) * exact.ratios[n] * (1.0f - 1e-6f))
                  << where;
            }
          }
          if (budget_kind == 3) {
            ASSERT_EQ(cones.ratios, exact.ratios) << where;
          }
        }
      }
}

// Non-square maps of 0.26 to 2.1 million texels, wide and tall up to 16:1, wrap and clamp, 4 and 8
// sectors: stage L certifies every texel within the default tolerance, so an unlimited bake ends
// after it (before the moves were fitted to the aspect, a 1024 x 512 brick map left 287,000 texels
// to the refinement and 8 sectors all of them).
TEST(BudgetedBaker, StageLCertifiesNonSquareMapsWithinTheDefaultTolerance) {
  Map waves{"waves", 4096, 256, std::vector<float>(std::size_t(4096) * 256)};
  for (int i = 0; i < waves.height; ++i)
    for (int j = 0; j < waves.width; ++j)
      waves.at(i, j) =
          0.5f +
          0.3f * std::sin(2.0f * std::numbers::pi_v<float> * (7.0f * j / 4096.0f + 3.0f * i / 256.0f)) +
          0.15f * std::cos(2.0f * std::numbers::pi_v<float> * (11.0f * i / 256.0f - 5.0f * j / 4096.0f));
  const Map maps[] = {test::make_ocean(2048, 1024),
                      test::make_ocean(1024, 2048),
                      test::make_bricks(1024, 512),
                      test::make_bricks(512, 1024),
                      waves,
                      test::make_bricks(4096, 256),
                      test::make_bricks(256, 4096)};
  for (const Map& map : maps)
    for (int sectors : {4, 8})
      for (Address address : {Address::wrap, Address::clamp}) {
        BudgetedBaker baker(map.width, map.height, sectors, address);
        ConeMap cones = make_cone_map(map, sectors);
        Budget none;
        none.milliseconds = 0.0;
        const BakeStats stats = baker.bake(view_of(map), none, cones.view());
        const std::string where = map.name + " " + std::to_string(map.width) + "x" +
                                  std::to_string(map.height) + " " + address_name(address) + " sectors " +
                                  std::to_string(sectors);
        EXPECT_EQ(stats.texels_fallback, 0) << where;
        EXPECT_EQ(baker.pending(none.tolerance), 0) << where;
        EXPECT_EQ(stats.texels_refined, 0) << where;
      }
}

TEST(BudgetedBaker, UnlimitedWithZeroToleranceIsExact) {
  for (const Map& map : hard_maps())
    for (int sectors : {1, 4, 8})
      for (Address address : {Address::wrap, Address::clamp}) {
        Budget budget;
        budget.tolerance = 0.0f;
        ConeMap cones = make_cone_map(map, sectors);
        bake_budgeted(view_of(map), address, budget, cones.view());
        ASSERT_EQ(cones.ratios, exact_of(map, sectors, address).ratios) << map.name << " sectors " << sectors;
      }
}

TEST(BudgetedBaker, RefinementContinuesAcrossCallsUntilDone) {
  const Map map = test::make_fractal_cliff(64, 48);
  const ConeMap exact = exact_of(map, 4, Address::wrap);
  BudgetedBaker baker(map.width, map.height, 4, Address::wrap);
  ConeMap cones = make_cone_map(map, 4);
  Budget budget;
  budget.tolerance = 0.0f;
  budget.max_work = 20000;  // a deterministic per-call budget
  BakeStats stats = baker.bake(view_of(map), budget, cones.view());
  long long pending = baker.pending();
  ASSERT_GT(pending, 0) << "the test needs a budget that runs out";
  EXPECT_EQ(violations(cones, exact).count, 0);
  int calls = 0;
  while (baker.pending() > 0 && calls < 1000) {
    stats = baker.refine(budget, cones.view());
    EXPECT_EQ(violations(cones, exact).count, 0);
    EXPECT_LE(baker.pending(), pending);
    pending = baker.pending();
    ++calls;
  }
  EXPECT_EQ(baker.pending(), 0);
  EXPECT_EQ(cones.ratios, exact.ratios);
}

TEST(BudgetedBaker, FakeClockBudgetStopsRefinement) {
  const Map map = test::make_fractal_cliff(64, 64);
  FakeClock clock;
  clock.step = 1.0;
  Budget budget;
  budget.tolerance = 0.0f;
  budget.clock = clock.function();
  budget.milliseconds = 10.0;  // ten clock readings
  ConeMap cones = make_cone_map(map, 4);
  BudgetedBaker baker(map.width, map.height, 4, Address::wrap);
  const BakeStats stats = baker.bake(view_of(map), budget, cones.view());
  EXPECT_GT(stats.texels_fallback, 0);
  EXPECT_LT(stats.texels_refined, 64 * 64);
  EXPECT_GE(stats.milliseconds, 10.0);
  EXPECT_EQ(violations(cones, exact_of(map, 4, Address::wrap)).count, 0);
}

// On a 40 x 32 map (8 sectors from quadrants) and a 48 x 24 one (octant sweeps).
TEST(BudgetedBaker, IncrementalUpdatesStayConservativeAndConverge) {
  std::uint64_t seed = 99;
  using Policy = BudgetedBaker::UpdatePolicy;
  for (const auto& [width, height] : {std::pair{40, 32}, std::pair{48, 24}})
    for (Policy policy : {Policy::incremental, Policy::cheaper, Policy::rebake})
      for (int sectors : {1, 4, 8})
        for (Address address : {Address::wrap, Address::clamp}) {
          Map map = test::make_fractal_cliff(width, height, seed);
          BudgetedBaker baker(map.width, map.height, sectors, address);
          ConeMap cones = make_cone_map(map, sectors);
          Budget unlimited;
          unlimited.tolerance = 0.0f;
          baker.bake(view_of(map), unlimited, cones.view());
          for (int frame = 0; frame < 12; ++frame) {
            // a random local raise or lowering
            const int w = 1 + int(test::hash01(seed, frame, 1) * 6),
                      h = 1 + int(test::hash01(seed, frame, 2) * 6);
            const int x0 = int(test::hash01(seed, frame, 3) * (map.width - w));
            const int y0 = int(test::hash01(seed, frame, 4) * (map.height - h));
            const bool raise = frame % 3 != 1;
            for (int i = y0; i < y0 + h; ++i)
              for (int j = x0; j < x0 + w; ++j) {
                float& value = map.at(i, j);
                value = raise ? std::min(1.0f, value + 0.3f * test::hash01(seed, i, j + frame))
                              : std::max(0.0f, value - 0.3f * test::hash01(seed, i, j + frame));
              }
            const Rect dirty{x0, y0, x0 + w, y0 + h};
            Budget none;
            none.milliseconds = 0.0;
            baker.update(view_of(map), std::span<const Rect>(&dirty, 1), none, cones.view(), policy);
            const ConeMap exact = exact_of(map, sectors, address);
            ASSERT_EQ(violations(cones, exact).count, 0)
                << "frame " << frame << (raise ? " raise" : " lower") << " sectors " << sectors << " "
                << address_name(address) << " policy " << int(policy) << " " << width << "x" << height;
            if (frame % 4 == 3) {  // later frames converge to the full rebake
              baker.refine(unlimited, cones.view());
              EXPECT_EQ(baker.pending(), 0);
              ASSERT_EQ(cones.ratios, exact.ratios) << "frame " << frame;
            }
          }
        }
}

// `cheaper` repairs a tiny change that reaches little incrementally (the changed group keeps the
// stage-0 floor until refined, so with no budget it is pending), and rebakes with stage L when the
// whole map changed (every texel certified at once).
TEST(BudgetedBaker, UpdatePicksTheCheaperRepair) {
  Map map = test::make_flat(256, 256, 0.5f);
  for (int i = 0; i < map.height; ++i)
    for (int j = 0; j < map.width; ++j) map.at(i, j) += 0.002f * test::hash01(5, i, j);
  BudgetedBaker baker(map.width, map.height, 4, Address::wrap);
  ConeMap cones = make_cone_map(map, 4);
  Budget none;
  none.milliseconds = 0.0;
  baker.bake(view_of(map), none, cones.view());
  EXPECT_EQ(baker.pending(none.tolerance), 0);
  map.at(100, 100) += 0.001f;  // tiny and local
  const Rect spot{100, 100, 101, 101};
  baker.update(view_of(map), std::span<const Rect>(&spot, 1), none, cones.view());
  EXPECT_GT(baker.pending(none.tolerance), 0) << "expected the incremental repair";
  EXPECT_EQ(violations(cones, exact_of(map, 4, Address::wrap)).count, 0);
  for (float& h : map.values) h = std::min(1.0f, h + 0.3f * test::hash01(6, int(&h - map.values.data()), 0));
  const Rect all{0, 0, map.width, map.height};
  baker.update(view_of(map), std::span<const Rect>(&all, 1), none, cones.view());
  EXPECT_EQ(baker.pending(none.tolerance), 0) << "expected a new stage L";
  EXPECT_EQ(violations(cones, exact_of(map, 4, Address::wrap)).count, 0);
}

// On large maps the certified bounds loosen (step rounding grows with the side); the lanes still
// certify every texel of smooth and brick maps up to 2048 within the default tolerance, so an
// unlimited bake ends after stage L there too.
TEST(BudgetedBaker, StageLCertifiesLargeMapsWithinTheDefaultTolerance) {
  Map waves{"waves", 2048, 1024, std::vector<float>(std::size_t(2048) * 1024)};
  for (int i = 0; i < waves.height; ++i)
    for (int j = 0; j < waves.width; ++j)
      waves.at(i, j) =
          0.5f +
          0.3f * std::sin(2.0f * std::numbers::pi_v<float> * (7.0f * j / 2048.0f + 3.0f * i / 1024.0f)) +
          0.15f * std::cos(2.0f * std::numbers::pi_v<float> * (11.0f * i / 1024.0f - 5.0f * j / 2048.0f));
  for (const Map& map : {waves, test::make_bricks(2048, 2048)}) {
    BudgetedBaker baker(map.width, map.height, 4, Address::wrap);
    ConeMap cones = make_cone_map(map, 4);
    Budget none;
    none.milliseconds = 0.0;
    const BakeStats stats = baker.bake(view_of(map), none, cones.view());
    EXPECT_EQ(stats.texels_fallback, 0) << map.name;
    EXPECT_EQ(baker.pending(none.tolerance), 0) << map.name;
  }
}

TEST(BudgetedBaker, RejectsHeightsChangedOutsideTheDirtyRegion) {
  Map map = test::make_bricks(16, 16);
  BudgetedBaker baker(16, 16, 4, Address::wrap);
  ConeMap cones = make_cone_map(map, 4);
  baker.bake(view_of(map), {}, cones.view());
  map.at(0, 0) += 0.01f;
  const Rect dirty{8, 8, 10, 10};
  EXPECT_THROW(baker.update(view_of(map), std::span<const Rect>(&dirty, 1), {}, cones.view()), BakeError);
}

// A smooth dome: rays aimed down its flank enter the relief and stay inside for long, so the relaxed
// cones there are much wider than the conservative ones.
Map make_dome(int w, int h) {
  Map m{"dome", w, h, std::vector<float>(std::size_t(w) * h)};
  for (int i = 0; i < h; ++i)
    for (int j = 0; j < w; ++j) {
      const float x = (j + 0.5f) / w - 0.5f, y = (i + 0.5f) / h - 0.5f;
      m.at(i, j) = 0.9f * std::exp(-(x * x + y * y) / 0.03f);
    }
  return m;
}

TEST(RelaxedBaker, NeverBelowConservativeAndWiderOnSmoothSlopes) {
  for (const Map& map : {make_dome(24, 24), test::make_spikes(24, 24), test::make_bricks(24, 24),
                         test::make_fractal_cliff(20, 20)})
    for (int sectors : {1, 4}) {
      const ConeMap exact = exact_of(map, sectors, Address::wrap);
      ConeMap relaxed = make_cone_map(map, sectors);
      bake_relaxed(view_of(map), Address::wrap, relaxed.view());
      double relaxed_sum = 0, exact_sum = 0;
      for (std::size_t n = 0; n < relaxed.ratios.size(); ++n) {
        ASSERT_GE(relaxed.ratios[n], exact.ratios[n]);
        ASSERT_LE(relaxed.ratios[n], 1.0f);
        relaxed_sum += relaxed.ratios[n];
        exact_sum += exact.ratios[n];
      }
      std::printf("relaxed %-14s n=%d: mean relaxed / mean conservative = %.3f\n", map.name.c_str(), sectors,
                  relaxed_sum / exact_sum);
      if (map.name == "dome") {
        EXPECT_GT(relaxed_sum, exact_sum * 1.05) << "sectors " << sectors;
      }
    }
}

// The definition, brute force in double: for every texel c and every texel d (with wrap images), the
// ray from (c, 1) through (d, h(d)) is followed at an eighth of a texel until it leaves the relief;
// the relaxed ratio is the smallest |E - c| / (h(E) - h(c)) over exits E above c, per sector.
TEST(RelaxedBaker, MatchesTheDefinitionByBruteForce) {
  for (const Map& map : {make_dome(16, 12), test::make_fractal_cliff(14, 14)}) {
    const int sectors = 4;
    ConeMap relaxed = make_cone_map(map, sectors);
    bake_relaxed(view_of(map), Address::wrap, relaxed.view());
    auto height_at = [&](double x, double y) {  // texel units, texel (i, j) centred at (j, i)
      const int j = int(std::floor(x)), i = int(std::floor(y));
      const double tx = x - j, ty = y - i;
      auto at = [&](int a, int b) {
        return double(map.values[std::size_t(((a % map.height) + map.height) % map.height) * map.width +
                                 ((b % map.width) + map.width) % map.width]);
      };
      return (at(i, j) * (1 - tx) + at(i, j + 1) * tx) * (1 - ty) +
             (at(i + 1, j) * (1 - tx) + at(i + 1, j + 1) * tx) * ty;
    };
    double worst = 0.0;
    int far_off = 0, count = 0;
    for (int ci = 0; ci < map.height; ++ci)
      for (int cj = 0; cj < map.width; ++cj) {
        const double hc = map.values[std::size_t(ci) * map.width + cj];
        double best[4] = {1, 1, 1, 1};
        for (int dy = -map.height - ci; dy < 2 * map.height - ci; ++dy)
          for (int dx = -map.width - cj; dx < 2 * map.width - cj; ++dx) {
            if (dx == 0 && dy == 0) continue;
            const double hd = height_at(cj + dx, ci + dy);
            if (!(hd > hc)) continue;
            const double len = std::sqrt(double(dx) * dx + double(dy) * dy);
            double s_inside = 1.0;
            bool constrained = true;
            if (hd < 1.0) {
              for (double s = 1.0 + 0.01 / len;; s += 0.01 / len) {
                const double z = 1.0 - (1.0 - hd) * s;
                if (z <= hc) {
                  constrained = false;
                  break;
                }
                if (height_at(cj + s * dx, ci + s * dy) <= z) break;
                s_inside = s;
              }
            }
            if (!constrained) continue;
            const double z = 1.0 - (1.0 - hd) * s_inside;
            const double du = s_inside * dx / map.width, dv = s_inside * dy / map.height;
            const double ratio = std::min(1.0, std::sqrt(du * du + dv * dv) / (z - hc));
            double azimuth = std::atan2(double(dy) / map.height, double(dx) / map.width);
            if (azimuth < 0) azimuth += 2 * std::numbers::pi;
            for (int k = 0; k < 4; ++k) {
              const double lo = k * std::numbers::pi / 2, hi = (k + 1) * std::numbers::pi / 2;
              if ((azimuth >= lo - 1e-12 && azimuth <= hi + 1e-12) ||
                  (k == 0 && azimuth >= 2 * std::numbers::pi - 1e-12) || (k == 3 && azimuth <= 1e-12))
                best[k] = std::min(best[k], ratio);
            }
          }
        for (int k = 0; k < 4; ++k) {
          // never wider than the fine march allows: an exit the march finds is never missed
          EXPECT_LE(relaxed.at(ci, cj, k), best[k] * 1.02) << map.name << " texel " << ci << "," << cj;
          const double diff = std::fabs(relaxed.at(ci, cj, k) - best[k]) / best[k];
          far_off += diff > 0.02;
          worst = std::max(worst, diff);
          ++count;
        }
      }
    std::printf(
        "relaxed %s: largest relative difference to the brute-force definition %.4f, %d of %d off by "
        "more than 2%%\n",
        map.name.c_str(), worst, far_off, count);
    // the baker solves each bilinear cell exactly; the reference marches at 1/100 texel and can step
    // over an exit thinner than that
    EXPECT_LE(far_off, count / 100) << map.name;
  }
}

TEST(Validation, RejectsBadInput) {
  std::vector<float> ratios(16 * 4);
  Map nan_map = test::make_flat(4, 4);
  nan_map.at(1, 2) = std::nanf("");
  EXPECT_THROW(bake_exact(view_of(nan_map), Address::wrap, {ratios.data(), 4, 4, 4}), BakeError);
  Map high = test::make_flat(4, 4);
  high.at(0, 0) = 1.5f;
  EXPECT_THROW(bake_budgeted(view_of(high), Address::wrap, {}, {ratios.data(), 4, 4, 4}), BakeError);
  EXPECT_THROW(bake_exact({nullptr, 0, 0}, Address::wrap, {ratios.data(), 0, 0, 4}), BakeError);
  const Map ok = test::make_flat(4, 4);
  EXPECT_THROW(bake_exact(view_of(ok), Address::wrap, {ratios.data(), 4, 4, 3}), BakeError);
  EXPECT_THROW(bake_relaxed(view_of(ok), Address::wrap, {ratios.data(), 4, 4, 8}), BakeError);
  EXPECT_THROW(bake_exact(view_of(ok), Address::wrap, {ratios.data(), 4, 5, 4}), BakeError);
  EXPECT_THROW(BudgetedBaker(0, 4, 4, Address::wrap), BakeError);
}

TEST(ExactBaker, FlatAndOneByOneMapsHaveNoBlockers) {
  for (const Map& map : {test::make_flat(9, 5), test::make_flat(1, 1), test::make_flat(1, 7)}) {
    const ConeMap exact = exact_of(map, 8, Address::wrap);
    for (float r : exact.ratios) EXPECT_EQ(r, 1.0f);
  }
}

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

int address_texel(int index, int count, Address address) {
  if (address == Address::clamp) return std::clamp(index, 0, count - 1);
  return ((index % count) + count) % count;
}

// The bilinear surface s(u, v) of bake.h with the address mode, in double.
double surface(const Map& map, Address address, double u, double v) {
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

Map make_single_spike(int w, int h) {
  Map m = test::make_flat(w, h, 0.1f);
  m.name = "single-spike";
  m.at(h / 2, w / 2) = 0.95f;
  return m;
}
Map make_ramp(int w, int h) {
  Map m{"ramp", w, h, std::vector<float>(std::size_t(w) * h)};
  for (int i = 0; i < h; ++i)
    for (int j = 0; j < w; ++j) m.at(i, j) = w > 1 ? float(j) / float(w - 1) : 0.5f;
  return m;
}
Map make_noise(int w, int h) {
  Map m{"noise", w, h, std::vector<float>(std::size_t(w) * h)};
  for (int i = 0; i < h; ++i)
    for (int j = 0; j < w; ++j) m.at(i, j) = test::hash01(29, i, j);
  return m;
}
Map named_flat(int w, int h, float value) {
  Map m = test::make_flat(w, h, value);
  m.name = "flat-" + std::to_string(value).substr(0, 3);
  return m;
}

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
constexpr int centres_checked = 256;         // voxel centres checked per map (all if fewer)
constexpr int random_points_checked = 256;   // points between centres checked per map

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

// ---- cone maps for the bilinear surface (bake_bilinear_cones)

struct BilinearCones {
  ConeMap cones;
  std::vector<float> apex;
  BakeStats stats;
};

BilinearCones bake_bilinear(const Map& map, int sectors, Address address,
                            int window = BilinearConeSettings{}.slope_window) {
  BilinearCones b{make_cone_map(map, sectors), std::vector<float>(map.values.size()), {}};
  b.stats = bake_bilinear_cones(view_of(map), address, b.cones.view(), b.apex, {window});
  return b;
}

double mean_ratio(const ConeMap& cones) {
  return std::accumulate(cones.ratios.begin(), cones.ratios.end(), 0.0) / double(cones.ratios.size());
}

// Sample positions: `sample_units` per texel along each axis, position X along u at texel-centre
// coordinate X / sample_units (texel j's centre at X = sample_units * j), u = (X / units + 0.5) / W.
constexpr int sample_units = 32;

// Sectors (bit k) whose closed wedge holds the uv direction of a sample offset (dx, dy), from the
// definition: exact on the sector edges (multiples of 45 degrees, both sectors), atan2 elsewhere.
unsigned direction_sectors(long long dx, long long dy, int width, int height, int sectors) {
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
BilinearCheck check_bilinear(const Map& map, Address address, const ConeMap& cones,
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

std::vector<Map> bilinear_maps() {
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

TEST(BilinearCones, NeverPiercedByTheBilinearSurfaceFromAnyPointOfTheTexel) {
  long long pairs = 0;
  for (const Map& map : bilinear_maps())
    for (int sectors : {1, 4, 8})
      for (Address address : {Address::wrap, Address::clamp}) {
        const BilinearCones b = bake_bilinear(map, sectors, address);
        const BilinearCheck check = check_bilinear(map, address, b.cones, b.apex);
        pairs += check.pairs;
        EXPECT_EQ(check.violations, 0) << map.name << " " << map.width << "x" << map.height << " sectors "
                                       << sectors << " " << address_name(address) << " worst " << check.worst;
        // H_c is the maximum of s over the texel's square: at least the centre's height
        for (std::size_t t = 0; t < map.values.size(); ++t) ASSERT_GE(b.apex[t], map.values[t]);
        for (float r : b.cones.ratios) ASSERT_TRUE(r > 0.0f && r <= 1.0f) << map.name;
      }
  std::printf("bilinear cones: %lld (p, x) pairs checked\n", pairs);
  EXPECT_GT(pairs, 1000000);
}

// The check has teeth: every ratio 10% too large, or every apex 0.01 too low, is caught.
TEST(BilinearCones, CheckCatchesRatiosTenPercentTooLargeAndApexesTooLow) {
  for (const Map& map : {make_ramp(8, 6), make_noise(6, 6), test::make_fractal_cliff(10, 8)})
    for (int sectors : {1, 4, 8})
      for (Address address : {Address::wrap, Address::clamp}) {
        BilinearCones b = bake_bilinear(map, sectors, address);
        BilinearCones wide = b;
        for (float& r : wide.cones.ratios) r *= 1.1f;
        const BilinearCheck too_wide = check_bilinear(map, address, wide.cones, wide.apex);
        std::vector<float> low = b.apex;
        for (float& h : low) h -= 0.01f;
        const BilinearCheck too_low = check_bilinear(map, address, b.cones, low);
        EXPECT_GT(too_wide.violations, 0)
            << map.name << " sectors " << sectors << " " << address_name(address);
        EXPECT_GT(too_low.violations, 0)
            << map.name << " sectors " << sectors << " " << address_name(address);
      }
}

// On a ramp h = u * slope the bound is tight next to the texel: the uphill sector's ratio is the
// slope's inverse times the far cells' factor, and the sectors that only look downhill or across
// the slope are never blocked (the pieces beyond an edge keep their directions).
TEST(BilinearCones, RampSeesOnlyUphill) {
  Map ramp{"ramp", 32, 8, std::vector<float>(32 * 8)};
  for (int i = 0; i < 8; ++i)
    for (int j = 0; j < 32; ++j) ramp.at(i, j) = 0.8f * (j + 0.5f) / 32.0f;
  const double slope = 0.8;  // height per uv
  const BilinearCones b = bake_bilinear(ramp, 4, Address::clamp);
  for (int i = 0; i < 8; ++i)
    for (int j = 0; j < 31; ++j) {
      EXPECT_EQ(b.cones.at(i, j, 1), 1.0f) << j;
      EXPECT_EQ(b.cones.at(i, j, 2), 1.0f) << j;
      EXPECT_LE(b.cones.at(i, j, 0), 1.0 / slope);
      EXPECT_GE(b.cones.at(i, j, 0), 0.75 / slope) << j;
      EXPECT_NEAR(b.apex[std::size_t(i) * 32 + j], 0.8 * (j + 1.0) / 32.0, 1e-6);
    }
}

// The slope window only raises ratios over the plain construction (no window: every piece bounded by
// distance over height gap, so a texel next to a higher cell gets 0), and keeps every ratio above 0.
// Prints the mean ratio against bake_exact's (between texel centres) for the tightness record.
TEST(BilinearCones, SlopeWindowRaisesEveryRatioAndTightnessIsRecorded) {
  for (const Map& map : {test::make_fractal_cliff(64, 64), test::make_bricks(64, 64), make_noise(48, 40)})
    for (Address address : {Address::wrap, Address::clamp}) {
      const ConeMap exact = exact_of(map, 4, address);
      const BilinearCones plain = bake_bilinear(map, 4, address, 0);
      std::printf("%-14s %-5s exact mean %.4f; bilinear: window 0 mean %.4f", map.name.c_str(),
                  address_name(address), mean_ratio(exact), plain.stats.mean_ratio);
      for (int window : {1, 4, 8}) {
        const BilinearCones b = bake_bilinear(map, 4, address, window);
        std::printf(", window %d mean %.4f", window, b.stats.mean_ratio);
        long long zeros = 0;
        for (std::size_t n = 0; n < b.cones.ratios.size(); ++n) {
          ASSERT_GE(b.cones.ratios[n], plain.cones.ratios[n])
              << map.name << " window " << window << " at " << n;
          zeros += b.cones.ratios[n] == 0.0f;
        }
        EXPECT_EQ(zeros, 0);
      }
      long long plain_zeros = 0;
      for (float r : plain.cones.ratios) plain_zeros += r == 0.0f;
      std::printf("; window 0 zero ratios %.1f%%\n", 100.0 * plain_zeros / double(plain.cones.ratios.size()));
    }
}

// The search's pruning (the far search's bounds and quick rejection, the window's cell test) only
// skips what cannot lower a ratio: the maps equal, bit for bit, those of the search that opens every
// block and bounds every window piece (prune = false), on the hard maps, noise and an ocean, for
// 1, 4 and 8 sectors, wrap and clamp, windows 0, 1, 4 and 9, and more work is done without it.
TEST(BilinearCones, PrunedSearchEqualsTheExhaustiveOne) {
  std::vector<Map> maps = bilinear_maps();
  maps.push_back(make_noise(24, 17));
  maps.push_back(test::make_ocean(32, 16));
  long long compared = 0, pruned_work = 0, whole_work = 0;
  for (const Map& map : maps)
    for (int sectors : {1, 4, 8})
      for (Address address : {Address::wrap, Address::clamp})
        for (int window : {0, 1, 4, 9}) {
          BilinearCones pruned = bake_bilinear(map, sectors, address, window);
          BilinearCones whole{make_cone_map(map, sectors), std::vector<float>(map.values.size()), {}};
          BilinearConeSettings settings{window};
          settings.prune = false;
          whole.stats = bake_bilinear_cones(view_of(map), address, whole.cones.view(), whole.apex, settings);
          ASSERT_EQ(pruned.cones.ratios.size(), whole.cones.ratios.size());
          for (std::size_t n = 0; n < whole.cones.ratios.size(); ++n)
            ASSERT_EQ(pruned.cones.ratios[n], whole.cones.ratios[n])
                << map.name << " " << map.width << "x" << map.height << " sectors " << sectors << " "
                << address_name(address) << " window " << window << " at " << n;
          EXPECT_EQ(pruned.apex, whole.apex);
          pruned_work += pruned.stats.work;
          whole_work += whole.stats.work;
          compared += (long long)whole.cones.ratios.size();
        }
  std::printf("pruned and exhaustive searches: %lld ratios compared, work %lld against %lld\n", compared,
              pruned_work, whole_work);
  EXPECT_LT(2 * pruned_work, whole_work);
}

// Tightness against the best any conservative baker could do for the same apexes: the sampled
// minimum of |x - p| / (s(x) - H_c) per texel and sector is an upper bound of the best ratio.
TEST(BilinearCones, CloseToTheSampledBestRatio) {
  for (const Map& map : {test::make_fractal_cliff(10, 10), make_noise(10, 10), make_ramp(10, 10)})
    for (Address address : {Address::wrap, Address::clamp}) {
      const BilinearCones b = bake_bilinear(map, 4, address);
      const BilinearCheck check = check_bilinear(map, address, b.cones, b.apex);
      const double sampled = std::accumulate(check.sampled.begin(), check.sampled.end(), 0.0);
      const double ours = std::accumulate(b.cones.ratios.begin(), b.cones.ratios.end(), 0.0);
      std::printf("%-14s %-5s mean ratio %.4f, sampled best %.4f: %.3f of it\n", map.name.c_str(),
                  address_name(address), ours / double(check.sampled.size()),
                  sampled / double(check.sampled.size()), ours / sampled);
      EXPECT_GE(ours, 0.6 * sampled) << map.name << " " << address_name(address);
    }
}

TEST(BilinearCones, RejectsBadInput) {
  const Map ok = test::make_flat(4, 4);
  std::vector<float> ratios(16 * 4), apex(16);
  EXPECT_THROW(bake_bilinear_cones(view_of(ok), Address::wrap, {ratios.data(), 4, 4, 3}, apex), BakeError);
  EXPECT_THROW(bake_bilinear_cones(view_of(ok), Address::wrap, {ratios.data(), 4, 4, 4}, {apex.data(), 15}),
               BakeError);
  EXPECT_THROW(bake_bilinear_cones(view_of(ok), Address::wrap, {ratios.data(), 4, 4, 4}, apex, {-1}),
               BakeError);
  EXPECT_THROW(bake_bilinear_cones(view_of(ok), Address::wrap, {ratios.data(), 4, 4, 4}, apex, {65}),
               BakeError);
  Map nan_map = test::make_flat(4, 4);
  nan_map.at(2, 2) = std::nanf("");
  EXPECT_THROW(bake_bilinear_cones(view_of(nan_map), Address::clamp, {ratios.data(), 4, 4, 4}, apex),
               BakeError);
  EXPECT_NO_THROW(bake_bilinear_cones(view_of(ok), Address::clamp, {ratios.data(), 4, 4, 4}, apex));
  for (float r : ratios) EXPECT_EQ(r, 1.0f);
  for (float h : apex) EXPECT_EQ(h, 0.5f);
}

// ---- the budgeted bilinear baker (BilinearBaker): bake_bilinear_cones' contract at every budget

struct BudgetedBilinear {
  ConeMap cones;
  std::vector<float> apex;
  BakeStats stats;
};

// The budgets every claim is tested at: 0 ms, a work limit of 0, small work limits, fake clocks that
// run out after a few readings (mid-refinement), and unlimited.
std::vector<Budget> bilinear_budgets() {
  std::vector<Budget> budgets;
  Budget zero;
  zero.milliseconds = 0.0;
  budgets.push_back(zero);
  for (long long work : {0ll, 1ll, 40ll, 400ll}) {
    Budget b;
    b.max_work = work;
    budgets.push_back(b);
  }
  for (double ms : {1.0, 2.0, 5.0}) {
    Budget b;
    b.clock = FakeClock{}.function();
    b.milliseconds = ms;
    budgets.push_back(b);
  }
  budgets.push_back(Budget{});
  Budget exact_search;  // tolerance 0: every texel not already at 1 is searched
  exact_search.tolerance = 0.0f;
  budgets.push_back(exact_search);
  return budgets;
}

BudgetedBilinear bake_bilinear_budgeted(const Map& map, int sectors, Address address, const Budget& budget) {
  BudgetedBilinear b{make_cone_map(map, sectors), std::vector<float>(map.values.size()), {}};
  BilinearBaker baker(map.width, map.height, sectors, address);
  b.stats = baker.bake(view_of(map), budget, b.cones.view(), b.apex);
  return b;
}

TEST(BilinearBaker, NeverPiercedAtAnyBudget) {
  long long pairs = 0;
  const std::vector<Budget> budgets = bilinear_budgets();
  for (const Map& map : bilinear_maps())
    for (int sectors : {1, 4, 8})
      for (Address address : {Address::wrap, Address::clamp}) {
        const BilinearCones full = bake_bilinear(map, sectors, address);
        for (std::size_t n = 0; n < budgets.size(); ++n) {
          const BudgetedBilinear b = bake_bilinear_budgeted(map, sectors, address, budgets[n]);
          // the apex is exactly bake_bilinear_cones'
          ASSERT_EQ(b.apex, full.apex) << map.name;
          for (float r : b.cones.ratios) ASSERT_TRUE(r > 0.0f && r <= 1.0f) << map.name << " " << r;
          // every texel of a 0 ms or 0-work bake keeps stage L's ratios; the check below holds anyway
          const int stride = n == 0 || n + 2 >= budgets.size() ? 1 : 3;
          const BilinearCheck check = check_bilinear(map, address, b.cones, b.apex, stride);
          pairs += check.pairs;
          ASSERT_EQ(check.violations, 0)
              << map.name << " " << map.width << "x" << map.height << " sectors " << sectors << " "
              << address_name(address) << " budget " << n << " worst " << check.worst;
          if (n + 2 == budgets.size()) {  // unlimited, tolerance 0.25: within it of the full bake
            // (searched texels are at least the full bake; certified ones at least 0.75 of a
            // certified upper bound of the best ratio, which the full bake does not exceed)
            for (std::size_t v = 0; v < b.cones.ratios.size(); ++v)
              ASSERT_GE(b.cones.ratios[v], 0.75f * full.cones.ratios[v] * (1.0f - 1e-6f))
                  << map.name << " value " << v;
          }
          if (n + 1 == budgets.size()) {  // tolerance 0, unlimited: never below the full bake
            EXPECT_EQ(b.stats.texels_fallback, 0);
            for (std::size_t v = 0; v < b.cones.ratios.size(); ++v)
              ASSERT_GE(b.cones.ratios[v], full.cones.ratios[v]) << map.name << " value " << v;
          }
        }
      }
  std::printf("budgeted bilinear cones: %lld (p, x) pairs checked\n", pairs);
  EXPECT_GT(pairs, 1000000);
}

// The check has teeth on this baker's maps too: stage L's ratios 10% too large are caught.
TEST(BilinearBaker, CheckCatchesStageLRatiosTenPercentTooLarge) {
  Budget zero;
  zero.milliseconds = 0.0;
  int caught = 0, tried = 0;
  for (const Map& map :
       {make_ramp(8, 6), make_noise(6, 6), test::make_fractal_cliff(10, 8), test::make_bricks(12, 8)})
    for (Address address : {Address::wrap, Address::clamp}) {
      BudgetedBilinear b = bake_bilinear_budgeted(map, 4, address, zero);
      for (float& r : b.cones.ratios) r = std::min(1.0f, r * 1.1f);
      ++tried;
      if (check_bilinear(map, address, b.cones, b.apex).violations > 0) ++caught;
    }
  std::printf("stage L ratios x1.1 caught on %d of %d maps\n", caught, tried);
  EXPECT_GE(caught, tried / 2);
}

// Stage L's floor from the surface's Lipschitz constant G (the largest rise of s per unit of uv
// length): s(x) - H_c <= s(x) - s(p) <= G |x - p|, so no ratio is below 1 / G. On a clamped map
// with a 4-texel ramp from 0.1 to 0.9 across its middle, the texels on the ramp have uphill ratios
// of exactly 1 / G, and a 0 ms bake reaches 1 / G everywhere - within the floor's rounding - but
// never passes the full bake; on a sinusoid field every ratio is at least 1 / G of its steepest cell.
TEST(BilinearBaker, StageLHoldsTheLipschitzFloor) {
  Budget zero;
  zero.milliseconds = 0.0;
  for (const auto& [w, h] : {std::pair{24, 9}, std::pair{9, 24}, std::pair{20, 20}}) {
    Map ramp = test::make_flat(w, h, 0.1f);
    const int start = w / 2 - 2;
    for (int i = 0; i < h; ++i)
      for (int j = 0; j < w; ++j) ramp.at(i, j) = 0.1f + 0.2f * float(std::clamp(j - start, 0, 4));
    const double rise = 0.2 * double(w);  // per unit of u
    const BudgetedBilinear b = bake_bilinear_budgeted(ramp, 4, Address::clamp, zero);
    const std::string where = std::to_string(w) + "x" + std::to_string(h);
    for (std::size_t v = 0; v < b.cones.ratios.size(); ++v)
      ASSERT_GE(b.cones.ratios[v], float(0.9999 / rise)) << where << " value " << v;
    EXPECT_EQ(check_bilinear(ramp, Address::clamp, b.cones, b.apex).violations, 0) << where;
    // the bound is tight here: 1% more is pierced (the full bake, itself a lower bound, stays below it)
    ConeMap raised = b.cones;
    for (float& r : raised.ratios) r = std::min(1.0f, std::max(r, float(1.01 / rise)));
    EXPECT_GT(check_bilinear(ramp, Address::clamp, raised, b.apex).violations, 0) << where;
  }
  Map waves{"waves", 32, 20, std::vector<float>(32 * 20)};
  for (int i = 0; i < waves.height; ++i)
    for (int j = 0; j < waves.width; ++j)
      waves.at(i, j) = float(0.5 + 0.3 * std::sin(0.7 * j + 0.2 * i) * std::cos(0.45 * i));
  double steepest = 0.0;  // the largest gradient bound of a cell, in uv (wrap)
  for (int i = 0; i < waves.height; ++i)
    for (int j = 0; j < waves.width; ++j) {
      const int i1 = (i + 1) % waves.height, j1 = (j + 1) % waves.width;
      const double du = std::max(std::abs(double(waves.at(i, j1)) - waves.at(i, j)),
                                 std::abs(double(waves.at(i1, j1)) - waves.at(i1, j))) *
                        waves.width;
      const double dv = std::max(std::abs(double(waves.at(i1, j)) - waves.at(i, j)),
                                 std::abs(double(waves.at(i1, j1)) - waves.at(i, j1))) *
                        waves.height;
      steepest = std::max(steepest, std::hypot(du, dv));
    }
  const BudgetedBilinear b = bake_bilinear_budgeted(waves, 4, Address::wrap, zero);
  for (float r : b.cones.ratios) ASSERT_GE(r, float(0.9999 / steepest));
  EXPECT_EQ(check_bilinear(waves, Address::wrap, b.cones, b.apex).violations, 0);
}

TEST(BilinearBaker, RandomMapsNeverPierced) {
  Budget zero;
  zero.milliseconds = 0.0;
  // a few spikes on a flat field: away from them only the far cells (the lane sweeps) decide
  for (int n = 0; n < 6; ++n) {
    const int w = 14 + n, h = 18 - n;
    Map map = test::make_flat(w, h, 0.1f);
    map.name = "sparse-spikes-" + std::to_string(n);
    for (int s = 0; s < 3; ++s)
      map.at(int(test::hash01(41, n, s) * h), int(test::hash01(43, n, s) * w)) =
          0.3f + 0.7f * test::hash01(47, n, s);
    for (int sectors : {4, 8})
      for (Address address : {Address::wrap, Address::clamp}) {
        const BudgetedBilinear b = bake_bilinear_budgeted(map, sectors, address, zero);
        const BilinearCheck check = check_bilinear(map, address, b.cones, b.apex, 2);
        ASSERT_EQ(check.violations, 0)
            << map.name << " sectors " << sectors << " " << address_name(address) << " worst " << check.worst;
      }
  }
  for (int n = 0; n < 24; ++n) {
    const int w = 1 + int(test::hash01(31, n, 1) * 9), h = 1 + int(test::hash01(31, n, 2) * 9);
    Map map = test::make_flat(w, h, 0.0f);
    map.name = "random-" + std::to_string(n);
    const int kind = n % 3;
    for (int i = 0; i < h; ++i)
      for (int j = 0; j < w; ++j) {
        const float r = test::hash01(37, n * 97 + i, j);
        map.at(i, j) = kind == 0 ? r : kind == 1 ? (r > 0.8f ? 1.0f : 0.0f) : std::round(r * 4.0f) / 4.0f;
      }
    for (int sectors : {1, 4, 8})
      for (Address address : {Address::wrap, Address::clamp}) {
        const BudgetedBilinear b = bake_bilinear_budgeted(map, sectors, address, zero);
        const BilinearCheck check = check_bilinear(map, address, b.cones, b.apex);
        ASSERT_EQ(check.violations, 0) << map.name << " " << w << "x" << h << " sectors " << sectors << " "
                                       << address_name(address) << " worst " << check.worst;
      }
  }
}

// Chains of update() with random raises and lowerings inside the dirty rectangles, at budget 0 and
// unlimited: conservative after every frame; heights changed outside the rectangles are an error.
TEST(BilinearBaker, UpdateChainsStayConservative) {
  for (Map map : {make_noise(9, 7), test::make_bricks(12, 8), test::make_spikes(9, 9)})
    for (int sectors : {1, 4, 8})
      for (Address address : {Address::wrap, Address::clamp})
        for (bool unlimited : {false, true}) {
          Budget budget;
          if (!unlimited) budget.milliseconds = 0.0;
          BilinearBaker baker(map.width, map.height, sectors, address);
          ConeMap cones = make_cone_map(map, sectors);
          std::vector<float> apex(map.values.size());
          baker.bake(view_of(map), budget, cones.view(), apex);
          for (int frame = 0; frame < 6; ++frame) {
            const std::uint64_t seed = 1000 + frame;
            Rect rect;
            rect.x0 = int(test::hash01(seed, 1, 0) * map.width);
            rect.y0 = int(test::hash01(seed, 2, 0) * map.height);
            rect.x1 = std::min(map.width, rect.x0 + 1 + int(test::hash01(seed, 3, 0) * 3));
            rect.y1 = std::min(map.height, rect.y0 + 1 + int(test::hash01(seed, 4, 0) * 3));
            for (int i = rect.y0; i < rect.y1; ++i)
              for (int j = rect.x0; j < rect.x1; ++j) {
                const float change = test::hash01(seed, i, j) - (frame % 2 ? 0.3f : 0.7f);
                map.at(i, j) = std::clamp(map.at(i, j) + change, 0.0f, 1.0f);
              }
            const Rect rects[] = {rect};
            baker.update(view_of(map), rects, budget, cones.view(), apex);
            const BilinearCheck check = check_bilinear(map, address, cones, apex);
            ASSERT_EQ(check.violations, 0)
                << map.name << " sectors " << sectors << " " << address_name(address) << " frame " << frame
                << " unlimited " << unlimited;
            const BilinearCones full = bake_bilinear(map, sectors, address);
            ASSERT_EQ(apex, full.apex) << map.name << " frame " << frame;
          }
          // a height changed outside the dirty rectangles is refused
          Map changed = map;
          changed.at(0, 0) = changed.at(0, 0) > 0.5f ? 0.1f : 0.9f;
          const Rect elsewhere[] = {{map.width - 1, map.height - 1, map.width, map.height}};
          if (map.width > 1 || map.height > 1) {
            EXPECT_THROW(baker.update(view_of(changed), elsewhere, budget, cones.view(), apex), BakeError);
          }
        }
}

// The certified upper bounds (lanes and near witnesses) are real: an unlimited bake keeps every
// ratio within the tolerance of the full bake, which the best ratio bounds, at every tolerance; and
// the witnesses do certify (a smooth map is not searched whole).
TEST(BilinearBaker, UpperBoundsHoldAtEveryTolerance) {
  std::vector<Map> maps = bilinear_maps();
  for (int n = 0; n < 12; ++n) {
    const int w = 2 + int(test::hash01(53, n, 1) * 12), h = 2 + int(test::hash01(53, n, 2) * 12);
    Map map = test::make_flat(w, h, 0.0f);
    map.name = "random-" + std::to_string(n);
    for (int i = 0; i < h; ++i)
      for (int j = 0; j < w; ++j) {
        const float r = test::hash01(59, n * 97 + i, j);
        map.at(i, j) = n % 2 ? r : (r > 0.85f ? 1.0f : 0.2f * r);
      }
    maps.push_back(map);
  }
  for (const Map& map : maps)
    for (int sectors : {1, 4})
      for (Address address : {Address::wrap, Address::clamp}) {
        const BilinearCones full = bake_bilinear(map, sectors, address);
        for (float tolerance : {0.02f, 0.1f, 0.5f, 0.9f}) {
          Budget budget;
          budget.tolerance = tolerance;
          const BudgetedBilinear b = bake_bilinear_budgeted(map, sectors, address, budget);
          for (std::size_t v = 0; v < b.cones.ratios.size(); ++v)
            ASSERT_GE(b.cones.ratios[v], (1.0f - tolerance) * full.cones.ratios[v] * (1.0f - 1e-6f))
                << map.name << " sectors " << sectors << " " << address_name(address) << " tolerance "
                << tolerance << " value " << v;
        }
      }
  const Map smooth = make_noise(32, 32);
  Budget budget;
  budget.tolerance = 0.5f;
  const BudgetedBilinear b = bake_bilinear_budgeted(smooth, 4, Address::wrap, budget);
  EXPECT_LT(b.stats.texels_refined, 32 * 32);
}

TEST(BilinearBaker, RefineContinuesAndPendingFalls) {
  const Map map = test::make_fractal_cliff(24, 20);
  for (Address address : {Address::wrap, Address::clamp}) {
    BilinearBaker baker(map.width, map.height, 4, address);
    ConeMap cones = make_cone_map(map, 4);
    std::vector<float> apex(map.values.size());
    Budget zero;
    zero.max_work = 0;
    zero.tolerance = 0.0f;
    baker.bake(view_of(map), zero, cones.view(), apex);
    const long long first = baker.pending();
    EXPECT_GT(first, 0);
    Budget some;
    some.max_work = 2000;
    some.tolerance = 0.0f;
    long long previous = first;
    for (int call = 0; call < 1000 && baker.pending() > 0; ++call) {
      const BakeStats stats = baker.refine(some, cones.view(), apex);
      EXPECT_LT(baker.pending(), previous);
      previous = baker.pending();
      ASSERT_EQ(check_bilinear(map, address, cones, apex, 5).violations, 0);
      // the stats' mean follows the ratios as refinement raises them
      EXPECT_NEAR(stats.mean_ratio, mean_ratio(cones), 1e-6);
    }
    EXPECT_EQ(baker.pending(), 0);
    const BilinearCones full = bake_bilinear(map, 4, address);
    for (std::size_t v = 0; v < cones.ratios.size(); ++v) ASSERT_GE(cones.ratios[v], full.cones.ratios[v]);
  }
}

// A budget that runs out has searched the texels whose ratios can rise most first: on an ocean, a
// cliff and bricks, the texels that a work limit of a tenth of the unlimited bake's raised gain, on
// average, over 1.5x what the unlimited bake's raised texels gain (1.8-2.3x; texel order gives
// 0.9-1.2x). NeverPiercedAtAnyBudget holds such maps to the contract.
TEST(BilinearBaker, ALimitedRefinementSearchesTheLargestGainsFirst) {
  const Map maps[] = {test::make_ocean(96, 96), test::make_fractal_cliff(96, 80), test::make_bricks(96, 96)};
  for (const Map& map : maps) {
    for (int sectors : {1, 4}) {
      std::vector<float> apex(map.values.size());
      auto baked = [&](long long max_work) {
        BilinearBaker baker(map.width, map.height, sectors, Address::wrap);
        ConeMap cones = make_cone_map(map, sectors);
        Budget budget;
        budget.max_work = max_work;
        const BakeStats stats = baker.bake(view_of(map), budget, cones.view(), apex);
        return std::pair{cones, stats};
      };
      const auto [stage_l, none] = baked(0);
      const auto [unlimited, all] = baked(-1);
      const auto [limited, some] = baked(all.work / 10);
      // per texel, what the unlimited bake raised its ratios by; over the texels it raised, and
      // over those the limited bake raised
      double raised_sum = 0.0, limited_sum = 0.0;
      long long raised = 0, limited_count = 0;
      for (std::size_t t = 0; t < map.values.size(); ++t) {
        double gain = 0.0;
        bool limited_raised = false;
        for (int k = 0; k < sectors; ++k) {
          const std::size_t v = t * std::size_t(sectors) + std::size_t(k);
          gain += double(unlimited.ratios[v]) - double(stage_l.ratios[v]);
          limited_raised |= limited.ratios[v] != stage_l.ratios[v];
        }
        if (gain <= 0.0) continue;
        raised_sum += gain;
        ++raised;
        if (limited_raised) {
          limited_sum += gain;
          ++limited_count;
        }
      }
      ASSERT_GT(raised, 0) << map.name;
      ASSERT_GT(limited_count, 0) << map.name;
      const double ratio = (limited_sum / double(limited_count)) / (raised_sum / double(raised));
      EXPECT_GT(ratio, 1.5) << map.name << " sectors " << sectors << ": " << limited_count << " of "
                            << raised;
      EXPECT_GT(some.mean_ratio, none.mean_ratio) << map.name;
    }
  }
}

// The first stage in steps (begin / advance: the pipeline's lagged maps). With the budget spent,
// each advance() runs one step; however the steps are spread, the map is bake()'s bit for bit; `out`
// and the apexes are left alone until the last step, the stage works on the heights begin() copied,
// an unlimited budget finishes in one call with bake()'s refinement, and bake() mid-stage ends it.
TEST(BilinearBaker, StagedFirstStageEqualsTheWholeBake) {
  std::vector<Map> maps = hard_maps();
  maps.push_back(test::make_fractal_cliff(96, 130));  // rows for every part of the near field
  maps.push_back(test::make_bricks(140, 40));
  Budget spent;
  spent.milliseconds = 0.0;
  for (const Map& map : maps)
    for (int sectors : {1, 4, 8})
      for (Address address : {Address::wrap, Address::clamp}) {
        std::ostringstream described;
        described << map.name << " " << map.width << "x" << map.height << " sectors " << sectors << " "
                  << address_name(address);
        const std::string what = described.str();
        const BudgetedBilinear expected = bake_bilinear_budgeted(map, sectors, address, spent);
        BilinearBaker baker(map.width, map.height, sectors, address);
        ConeMap cones = make_cone_map(map, sectors);
        std::vector<float> apex(map.values.size(), -1.0f);
        std::fill(cones.ratios.begin(), cones.ratios.end(), -1.0f);
        Map input = map;
        baker.begin(view_of(input));
        std::fill(input.values.begin(), input.values.end(), 0.5f);  // the stage has its own copy
        EXPECT_THROW(baker.refine(spent, cones.view(), apex), BakeError) << what;
        BakeStats stats;
        int calls = 1;
        for (; !baker.advance(spent, cones.view(), apex, stats); ++calls) {
          ASSERT_TRUE(baker.in_progress()) << what;
          ASSERT_LT(calls, BilinearBaker::first_stage_steps()) << what;
          for (float r : cones.ratios) ASSERT_EQ(r, -1.0f) << what;
          for (float a : apex) ASSERT_EQ(a, -1.0f) << what;
        }
        EXPECT_FALSE(baker.in_progress()) << what;
        EXPECT_GE(calls, 6) << what;  // the apexes in 2 parts, the cells, 2 sweeps, the near field
        if (map.height > 96) {
          EXPECT_EQ(calls, BilinearBaker::first_stage_steps()) << what;
        }
        EXPECT_EQ(cones.ratios, expected.cones.ratios) << what;
        EXPECT_EQ(apex, expected.apex) << what;
        EXPECT_EQ(stats.work, expected.stats.work) << what;
        EXPECT_EQ(stats.texels_fallback, expected.stats.texels_fallback) << what;
        EXPECT_EQ(baker.pending(), expected.stats.texels_fallback) << what;
        // bake() emits each row as stage L finishes it, advance() all rows at the end: the same sum
        EXPECT_EQ(stats.mean_ratio, expected.stats.mean_ratio) << what;
        EXPECT_THROW(baker.advance(spent, cones.view(), apex, stats), BakeError) << what;  // nothing begun
        if (sectors != 4) continue;
        // an unlimited budget: one call, refined as bake() refines
        Budget unlimited;
        unlimited.tolerance = 0.0f;
        const BudgetedBilinear refined = bake_bilinear_budgeted(map, sectors, address, unlimited);
        baker.begin(view_of(map));
        ASSERT_TRUE(baker.advance(unlimited, cones.view(), apex, stats)) << what;
        EXPECT_EQ(cones.ratios, refined.cones.ratios) << what;
        EXPECT_EQ(stats.texels_refined, refined.stats.texels_refined) << what;
        // bake() in the middle of a stage ends it
        baker.begin(view_of(input));
        EXPECT_FALSE(baker.advance(spent, cones.view(), apex, stats)) << what;
        baker.bake(view_of(map), spent, cones.view(), apex);
        EXPECT_FALSE(baker.in_progress()) << what;
        EXPECT_EQ(cones.ratios, expected.cones.ratios) << what;
      }
}

TEST(BilinearBaker, RejectsBadInput) {
  EXPECT_THROW(BilinearBaker(0, 4, 4, Address::wrap), BakeError);
  EXPECT_THROW(BilinearBaker(4, 4, 3, Address::wrap), BakeError);
  BilinearBaker baker(4, 4, 4, Address::wrap);
  const Map ok = test::make_flat(4, 4);
  std::vector<float> ratios(16 * 4), apex(16);
  EXPECT_THROW(baker.refine({}, {ratios.data(), 4, 4, 4}, apex), BakeError);  // nothing baked yet
  EXPECT_THROW(baker.bake(view_of(ok), {}, {ratios.data(), 4, 4, 4}, {apex.data(), 15}), BakeError);
  const Map other = test::make_flat(5, 4);
  std::vector<float> other_ratios(20 * 4), other_apex(20);
  EXPECT_THROW(baker.bake(view_of(other), {}, {other_ratios.data(), 5, 4, 4}, other_apex), BakeError);
  Map nan_map = test::make_flat(4, 4);
  nan_map.at(1, 1) = std::nanf("");
  EXPECT_THROW(baker.bake(view_of(nan_map), {}, {ratios.data(), 4, 4, 4}, apex), BakeError);
  Budget bad;
  bad.tolerance = 1.5f;
  EXPECT_THROW(baker.bake(view_of(ok), bad, {ratios.data(), 4, 4, 4}, apex), BakeError);
  EXPECT_NO_THROW(baker.bake(view_of(ok), {}, {ratios.data(), 4, 4, 4}, apex));
  for (float r : ratios) EXPECT_EQ(r, 1.0f);
}

// Progress reports (bake.h, Progress) as a property, not a timing: the fractions strictly increase
// in (0, 1], the last is exactly 1, no two calls overlap, there are at most max_progress_reports + 1
// of them, and the map is the one baked without them.
struct ProgressLog {
  std::mutex mutex;
  std::vector<double> fractions;
  std::atomic<int> inside{0};
  std::atomic<bool> overlapped{false};

  Progress callback() {
    return [this](double fraction) {
      if (inside.fetch_add(1) != 0) overlapped = true;
      std::this_thread::yield();  // widen the window another call would overlap in
      {
        const std::lock_guard lock(mutex);
        fractions.push_back(fraction);
      }
      inside.fetch_sub(1);
    };
  }

  void expect_well_formed(const std::string& what) const {
    ASSERT_FALSE(fractions.empty()) << what;
    EXPECT_FALSE(overlapped) << what;
    EXPECT_LE(fractions.size(), std::size_t(max_progress_reports) + 1) << what;
    EXPECT_EQ(fractions.back(), 1.0) << what;
    for (std::size_t k = 0; k < fractions.size(); ++k) {
      EXPECT_GT(fractions[k], 0.0) << what << " call " << k;
      EXPECT_LE(fractions[k], 1.0) << what << " call " << k;
      if (k > 0) {
        EXPECT_GT(fractions[k], fractions[k - 1]) << what << " call " << k;
      }
    }
  }
};

TEST(Progress, ReportsIncreasingFractionsEndingAtOne) {
  Map tall = make_noise(6, 1500);  // more rows than reports: the throttle has to skip
  tall.name = "tall-noise";
  Map one = test::make_flat(1, 1, 0.3f);
  one.name = "one-texel";
  for (const Map& map : {make_noise(48, 40), tall, test::make_bricks(33, 17), one})
    for (Address address : {Address::wrap, Address::clamp}) {
      const std::string what = map.name + " " + address_name(address);
      ProgressLog log;
      BilinearConeSettings settings;
      settings.progress = log.callback();
      const BilinearCones without = bake_bilinear(map, 4, address);
      std::vector<float> apex(map.values.size());
      ConeMap cones = make_cone_map(map, 4);
      bake_bilinear_cones(view_of(map), address, cones.view(), apex, settings);
      log.expect_well_formed("bilinear " + what);
      EXPECT_EQ(cones.ratios, without.cones.ratios) << what;
      EXPECT_EQ(apex, without.apex) << what;

      // the other row-by-row bakers
      const ConeMap exact = exact_of(map, 4, address);
      using Baker = BakeStats (*)(HeightView, Address, ConeView, const Progress&);
      const std::pair<const char*, Baker> bakers[] = {
          {"exact", bake_exact}, {"original", bake_original}, {"relaxed", bake_relaxed}};
      for (const auto& [name, baker] : bakers) {
        if (std::string(name) == "relaxed" && map.height > 100) continue;  // seconds, and no new path
        ProgressLog baker_log;
        ConeMap out = make_cone_map(map, 4);
        baker(view_of(map), address, out.view(), baker_log.callback());
        baker_log.expect_well_formed(std::string(name) + " " + what);
        if (std::string(name) != "relaxed") {
          EXPECT_EQ(out.ratios, exact.ratios) << name << " " << what;
        }
      }
    }
}

// On one thread nothing is skipped: one report per ceil(rows / max_progress_reports) rows, then 1.
TEST(Progress, OnOneThreadReportsAtEveryThrottleStep) {
  for (const int rows : {1, 7, 200, 201, 1500}) {
    const Map map = make_noise(3, rows);
    ProgressLog log;
    BilinearConeSettings settings;
    settings.progress = log.callback();
    std::vector<float> apex(map.values.size());
    ConeMap cones = make_cone_map(map, 1);
    tbb::task_arena one_thread(1);
    one_thread.execute(
        [&] { bake_bilinear_cones(view_of(map), Address::wrap, cones.view(), apex, settings); });
    log.expect_well_formed(std::to_string(rows) + " rows");
    const int step = (rows + max_progress_reports - 1) / max_progress_reports;
    EXPECT_EQ(log.fractions.size(), std::size_t((rows - 1) / step + 1)) << rows << " rows";
    for (std::size_t k = 0; k + 1 < log.fractions.size(); ++k) {
      EXPECT_EQ(log.fractions[k], double((k + 1) * step) / rows) << rows << " rows, call " << k;
    }
  }
}

}  // namespace
}  // namespace displace::bake
