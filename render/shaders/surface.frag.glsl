// render/shaders/surface.frag.glsl - one fragment shader for every method: trace the view ray
// through the relief (methods.inc.glsl), shade the hit (shading.inc.glsl), and write the colour,
// the hit AOV (u, v, hit, depth) and the counters (iterations, fetches).
#version 450
#extension GL_GOOGLE_include_directive : require
#include "config.h"

layout(constant_id = 0) const int METHOD = METHOD_RELIEF;
layout(constant_id = 1) const int SURFACE = SURFACE_PLANE;

layout(std140, binding = BINDING_FRAME) uniform FrameBlock { FrameUniforms frame; };
layout(binding = BINDING_HEIGHT) uniform sampler2D height_map;
layout(binding = BINDING_CONES) uniform sampler2DArray cone_map;

layout(location = 0) in vec3 in_world;
layout(location = 1) in vec2 in_uv;
layout(location = 2) in vec3 in_tangent_u;
layout(location = 3) in vec3 in_tangent_v;
layout(location = 4) in vec3 in_normal;
layout(location = 5) in float in_h;

layout(location = ATTACHMENT_COLOR) out vec4 out_color;
layout(location = ATTACHMENT_HIT) out vec4 out_hit;
layout(location = ATTACHMENT_COUNTERS) out vec4 out_counters;

uint g_iterations = 0u;
uint g_fetches = 0u;

#include "methods.inc.glsl"
#include "shading.inc.glsl"
#include "quadric.inc.glsl"
#include "quadric_trace.inc.glsl"

// The reference's triangles interpolate the texel heights linearly over two triangles per texel
// square, while every method samples the bilinear surface: they differ inside a square by up to a
// quarter of |h00 - h01 - h10 + h11|, and at a sharp edge a ray may pass one and hit the other
// (measured: 258 of 8706 pixels more than half a texel off on the brick relief). Rasterizing the
// tessellation decides which pixels see the relief; the hit is then the first crossing of the view
// ray with the bilinear surface, marched from the entry point in eighth-texel steps and bisected,
// so that comparisons measure the methods' errors and not the triangulation's.
const float snap_steps_per_texel = 8.0;  // march steps per texel of horizontal travel (as the CPU trace)
const int snap_max_steps = 4096;  // the march covers the whole ray in at most this many steps
const int snap_bisections = 24;

float snap_gap(vec3 origin, vec3 descent, float s) {
  vec3 q = origin + s * descent;
  return q.z - shading_height(q.xy);
}

vec3 snap_to_bilinear(vec3 origin, vec3 direction) {
  float dz = min(direction.z, -min_descent);
  vec3 descent = vec3(direction.xy / -dz, -1.0);
  float travel_texels = max(length(descent.xy * frame.map_size.xy), 1e-6);
  float step = max(1.0 / (travel_texels * snap_steps_per_texel), 1.0 / float(snap_max_steps));
  float lo = 0.0, below = 1.0;
  if (snap_gap(origin, descent, 0.0) <= 0.0) return origin;
  for (int i = 1; i <= snap_max_steps; ++i) {
    float s = min(float(i) * step, 1.0);
    if (snap_gap(origin, descent, s) <= 0.0) {
      below = s;
      break;
    }
    lo = s;
  }
  for (int i = 0; i < snap_bisections; ++i) {
    float mid = 0.5 * (lo + below);
    if (snap_gap(origin, descent, mid) > 0.0) lo = mid; else below = mid;
  }
  return origin + below * descent;
}

void main() {
  if (SURFACE != SURFACE_PLANE) {
    quadric_fragment();
    return;
  }
  vec3 to_point = in_world - frame.eye.xyz;
  vec3 d = normalize(to_point);
  vec3 normal = normalize(in_normal);
  mat3 tangent_frame = mat3(in_tangent_u, in_tangent_v, normal * frame.surface.y);
  vec3 hit = vec3(in_uv, in_h);
  if (METHOD == METHOD_REFERENCE) {
    // Only what is seen through the base polygon, as for the per-pixel methods: a ray that enters
    // the relief box through one of its sides has no fragment on the polygon.
    float t_entry = -frame.eye.z / d.z;
    vec2 entry = frame.eye.xy + t_entry * d.xy;
    if (frame.eye.z <= 0.0 || d.z >= 0.0 || any(lessThan(entry, vec2(0.0))) || any(greaterThan(entry, vec2(1.0)))) {
      discard;
    }
    hit = snap_to_bilinear(vec3(entry * frame.surface.x, 1.0), inverse(tangent_frame) * d);
  } else {
    if (dot(d, normal) >= 0.0) discard;  // the relief is seen from above only
    vec3 origin = vec3(in_uv, 1.0);
    Trace traced = trace(origin, inverse(tangent_frame) * d, -dot(d, normal));
    hit = traced.p;
    // the ray left the relief volume through a side of the patch
    if (any(lessThan(hit.xy, vec2(0.0))) || any(greaterThan(hit.xy, vec2(frame.surface.x)))) discard;
  }
  vec3 world_hit = in_world + tangent_frame * (hit - vec3(in_uv, in_h));
  vec4 clip = frame.view_projection * vec4(world_hit, 1.0);
  gl_FragDepth = clamp(clip.z / clip.w, 0.0, 1.0);
  out_color = vec4(shade(hit.xy, tangent_frame, d), 1.0);
  out_hit = vec4(hit.xy, 1.0, length(world_hit - frame.eye.xyz));
  out_counters = vec4(float(g_iterations), float(g_fetches), 0.0, 0.0);
}
