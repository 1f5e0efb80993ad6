// render/shaders/quadric_reference.vert.glsl - true displacement on a quadric: the height field
// tessellated at one vertex per texel centre plus the seam (u = 0 and u = K) and the ends (v = 0 and
// v = K), each vertex displaced along the normal to radius R - (1 - h) D (quadric.inc.glsl,
// quadric_frame). The seam column u = K takes its height and position from u = 0, and on the sphere
// every vertex of a pole row takes the height at u = 0, so the mesh closes around the axis and over
// the poles with shared vertices: no cracks for the rasterizer's watertight edge rule to miss.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "config.h"

layout(constant_id = 1) const int SURFACE = SURFACE_SPHERE;

#include "frame_block.inc.glsl"
layout(binding = BINDING_HEIGHT) uniform sampler2D height_map;
#include "height_fetch.inc.glsl"

#include "quadric.inc.glsl"

layout(location = 0) in vec2 in_uv;  // texture coordinates in [0, tile]

#include "surface_varyings.inc.glsl"

void main() {
  float tile = frame.surface.x;
  vec2 placed = vec2(in_uv.x >= tile ? 0.0 : in_uv.x, in_uv.y);
  if (SURFACE == SURFACE_SPHERE && (in_uv.y <= 0.0 || in_uv.y >= tile)) placed.x = 0.0;
  float h = bilinear_height_of(height_map, placed);
  QuadricFrame f = quadric_frame(placed, h);
  out_world = f.position;
  out_uv = in_uv;
  out_tangent_u = f.along_u;
  out_tangent_v = f.along_v;
  out_normal = f.normal;
  out_h = h;
  out_curvature = vec2(0.0);
  gl_Position = frame.view_projection * vec4(f.position, 1.0);
}
