// render/shaders/mesh.vert.glsl - a triangle mesh as the base surface (render/mesh.h): per vertex the
// position, texture coordinates, tangent frame (dP/du, dP/dv, normal) and curvature. The per-pixel
// methods rasterize the mesh itself (the top of the relief, height 1); the reference rasterizes its
// tessellation (render/renderer.cpp) with every vertex moved (1 - h) D inwards along the normal.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "config.h"

layout(constant_id = 0) const int METHOD = METHOD_RELIEF;

#include "frame_block.inc.glsl"
layout(binding = BINDING_HEIGHT) uniform sampler2D height_map;
#include "height_fetch.inc.glsl"

layout(location = 0) in vec4 in_position_u;   // xyz: position, w: u
layout(location = 1) in vec4 in_dp_du_v;      // xyz: dP/du, w: v
layout(location = 2) in vec4 in_dp_dv_kuu;    // xyz: dP/dv, w: curvature along u
layout(location = 3) in vec4 in_normal_kvv;   // xyz: unit normal, w: curvature along v

#include "surface_varyings.inc.glsl"

void main() {
  // texture coordinates run over [0, K] with --tile K: dP/du' = dP/du / K
  vec2 uv = vec2(in_position_u.w, in_dp_du_v.w) * frame.surface.x;
  vec3 normal = normalize(in_normal_kvv.xyz);
  vec3 world = in_position_u.xyz;
  float h = 1.0;
  if (METHOD == METHOD_REFERENCE) {
    h = bilinear_height_of(height_map, uv);
    world -= (1.0 - h) * frame.surface.y * normal;
  }
  out_world = world;
  out_uv = uv;
  out_tangent_u = in_dp_du_v.xyz * frame.surface.z;
  out_tangent_v = in_dp_dv_kuu.xyz * frame.surface.z;
  out_normal = normal;
  out_h = h;
  out_curvature = vec2(in_dp_dv_kuu.w, in_normal_kvv.w);
  gl_Position = frame.view_projection * vec4(world, 1.0);
}
