#version 450
#extension GL_GOOGLE_include_directive : require
// bake/device/shaders/level_down.comp.glsl - one level of detail from the one below (bake/device/device_levels.cpp;
// bake/detail_levels.cpp's downsample_heights, gradient_moments and downsample_moments, ported in their
// order of operations): texel (i, j) of level l is the 2 x 2 box mean of texels (2i + b, 2j + a) of level
// l - 1, ((row 2i's pair) + (row 2i + 1's pair)) / 4, and so are its three slope moments (g_u, g_v,
// |g|^2) of level l - 1's; level 1 makes level 0's moments from its heights by central differences,
// wrapped, in height units per uv. `precise` keeps each product and sum rounded alone, as the CPU's
// (built without fused multiply-adds). Writes level l's heights (what its cone bake reads) and its
// texels of the heights atlas (height, g_u, g_v, |g|^2), which the renderer samples.
#include "cones.h"

layout(local_size_x = CONE_TILE, local_size_y = CONE_TILE, local_size_z = 1) in;

layout(binding = 0, r32f) uniform readonly image2D fine;     // level l - 1's heights
layout(binding = 1, rgba32f) uniform image2D atlas;          // levels 1 .. L: height and moments
layout(binding = 2, r32f) uniform writeonly image2D coarse;  // level l's heights

layout(push_constant) uniform Push { LevelDownPush push; };

float fine_height(int x, int y) {  // wrapped (x, y within one period of the map)
  const int w = push.fine_width, h = push.fine_height;
  return imageLoad(fine, ivec2((x + w) % w, (y + h) % h)).r;
}

// level 0's moments at its texel (x, y): bake::gradient_moments
vec3 level0_moments(int x, int y) {
  precise const float gu = (fine_height(x + 1, y) - fine_height(x - 1, y)) * (0.5 * float(push.fine_width));
  precise const float gv = (fine_height(x, y + 1) - fine_height(x, y - 1)) * (0.5 * float(push.fine_height));
  precise const float squared = gu * gu + gv * gv;
  return vec3(gu, gv, squared);
}

vec3 fine_moments(int x, int y) {
  if (push.from_level0 != 0) return level0_moments(x, y);
  return imageLoad(atlas, ivec2(push.fine_origin_x + x, push.fine_origin_y + y)).yzw;
}

void main() {
  const int j = int(gl_GlobalInvocationID.x), i = int(gl_GlobalInvocationID.y);
  if (j >= push.fine_width / 2 || i >= push.fine_height / 2) return;
  const int x = 2 * j, y = 2 * i;
  precise const float height = ((imageLoad(fine, ivec2(x, y)).r + imageLoad(fine, ivec2(x + 1, y)).r) +
                                (imageLoad(fine, ivec2(x, y + 1)).r + imageLoad(fine, ivec2(x + 1, y + 1)).r)) *
                               0.25;
  precise const vec3 moments =
      ((fine_moments(x, y) + fine_moments(x + 1, y)) + (fine_moments(x, y + 1) + fine_moments(x + 1, y + 1))) * 0.25;
  imageStore(coarse, ivec2(j, i), vec4(height));
  imageStore(atlas, ivec2(push.origin_x + j, push.origin_y + i), vec4(height, moments));
}
