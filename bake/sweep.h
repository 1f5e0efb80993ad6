// bake/sweep.h - quadrant dilation sweeps (internal to bake/; see cone_sweep.cpp).
#pragma once

#include <array>
#include <functional>

#include "bake/geometry.h"

namespace displace::bake::detail {

constexpr int sweep_lane_count = 24;        // ratios tested per texel in one sweep
constexpr float sweep_lowest_ratio = 0.02f;  // lanes are geometric from this ratio up to 1

std::array<float, sweep_lane_count> sweep_lanes();

// For quadrant q (sector q of 4: 0 = du >= 0, dv >= 0, then counter-clockwise), writes out[texel] = a
// lower bound of the texel's exact cone ratio over blockers in that closed quadrant: the largest lane
// whose dilation test passes (0 when none does). height_range = max height - min height of the map.
// stop() is asked every few rows; when it says yes the sweep ends and the rows not yet swept keep
// whatever out held.
void sweep_quadrant(const Grid& grid, const float* heights, float height_range, int quadrant,
                    const std::function<bool()>& stop, float* out);

}  // namespace displace::bake::detail
