// tests/bake/work_span_test.cpp - the record of a bake's work and span (bake/work_span.cpp), and what
// it must not change: stage L of BilinearBaker gives the same bits on 1, 2, 3 and 16 threads and
// while it is recorded (the recording cuts the regions into their finest pieces).
#include "bake/work_span.h"

#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cstring>
#include <string>
#include <vector>

#include "bake/bake.h"
#include "tests/test_maps.h"

namespace displace::bake {
namespace {

using test::Map;

TEST(WorkSpan, BoundIsSerialPlusEachRegionsWorkOverThreadsOrItsSpan) {
  detail::WorkSpan record;
  record.serial = 1.0;
  record.regions.push_back({"wide", 16.0, 0.5, 32});
  record.regions.push_back({"narrow", 8.0, 4.0, 2});
  EXPECT_DOUBLE_EQ(detail::work_span_total(record), 25.0);
  EXPECT_DOUBLE_EQ(detail::work_span_bound(record, 1), 25.0);
  EXPECT_DOUBLE_EQ(detail::work_span_bound(record, 2), 1.0 + 8.0 + 4.0);
  EXPECT_DOUBLE_EQ(detail::work_span_bound(record, 16), 1.0 + 1.0 + 4.0);
}

struct StageL {
  std::vector<float> cones, apex;
};

StageL bake_stage_l(const Map& map, Address address, int sectors, detail::WorkSpan* record = nullptr) {
  StageL out;
  out.cones.resize(map.values.size() * std::size_t(sectors));
  out.apex.resize(map.values.size());
  BilinearBaker baker(map.width, map.height, sectors, address);
  Budget budget;
  budget.milliseconds = 0.0;
  const HeightView heights{map.values.data(), map.width, map.height};
  const ConeView cones{out.cones.data(), map.width, map.height, sectors};
  baker.bake(heights, budget, cones, out.apex);
  if (record) {
    const detail::WorkSpanRecording recording(*record);
    baker.bake(heights, budget, cones, out.apex);
  }
  return out;
}

bool same_bits(const std::vector<float>& a, const std::vector<float>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0;
}

TEST(WorkSpan, RecordsEveryParallelRegionOfStageL) {
  const Map map = test::make_ocean(96, 64);
  detail::WorkSpan record;
  bake_stage_l(map, Address::wrap, 4, &record);
  std::vector<std::string> names;
  for (const detail::WorkSpanRegion& region : record.regions) {
    names.push_back(region.name);
    EXPECT_GT(region.tasks, 0) << region.name;
    EXPECT_GE(region.work, region.span) << region.name;
    EXPECT_GE(region.span, 0.0) << region.name;
  }
  // a recording predicts many threads: each quadrant's sweep in two strips, two passes
  for (const char* name : {"heights", "apexes", "cells", "lane plan", "sweeps: first passes",
                           "sweeps: second passes", "near field"})
    EXPECT_NE(std::find(names.begin(), names.end(), name), names.end()) << name;
  for (const detail::WorkSpanRegion& region : record.regions) {
    if (region.name.rfind("sweeps: ", 0) == 0) {
      EXPECT_EQ(region.tasks, 8);  // two strips per quadrant
    } else if (region.name == "near field") {
      EXPECT_EQ(region.tasks, 8);  // 64 rows in bands of 8, the fewest rows a band has
    } else if (region.name == "apexes") {
      EXPECT_EQ(region.tasks, 64);  // a row each
    }
  }
  EXPECT_GE(record.serial, 0.0);
  EXPECT_LE(detail::work_span_bound(record, 16), detail::work_span_total(record));
  EXPECT_FALSE(detail::work_span_active.load());
}

// Non-square, odd-sized, wrap and clamp: every thread count bakes the same bits, recorded or not.
TEST(WorkSpan, StageLIsTheSameOnAnyThreadCount) {
  struct Case {
    Map map;
    Address address;
    int sectors;
  };
  const std::vector<Case> cases = {
      {test::make_ocean(62, 47), Address::wrap, 4},    {test::make_spikes(61, 47), Address::clamp, 4},
      {test::make_bricks(130, 33), Address::clamp, 4}, {test::make_ocean(33, 130), Address::wrap, 4},
      {test::make_spikes(200, 72), Address::wrap, 8},  {test::make_fractal_cliff(257, 255), Address::wrap, 1},
      {test::make_ocean(256, 256), Address::wrap, 4},  {test::make_terraces(17, 300), Address::clamp, 4},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.map.name + " " + std::to_string(c.map.width) + " x " + std::to_string(c.map.height) +
                 (c.address == Address::wrap ? " wrap" : " clamp"));
    StageL one;
    tbb::task_arena(1).execute([&] { one = bake_stage_l(c.map, c.address, c.sectors); });
    for (int threads : {2, 3, 16}) {
      StageL many, recorded;
      detail::WorkSpan record;
      tbb::task_arena arena(threads);
      arena.execute([&] {
        many = bake_stage_l(c.map, c.address, c.sectors);
        recorded = bake_stage_l(c.map, c.address, c.sectors, &record);
      });
      EXPECT_TRUE(same_bits(one.cones, many.cones)) << threads << " threads";
      EXPECT_TRUE(same_bits(one.apex, many.apex)) << threads << " threads";
      EXPECT_TRUE(same_bits(one.cones, recorded.cones)) << threads << " threads, recorded";
      EXPECT_TRUE(same_bits(one.apex, recorded.apex)) << threads << " threads, recorded";
    }
  }
}

}  // namespace
}  // namespace displace::bake
