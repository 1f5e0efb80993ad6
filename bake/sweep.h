// bake/sweep.h - quadrant dilation sweeps (internal to bake/; see cone_sweep.cpp).
#pragma once

#include <array>
#include <functional>

#include "bake/geometry.h"

namespace displace::bake::detail {

// Ratio lanes come in two bands of geometric lanes. The low band needs only a short warm-up past
// the wrap seam (its largest ratio reaches only that far), so it gives results early; the high band
// needs the whole map as warm-up.
constexpr int sweep_band_count = 2;
constexpr int sweep_lane_count = 12;                                  // ratios tested per band
constexpr float sweep_band_edges[sweep_band_count + 1] = {0.02f, 0.2f, 1.0f};  // lowest .. highest ratio

std::array<float, sweep_lane_count> sweep_lanes(int band);

// For quadrant q (sector q of 4: 0 = du >= 0, dv >= 0, then counter-clockwise), raises out[texel] to
// the largest lane of `band` whose dilation test passes: a lower bound of the texel's exact cone
// ratio over blockers in that closed quadrant. height_range = max height - min height of the map.
// stop() is asked every few rows; when it says yes the sweep ends and the rows not yet swept keep
// whatever out held.
void sweep_quadrant(const Grid& grid, const float* heights, float height_range, int quadrant, int band,
                    const std::function<bool()>& stop, float* out);

}  // namespace displace::bake::detail
