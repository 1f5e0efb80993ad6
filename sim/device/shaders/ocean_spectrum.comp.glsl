#version 450
#extension GL_GOOGLE_include_directive : require
// sim/device/shaders/ocean_spectrum.comp.glsl - the device ocean's spectra at time t (sim/device/device_sim.cpp):
// per mode of the half spectrum h~ = (p c + q s) + i (r c + u s), (c, s) = (cos, sin) of w t, then the
// derived spectra the effects need, one batch of the inverse FFT each (sim/fft_ocean.cpp's Grid order):
// the choppy displacement i lambda k / |k| h~ and the Jacobian terms -lambda k k^T / |k| h~.
//
// The phase w t: w t_anchor reduced modulo 2 pi on the host in double (anchor, as its cos and sin),
// plus w (t - t_anchor) here, |w (t - t_anchor)| < 1e5 rad: w and t - t_anchor split into a high part
// of 12 significant bits (whose product is exact in float) and the rest, then reduced by 2 pi in three
// Cody-Waite steps; so frames at t = 1e9 s are as precise as at t = 0.
#include "ocean.h"
#include "phase.inc.glsl"

layout(local_size_x = OCEAN_LOCAL_SIZE, local_size_y = 1, local_size_z = 1) in;

layout(std430, binding = 0) readonly buffer Coefficients { vec4 coefficients[]; };  // (p, q, r, u)
layout(std430, binding = 1) readonly buffer Omega { vec2 omega_split[]; };        // w high, w low
layout(std430, binding = 2) readonly buffer Anchor { vec2 anchor[]; };             // cos, sin of w t_anchor
layout(std430, binding = 3) writeonly buffer Spectra { vec2 spectra[]; };          // batches, N x (N/2 + 1)

layout(push_constant) uniform Push { OceanSpectrumPush push; };

void main() {
  const uint half_width = uint(push.size / 2 + 1);
  const uint modes = uint(push.size) * half_width;
  const uint mode = gl_GlobalInvocationID.x;
  if (mode >= modes) return;
  const int i = int(mode / half_width), j = int(mode % half_width);

  // w (t - t_anchor), reduced to [-pi, pi]
  const float reduced = phase_since_anchor(omega_split[mode], push.time_high, push.time_low);
  const vec2 step_rotation = vec2(cos(reduced), sin(reduced));
  const vec2 start = anchor[mode];
  const float c = start.x * step_rotation.x - start.y * step_rotation.y;
  const float s = start.y * step_rotation.x + start.x * step_rotation.y;

  const vec4 k = coefficients[mode];
  const vec2 h = vec2(k.x * c + k.y * s, k.z * c + k.w * s);
  spectra[mode] = h;
  if (push.batches == 1) return;

  // derived spectra
  const float kx = float(j) * push.wave_step;
  const float ky = float(i < push.size / 2 ? i : i - push.size) * push.wave_step;
  const float length_k = sqrt(kx * kx + ky * ky);
  const float inverse_k = length_k > 0.0 ? 1.0 / length_k : 0.0;
  const float lambda = push.choppiness;
  const vec2 times_i = vec2(-h.y, h.x);
  uint batch = 1u;
  if (push.choppy != 0) {
    spectra[batch++ * modes + mode] = lambda * kx * inverse_k * times_i;
    spectra[batch++ * modes + mode] = lambda * ky * inverse_k * times_i;
  }
  if (push.foam != 0) {
    spectra[batch++ * modes + mode] = -lambda * kx * kx * inverse_k * h;
    spectra[batch++ * modes + mode] = -lambda * ky * ky * inverse_k * h;
    spectra[batch++ * modes + mode] = -lambda * kx * ky * inverse_k * h;
  }
}
