#version 450
#extension GL_GOOGLE_include_directive : require
// bake/device/shaders/cone_reduce.comp.glsl - one level of the device cone maps' max pyramid over cells
// (bake/device/device_cones.cpp): node (a, b) of level L + 1 holds the largest of its existing children
// (2a + da, 2b + db) of level L, so that it bounds the bilinear surface over every cell it covers
// (bake.h's MaxPyramid: footprints truncated at the grid's end, never padded).
#include "cones.h"

layout(local_size_x = CONE_TILE, local_size_y = CONE_TILE, local_size_z = 1) in;

layout(std430, binding = 0) buffer Pyramid { float node_max[]; };

layout(push_constant) uniform Push { ConeReducePush push; };

void main() {
  const int a = int(gl_GlobalInvocationID.x), b = int(gl_GlobalInvocationID.y);
  if (a >= push.target_width || b >= push.target_height) return;
  float top = 0.0;
  for (int db = 0; db < 2 && 2 * b + db < push.source_height; ++db)
    for (int da = 0; da < 2 && 2 * a + da < push.source_width; ++da)
      top = max(top, node_max[push.source_offset + (2 * b + db) * push.source_width + 2 * a + da]);
  node_max[push.target_offset + b * push.target_width + a] = top;
}
