// tests/sim/mapping_test.cpp - metres to [0, 1] (sim/mapping.cpp).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <numbers>
#include <stdexcept>
#include <thread>
#include <vector>

#include "sim/sim.h"

namespace displace::sim {
namespace {

using Complex = std::complex<double>;

TEST(HeightMapping, ClampsAndCounts) {
  const HeightMapping mapping{0.5f, 0.5f};
  const std::vector<float> raw = {-3.0f, -1.0f, 0.0f, 1.0f, 2.5f, NAN};
  std::vector<float> out(raw.size());
  EXPECT_EQ(apply_mapping(mapping, raw, out), 3u);
  EXPECT_EQ(out, (std::vector<float>{0.0f, 0.0f, 0.5f, 1.0f, 1.0f, 0.0f}));
  std::vector<float> short_out(2);
  EXPECT_THROW(apply_mapping(mapping, raw, short_out), std::invalid_argument);
}

}  // namespace
}  // namespace displace::sim
