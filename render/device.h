// render/device.h - the device path: maps made in compute shaders on the renderer's own Vulkan device,
// written straight into the images it samples, so that a frame uploads nothing but its uniforms.
//
// DeviceOcean: Tessendorf's FFT ocean (sim/sim.h's Ocean) evaluated on the device - the spectrum's
// evolution, VkFFT's inverse FFTs and the choppy resampling to a height field - from the spectrum the
// CPU made once (OceanSpectrumView). The heights equal sim::Ocean's (through sim::resample_displaced
// for choppy water, and the same HeightMapping) within float rounding; where choppy water folds over,
// the inverse of the displacement is not unique and a texel may take another fold's height.
// Time is double on the host; phases reach the shader reduced (|w dt| < 1e5 rad), so t = 1e9 s is as
// precise as t = 0.
#pragma once

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

enum DeviceEffect : unsigned {
  device_choppy = 1u << 0,  // the horizontal displacement, resampled onto the grid (choppiness > 0)
  device_foam = 1u << 1,    // foam coverage from the Jacobian of the displacement
};

class DeviceOcean {
 public:
  // Uploads the spectrum and plans the FFTs once (throws RenderError); `effects`: DeviceEffect bits.
  DeviceOcean(Renderer& renderer, const OceanSpectrumView& spectrum, unsigned effects);
  ~DeviceOcean();
  DeviceOcean(const DeviceOcean&) = delete;
  DeviceOcean& operator=(const DeviceOcean&) = delete;

  // Records the ocean at `time` (seconds) into the renderer's next frame, ahead of its draw. The
  // renderer samples these heights (and foam) for the frames whose MapSet says heights_on_device
  // (foam_on_device).
  void simulate(double time);
  // Submits what is recorded, waits, and reads back the last simulate()'s maps (any may be null):
  // heights in [0, 1], heights in metres, foam coverage (empty without device_foam).
  void read_back(std::vector<float>* heights, std::vector<float>* metres, std::vector<float>* foam);

  int size() const;
  unsigned effects() const;
  long long fft_count() const;  // inverse FFTs recorded: 1 per frame for heights, 3 choppy, 4 foam, 6 both

  struct State;

 private:
  std::unique_ptr<State> state_;
};

}  // namespace displace::render
