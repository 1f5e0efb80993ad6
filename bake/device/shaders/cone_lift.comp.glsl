#version 450
#extension GL_GOOGLE_include_directive : require
// bake/device/shaders/cone_lift.comp.glsl - lagged device cone maps (bake/device/device_cones.cpp): the most
// any texel rose since the heights the served map was made from, max(0, now - then), reduced per
// group and then by an atomic max of its bits into CONE_COUNTER_LIFT (non-negative floats order as
// their bits). The bilinear surface interpolates its texels' changes, so it rose by at most that much
// anywhere (docs/design/lagged-cone-maps.md). A height now that is not a finite value in [0, 1]
// raises CONE_COUNTER_BAD.
#include "cones.h"
#include "group_max.inc.glsl"

layout(local_size_x = CONE_TILE, local_size_y = CONE_TILE, local_size_z = 1) in;

layout(binding = 0, r32f) uniform readonly image2D heights;       // this frame's
layout(binding = 1, r32f) uniform readonly image2D then_heights;  // the served map's
layout(std430, binding = 2) buffer Counters { uint counters[]; };

layout(push_constant) uniform Push { ConeLiftPush push; };

shared uint group_bad;

void main() {
  const uint local = gl_LocalInvocationIndex;
  if (local == 0) group_bad = 0;
  barrier();
  const ivec2 texel = ivec2(gl_GlobalInvocationID.xy);
  float rise = 0.0;
  if (texel.x < push.width && texel.y < push.height) {
    const float now = imageLoad(heights, texel).r;
    if (!(now >= 0.0 && now <= 1.0)) atomicOr(group_bad, 1u);  // NaN fails every comparison
    rise = max(now - imageLoad(then_heights, texel).r, 0.0);
    if (!(rise <= 1.0)) rise = 1.0;  // a NaN now: flagged above, and at most 1 is all a lift can be
  }
  const float largest = group_max(rise);
  if (local == 0) {
    atomicMax(counters[CONE_COUNTER_LIFT], floatBitsToUint(largest));
    if (group_bad != 0) atomicOr(counters[CONE_COUNTER_BAD], 1u);
  }
}
