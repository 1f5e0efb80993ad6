// render/shaders/reference.vert.glsl - true displacement: the height field tessellated at one vertex
// per texel centre (plus the patch border), each vertex moved to its sampled height.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "config.h"

#include "frame_block.inc.glsl"
layout(binding = BINDING_HEIGHT) uniform sampler2D height_map;
#include "height_fetch.inc.glsl"

layout(location = 0) in vec2 in_uv;  // texture coordinates in [0, tile]

#include "surface_varyings.inc.glsl"

void main() {
  float h = bilinear_height_of(height_map, in_uv);
  vec3 world = vec3(in_uv * frame.surface.z, (h - 1.0) * frame.surface.y);
  out_world = world;
  out_uv = in_uv;
  out_tangent_u = vec3(frame.surface.z, 0.0, 0.0);
  out_tangent_v = vec3(0.0, frame.surface.z, 0.0);
  out_normal = vec3(0.0, 0.0, 1.0);
  out_h = h;
  out_curvature = vec2(0.0);
  gl_Position = frame.view_projection * vec4(world, 1.0);
}
