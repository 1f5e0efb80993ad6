#version 450
#extension GL_GOOGLE_include_directive : require
// bake/device/shaders/cone_cells.comp.glsl - the device cone maps' first step (bake/device/device_cones.cpp): per
// cell of the bilinear surface (the square between four texel centres) its maximum, the base of the
// max pyramid (a bilinear patch peaks at a corner, so the maximum of its four corners is exact), and
// the largest gradient any cell allows, sqrt((W du)^2 + (H dv)^2) with du, dv the cell's largest
// corner differences along u and v: the surface's Lipschitz constant in uv, reduced per group and
// then by an atomic max of its bits (non-negative floats order as their bits). A height that is not a
// finite value in [0, 1] raises CONE_COUNTER_BAD.
#include "cones.h"
#include "cone_axis.inc.glsl"
#include "group_max.inc.glsl"

layout(local_size_x = CONE_TILE, local_size_y = CONE_TILE, local_size_z = 1) in;

layout(binding = 0, r32f) uniform readonly image2D heights;
layout(std430, binding = 1) writeonly buffer Pyramid { float node_max[]; };
layout(std430, binding = 2) buffer Counters { uint counters[]; };

layout(push_constant) uniform Push { ConeCellsPush push; };

shared uint group_bad;

float height_at(int a, int b) {
  const bool wrap = push.wrap != 0;
  return imageLoad(heights, ivec2(axis_texel(a, push.width, wrap), axis_texel(b, push.height, wrap))).r;
}

void main() {
  const uint local = gl_LocalInvocationIndex;
  if (local == 0) group_bad = 0;
  barrier();
  const int nu = int(gl_GlobalInvocationID.x), nv = int(gl_GlobalInvocationID.y);
  float lipschitz = 0.0;
  if (nu < push.cells_u && nv < push.cells_v) {
    const bool wrap = push.wrap != 0;
    const int a = cell_left_centre(nu, wrap), b = cell_left_centre(nv, wrap);
    const float h0 = height_at(a, b), h1 = height_at(a + 1, b), h2 = height_at(a, b + 1),
                h3 = height_at(a + 1, b + 1);
    // NaN fails every comparison
    if (!(h0 >= 0.0 && h0 <= 1.0 && h1 >= 0.0 && h1 <= 1.0 && h2 >= 0.0 && h2 <= 1.0 && h3 >= 0.0 && h3 <= 1.0))
      atomicOr(group_bad, 1u);
    node_max[nv * push.cells_u + nu] = max(max(h0, h1), max(h2, h3));
    const float du = max(abs(h1 - h0), abs(h3 - h2)) * float(push.width);
    const float dv = max(abs(h2 - h0), abs(h3 - h1)) * float(push.height);
    lipschitz = sqrt(du * du + dv * dv);
  }
  // the group's largest
  const float largest = group_max(lipschitz);
  if (local == 0) {
    atomicMax(counters[CONE_COUNTER_LIPSCHITZ], floatBitsToUint(largest));
    if (group_bad != 0) atomicOr(counters[CONE_COUNTER_BAD], 1u);
  }
}
