// tests/bake/cone_original_test.cpp - the original baker (bake/cone_original.cpp).
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

}  // namespace
}  // namespace displace::bake
