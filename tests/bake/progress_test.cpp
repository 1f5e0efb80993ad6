// tests/bake/progress_test.cpp - the bakers' progress reports (bake/progress.h).
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
