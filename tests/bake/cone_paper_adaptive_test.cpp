// tests/bake/cone_paper_adaptive_test.cpp - the paper's adaptive baker (bake/cone_paper_adaptive.cpp).
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

}  // namespace
}  // namespace displace::bake
