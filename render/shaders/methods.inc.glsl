// render/shaders/methods.inc.glsl - the per-pixel displacement methods, one family of functions
// selected by the METHOD specialization constant. Included by surface.frag.glsl, which declares
// `frame`, `height_map`, `cone_map`, `distance_map` and the counters g_iterations, g_fetches.
//
// Every method traces in texture space (u, v, h): the ray enters the relief on the top plane (h = 1)
// and is written p(s) = origin + s * descent, where `descent` has z = -1, so s is the height the ray
// has descended and s = 1 reaches the bottom (h = 0). Because heights are >= 0, every ray meets the
// relief by s = 1. A trace returns the texture-space point it settled on. pom, relief, interval,
// csm, acm and acm4-interval are the root searches every surface shares (root_search.inc.glsl), with
// the plane's cone step and cell steps below; the other methods are the plane's own.

// numerical guards
const float min_descent = 1e-6;    // smallest |dh| per unit world distance: grazing rays stay finite
const float min_denominator = 1e-12;  // interpolation weights when two height differences coincide
const float cone_gap_epsilon = 1e-5;  // cone stepping that reads gaps (quadrics) stops this close (height units) above the surface

// tuning constants of the secant-refined methods (interval, acm4-interval)
const float secant_gap_epsilon = 1e-6;  // height units: secant refinement stops this close (Risser et al. use 0.01)
const float bracket_first_gap_factor = 2.0;  // first bracketing step after cone stepping, in gaps left above the surface
const float bracket_min_step = 1e-6;    // height units: smallest first bracketing step, for a gap of 0
const float bracket_growth = 2.0;       // ratio between consecutive bracketing steps (unitless)
const int bracket_max_steps = 32;       // bracketing steps; the last one always reaches the search's end (a count)

float fetch_height(vec2 uv) {
  g_fetches += 1u;
  return on_level() ? level_bilinear_height(uv) : bilinear_height_of(height_map, uv);
}

// The sector of an n-sector cone map holding horizontal direction d (azimuth atan(dv, du) in [0, 2 pi)).
int cone_sector(vec2 d, int sectors) {
  if (sectors <= 1 || (d.x == 0.0 && d.y == 0.0)) return 0;
  float azimuth = atan(d.y, d.x);
  if (azimuth < 0.0) azimuth += 6.28318530718;
  return clamp(int(azimuth * float(sectors) / 6.28318530718), 0, sectors - 1);
}

// b / (b - c) for a bracket where b >= 0 >= c: the zero of the line through them, in [0, 1].
float crossing_fraction(float above, float below) {
  return clamp(above / max(above - below, min_denominator), 0.0, 1.0);
}

// Cone stepping that is conservative for the BILINEAR surface the rays sample. The cone maps are
// baked for it (bake::bake_bilinear_cones): texel c holds an apex height H_c, the maximum of the
// surface over its square Q_c (c plus or minus half a texel), and per sector k a ratio r_k such that
// from ANY point p of Q_c every surface point x whose direction from p lies in sector k satisfies
// s(x) <= H_c + |x - p| / r_k. A ray point p at height z reads the cone of its own texel (the
// nearest centre, so p lies in Q_c) in its azimuth's sector, and may descend
// r_k (z - H_c) / (r_k + L) without meeting the surface. A ray on a sector boundary may read either
// sector: the bake puts boundary directions in both. One fetch per step: layer k holds (r_k, H_c).
// With cones measured between texel centres the step needed a slack for p's offset from the centre
// and, near the apex, the smallest ratio of all sectors (acm4 then cost as many fetches as csm);
// and the published step r (z - s(p)) / (r + L) (Dummer; Chen & Chuang) with them is not safe: it
// lets rays cross sharp bilinear edges (measured: rmse 9-11 on the brick and cliff scenes).
// Where the safe step is shorter than a quarter texel of travel (the ray is close to the surface, or
// under its texel's apex), the ray takes an exact cell step instead: one gather reads the four
// texels around the cell the ray is in, and the ray's crossing with that cell's bilinear patch is
// solved (bilinear_cell.inc.glsl); without one the ray moves on to the cell's exit. Nothing is
// skipped, so a march that runs to its end lands on the exact hit. (It replaced a quarter-texel
// linear step, which skipped clips thinner than its length: csm and acm4 plateaued at RMSE 4.6 on
// the built-in bricks from 256 steps on.) A gather counts as one fetch, like one filtered read.
const float fallback_step_texels = 0.25;  // safe steps shorter than this (horizontal travel, texels) become cell steps

// The cell (between four texel centres) that the ray origin + s * descent is in, as the reference's
// cell walk numbers them (texel centre (i, j) at cell coordinates (j, i)).
ivec2 cell_at(vec3 origin, vec3 descent, float s) {
  return ivec2(floor((origin.xy + s * descent.xy) * traced_map_size().xy - 0.5));
}

// An exact step through one cell: the crossing in it (exact = true), or the s where the ray leaves
// it, with `cell` moved to the cell it enters (as in a grid walk, so rounding never stalls it), and
// the ray's height above the cell's patch there (exit_gap).
float cell_step(vec3 origin, vec3 descent, float s, inout ivec2 cell, out bool exact, out float exit_gap) {
  g_fetches += 1u;
  vec4 map_size = traced_map_size();
  vec2 size = map_size.xy;
  // the gather at the cell's middle returns its corners: w = (j, i), z = (j+1, i), x = (j, i+1), y = (j+1, i+1)
  vec4 corners = on_level() ? level_gather(cell) : textureGather(height_map, (vec2(cell) + 1.0) * map_size.zw, 0);
  vec2 x0 = origin.xy * size - 0.5, dx = descent.xy * size;
  vec2 exits = vec2(3.0e38);
  for (int axis = 0; axis < 2; ++axis) {
    if (dx[axis] != 0.0) exits[axis] = (float(cell[axis]) + (dx[axis] > 0.0 ? 1.0 : 0.0) - x0[axis]) / dx[axis];
  }
  float exit_s = clamp(min(exits.x, exits.y), s, 1.0);
  BilinearCell c;
  c.z0 = origin.z;
  c.f0 = x0 - vec2(cell);
  c.df = dx;
  c.h = vec4(corners.w, corners.z, corners.x, corners.y);
  float root = cell_first_root(c, s, exit_s);
  exact = root >= 0.0;
  exit_gap = cell_gap(c, exit_s);
  if (exact) return root;
  for (int axis = 0; axis < 2; ++axis) {
    if (exits[axis] <= exit_s) cell[axis] += dx[axis] > 0.0 ? 1 : -1;
  }
  return exit_s;
}

float cell_step(vec3 origin, vec3 descent, float s, inout ivec2 cell, out bool exact) {
  float exit_gap;
  return cell_step(origin, descent, s, cell, exact, exit_gap);
}

// The cone map texel whose square holds uv (unwrapped texture coordinates): the nearest centre,
// wrapped or clamped like the map.
ivec2 cone_texel(vec2 uv) {
  vec4 map_size = traced_map_size();
  ivec2 size = ivec2(map_size.xy);
  ivec2 texel = ivec2(floor(uv * map_size.xy));
  if ((frame.counts.z & FLAG_WRAP) != 0) return texel - size * ivec2(floor(vec2(texel) / vec2(size)));
  return clamp(texel, ivec2(0), size - 1);
}

// What the plane's cone steps along one ray share, found once per ray (a straight ray keeps them at
// every step; lavapipe does not hoist them out of the march's loop): the sector of the ray's azimuth,
// its horizontal travel per unit of descent, and `stall`, a quarter texel of travel, the step below
// which the march takes an exact cell step instead.
struct PlaneCones {
  int sector;
  float travel;
  float stall;
};
PlaneCones plane_cones(vec3 descent, int sectors) {
  PlaneCones c;
  c.travel = length(descent.xy);
  vec2 texel = traced_map_size().zw;
  c.sector = cone_sector(descent.xy, sectors);
  c.stall = c.travel > 0.0 ? fallback_step_texels * min(texel.x, texel.y) / c.travel : 1.0;
  return c;
}

// The plane's safe cone step from s (cone_march in root_search.inc.glsl): one fetch of the cone of
// the texel under the ray point in the ray's sector.
float plane_safe_cone_step(vec3 origin, vec3 descent, float s, PlaneCones c) {
  vec3 p = origin + s * descent;
  g_fetches += 1u;
  vec2 cone = cone_value(ivec3(cone_texel(p.xy), c.sector));  // (r_k, H_c)
  return max(cone.x * (p.z - cone.y) / max(cone.x + c.travel, min_denominator), 0.0);
}

// Whether the plane's safe cone step from a point `gap` above the surface under it would stall for
// certain: the stored ratios are at most 1 and the apex H_c of the point's texel is at or above the
// surface there, so the step r (z - H_c) / (r + travel) is at most gap / (1 + travel); a relative
// 1e-3 keeps a float rounding from calling a step that would not stall a stall.
bool plane_cone_step_stalls(PlaneCones c, float gap) { return gap < c.stall * (1.0 + c.travel) * 0.999; }

#include "root_search.inc.glsl"
#include "relaxed_march.inc.glsl"

// Iterative parallax mapping with slope information (Premecz, sec. 3): the surface near the current
// point p_i = (u_i, v_i, h_i) is taken as the plane through (u_i, v_i, h(u_i, v_i)) with normal N', and
// the division by N' . V of the exact ray-plane intersection is dropped, as offset limiting does:
//   p_{i+1} = p_i + (h(u_i, v_i) - h_i) * N'_z * V,
// V the unit view direction, N' the unit surface normal, both in world units. Along our ray that
// moves s by gap * N'_z * D * (-dz) (a world step of gap * D * N'_z). Premecz reads N' from a normal
// map stored with the height (one read); here N' comes from central differences one texel apart
// (4 more counted reads) on the plane's tangent frame (dP/du = dP/dv = 1 / K, dP/dh = D). On a flat
// surface every iteration keeps a fraction 1 - cos(view angle) of the gap, and the first equals
// parallax with offset limiting. Not exact: it converges slowly at grazing angles and may settle on a
// hidden crossing. s is kept in [0, 1], inside the relief volume.
float parallax_slope(vec3 origin, vec3 descent, float dz, int iterations) {
  vec2 texel = frame.map_size.zw;
  float slope_scale = frame.surface.y * frame.surface.x;  // D * K: world slope per unit of dh/du
  float s = 0.0;
  for (int i = 0; i < iterations; ++i) {
    g_iterations += 1u;
    vec3 p = origin + s * descent;
    float gap = p.z - fetch_height(p.xy);
    float dh_du = (fetch_height(p.xy + vec2(texel.x, 0.0)) - fetch_height(p.xy - vec2(texel.x, 0.0))) / (2.0 * texel.x);
    float dh_dv = (fetch_height(p.xy + vec2(0.0, texel.y)) - fetch_height(p.xy - vec2(0.0, texel.y))) / (2.0 * texel.y);
    float normal_z = inversesqrt(1.0 + slope_scale * slope_scale * (dh_du * dh_du + dh_dv * dh_dv));
    s = clamp(s + gap * normal_z * frame.surface.y * -dz, 0.0, 1.0);
  }
  return s;
}

#include "max_pyramid.inc.glsl"
#include "sphere_trace.inc.glsl"

struct Trace {
  vec3 p;  // texture-space point (u, v, h)
};

// origin: (u, v, 1) on the top plane; direction: texture-space direction per unit world distance
// (dir.z < 0 for a ray entering the relief); cos_view: cosine between view ray and surface normal.
Trace trace(vec3 origin, vec3 direction, float cos_view) {
  float dz = min(direction.z, -min_descent);
  vec3 descent = vec3(direction.xy / -dz, -1.0);
  Trace result;
  result.p = origin;
  if (METHOD == METHOD_BUMP) return result;
  if (METHOD == METHOD_PARALLAX || METHOD == METHOD_PARALLAX_LIMITED) {
    // Kaneko's parallax: assume the surface is flat at the height under the entry point. Offset
    // limiting (Welsh) drops the 1 / cos division: the offset is scaled by cos_view.
    g_iterations += 1u;
    float h0 = fetch_height(origin.xy);
    float s = 1.0 - h0;
    if (METHOD == METHOD_PARALLAX_LIMITED) s *= clamp(cos_view, 0.0, 1.0);
    result.p = vec3(origin.xy + s * descent.xy, h0);
    return result;
  }
  float s = 0.0;
  if (METHOD == METHOD_RELAXED) {
    s = relaxed_march(origin, descent, frame.counts.x);
  } else if (METHOD == METHOD_MAXMIP) {
    s = max_pyramid_trace(origin, descent, frame.counts.x, false);
  } else if (METHOD == METHOD_QDM) {
    s = max_pyramid_trace(origin, descent, frame.counts.x, true);
  } else if (METHOD == METHOD_SPHERE) {
    s = sphere_trace(origin, descent, frame.counts.x);
  } else if (METHOD == METHOD_PARALLAX_SLOPE) {
    s = parallax_slope(origin, descent, dz, frame.counts.x);
  } else {
    // pom, relief, interval, csm, acm: the searches shared with the quadrics, over s in [0, 1], where
    // every ray meets the relief
    root_search(SearchRay(origin, descent, g_level_start, 1.0, true), s);
  }
  result.p = origin + s * descent;
  return result;
}
