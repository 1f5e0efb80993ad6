// tests/bake/lane_sweep_test.cpp - the lane sweep and its kernels (bake/lane_sweep*.cpp, bake/*_kernel.h).
#include "bake/lane_sweep.h"

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
#include "tests/bake/bake_checks.h"
#include "tests/test_maps.h"

namespace displace::bake {
namespace {

using test::Map;

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

// The bilinear sweeps' inputs besides the plan - texel bottoms hashed from (salt, seed), at least
// `low` of the range, and fixed lane bonuses - and their counts: the four quadrants' passes, then
// the four of bonus3.
struct BilinearSweep {
  int width, height;
  std::vector<std::uint16_t> bottom;
  alignas(64) std::uint16_t bonus[detail::lane_count], bonus3[detail::lane_count];

  BilinearSweep(int W, int H, std::uint64_t salt, std::uint64_t seed, float low)
      : width(W), height(H), bottom(std::size_t(W) * H) {
    for (std::size_t t = 0; t < bottom.size(); ++t)
      bottom[t] = std::uint16_t(65535.0f * (low + (1.0f - low) * test::hash01(salt, seed, t)));
    for (int l = 0; l < detail::lane_count; ++l) {
      bonus[l] = std::uint16_t(300 + 20 * l);
      bonus3[l] = std::uint16_t(900 + 60 * l);
    }
  }

  std::vector<std::uint8_t> counts(const detail::LanePlan& plan, bool stop_early, bool split = false) const {
    const std::size_t texels = std::size_t(width) * std::size_t(height);
    std::vector<std::uint8_t> counts(texels * 8);
    std::uint8_t* passed[4];
    std::uint8_t* passed3[4];
    for (int q = 0; q < 4; ++q) {
      passed[q] = counts.data() + std::size_t(q) * texels;
      passed3[q] = counts.data() + std::size_t(4 + q) * texels;
    }
    detail::sweep_bilinear_quadrants(plan, width, height, bottom.data(), bonus, passed, bonus3, passed3, -1,
                                     stop_early, 0, 4, split);
    return counts;
  }
};

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
    const BilinearSweep sweep(W, H, 151, seed, 0.2f);
    auto run = [&](bool stop_early) { return sweep.counts(plan, stop_early); };
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

// The split sweeps (each quadrant in two strips, for many threads) give the whole sweeps' counts, bit
// for bit, with wrap and clamp, on odd and non-square maps, whatever the guesses of the rows the
// second passes take and however many threads run them - also where a strip's second pass does not
// meet its first and the quadrant is swept whole again (the near-flat and sparse maps).
TEST(LaneSweep, BilinearSplitSweepsGiveTheWholeSweepsCounts) {
  const std::pair<int, int> sizes[] = {{32, 32}, {33, 47},  {64, 35}, {40, 96},
                                       {97, 64}, {128, 41}, {3, 100}, {5, 90}};
  int maps = 0;
  for (std::uint64_t seed = 1; seed <= 64; ++seed) {
    const auto [W, H] = sizes[seed % 8];
    const bool wrap = seed % 4 != 0;
    const int cells_u = wrap ? W : W + 1, cells_v = wrap ? H : H + 1;
    std::vector<float> cells(std::size_t(cells_u) * cells_v, 0.0f);
    const int kind = int(seed % 4);
    for (int i = 0; i < cells_v; ++i)
      for (int j = 0; j < cells_u; ++j) {
        const float r = test::hash01(163, seed * 101 + std::uint64_t(i), std::uint64_t(j));
        cells[std::size_t(i) * cells_u + j] = kind == 0   ? 0.05f * r
                                              : kind == 1 ? (r > 0.97f ? r : 0.0f)
                                              : kind == 2 ? 0.5f * r * r
                                                          : 0.0f;
      }
    if (kind == 3)  // one spike on a flat map: its cone reaches across the map, past a strip
      cells[std::size_t(test::hash01(179, seed, 0) * float(cells_v)) % cells_v * cells_u +
            std::size_t(test::hash01(181, seed, 0) * float(cells_u)) % cells_u] = 1.0f;
    detail::LanePlan plan;
    detail::make_lane_plan(cells.data(), cells_u, cells_v, wrap, 0.02f, true, false, plan);
    const BilinearSweep sweep(W, H, 167, seed, 0.1f);
    auto run = [&](bool split) { return sweep.counts(plan, true, split); };
    const std::vector<std::uint8_t> whole = run(false);
    for (int threads : {1, 2, 3, 16}) {
      // guesses of the rows each second pass takes: from none to past the strip
      for (int slot = 0; slot < 8; ++slot)
        plan.scratch[std::size_t(slot)].second_lap_rows =
            int(test::hash01(173, seed * 17 + std::uint64_t(threads), std::uint64_t(slot)) * float(H));
      std::vector<std::uint8_t> split;
      tbb::task_arena(threads).execute([&] { split = run(true); });
      EXPECT_EQ(split, whole) << "seed " << seed << ", " << W << " x " << H << (wrap ? " wrap" : " clamp")
                              << ", " << threads << " threads";
    }
    ++maps;
  }
  EXPECT_EQ(maps, 64);
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
    // (copies: clang 14 lambdas capture no structured binding)
    auto length = [width = w, height = h](int da, int db) {
      return std::hypot(double(db) / width, double(da) / height);
    };
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

}  // namespace
}  // namespace displace::bake
