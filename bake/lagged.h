// bake/lagged.h - lagged cone maps on the CPU: a BilinearBaker's first stage spread over frames while
// every frame samples the map made last, its apexes raised for the frame's own heights, so that each
// cone stays conservative (docs/design/lagged-cone-maps.md has the proof). The device's are
// bake::DeviceCones::bake_lagged (bake/device/device_cones.h): the same contract, its own schedule.
//
// LaggedCones::advance, one call a frame: the map in progress takes an even share of the first stage
// (k / (N + 1) after its k-th frame, more while the budget lasts; a new one begins on the frame's
// heights when none is in progress, and the first is made whole), and the map made last is served
// with every apex raised by raise_apexes: at most 2N frames old, a new one at least every N + 1.
#pragma once

#include <array>
#include <span>
#include <vector>

#include "bake/bake.h"

namespace displace::bake {

// The raise: lift = max(0, largest now[t] - made_from[t]), and `raised` = each apex + lift rounded up
// (at most 1), so that a cone map made from `made_from` holds for `now`. Returns the lift. All four
// spans one value a texel, as many.
float raise_apexes(std::span<const float> made_from, std::span<const float> now, std::span<const float> apex,
                   std::span<float> raised);

class LaggedCones {
 public:
  // The map a frame samples: the served map's ratios (W x H x sectors, ConeView's layout; valid until
  // the next advance that serves another map), its bake stats, its age in frames and the lift.
  struct Served {
    std::span<const float> ratios;
    BakeStats stats;
    long long age = 0;
    float lift = 0.0f;
  };
  // One frame `frame` of heights `heights` with lag N = lag_frames >= 1 on `baker` (made for their
  // size, sector count and address; between calls it bakes nothing else): writes the served map's
  // raised apexes into `raised` (resized to W x H).
  Served advance(BilinearBaker& baker, HeightView heights, int sector_count, const Budget& budget,
                 int lag_frames, long long frame, std::vector<float>& raised);

 private:
  // A map as the baker emitted it (apexes not raised), with the heights it was made from: the one
  // served and the one the baker emits into, so that a frame still uploading a map never sees it change.
  struct Map {
    std::vector<float> ratios, apex, heights;
    BakeStats stats;
    long long frame = 0;  // whose heights
  };
  std::array<Map, 2> maps_;
  int served_ = -1, building_ = 0;  // served (-1: none yet) and the one being made
  int build_frames_ = 0;            // frames the map being made has had so far
};

}  // namespace displace::bake
