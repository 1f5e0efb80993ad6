// render/shaders/surface.frag.glsl - one fragment shader for every method: trace the view ray
// through the relief (methods.inc.glsl), shade the hit (shading.inc.glsl), and write the colour,
// the hit AOV (u, v, hit, depth) and the counters (iterations, fetches).
#version 450
#extension GL_GOOGLE_include_directive : require
#include "config.h"

layout(constant_id = 0) const int METHOD = METHOD_RELIEF;
layout(constant_id = 1) const int SURFACE = SURFACE_PLANE;
// The features the pipeline is made for (config.h, FEATURE_FLAGS), constants when it is compiled: a
// pipeline keeps no code of the others.
layout(constant_id = 2) const int FEATURES = 0;
const bool water_on = (FEATURES & FLAG_WATER) != 0;
const bool unbounded_on = (FEATURES & FLAG_UNBOUNDED) != 0;
const bool levels_on = (FEATURES & FLAG_LEVELS) != 0;
const bool sky_pass = (FEATURES & FLAG_SKY) != 0;

#include "frame_block.inc.glsl"

// shadows: a constant on the plane; meshes and quadrics read the uniform flag (config.h)
bool shadows_on() {
  return SURFACE == SURFACE_PLANE ? (FEATURES & FLAG_SHADOWS) != 0 : (frame.counts.z & FLAG_SHADOWS) != 0;
}

layout(binding = BINDING_HEIGHT) uniform sampler2D height_map;
#include "height_fetch.inc.glsl"
layout(binding = BINDING_CONES) uniform usampler2DArray cone_map;
layout(binding = BINDING_ALBEDO) uniform sampler2D albedo_map;
layout(binding = BINDING_DISTANCE) uniform sampler3D distance_map;
layout(binding = BINDING_FOAM) uniform sampler2D foam_map;
layout(binding = BINDING_HEIGHT_LEVELS) uniform sampler2D height_levels;
layout(binding = BINDING_CONE_LEVELS) uniform usampler2DArray cone_levels;

layout(location = 0) in vec3 in_world;
layout(location = 1) in vec2 in_uv;
layout(location = 2) in vec3 in_tangent_u;
layout(location = 3) in vec3 in_tangent_v;
layout(location = 4) in vec3 in_normal;
layout(location = 5) in float in_h;
layout(location = 6) in vec2 in_curvature;  // meshes only: k_uu, k_vv (1 / world units)

layout(location = ATTACHMENT_COLOR) out vec4 out_color;
layout(location = ATTACHMENT_HIT) out vec4 out_hit;
layout(location = ATTACHMENT_COUNTERS) out vec4 out_counters;

uint g_iterations = 0u;
uint g_fetches = 0u;

// The level of detail the pixel traces (choose_level; 0: the map itself, as in every view without
// levels): its size (W >> l, H >> l and their inverses) and where it starts in the levels' atlases
// (config.h). Every read of the trace and the shading goes to that level's heights and cones, so the
// ray meets that level's own bilinear surface, with the cones baked for it.
int g_level = 0;
const float level_top_margin = 1e-6;  // height units: over a bilinear value's float rounding (< 2e-7)
vec4 g_level_size = vec4(0.0);
ivec2 g_level_origin = ivec2(0);
float g_level_start = 0.0;  // the s where a ray on the level starts its march: above the level's top

// Whether the pixel traces a coarser level than the map itself: exactly in the pipelines with
// FLAG_LEVELS, which discard every pixel of level 0 (main).
bool on_level() { return levels_on; }

// The map size the trace works with: level 0's (frame.map_size) or the level's.
vec4 traced_map_size() { return on_level() ? g_level_size : frame.map_size; }

// The atlas texels of the level's cell whose lower corner is texel `cell`: its lower corner (xy) and
// its upper one (zw), each wrapped into the level (levels serve the unbounded plane, which wraps).
// One division per axis: the upper corner is the lower one's next texel, or texel 0 past the last.
ivec4 level_cell_texels(ivec2 cell) {
  ivec2 size = ivec2(g_level_size.xy);
  ivec2 lower = cell - size * ivec2(floor(vec2(cell) / vec2(size)));
  ivec2 upper = lower + 1;
  upper.x = upper.x == size.x ? 0 : upper.x;
  upper.y = upper.y == size.y ? 0 : upper.y;
  return ivec4(lower + g_level_origin, upper + g_level_origin);
}

// The level's height (r) and slope moments (gba: the means of level 0's g_u, g_v and g_u^2 + g_v^2
// over each texel's footprint, bake::downsample_moments) at uv, bilinear.
vec4 level_height_and_moments(vec2 uv) {
  vec2 x = uv * g_level_size.xy - 0.5;
  ivec4 t = level_cell_texels(ivec2(floor(x)));
  vec2 f = x - floor(x);
  vec4 m00 = texelFetch(height_levels, t.xy, 0), m10 = texelFetch(height_levels, t.zy, 0);
  vec4 m01 = texelFetch(height_levels, t.xw, 0), m11 = texelFetch(height_levels, t.zw, 0);
  return mix(mix(m00, m10, f.x), mix(m01, m11, f.x), f.y);
}

// The four texels of the level's cell whose lower corner is texel `cell`, in textureGather's order
// (u0 v1, u1 v1, u1 v0, u0 v0): four texel reads, counted as one fetch like a gather.
vec4 level_gather(ivec2 cell) {
  ivec4 t = level_cell_texels(cell);
  return vec4(texelFetch(height_levels, t.xw, 0).r, texelFetch(height_levels, t.zw, 0).r,
              texelFetch(height_levels, t.zy, 0).r, texelFetch(height_levels, t.xy, 0).r);
}

// The level's bilinear height at uv, as bilinear_height_of on level 0.
float level_bilinear_height(vec2 uv) {
  vec2 x = uv * g_level_size.xy - 0.5;
  vec2 cell = floor(x);
  vec2 f = x - cell;
  vec4 c = level_gather(ivec2(cell));
  return mix(mix(c.w, c.z, f.x), mix(c.x, c.y, f.x), f.y);
}

// (ratio, apex height) of cone map texel `texel` (x, y, layer) of the traced level. The image is
// R16G16_UINT: the ratio as a half float rounded down and the apex in units of 1 / 65535 rounded up
// (render/map_pack.h), so the values read claim no more empty space than the baked ones.
vec2 cone_value(ivec3 texel) {
  uvec2 stored = on_level() ? texelFetch(cone_levels, ivec3(texel.xy + g_level_origin, texel.z), 0).rg
                            : texelFetch(cone_map, texel, 0).rg;
  return vec2(unpackHalf2x16(stored.x).x, float(stored.y) / 65535.0);
}

#include "bilinear_cell.inc.glsl"
#include "quadric.inc.glsl"
#include "methods.inc.glsl"
#include "shading.inc.glsl"

// The reference's triangles interpolate the texel heights linearly over two triangles per texel
// square, while every method samples the bilinear surface: they differ inside a square by up to a
// quarter of |h00 - h01 - h10 + h11|, and at a sharp edge a ray may pass one and hit the other
// (measured: 258 of 8706 pixels more than half a texel off on the brick relief). Rasterizing the
// tessellation decides which pixels see the relief; the hit is then the exact first crossing of the
// view ray with the bilinear surface (reference.inc.glsl), so that comparisons measure the methods'
// errors and not the triangulation's. An earlier eighth-texel march here stepped over thin clips at
// brick edges: relief at 1024 and 4096 steps then drifted away from it (RMSE 3.07, 3.27 vs 2.74 at
// 256 steps on the built-in bricks).
#include "reference.inc.glsl"

// Self-shadowing (Policarpo et al.'s relief mapping shadows): the light ray through the hit enters
// the relief on the top plane h = 1; the frame's method traces it from there towards the hit. When
// it stops clearly before the hit - more than shadow_bias_height of descent plus half a texel of
// travel - something lies between the hit and the light. The margin keeps a method's own error at
// the hit from shadowing it. A light at or below the base surface's horizon leaves everything dark.
// Shadow rays see the relief beyond the patch continued by the address mode. Their reads count in
// the fetch AOV: they are part of what a frame with shadows costs.
const float shadow_bias_height = 0.01;  // height units

float light_visibility(vec3 hit, mat3 tangent_frame, vec3 normal) {
  vec3 l = inverse(tangent_frame) * normalize(frame.light.xyz);  // texture space, per world unit
  if (l.z <= min_descent) return 0.0;
  vec3 descent = vec3(-l.xy / l.z, -1.0);
  float s_hit = 1.0 - hit.z;  // descent from the top plane to the hit along the light ray
  vec3 entry = hit - s_hit * descent;
  float travel = length(descent.xy);
  vec4 map_size = traced_map_size();
  float bias = shadow_bias_height + (travel > 0.0 ? 0.5 * min(map_size.z, map_size.w) / travel : 1.0);
  if (s_hit <= bias) return 1.0;
  float s = 1.0;
  if (METHOD == METHOD_REFERENCE) {
    s = reference_first_crossing(entry, descent, s_hit, false);
  } else {
    s = 1.0 - trace(entry, -l, dot(normalize(frame.light.xyz), normal)).p.z;
  }
  return s < s_hit - bias ? 0.0 : 1.0;
}

// The unit direction of the pixel's own ray (Camera::pixel_rays), not one from interpolated vertex
// attributes: the ray the CPU's exact traces follow, to float rounding.
vec3 pixel_direction() {
  return normalize(frame.ray_corner.xyz + gl_FragCoord.x * frame.ray_along_x.xyz + gl_FragCoord.y * frame.ray_along_y.xyz);
}

// Where the pixel's ray (direction d) meets the fragment's tangent plane (through the interpolated
// point, with the interpolated normal), in world space and in texture space (u, v, h): the
// interpolated attributes moved along the tangent frame by their interpolation error. On the plane
// this is the ray's exact entry into z = 0.
struct Entry {
  vec3 world;
  vec3 texture;
};
Entry tangent_plane_entry(vec3 d, vec3 normal, mat3 to_texture) {
  Entry e;
  e.world = frame.eye.xyz + (dot(in_world - frame.eye.xyz, normal) / dot(d, normal)) * d;
  e.texture = vec3(in_uv + (to_texture * (e.world - in_world)).xy, in_h);
  return e;
}

// Writes a hit found in the fragment's tangent frame (plane and meshes): depth, the shaded colour
// (with the light's visibility under --shadows), the hit AOV and the counters. base_world and
// base_texture: where the ray entered the base surface, in world and texture space (u, v, h).
void write_hit(vec3 hit, mat3 tangent_frame, vec3 d, vec3 normal, vec3 base_world, vec3 base_texture) {
  vec3 world_hit = base_world + tangent_frame * (hit - base_texture);
  vec4 clip = frame.view_projection * vec4(world_hit, 1.0);
  // (the unbounded plane's hits past the far plane keep the farthest depth the LESS test passes)
  gl_FragDepth = clamp(clip.z / clip.w, 0.0, 1.0 - 1.0 / 16777216.0);
  float lit = shadows_on() ? light_visibility(hit, tangent_frame, normal) : 1.0;
  vec3 colour = shade(hit.xy, tangent_frame, d, lit);
  if (unbounded_on) {
    // aerial perspective: towards the sky's colour at the horizon with the distance
    float seen = exp(-length(world_hit - frame.eye.xyz) / AERIAL_DISTANCE);
    colour = mix(sky(vec3(d.xy, 0.0)), colour, seen);
  }
  out_color = vec4(colour, 1.0);
  out_hit = vec4(hit.xy, 1.0, length(world_hit - frame.eye.xyz));
  out_counters = vec4(float(g_iterations), float(g_fetches), 0.0, 0.0);
}

// The sky seen in direction d (unbounded plane): at the farthest depth the LESS test keeps.
void write_sky(vec3 d) {
  out_color = vec4(sky_with_sun(d), 1.0);
  out_hit = vec4(0.0);
  out_counters = vec4(0.0);
  gl_FragDepth = 1.0 - 1.0 / 16777216.0;
}

#if SEARCH_PLANAR
#include "mesh.inc.glsl"

// The unbounded plane's level of detail for this pixel's ray d (FrameUniforms::levels): the pinned
// level, or the one its footprint asks for where the ray enters the relief (the plane z = 0, at
// distance eye.z / -d.z): the level-0 texels a pixel spans there across the ray, the pixel's angle
// times the distance, stretched by (1 / |d.z|)^LEVEL_ANISOTROPY towards its long side along the
// ray, log2, plus LEVEL_BIAS, rounded down and clamped to the levels held. One level per pixel: the
// ray meets that level's surface and nothing of the others.
void choose_level(vec3 d) {
  int levels = int(frame.levels.x);
  int level = int(frame.levels.y);
  if (level < 0) {
    vec3 through = frame.ray_corner.xyz + gl_FragCoord.x * frame.ray_along_x.xyz + gl_FragCoord.y * frame.ray_along_y.xyz;
    float pixel_angle = length(frame.ray_along_y.xyz) / length(through);  // radians
    float distance = frame.eye.z / -d.z;
    float texels = distance * pixel_angle * frame.surface.x * max(frame.map_size.x, frame.map_size.y);
    float detail = log2(max(texels, 1e-30)) + LEVEL_ANISOTROPY * log2(-1.0 / d.z) + LEVEL_BIAS;
    level = int(clamp(floor(detail), 0.0, float(levels)));
  }
  g_level = clamp(level, 0, levels);
  if (g_level > 0) {
    ivec2 size = ivec2(frame.map_size.xy) >> g_level;
    g_level_size = vec4(vec2(size), 1.0 / vec2(size));
    ivec2 half_size = ivec2(frame.map_size.xy) >> 1;
    g_level_origin = g_level == 1 ? ivec2(0) : ivec2(half_size.x, half_size.y - (int(frame.map_size.y) >> (g_level - 1)));
    // every height of the level, and so its bilinear surface (within a rounding), is at most its top:
    // the ray (height 1 - s) meets nothing before it comes down to the top plus a margin
    float top = frame.level_tops[(g_level - 1) / 4][(g_level - 1) % 4];
    g_level_start = clamp(1.0 - top - level_top_margin, 0.0, 1.0);
  }
}

void main() {
  if (SURFACE == SURFACE_MESH) {
    mesh_fragment();
    return;
  }
  vec3 d = pixel_direction();
  const bool unbounded = unbounded_on;
  const bool sky = unbounded && (frame.eye.z <= 0.0 || d.z >= 0.0);  // above the horizon
  if (sky_pass) {  // the sky pass (config.h, FLAG_SKY): the sky and nothing else
    if (!sky) discard;
    write_sky(d);
    return;
  }
  if (sky) {
    if (frame.levels.x > 0.0) discard;  // a view with levels draws its sky in the sky pass
    write_sky(d);
    return;
  }
  vec3 normal = normalize(in_normal);
  mat3 tangent_frame = mat3(in_tangent_u, in_tangent_v, normal * frame.surface.y);
  mat3 to_texture = inverse(tangent_frame);
  if (frame.eye.z <= 0.0 || d.z >= 0.0) discard;  // the relief is seen from above only
  if (unbounded && frame.levels.x > 0.0) {
    choose_level(d);
    if ((g_level > 0) != levels_on) discard;  // the other pass draws it (config.h, FLAG_LEVELS)
  }
  // Only what is seen through the base polygon: a ray that enters the relief box through one of its
  // sides has no fragment there (nor has a fragment on the polygon's edge whose ray misses it). The
  // reference's fragments lie on the displaced surface (reference.vert.glsl), not on the base plane.
  Entry entry;
  if (METHOD == METHOD_REFERENCE || unbounded) {
    entry.world = frame.eye.xyz - (frame.eye.z / d.z) * d;
    entry.texture = vec3(entry.world.xy * frame.surface.x, 1.0);
  } else {
    entry = tangent_plane_entry(d, normal, to_texture);
  }
  if (!unbounded &&
      (any(lessThan(entry.world.xy, vec2(0.0))) || any(greaterThan(entry.world.xy, vec2(1.0)))))
    discard;
  vec3 direction = to_texture * d;
  vec3 origin = vec3(entry.texture.xy, 1.0);
  vec3 hit;
  if (METHOD == METHOD_REFERENCE) {
    vec3 descent = vec3(direction.xy / max(-direction.z, min_descent), -1.0);
    hit = origin + reference_first_crossing(origin, descent, 1.0, true) * descent;
  } else {
    Trace traced = trace(origin, direction, -dot(d, normal));
    hit = traced.p;
  }
  // the ray left the relief volume through a side of the patch
  if (!unbounded && (any(lessThan(hit.xy, vec2(0.0))) || any(greaterThan(hit.xy, vec2(frame.surface.x)))))
    discard;
  write_hit(hit, tangent_frame, d, normal, entry.world, entry.texture);
}
#else
#include "quadric_trace.inc.glsl"

void main() { quadric_fragment(); }
#endif
