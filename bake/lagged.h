// bake/lagged.h - lagged cone maps: a map's bake spread over frames while every frame samples the
// map made last, its apexes raised for the frame's own heights, so that each cone stays conservative
// (docs/design/lagged-cone-maps.md has the proof).
//
// LagSchedule is the one schedule both backends keep: the first map is made whole; after it a map
// begun on frame b takes a share of its work each frame - at least (k + 1) / S of it done by the end
// of its k-th, all of it by its share S - 1 - and is served from the first frame whose draw comes
// after its last share: S = N + 1 shares where a frame's work is done before its draw (the CPU's),
// S = N where it lands after (the device's, beside the draw). Either way it is served on frame b + N
// (sooner where the CPU finishes early), the next begins once none is in progress, and a served map
// is at most 2N (CPU) or 2N - 1 (device) frames old. A change of N keeps the map in progress; its
// shares count on under the new N.
//
// LaggedCones::advance is the CPU's, one call a frame, on a BilinearBaker's first stage; the device's
// is bake::DeviceCones::bake_lagged (bake/device/device_cones.h). raise_apexes is the raise in floats
// (the device raises its 16-bit apexes in a compute pass, by the same rule).
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

class LagSchedule {
 public:
  // Where a frame's share of a map is done: before the frame's draw, or only after it.
  enum class Lands { before_draw, after_draw };
  explicit LagSchedule(Lands lands) : lands_(lands) {}

  // What a frame does, in this order: serve the map in progress (its last share landed after the
  // frame before's draw), begin a map from this frame's heights (none in progress), run its share.
  struct Share {
    bool serve = false;
    bool begin = false;
    bool whole = false;  // no map served yet: the one begun is made whole now and served this frame
    int index = 0;       // this frame's share of the map in progress (0 on the frame it began)
    int count = 1;       // by the end of share `index`, at least (index + 1) / count of the map is done
    bool last() const { return index + 1 >= count; }
  };
  // One call a frame before its work; `frame` numbers the frames (an age is a difference of them),
  // lag N >= 1.
  Share next(long long frame, int lag_frames);
  // After the frame's share: whether the map in progress is complete (a whole one always is; one done
  // before its last share: before_draw only). Returns whether this frame serves it.
  bool finished(bool complete);

  bool in_progress() const { return begun_ >= 0; }
  // The frame the served map's heights are from (-1: none yet); a frame's age of it is the difference.
  long long served_frame() const { return served_; }
  // The map in progress is gone (its backend dropped it): the next frame begins another.
  void drop_in_progress();
  // Nothing served any more (heights of another size): the next map is whole.
  void restart();

 private:
  Lands lands_;
  long long begun_ = -1;   // the frame the map in progress began on (-1: none)
  long long served_ = -1;  // the frame the served map began on (-1: none)
  int shares_ = 0;         // shares the map in progress has had
  bool whole_ = false, complete_ = false;
};

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
  };
  std::array<Map, 2> maps_;
  int served_ = -1, building_ = 0;  // served (-1: none yet) and the one being made
  LagSchedule schedule_{LagSchedule::Lands::before_draw};
};

}  // namespace displace::bake
