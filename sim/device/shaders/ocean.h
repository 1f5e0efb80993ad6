// sim/device/shaders/ocean.h - the device sim's push constants (ocean_spectrum.comp.glsl,
// ocean_assemble.comp.glsl, sinusoids.comp.glsl), shared by GLSL and C++ (sim/device/device_sim.cpp, with
// static_asserts).
#ifndef DISPLACE_SIM_OCEAN_H
#define DISPLACE_SIM_OCEAN_H

#ifdef __cplusplus
#include <cstdint>
namespace displace::sim::gpu {
#endif

#define OCEAN_LOCAL_SIZE 64  // invocations per group of the spectrum kernel
#define OCEAN_TILE 8         // the assembly kernel's groups: 8 x 8 texels

struct OceanSpectrumPush {
  int size;          // N
  int batches;       // spectra written: 1 (heights), + 2 (choppy), + 3 (foam)
  int choppy;        // 1: the displacement spectra
  int foam;          // 1: the Jacobian spectra
  float time_high;   // t - t_anchor, seconds: 12 significant bits
  float time_low;    // and the rest
  float wave_step;   // 2 pi / L, rad/m
  float choppiness;  // lambda
};

struct OceanAssemblePush {
  int size;        // N
  int choppy;      // 1: resample the displaced surface onto the grid
  int foam;        // 1: foam coverage from the Jacobian
  int iterations;  // Newton steps at most
  float texels_per_metre;
  float settle;       // texels: a texel stops once its residual is within this
  float scale, bias;  // heights in [0, 1] = clamp(metres * scale + bias, 0, 1)
  float foam_start;   // foam none at J >= foam_start, full at J <= foam_full
  float foam_full;
  int pad0, pad1;
};

struct SinusoidPush {
  int size;  // texels a side
  int wave_count;
  float patch_size;   // metres
  float time_high;    // t - t_anchor, seconds: 12 significant bits
  float time_low;     // and the rest
  float scale, bias;  // heights in [0, 1] = clamp(metres * scale + bias, 0, 1)
  int pad0;
};

#ifdef __cplusplus
}  // namespace displace::sim::gpu
#endif
#endif
