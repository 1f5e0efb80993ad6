// render/shaders/quadric_proxy.vert.glsl - the proxy the per-pixel methods rasterize on a quadric: the
// box that holds the whole relief (quadric.inc.glsl, quadric_box), its back faces only (the pipeline
// culls front faces), so that every pixel that can see the relief gets exactly one fragment, with the
// eye outside the box or inside it. The fragment shader intersects the pixel's ray with the
// bounding surfaces itself; only out_world (a point on the ray) matters.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "config.h"

layout(constant_id = 1) const int SURFACE = SURFACE_SPHERE;

#include "frame_block.inc.glsl"

#include "quadric.inc.glsl"

#include "surface_varyings.inc.glsl"

// corner c of the box is (c & 1, (c >> 1) & 1, (c >> 2) & 1) between lo and hi; two triangles per
// face, counter-clockwise seen from outside
const int box_corners[36] = int[](4, 6, 2, 4, 2, 0, 1, 3, 7, 1, 7, 5, 0, 1, 5, 0, 5, 4,
                                  6, 7, 3, 6, 3, 2, 2, 3, 1, 2, 1, 0, 4, 5, 7, 4, 7, 6);

void main() {
  vec3 lo, hi;
  quadric_box(lo, hi);
  int corner = box_corners[gl_VertexIndex];
  vec3 world = mix(lo, hi, vec3(float(corner & 1), float((corner >> 1) & 1), float((corner >> 2) & 1)));
  out_world = world;
  out_uv = vec2(0.0);
  out_tangent_u = vec3(0.0);
  out_tangent_v = vec3(0.0);
  out_normal = vec3(0.0);
  out_h = 1.0;
  out_curvature = vec2(0.0);
  gl_Position = frame.view_projection * vec4(world, 1.0);
}
