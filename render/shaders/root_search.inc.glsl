// render/shaders/root_search.inc.glsl - the root searches shared by the plane (and meshes) and the
// quadrics: linear search with its refinements (pom, relief, interval), cone stepping (csm, acm) and
// the bracket after it (acm4-interval). Written once against a surface: SEARCH_PLANAR, a
// preprocessor constant, chooses its family (the fragment shader is built once for each,
// render/CMakeLists.txt: a module holds no code of the other), the SURFACE specialization constant
// the surface within it. Included by methods.inc.glsl after fetch_height, cone_sector,
// crossing_fraction, the tuning constants and the plane's cell steps.
//
// The surface interface. A search follows a ray through the relief along a parameter t in
// [t_in, t_end]; the surface maps the ray point at t to texture space (u, v, h) (search_point), so the
// gap, the ray's height above the surface, is search_point(t).z - fetch_height(search_point(t).xy).
// - planar (plane, mesh): the ray is a line in texture space, origin + t * descent with descent.z =
//   -1, over [0, 1]: t is the height descended, and every ray meets the relief by t = 1 (certain).
//   Its cone steps are proven above the surface; where they stall it takes exact cell steps.
// - quadric (sphere, cylinder, cone): the ray is a world line, mapped to a curve in (u, v, h) by the
//   quadric (quadric_march.inc.glsl, which documents the curve's bounds), over its span in the
//   relief shell; t is the world distance from the eye. Where cone steps stall it takes linear steps,
//   which may cross the surface, so its march reads the gap at each point.
// For each surface these do the floating-point operations of the separate searches they replaced
// (the plane's in methods.inc.glsl, the quadrics' in quadric_trace.inc.glsl), to the bit: the plane's
// descent rate and height unit are 1, its linear search's last step is t_end = 1 (it was steps /
// steps, the same float), and its bracket after cones stops where a probe reaches t_end, which a
// planar ray at h <= 0 there never passes above.

// A ray in a surface's search parameter t.
struct SearchRay {
  vec3 origin;     // planar: (u, v, h) at t = 0; quadric: the eye, relative to quadric_anchor()
  vec3 direction;  // planar: descent per unit t (z = -1); quadric: unit, world
  float t_in;      // where the search starts (planar: 0; quadric: where the ray enters the outer surface)
  float t_end;     // where it ends (planar: 1; quadric: the inner surface, the outer one again, or the box)
  bool certain;    // the ray meets the relief by t_end (planar: always; quadric: t_end on the inner surface)
};

// A bracket along t: the last point above the surface and the first at or below it, with the gaps
// (ray-minus-surface height differences) there.
struct Bracket {
  float t_above, t_below;
  float gap_above, gap_below;
};

// Where a cone march stopped (t): the exact crossing (exact, found by a planar cell step), or a point
// never below the surface but after a quadric's linear step. gap: the gap at t when it was read
// (gap_known); t_above, gap_above: the point read above the surface before t (quadric marches only,
// which read the gap at every point). walking, cell: a planar cell walk's state, the cell the ray
// entered with the last step when that was a cell step.
struct ConeMarch {
  float t, gap;
  bool gap_known;
  float t_above, gap_above;
  bool exact;
  bool walking;
  ivec2 cell;
  float exit_gap;  // planar walks: the ray's height above the surface where its last cell step left
};

#ifndef SEARCH_PLANAR
#error "SEARCH_PLANAR: 1 for the plane and meshes, 0 for the quadrics"
#endif
const bool planar_search = SEARCH_PLANAR != 0;
const bool march_reads_gap = !planar_search;
#if !SEARCH_PLANAR
#include "quadric_march.inc.glsl"
#endif

// The texture-space point (u, v, h) of the ray at t.
vec3 search_point(SearchRay ray, float t) {
#if SEARCH_PLANAR
  return ray.origin + t * ray.direction;
#else
  return quadric_point(ray, t);
#endif
}

// The ray-minus-surface height at t: one counted fetch.
float search_gap(SearchRay ray, float t) {
  vec3 p = search_point(ray, t);
  return p.z - fetch_height(p.xy);
}

// The most height the ray can lose per unit t from t on (planar: exactly 1).
float search_descent_rate(SearchRay ray, float t) {
#if SEARCH_PLANAR
  return 1.0;
#else
  return quadric_descent_rate(ray, t);
#endif
}

// One height unit in t along the surface's normal (planar: 1; quadric: the depth scale D).
float search_height_unit() { return planar_search ? 1.0 : frame.surface.y; }

// One search step: reads the surface at t. At or below it, t closes the bracket (returns true);
// above it, t becomes the bracket's upper end.
bool probe_bracket(SearchRay ray, float t, inout Bracket b) {
  g_iterations += 1u;
  float gap = search_gap(ray, t);
  if (gap <= 0.0) {
    b.t_below = t;
    b.gap_below = gap;
    return true;
  }
  b.t_above = t;
  b.gap_above = gap;
  return false;
}

// Linear search: the first of `steps` equal steps of t over [t_in, t_end] that ends at or below the
// surface; the last step is t_end. Returns the bracket; false for a miss (a ray that is not certain
// to meet the relief and finds no point below it).
bool linear_search(SearchRay ray, int steps, out Bracket b) {
  b.t_above = ray.t_in;
  b.gap_above = search_gap(ray, ray.t_in);
  b.t_below = ray.t_in;
  b.gap_below = b.gap_above;
  if (b.gap_above <= 0.0) return true;
  for (int i = 1; i <= steps; ++i) {
    float t = i == steps ? ray.t_end : mix(ray.t_in, ray.t_end, float(i) / float(steps));
    if (probe_bracket(ray, t, b)) return true;
  }
  b.t_below = ray.t_end;  // planar: not reached, the ray is at h = 0 at t = 1; quadric: the inner surface
  b.gap_below = 0.0;
  return ray.certain;
}

// Binary search inside a bracket (relief mapping's refinement).
float binary_refine(SearchRay ray, Bracket b, int refine) {
  float above = b.t_above, below = b.t_below;
  for (int i = 0; i < refine; ++i) {
    g_iterations += 1u;
    float middle = 0.5 * (above + below);
    if (search_gap(ray, middle) > 0.0) above = middle; else below = middle;
  }
  return 0.5 * (above + below);
}

// Interval mapping's refinement (Risser, Shah & Pattanaik, "Interval Mapping", sec. 3): join the
// surface points under the two ends of the bracket with a line, intersect it with the ray, and let
// that point replace the end on its side of the surface (a secant step that keeps a valid bracket:
// regula falsi). On the ray the line's crossing is the zero of the gaps interpolated linearly,
// t = t_above + (t_below - t_above) * g_above / (g_above - g_below); crossing_fraction guards the
// division (an all-flat bracket makes it 0 / 0). Like their shader it stops early once a new point
// is within secant_gap_epsilon of the surface. Their shader ends on the ray point at the height last
// read; this returns the secant point of the final bracket instead, which costs no read and stays
// inside the bracket.
float secant_refine(SearchRay ray, Bracket b, int refine) {
  for (int i = 0; i < refine && b.t_below > b.t_above; ++i) {
    g_iterations += 1u;
    float t = mix(b.t_above, b.t_below, crossing_fraction(b.gap_above, b.gap_below));
    float gap = search_gap(ray, t);
    if (gap > 0.0) {
      b.t_above = t;
      b.gap_above = gap;
    } else {
      b.t_below = t;
      b.gap_below = gap;
    }
    if (abs(gap) <= secant_gap_epsilon) return t;
  }
  return mix(b.t_above, b.t_below, crossing_fraction(b.gap_above, b.gap_below));
}

// Moves the march on to t; the point it leaves is the last one read above the surface.
void march_to(inout ConeMarch m, float t) {
  m.t_above = m.t;
  m.gap_above = m.gap;
  m.t = t;
  m.gap_known = false;
}

// Where cones stall: planar, an exact cell step (returns true on the crossing; without one the ray
// moves on to the cell's exit); quadric, a linear step of `stall`.
bool fallback_step(SearchRay ray, float stall, inout ConeMarch m) {
#if SEARCH_PLANAR
  if (!m.walking) m.cell = cell_at(ray.origin, ray.direction, m.t);
  m.walking = true;
  m.t = cell_step(ray.origin, ray.direction, m.t, m.cell, m.exact, m.exit_gap);
  return m.exact;
#else
  march_to(m, min(m.t + stall, ray.t_end));
  return false;
#endif
}

// Cone stepping (Dummer; Chen & Chuang's anisotropic cones with `sectors` > 1): from a point at gap g
// above the surface, a cone of ratio r (horizontal over vertical) with its apex on the surface below
// lets the ray descend r g / (r + L), L = horizontal travel per unit descent, without entering the
// relief (the surfaces' cone steps say which cones and which bounds on their curves). Stops on the
// exact crossing, at t_end, within cone_gap_epsilon of the surface (marches that read the gap), or
// where the steps run out.
ConeMarch cone_march(SearchRay ray, int steps, int sectors) {
  ConeMarch m = ConeMarch(ray.t_in, 0.0, false, ray.t_in, 0.0, false, false, ivec2(0), 3.0e38);
#if SEARCH_PLANAR
  PlaneCones cones = plane_cones(ray.direction, sectors);  // the same at every step of a straight ray
#endif
  for (int i = 0; i < steps; ++i) {
    if (march_reads_gap) {
      m.gap = search_gap(ray, m.t);
      m.gap_known = true;
      if (m.gap <= cone_gap_epsilon) break;
    }
    if (m.t >= ray.t_end) break;  // planar: on the floor h = 0, the ray cannot be above the surface there
    g_iterations += 1u;
#if SEARCH_PLANAR
    // the safe cone step from t (never into the relief), and the step below which the march takes
    // the surface's fallback step instead. On a level of detail (levels.md) a walk goes on without
    // the cone fetch where that fetch would stall for certain (the same cell step follows either
    // way, so the march is unchanged); the march keeps one cell step in its loop, not two (lavapipe
    // would run both).
    float stall = cones.stall;
    float step = 0.0;
    if (!(on_level() && m.walking && plane_cone_step_stalls(cones, m.exit_gap)))
      step = plane_safe_cone_step(ray.origin, ray.direction, m.t, cones);
#else
    float stall;
    float step = quadric_safe_cone_step(ray, m.t, sectors, stall);
#endif
    if (step >= stall) {
      march_to(m, min(m.t + step, ray.t_end));
      m.walking = false;
    } else if (fallback_step(ray, stall, m)) {
      break;
    }
  }
  return m;
}

// Where a cone march ended: the crossing when it got within cone_gap_epsilon or crossed the surface
// (a linear step's crossing interpolated in its bracket); a ray that ran out of steps or reached t_end
// above it settles where it stopped if it is certain to hit, and is a miss otherwise.
bool cone_hit(SearchRay ray, ConeMarch m, out float t) {
  if (m.gap_known && m.gap <= cone_gap_epsilon) {
    bool crossed = m.gap < 0.0 && m.t > m.t_above;
    t = crossed ? mix(m.t_above, m.t, crossing_fraction(m.gap_above, m.gap)) : m.t;
    return true;
  }
  t = m.t;
  return ray.certain;
}

// A bracket after cone stepping (Chen & Chuang's suggested combination of ACM with a root search),
// for a march that stopped short of an exact crossing: the last cone point is the upper end; the
// lower end is found by stepping on along the ray: the first step is twice the distance a flat
// surface would need (twice the gap over the descent rate), each next step twice the previous, and
// the last one reaches t_end. A march point at or below the surface closes the bracket at once:
// after a linear step that crossed it, the bracket of that step; on a planar march (proven steps, so
// below only where the filtered read differs from the exact bilinear value by rounding), the empty
// bracket at the point. False for a miss.
bool bracket_after_cones(SearchRay ray, ConeMarch m, out Bracket b) {
  if (!m.gap_known) m.gap = search_gap(ray, m.t);
  if (m.gap <= 0.0) {
    b.t_above = march_reads_gap ? m.t_above : m.t;
    b.gap_above = march_reads_gap ? m.gap_above : 0.0;
    b.t_below = m.t;
    b.gap_below = m.gap;
    return true;
  }
  b.t_above = m.t;
  b.gap_above = m.gap;
  b.t_below = ray.t_end;
  b.gap_below = 0.0;
  float descent = search_descent_rate(ray, m.t);
  float step = descent > 0.0 ? bracket_first_gap_factor * m.gap / descent : ray.t_end - m.t;
  step = max(step, bracket_min_step * search_height_unit());
  for (int i = 0; i < bracket_max_steps && b.t_above < ray.t_end; ++i) {
    float t = (i == bracket_max_steps - 1) ? ray.t_end : min(b.t_above + step, ray.t_end);
    if (probe_bracket(ray, t, b)) return true;
    step *= bracket_growth;
  }
  b.t_below = ray.t_end;
  b.gap_below = 0.0;
  return ray.certain;
}

// The hit's parameter t for the methods shared by every surface (pom, relief, interval, csm, acm4,
// acm8, acm4-interval); false for a miss, or for another method (t is then t_in).
bool root_search(SearchRay ray, out float t) {
  t = ray.t_in;
  Bracket b;
  if (METHOD == METHOD_POM) {
    if (!linear_search(ray, frame.counts.x, b)) return false;
    t = mix(b.t_above, b.t_below, crossing_fraction(b.gap_above, b.gap_below));
    return true;
  }
  if (METHOD == METHOD_RELIEF) {
    if (!linear_search(ray, frame.counts.x, b)) return false;
    t = binary_refine(ray, b, frame.counts.y);
    return true;
  }
  if (METHOD == METHOD_INTERVAL) {
    if (!linear_search(ray, frame.counts.x, b)) return false;
    t = secant_refine(ray, b, frame.counts.y);
    return true;
  }
  if (METHOD == METHOD_CSM) return cone_hit(ray, cone_march(ray, frame.counts.x, 1), t);
  if (METHOD == METHOD_ACM4) return cone_hit(ray, cone_march(ray, frame.counts.x, 4), t);
  if (METHOD == METHOD_ACM8) return cone_hit(ray, cone_march(ray, frame.counts.x, 8), t);
  if (METHOD == METHOD_ACM4_INTERVAL) {
    ConeMarch m = cone_march(ray, frame.counts.x, 4);
    if (m.exact) {
      t = m.t;
      return true;
    }
    if (!bracket_after_cones(ray, m, b)) return false;
    t = secant_refine(ray, b, frame.counts.y);
    return true;
  }
  return false;
}
