#version 450
#extension GL_GOOGLE_include_directive : require
// sim/device/shaders/sinusoids.comp.glsl - sinusoid water on the device (sim/device/device_sim.cpp): per texel
// h = sum_i a_i sin(k_i . x + phi_i - w_i t), written as metres and as heights in [0, 1].
//
// Precision: k_i . x in turns from integers where the wave lies on the patch's lattice (k = 2 pi (m, n)
// / L: the turns are m (2 j + 1) / (2 W) + n (2 i + 1) / (2 H), exact modulo 1), else in float; the
// time part phi_i - w_i t as in ocean_spectrum.comp.glsl (an anchor reduced on the host, plus w (t -
// t_anchor) in split floats: phase.inc.glsl), so t = 1e9 s is as precise as t = 0.
#include "ocean.h"
#include "phase.inc.glsl"

layout(local_size_x = OCEAN_TILE, local_size_y = OCEAN_TILE, local_size_z = 1) in;

// per wave: (kx, ky) rad/m, amplitude m, lattice flag (1: m, n below are exact), then (m, n) as floats
layout(std430, binding = 0) readonly buffer Waves { vec4 waves[]; };   // (kx, ky, amplitude, lattice)
layout(std430, binding = 1) readonly buffer Lattice { vec2 lattice[]; };  // (m, n)
layout(std430, binding = 2) readonly buffer Omega { vec2 omega_split[]; };  // w high, w low
layout(std430, binding = 3) readonly buffer Anchor { vec2 anchor[]; };      // cos, sin of phi - w t_anchor
layout(std430, binding = 4) writeonly buffer Metres { float metres[]; };
layout(binding = 5, r32f) uniform writeonly image2D heights;

layout(push_constant) uniform Push { SinusoidPush push; };

void main() {
  const ivec2 texel = ivec2(gl_GlobalInvocationID.xy);
  if (texel.x >= push.size || texel.y >= push.size) return;
  float height_metres = 0.0;
  for (int i = 0; i < push.wave_count; ++i) {
    const vec4 wave = waves[i];
    // k . x at the texel centre, reduced to turns in [0, 1)
    float turns;
    if (wave.w != 0.0) {
      const int twice = 2 * push.size;
      const ivec2 m = ivec2(lattice[i]);
      // m, n come in [0, 2 W) (device_sim.cpp): no operand of % is negative (undefined in GLSL)
      const int along_x = (m.x * (2 * texel.x + 1)) % twice, along_y = (m.y * (2 * texel.y + 1)) % twice;
      turns = float((along_x + along_y) % twice) / float(twice);
    } else {
      const vec2 position = (vec2(texel) + 0.5) * (push.patch_size / float(push.size));
      turns = fract(dot(wave.xy, position) * 0.15915494309189535);
    }
    const float space = turns * 6.283185307179586;
    // phi - w t = anchor - w (t - t_anchor)
    const float reduced = phase_since_anchor(omega_split[i], push.time_high, push.time_low);
    const vec2 start = anchor[i];
    const float c = start.x * cos(reduced) + start.y * sin(reduced);  // cos(anchor - reduced)
    const float s = start.y * cos(reduced) - start.x * sin(reduced);  // sin(anchor - reduced)
    height_metres += wave.z * (sin(space) * c + cos(space) * s);
  }
  metres[texel.y * push.size + texel.x] = height_metres;
  imageStore(heights, texel, vec4(clamp(height_metres * push.scale + push.bias, 0.0, 1.0)));
}
