// render/shaders/methods.inc.glsl - the per-pixel displacement methods, one family of functions
// selected by the METHOD specialization constant. Included by surface.frag.glsl, which declares
// `frame`, `height_map`, `cone_map` and the counters g_iterations, g_fetches.
//
// Every method traces in texture space (u, v, h): the ray enters the relief on the top plane (h = 1)
// and is written p(s) = origin + s * descent, where `descent` has z = -1, so s is the height the ray
// has descended and s = 1 reaches the bottom (h = 0). Because heights are >= 0, every ray meets the
// relief by s = 1. A trace returns the texture-space point it settled on.

// numerical guards
const float min_descent = 1e-6;    // smallest |dh| per unit world distance: grazing rays stay finite
const float min_denominator = 1e-12;  // interpolation weights when two height differences coincide
const float cone_gap_epsilon = 1e-5;  // cone stepping stops this close (in height units) above the surface

float fetch_height(vec2 uv) {
  g_fetches += 1u;
  return textureLod(height_map, uv, 0.0).r;
}

float fetch_cone(vec2 uv, int sector) {
  g_fetches += 1u;
  vec4 ratios = textureLod(cone_map, vec3(uv, float(sector / 4)), 0.0);
  return ratios[sector % 4];
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

// Linear search: the first of `steps` equal steps of s that ends at or below the surface. Returns the
// bracket [s_above, s_below] and the ray-minus-surface differences at its ends.
struct Bracket {
  float s_above, s_below;
  float gap_above, gap_below;
};

Bracket linear_search(vec3 origin, vec3 descent, int steps) {
  Bracket b;
  b.s_above = 0.0;
  b.gap_above = origin.z - fetch_height(origin.xy);
  b.s_below = 0.0;
  b.gap_below = b.gap_above;
  if (b.gap_above <= 0.0) return b;
  for (int i = 1; i <= steps; ++i) {
    g_iterations += 1u;
    float s = float(i) / float(steps);  // the last step is exactly s = 1
    vec3 p = origin + s * descent;
    float gap = p.z - fetch_height(p.xy);
    if (gap <= 0.0) {
      b.s_below = s;
      b.gap_below = gap;
      return b;
    }
    b.s_above = s;
    b.gap_above = gap;
  }
  b.s_below = 1.0;  // not reached: the ray is at h = 0 at s = 1
  b.gap_below = 0.0;
  return b;
}

// Binary search inside a bracket (relief mapping's refinement).
float binary_refine(vec3 origin, vec3 descent, Bracket b, int refine) {
  float lo = b.s_above, hi = b.s_below;
  for (int i = 0; i < refine; ++i) {
    g_iterations += 1u;
    float mid = 0.5 * (lo + hi);
    vec3 p = origin + mid * descent;
    if (p.z - fetch_height(p.xy) > 0.0) lo = mid; else hi = mid;
  }
  return 0.5 * (lo + hi);
}

// Cone stepping (Dummer): from a point at height gap g above the surface, a cone of ratio r
// (horizontal over vertical) with its apex on the surface below lets the ray descend
// r * g / (r + L), L = horizontal travel per unit descent, without entering the relief.
float cone_march(vec3 origin, vec3 descent, int steps, int sectors) {
  float travel = length(descent.xy);
  int sector = cone_sector(descent.xy, sectors);
  float s = 0.0;
  for (int i = 0; i < steps; ++i) {
    vec3 p = origin + s * descent;
    float gap = p.z - fetch_height(p.xy);
    if (gap <= cone_gap_epsilon) break;
    g_iterations += 1u;
    float ratio = fetch_cone(p.xy, sector);
    s = min(s + ratio * gap / max(ratio + travel, min_denominator), 1.0);
  }
  return s;
}

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
  if (METHOD == METHOD_POM) {
    Bracket b = linear_search(origin, descent, frame.counts.x);
    s = mix(b.s_above, b.s_below, crossing_fraction(b.gap_above, b.gap_below));
  } else if (METHOD == METHOD_RELIEF) {
    Bracket b = linear_search(origin, descent, frame.counts.x);
    s = binary_refine(origin, descent, b, frame.counts.y);
  } else if (METHOD == METHOD_CSM) {
    s = cone_march(origin, descent, frame.counts.x, 1);
  } else if (METHOD == METHOD_ACM4) {
    s = cone_march(origin, descent, frame.counts.x, 4);
  } else if (METHOD == METHOD_ACM8) {
    s = cone_march(origin, descent, frame.counts.x, 8);
  }
  result.p = origin + s * descent;
  return result;
}
