// render/shaders/relief.vert.glsl - the base polygon of the per-pixel methods: the plane's two
// triangles, generated from the vertex index, with the tangent frame the fragment shader traces in;
// for the unbounded plane (FLAG_UNBOUNDED) two triangles over the whole screen.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "config.h"

#include "frame_block.inc.glsl"

#include "surface_varyings.inc.glsl"

const vec2 corners[6] = vec2[](vec2(0, 0), vec2(1, 0), vec2(1, 1), vec2(0, 0), vec2(1, 1), vec2(0, 1));

void main() {
  vec2 corner = corners[gl_VertexIndex];
  if ((frame.counts.z & FLAG_UNBOUNDED) != 0) {
    // the whole screen: each fragment finds where its own ray meets the plane, or the sky
    out_world = vec3(0.0);
    out_uv = vec2(0.0);
    out_tangent_u = vec3(frame.surface.z, 0.0, 0.0);
    out_tangent_v = vec3(0.0, frame.surface.z, 0.0);
    out_normal = vec3(0.0, 0.0, 1.0);
    out_h = 1.0;
    out_curvature = vec2(0.0);
    gl_Position = vec4(corner * 2.0 - 1.0, 0.5, 1.0);
    return;
  }
  vec3 world = vec3(corner, 0.0);
  out_world = world;
  out_uv = corner * frame.surface.x;
  out_tangent_u = vec3(frame.surface.z, 0.0, 0.0);
  out_tangent_v = vec3(0.0, frame.surface.z, 0.0);
  out_normal = vec3(0.0, 0.0, 1.0);
  out_h = 1.0;
  out_curvature = vec2(0.0);
  gl_Position = frame.view_projection * vec4(world, 1.0);
}
