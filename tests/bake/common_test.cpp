// tests/bake/common_test.cpp - the input validation every baker shares (bake/common.cpp).
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

}  // namespace
}  // namespace displace::bake
