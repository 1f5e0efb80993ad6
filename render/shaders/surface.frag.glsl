// render/shaders/surface.frag.glsl - one fragment shader for every method: trace the view ray
// through the relief (methods.inc.glsl), shade the hit (shading.inc.glsl), and write the colour,
// the hit AOV (u, v, hit, depth) and the counters (iterations, fetches).
#version 450
#extension GL_GOOGLE_include_directive : require
#include "config.h"

layout(constant_id = 0) const int METHOD = METHOD_RELIEF;

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

// The reference's triangles interpolate the texel heights linearly over two triangles per texel
// square, while every method samples the bilinear surface: they differ inside a square by up to a
// quarter of |h00 - h01 - h10 + h11|. Rasterizing the tessellation decides visibility; this then
// moves the hit along the view ray onto the bilinear surface (the first crossing within a window
// of two texels around the rasterized point), so that comparisons measure the methods' errors only.
const int snap_steps = 32;      // linear steps across the window
const int snap_bisections = 24;
const float snap_window_texels = 2.0;

vec3 snap_to_bilinear(vec3 origin, vec3 direction, float s_raster) {
  float dz = min(direction.z, -min_descent);
  vec3 descent = vec3(direction.xy / -dz, -1.0);
  float travel_texels = length(descent.xy * frame.map_size.xy);
  float window = max(snap_window_texels / max(travel_texels, 1e-6), 1e-3);
  float lo = max(s_raster - window, 0.0), hi = min(s_raster + window, 1.0);
  vec3 p = origin + lo * descent;
  if (p.z - shading_height(p.xy) <= 0.0) return origin + s_raster * descent;
  float below = -1.0;
  for (int i = 1; i <= snap_steps; ++i) {
    float s = mix(lo, hi, float(i) / float(snap_steps));
    vec3 q = origin + s * descent;
    if (q.z - shading_height(q.xy) <= 0.0) {
      below = s;
      break;
    }
    lo = s;
  }
  if (below < 0.0) return origin + s_raster * descent;
  for (int i = 0; i < snap_bisections; ++i) {
    float mid = 0.5 * (lo + below);
    vec3 q = origin + mid * descent;
    if (q.z - shading_height(q.xy) > 0.0) lo = mid; else below = mid;
  }
  return origin + below * descent;
}

void main() {
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
    hit = snap_to_bilinear(vec3(entry * frame.surface.x, 1.0), inverse(tangent_frame) * d, 1.0 - in_h);
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
