// render/device.h - the device path: maps made in compute shaders on the renderer's own Vulkan device,
// written straight into the images it samples, so that a frame uploads nothing but its uniforms.
//
// DeviceSim: the moving sources of sim/sim.h evaluated on the device. The FFT ocean (Tessendorf; the
// spectrum made once on the CPU, OceanSpectrumView): per frame the spectrum's evolution, VkFFT's
// inverse FFTs and the choppy resampling to a height field. Sinusoid water (SinusoidWavesView): the
// sum per texel. The heights equal the CPU's (sim::Ocean::evaluate with sim::resample_displaced for
// choppy water; sim::sinusoid_heights) under the same mapping within float rounding; where choppy
// water folds over, the inverse of the displacement is not unique and a texel may take another
// fold's height. Time is double on the host; phases reach the shader reduced (w t_anchor modulo
// 2 pi in double, plus |w (t - t_anchor)| < 1e5 rad in split floats), so t = 1e9 s is as precise as 0.
//
// DeviceCones: the renderer's cone maps (bake.h's bake_bilinear_cones contract: apex H_c = max of the
// bilinear surface over the texel's square, r_k valid from every point of it) made in compute from
// heights on the device - a DeviceSim's, or a static map uploaded once - into the cone image the
// renderer samples (ConeMapView::on_device). Proof: docs/design/device-cones.md; figures: docs/figures.md.
//
// DeviceLevels: the levels of detail of a DeviceSim's heights (bake.h's chain and its slope moments)
// with each level's cones, made in compute into the atlases the renderer samples
// (MapSet::device_levels): the far sea of the device path. docs/design/levels.md.
#pragma once

#include <memory>
#include <span>
#include <vector>

#include "render/render.h"

namespace displace::render {

// What the device ocean needs, made once on the CPU (pipeline/ fills it from sim::Ocean::half_spectrum).
struct OceanSpectrumView {
  int size = 0;             // N, even, >= 2
  float patch_size = 0.0f;  // metres
  float choppiness = 0.0f;  // lambda of the choppy displacement
  // N x (N/2 + 1) modes, row i (wave number index along y, FFTW's unshifted order), column j (along x):
  // h~(t) = (p c + q s) + i (r c + u s) with (c, s) = (cos, sin)(w t), the half-texel shift folded in
  std::span<const float> coefficients;  // (p, q, r, u) per mode
  std::span<const float> omega;         // w per mode, rad/s
  float scale = 1.0f, bias = 0.0f;      // heights in [0, 1] = clamp(metres * scale + bias, 0, 1)
  float foam_start = 0.85f;             // foam coverage none at Jacobian >= foam_start ...
  float foam_full = 0.45f;              // ... full at <= foam_full
};

// Sinusoid water: h(x, t) = sum_i a_i sin(k_i . x - w_i t + phi_i) at the texel centres of a
// size x size map `patch_size` metres wide (sim::sinusoid_heights).
struct SinusoidWavesView {
  int size = 0;                     // texels a side, >= 1
  float patch_size = 0.0f;          // metres
  std::span<const float> waves;     // (kx, ky, amplitude, omega, phase) per wave, sim::Wave's fields
  float scale = 1.0f, bias = 0.0f;  // as OceanSpectrumView's
};

enum DeviceEffect : unsigned {
  device_choppy = 1u << 0,  // the ocean's horizontal displacement, resampled onto the grid (choppiness > 0)
  device_foam = 1u << 1,    // the ocean's foam coverage from the Jacobian of the displacement
};

class DeviceSim {
 public:
  // Uploads the spectrum (or the waves), makes the kernels and plans the FFTs once; throws RenderError.
  // `effects`: DeviceEffect bits. The renderer must outlive this.
  DeviceSim(Renderer& renderer, const OceanSpectrumView& spectrum, unsigned effects);
  DeviceSim(Renderer& renderer, const SinusoidWavesView& waves);
  ~DeviceSim();
  DeviceSim(const DeviceSim&) = delete;
  DeviceSim& operator=(const DeviceSim&) = delete;

  // Records the heights at `time` (seconds) into the renderer's next frame, ahead of its draw. The
  // renderer samples these heights (and foam) for the frames whose MapSet::device_heights is maps().
  void simulate(double time);
  // Submits what is recorded, waits, and reads back the last simulate()'s maps (any may be null):
  // heights in [0, 1], heights in metres, foam coverage (empty without device_foam).
  void read_back(std::vector<float>* heights, std::vector<float>* metres, std::vector<float>* foam);
  // Submits what is recorded and waits for it (a caller that times the device, or hands the heights
  // to another queue's work).
  void finish();

  // The heights (and foam) as a MapSet names them, and as DeviceCones and DeviceLevels read them.
  std::shared_ptr<const DeviceHeightImages> maps() const;
  int size() const;
  unsigned effects() const;
  long long fft_count()
      const;  // inverse FFTs recorded: per ocean frame 1 for heights, 3 choppy, 4 foam, 6 both
  // The device's milliseconds for the last simulate() whose frame has finished (GPU timestamps around
  // its kernels); 0 where the device has no timestamps or none has finished.
  double device_milliseconds() const;

  struct State;

 private:
  std::unique_ptr<State> state_;
};

// How much of a DeviceCones bake goes beyond the first pass. A texel whose first pass bounded a node
// whole is "cut", and up to `texels` cut texels (which ones: the order the device runs them in) are
// searched again down to the cells (from the same window). unlimited_texels: no first pass, every
// texel searched to the cells from the full window. Each is conservative on its own.
inline constexpr long long unlimited_texels = -1;
struct DeviceConeBudget {
  long long texels = unlimited_texels;  // cut texels searched again per bake, at most; 0: the first pass only
  DeviceFirstPass first_pass = {};
};

struct DeviceConeStats {
  long long texels_refined = 0;  // texels searched down to the cells (all of them when unlimited)
  long long texels_cut = 0;      // texels the first pass cut (0 when unlimited: no first pass)
};

class DeviceCones {
 public:
  // Cones of the heights a device stage of this renderer writes (DeviceSim::maps(); alive while this
  // bakes).
  DeviceCones(Renderer& renderer, std::shared_ptr<const DeviceHeightImages> heights, int sector_count,
              bake::Address address);
  // Cones of a static map, uploaded once (heights finite, in [0, 1]).
  DeviceCones(Renderer& renderer, bake::HeightView heights, int sector_count, bake::Address address);
  ~DeviceCones();
  DeviceCones(const DeviceCones&) = delete;
  DeviceCones& operator=(const DeviceCones&) = delete;

  // Records the bake into the renderer's next frame, after the ocean's simulate() recorded there and
  // ahead of the draw; frames whose MapSet has cones[cone_slot(sector_count)].device = map() sample it.
  void bake(const DeviceConeBudget& budget = {});
  // Submits what is recorded, waits, and reads back what the renderer samples (either may be null):
  // ratios decoded, W x H x sectors interleaved (bake::ConeView's layout), and apex heights decoded.
  // Throws RenderError where the heights held a NaN or a value outside [0, 1]. After bake_lagged()
  // the stats and the heights' check are those of the served map (nothing waits for a band in flight).
  DeviceConeStats read_back(std::vector<float>* ratios, std::vector<float>* apex);

  // Lagged maps (lag_frames = N > 0): one map's bake is spread over N calls - a snapshot of the
  // heights and its pyramid when it begins, then an even share of the texel rows a call, on the
  // renderer's async queue (RendererOptions::async_compute: beside the frame's draw on a GPU) - and
  // served from the N-th call after it began, when the next one begins. Each call's frame samples the
  // served map with every apex raised by the most any texel rose since that map's heights (rounded
  // up): conservative for the frame's own heights, at most 2N - 1 calls old. The first call, and the
  // first after N changed, makes a whole map. Returns the age in calls of the map the frame samples;
  // 0 is bake(budget). docs/design/lagged-cone-maps.md.
  long long bake_lagged(const DeviceConeBudget& budget, int lag_frames);
  // bake_lagged(budget, N >= 1) in its two halves, so that the heights may change between them:
  // advance_lagged serves the map whose bands are done and begins the next from the heights as they
  // are (and records this frame's band); compose_lagged raises the served map by the lift over the
  // heights as they are then, for this frame's draw, and returns its age. A map made from heights
  // simulated at the next frame's time (the sim run again at this frame's own before compose) is
  // served the next frame with a lift of about 0: the frame's own map, baked beside the frame before.
  void advance_lagged(const DeviceConeBudget& budget, int lag_frames);
  long long compose_lagged();
  // How far the apexes were raised in the last bake_lagged() frame that has finished (0: none yet,
  // or it was not lagged).
  float lift() const;

  std::shared_ptr<const DeviceConeImage> map() const;  // the cone map as a MapSet names it
  int width() const;
  int height() const;
  int sector_count() const;
  bake::Address address() const;
  // The device's milliseconds for the last bake() whose frame has finished (GPU timestamps); 0 where
  // none has, or the device has no timestamps.
  double device_milliseconds() const;

  struct State;

 private:
  std::unique_ptr<State> state_;
};

// DeviceLevels: the levels of detail of the heights this renderer's DeviceSim writes, made on the
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
  DeviceLevels(Renderer& renderer, std::shared_ptr<const DeviceHeightImages> heights, int sector_count,
               bake::Address address);
  ~DeviceLevels();
  DeviceLevels(const DeviceLevels&) = delete;
  DeviceLevels& operator=(const DeviceLevels&) = delete;

  // Records the chain of the heights as they are and every level's cone bake (each within `budget`)
  // into the renderer's next frame, after the ocean's simulate() there and ahead of the draw.
  void make(const DeviceConeBudget& budget = {});
  // Submits what is recorded, waits, and reads back level `level` (1 .. level_count()) as the renderer
  // samples it (any may be null): heights, slope moments (3 a texel), ratios (W x H x sectors,
  // decoded), apex heights and the level's highest height (where its rays start); returns that
  // level's bake stats. Throws RenderError as DeviceCones::read_back does, and for a level out of range.
  DeviceConeStats read_back(int level, std::vector<float>* heights, std::vector<float>* slopes,
                            std::vector<float>* ratios, std::vector<float>* apex, float* top = nullptr);

  std::shared_ptr<const DeviceLevelImages> maps() const;  // the levels as a MapSet names them
  int level_count() const;                                // 0 for a map with an odd side
  int sector_count() const;
  bake::Address address() const;
  // The device's milliseconds for the last make() whose frame has finished (the chain and every
  // level's bake); 0 where none has, or the device has no timestamps.
  double device_milliseconds() const;

  struct State;

 private:
  std::unique_ptr<State> state_;
};

}  // namespace displace::render
