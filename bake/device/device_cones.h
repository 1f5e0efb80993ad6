// bake/device/device_cones.h - cone maps and levels of detail made on the device, in compute, from
// heights on the device, into the images the renderer samples: nothing is read back or uploaded per
// frame.
//
// DeviceCones: the renderer's cone maps (bake.h's bake_bilinear_cones contract: apex H_c = max of the
// bilinear surface over the texel's square, r_k valid from every point of it) from a
// sim::DeviceSim's heights or a static map uploaded once. Proof: docs/design/device-cones.md.
//
// DeviceLevels: the levels of detail of a DeviceSim's heights (bake.h's chain and its slope moments)
// with each level's cones: the far sea of the device path. docs/design/levels.md.
//
// Both record into the frames of a vulkan::Frames (the renderer's: Renderer::frames()), after the
// heights' stage and ahead of the draw; map() / maps() are what a MapSet names (render/map_set.h).
// Errors: vulkan::Error (render::RenderError).
#pragma once

#include <memory>
#include <vector>

#include "bake/bake.h"
#include "bake/device/first_pass.h"

namespace displace::vulkan {
class Frames;
struct DeviceHeightImages;
struct DeviceConeImage;
struct DeviceLevelImages;
}  // namespace displace::vulkan

namespace displace::bake {

// How much of a DeviceCones bake goes beyond its first pass, from the Budget every baker takes - the
// one rule, for every caller: a work budget (max_work >= 0) is that many "cut" texels (whose first
// pass bounded a node whole; which ones: the order the device runs them in) searched again down to
// the cells from the same window; a wall-clock budget (finite milliseconds) is the first pass alone,
// for a dispatch cannot stop when the time runs out; neither (Budget{}) is every texel searched to
// the cells from the full window, no first pass. Each is conservative on its own. Returns the cut
// texels searched again, or unlimited_texels for the last.
inline constexpr long long unlimited_texels = -1;
long long device_refine_limit(const Budget& budget);
// The Budget of `texels` cut texels searched again (unlimited_texels: every texel to the cells).
inline Budget work_budget(long long texels) {
  Budget budget;
  budget.max_work = texels;
  return budget;
}

// The stats of a device bake (BakeStats, as every baker's): texels_refined, the texels searched down
// to the cells (all of them when unlimited); texels_fallback, the cut texels left at their first
// pass's bound; milliseconds, the device's time where it has timestamps (0 otherwise); mean_ratio
// where the ratios were read back. work is not counted on the device (0).

class DeviceCones {
 public:
  // Cones of the heights a device stage on the same Frames writes (DeviceSim::maps(); alive while this
  // bakes).
  DeviceCones(vulkan::Frames& frames, std::shared_ptr<const vulkan::DeviceHeightImages> heights,
              int sector_count, Address address);
  // Cones of a static map, uploaded once (heights finite, in [0, 1]).
  DeviceCones(vulkan::Frames& frames, HeightView heights, int sector_count, Address address);
  ~DeviceCones();
  DeviceCones(const DeviceCones&) = delete;
  DeviceCones& operator=(const DeviceCones&) = delete;

  // Records the bake into the next frame of its Frames, after the ocean's simulate() recorded there and
  // ahead of the draw; frames whose MapSet has cones[cone_slot(sector_count)].device = map() sample it.
  void bake(const Budget& budget = {}, const DeviceFirstPass& first_pass = {});
  // Submits what is recorded, waits, and reads back what the renderer samples (either may be null):
  // ratios decoded, W x H x sectors interleaved (bake::ConeView's layout), and apex heights decoded.
  // Throws vulkan::Error where the heights held a NaN or a value outside [0, 1]. After bake_lagged()
  // the stats and the heights' check are those of the served map (nothing waits for a band in flight).
  BakeStats read_back(std::vector<float>* ratios, std::vector<float>* apex);

  // Lagged maps (lag_frames = N > 0): one map's bake is spread over N calls - a snapshot of the
  // heights and its pyramid when it begins, then an even share of the texel rows a call, on the
  // async queue (Context::async_queue, RendererOptions::async_compute: beside the frame's draw on a GPU) -
  // and served from the N-th call after it began, when the next one begins. Each call's frame samples the
  // served map with every apex raised by the most any texel rose since that map's heights (rounded
  // up): conservative for the frame's own heights, at most 2N - 1 calls old (bake::LagSchedule,
  // bake/lagged.h: the first call makes a whole map; a change of N keeps the map under way). Returns the age
  // in calls of the map the frame samples; 0 is bake(budget). docs/design/lagged-cone-maps.md.
  long long bake_lagged(const Budget& budget, int lag_frames, const DeviceFirstPass& first_pass = {});
  // bake_lagged(budget, N >= 1) in its two halves, so that the heights may change between them:
  // advance_lagged serves the map whose bands are done and begins the next from the heights as they
  // are (and records this frame's band); compose_lagged raises the served map by the lift over the
  // heights as they are then, for this frame's draw, and returns its age. A map made from heights
  // simulated at the next frame's time (the sim run again at this frame's own before compose) is
  // served the next frame with a lift of about 0: the frame's own map, baked beside the frame before.
  void advance_lagged(const Budget& budget, int lag_frames, const DeviceFirstPass& first_pass = {});
  long long compose_lagged();
  // How far the apexes were raised in the last bake_lagged() frame that has finished (0: none yet,
  // or it was not lagged).
  float lift() const;

  std::shared_ptr<const vulkan::DeviceConeImage> map() const;  // the cone map as a MapSet names it
  int width() const;
  int height() const;
  int sector_count() const;
  Address address() const;
  // The device's milliseconds for the last bake() whose frame has finished (GPU timestamps); 0 where
  // none has, or the device has no timestamps.
  double device_milliseconds() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

// DeviceLevels: the levels of detail of the heights a DeviceSim on the same Frames writes, made on the
// device for frames whose MapSet::device_levels is maps(). The chain is bake.h's (levels 1 ..
// bake::detail_level_count(W, H), each the 2 x 2 box means of the one below, with the slope moments of
// bake::gradient_moments and downsample_moments): the same heights as the CPU's chain of the same
// level-0 heights, bit for bit, and the same moments within a float rounding. Each level's cones are
// a DeviceCones' of that level's heights (bake.h's bilinear contract for the level's surface), and
// each level's highest height (where a ray on it starts) is the top of that bake's max pyramid,
// copied into the frame's uniforms on the device: nothing is read back or uploaded per frame.
class DeviceLevels {
 public:
  // A chain of a DeviceSim's heights (DeviceSim::maps(), alive while this makes levels), with
  // cones of `sector_count` sectors and `address`; its images and bakes are made here, once.
  DeviceLevels(vulkan::Frames& frames, std::shared_ptr<const vulkan::DeviceHeightImages> heights,
               int sector_count, Address address);
  ~DeviceLevels();
  DeviceLevels(const DeviceLevels&) = delete;
  DeviceLevels& operator=(const DeviceLevels&) = delete;

  // Records the chain of the heights as they are and every level's cone bake (each within `budget`)
  // into the next frame of its Frames, after the ocean's simulate() there and ahead of the draw.
  void make(const Budget& budget = {}, const DeviceFirstPass& first_pass = {});
  // Submits what is recorded, waits, and reads back level `level` (1 .. level_count()) as the renderer
  // samples it (any may be null): heights, slope moments (3 a texel), ratios (W x H x sectors,
  // decoded), apex heights and the level's highest height (where its rays start); returns that
  // level's bake stats. Throws vulkan::Error as DeviceCones::read_back does, and for a level out of range.
  BakeStats read_back(int level, std::vector<float>* heights, std::vector<float>* slopes,
                      std::vector<float>* ratios, std::vector<float>* apex, float* top = nullptr);

  std::shared_ptr<const vulkan::DeviceLevelImages> maps() const;  // the levels as a MapSet names them
  int level_count() const;                                        // 0 for a map with an odd side
  int sector_count() const;
  Address address() const;
  // The device's milliseconds for the last make() whose frame has finished (the chain and every
  // level's bake); 0 where none has, or the device has no timestamps.
  double device_milliseconds() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace displace::bake
