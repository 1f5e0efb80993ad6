#version 450
#extension GL_GOOGLE_include_directive : require
// sim/device/shaders/ocean_assemble.comp.glsl - the device ocean's inverse FFTs to the maps the renderer
// samples (sim/device/device_sim.cpp): per texel its height in metres and in [0, 1], and its foam.
//
// Choppy water (sim/choppy.cpp's contract, per texel here): the height above grid position x is h(p)
// for the p with p + D(p) = x, found by Newton's method on F(p) = p + D(p) - x with D bilinear and
// periodic, J = I + grad D from the same four texels, the fixed-point step p <- x - D(p) where det J is
// below 0.2 (a folding crest). Each texel starts from x - D(x) and stops once |F| is within `settle`, or after `iterations` steps.
#include "ocean.h"

layout(local_size_x = OCEAN_TILE, local_size_y = OCEAN_TILE, local_size_z = 1) in;

// the inverse FFTs in place: batch b's row i at b * N * (N + 2) + i * (N + 2) (padded real rows)
layout(std430, binding = 0) readonly buffer Fields { float fields[]; };
layout(std430, binding = 1) writeonly buffer Metres { float metres[]; };  // N x N
layout(binding = 2, r32f) uniform writeonly image2D heights;              // [0, 1]
layout(binding = 3, r32f) uniform writeonly image2D foam;                 // coverage in [0, 1]

layout(push_constant) uniform Push { OceanAssemblePush push; };

float field(int batch, ivec2 texel) {
  const int row = push.size + 2;
  return fields[batch * push.size * row + texel.y * row + texel.x];
}

// The four texels around p = base + offset (texels, centres at integers; the offset small, so that it
// keeps its precision far from the origin), wrapped, and p's place between them.
struct Tap {
  ivec2 t00, t11;
  vec2 f;
};
Tap tap_at(ivec2 base, vec2 offset) {
  offset = clamp(offset, vec2(-1e6), vec2(1e6));  // no real ocean moves a texel that far (NaN: -1e6)
  const vec2 floor_offset = floor(offset);
  Tap tap;
  // wrapped without % of a negative operand (undefined in GLSL): |p| < 2^24, so the float quotient's
  // floor is exact, and the last two lines only guard it
  const ivec2 p = base + ivec2(floor_offset);
  tap.t00 = p - push.size * ivec2(floor(vec2(p) / float(push.size)));
  tap.t00 += ivec2(lessThan(tap.t00, ivec2(0))) * push.size;
  tap.t00 -= ivec2(greaterThanEqual(tap.t00, ivec2(push.size))) * push.size;
  tap.t11 = (tap.t00 + 1) % push.size;
  tap.f = offset - floor_offset;
  return tap;
}
float sample_field(int batch, Tap tap) {
  const float a = field(batch, tap.t00), b = field(batch, ivec2(tap.t11.x, tap.t00.y));
  const float c = field(batch, ivec2(tap.t00.x, tap.t11.y)), d = field(batch, tap.t11);
  const float top = a + (b - a) * tap.f.x;
  const float bottom = c + (d - c) * tap.f.x;
  return top + (bottom - top) * tap.f.y;
}
// the sample and its derivatives along x and y (per texel)
vec3 sample_with_slopes(int batch, Tap tap) {
  const float a = field(batch, tap.t00), b = field(batch, ivec2(tap.t11.x, tap.t00.y));
  const float c = field(batch, ivec2(tap.t00.x, tap.t11.y)), d = field(batch, tap.t11);
  const float top = a + (b - a) * tap.f.x;
  const float bottom = c + (d - c) * tap.f.x;
  return vec3(top + (bottom - top) * tap.f.y, (b - a) + ((d - c) - (b - a)) * tap.f.y, bottom - top);
}
float jacobian_at(Tap tap, int first) {
  const float xx = sample_field(first, tap), yy = sample_field(first + 1, tap), xy = sample_field(first + 2, tap);
  return (1.0 + xx) * (1.0 + yy) - xy * xy;
}

void main() {
  const ivec2 texel = ivec2(gl_GlobalInvocationID.xy);
  if (texel.x >= push.size || texel.y >= push.size) return;
  const int foam_batch = push.choppy != 0 ? 3 : 1;
  float height_metres;
  float jacobian = 1.0;
  if (push.choppy == 0) {
    height_metres = field(0, texel);
    if (push.foam != 0) {
      const float xx = field(foam_batch, texel), yy = field(foam_batch + 1, texel);
      const float xy = field(foam_batch + 2, texel);
      jacobian = (1.0 + xx) * (1.0 + yy) - xy * xy;
    }
  } else {
    // p = texel + offset
    const float scale = push.texels_per_metre;
    vec2 offset = -vec2(field(1, texel), field(2, texel)) * scale;
    for (int step = 0; step < push.iterations; ++step) {
      const Tap tap = tap_at(texel, offset);
      const vec3 sx = sample_with_slopes(1, tap), sy = sample_with_slopes(2, tap);
      const vec2 residual = offset + vec2(sx.x, sy.x) * scale;
      if (dot(residual, residual) <= push.settle * push.settle) break;
      const float a = 1.0 + sx.y * scale, c = sx.z * scale;
      const float e = sy.y * scale, d = 1.0 + sy.z * scale;
      const float det = a * d - c * e;
      offset -= det >= 0.2 ? vec2(d * residual.x - c * residual.y, a * residual.y - e * residual.x) / det : residual;
    }
    const Tap tap = tap_at(texel, offset);
    height_metres = sample_field(0, tap);
    if (push.foam != 0) jacobian = jacobian_at(tap, foam_batch);
  }
  metres[texel.y * push.size + texel.x] = height_metres;
  imageStore(heights, texel, vec4(clamp(height_metres * push.scale + push.bias, 0.0, 1.0)));
  if (push.foam != 0) {
    const float coverage = clamp((push.foam_start - jacobian) / (push.foam_start - push.foam_full), 0.0, 1.0);
    imageStore(foam, texel, vec4(coverage));
  }
}
