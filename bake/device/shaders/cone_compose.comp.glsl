#version 450
#extension GL_GOOGLE_include_directive : require
// bake/device/shaders/cone_compose.comp.glsl - lagged device cone maps (bake/device/device_cones.cpp): the
// served map as this frame samples it, every apex raised by the lift (CONE_COUNTER_LIFT, this frame's
// cone_lift.comp.glsl) and the ratios as they are. The apex is stored as q / 65535, rounded up; the
// lift is added in units rounded up, plus one for the float rounding of the lift itself (a difference
// of two values in [0, 1], within 6e-8 of the exact one), and the sum is clamped at 65535 (1: no
// height is higher). Same layout in and out: layer l, texel t at l * W * H + t.
#include "cones.h"

layout(local_size_x = CONE_TILE, local_size_y = CONE_TILE, local_size_z = 1) in;

layout(std430, binding = 0) readonly buffer Served { uint served[]; };
layout(std430, binding = 1) readonly buffer Counters { uint counters[]; };
layout(std430, binding = 2) writeonly buffer Composed { uint composed[]; };

layout(push_constant) uniform Push { ConeComposePush push; };

void main() {
  const int j = int(gl_GlobalInvocationID.x), i = int(gl_GlobalInvocationID.y);
  if (j >= push.width || i >= push.height) return;
  const float lift = uintBitsToFloat(counters[CONE_COUNTER_LIFT]);
  const uint units = lift > 0.0 ? uint(min(ceil(lift * 65535.0) + 1.0, 65535.0)) : 0u;
  const int texels = push.width * push.height, texel = i * push.width + j;
  for (int layer = 0; layer < push.layers; ++layer) {
    const uint value = served[layer * texels + texel];
    composed[layer * texels + texel] = (value & 0xffffu) | (min((value >> 16) + units, 65535u) << 16);
  }
}
