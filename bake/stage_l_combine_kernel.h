// bake/stage_l_combine_kernel.h - the last step of the bilinear baker's stage L for a row of texels:
// each quadrant's ratio from its lanes, its near field and the floors (cone_bilinear_budgeted.cpp
// says why each bound holds), one texel at a time; lane_sweep_avx512.cpp does 16 at a time with the
// same arithmetic, and the same bits (LaneSweep.StageLCombineKernelsAgree).
#pragma once

#include <algorithm>
#include <cstdint>

#include "bake/lane_sweep.h"

namespace displace::bake::detail {

// Texels [first, last) of the row.
inline void stage_l_combine_kernel(const StageLCombineJob& job, int first, int last) {
  const float* const lane_ratio = job.lane_ratio;
  const double highest = double(job.highest);
  for (int j = first; j < last; ++j) {
    const float apex = job.apex[j];
    // below the lowest lane: every far cell is at least half a texel away and at most `highest`
    const float floor =
        job.highest > apex ? float(job.half_texel / (highest - double(apex)) * (1.0 - 1e-6)) : 1.0f;
    for (int q = 0; q < 4; ++q) {
      const float beyond2 = std::max(floor, lane_ratio[job.passed[q][j]]);
      const float beyond3 = std::max(floor, lane_ratio[job.passed3[q][j]]);
      // cells beyond box 3: the lanes; between the boxes: the lanes or the slope; box 2: near (and the
      // Lipschitz bound holds for every cell, near and far)
      job.out[std::size_t(j) * 4 + std::size_t(q)] = std::max(
          std::min(std::min(beyond3, std::max(beyond2, job.slope3[q][j])), std::min(job.near[q][j], 1.0f)),
          job.lipschitz);
    }
  }
}

}  // namespace displace::bake::detail
