// sim/device/device_sim.h - the moving sources of sim/sim.h evaluated on the device, written
// straight into images the renderer samples, so that a frame uploads nothing but its uniforms.
//
// DeviceSim: the FFT ocean (Tessendorf; the spectrum made once on the CPU, OceanSpectrumView): per
// frame the spectrum's evolution, VkFFT's inverse FFTs and the choppy resampling to a height field.
// Sinusoid water (SinusoidWavesView): the sum per texel. The heights equal the CPU's
// (sim::Ocean::evaluate with sim::resample_displaced for choppy water; sim::sinusoid_heights) under
// the same mapping within float rounding; where choppy water folds over, the inverse of the
// displacement is not unique and a texel may take another fold's height. Time is double on the host;
// phases reach the shader reduced (w t_anchor modulo 2 pi in double, plus |w (t - t_anchor)| < 1e5 rad
// in split floats), so t = 1e9 s is as precise as 0.
//
// It records into the frames of a vulkan::Frames (the renderer's: Renderer::frames()), ahead of the
// frame's draw; its maps() are what a MapSet names (render/map_set.h) and what bake::DeviceCones and
// bake::DeviceLevels read. Errors: vulkan::Error (render::RenderError).
#pragma once

#include <memory>
#include <span>
#include <vector>

namespace displace::vulkan {
class Frames;
struct DeviceHeightImages;
}  // namespace displace::vulkan

namespace displace::sim {

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
  // Uploads the spectrum (or the waves), makes the kernels and plans the FFTs once; throws vulkan::Error.
  // `effects`: DeviceEffect bits. The Frames must outlive this.
  DeviceSim(vulkan::Frames& frames, const OceanSpectrumView& spectrum, unsigned effects);
  DeviceSim(vulkan::Frames& frames, const SinusoidWavesView& waves);
  ~DeviceSim();
  DeviceSim(const DeviceSim&) = delete;
  DeviceSim& operator=(const DeviceSim&) = delete;

  // Records the heights at `time` (seconds) into the next frame of its Frames, ahead of its draw. The
  // renderer samples these heights (and foam) for the frames whose MapSet::device_heights is maps().
  void simulate(double time);
  // Submits what is recorded, waits, and reads back the last simulate()'s maps (any may be null):
  // heights in [0, 1], heights in metres, foam coverage (empty without device_foam).
  void read_back(std::vector<float>* heights, std::vector<float>* metres, std::vector<float>* foam);
  // Submits what is recorded and waits for it (a caller that times the device, or hands the heights
  // to another queue's work).
  void finish();

  // The heights (and foam) as a MapSet names them, and as DeviceCones and DeviceLevels read them.
  std::shared_ptr<const vulkan::DeviceHeightImages> maps() const;
  int size() const;
  unsigned effects() const;
  long long fft_count()
      const;  // inverse FFTs recorded: per ocean frame 1 for heights, 3 choppy, 4 foam, 6 both
  // The device's milliseconds for the last simulate() whose frame has finished (GPU timestamps around
  // its kernels); 0 where the device has no timestamps or none has finished.
  double device_milliseconds() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace displace::sim
