// render/shaders/quadric_trace.inc.glsl - the per-pixel methods on the quadrics, after Patterson,
// Hoggar & Logie, "Inverse Displacement Mapping" (1991): intersect the view ray analytically with the
// outer and the inner bounding surface, then trace between them in parameter space, where the ray
// is a curve (u(t), v(t), h(t)) of the world distance t (quadric.inc.glsl maps points to it).
// Included by surface.frag.glsl after methods.inc.glsl, shading.inc.glsl and the plane's shadow
// block; it shares their counted fetch_height, cone_sector, crossing_fraction, tuning constants,
// shade() and shadow_bias_height, and keeps its own march and bracket types. quadric_fragment() is
// the fragment shader's main for quadrics.
//
// What differs from the plane:
// - The search interval. The ray enters the outer surface at t_in and is in the relief shell until it
//   enters the inner surface (every height is >= 0, so it has hit the relief by then: "certain") or
//   leaves the outer surface again (it passed by: a miss unless it met the relief). The outer and
//   inner solids are convex, so the ray is in the shell over one interval: it cannot come back
//   after leaving. Patterson et al. split the rays that miss the inner surface at their closest
//   approach; a search along t needs no split, h(t) is simply not monotonic there.
// - Linear searches take equal steps of t over [t_in, t_end]. A ray that misses the inner surface
//   and finds no point below the relief is a miss; one that meets it ends its search there.
// - Cone steps. A cone map bounds heights by uv distances of the flat map. Along the curve, h falls at
//   most at the rate it falls at the step's start (h(t) is convex in t: a distance to a point or an
//   axis, or that minus a linear term on the cone), and (u, v) moves at most `speed` texture units
//   per world unit, bounded over the whole step by the step's least distance from the axis and the
//   centre, where the longitude and the polar angle turn fastest. The step is computed with the
//   speed at its start, then again with the worst speed over that step, which only shortens it.
//   The anisotropic sector must hold every direction from the start to a point of the step: the
//   curve in (u, v) is a graph over the longitude, so by the mean value theorem those directions lie
//   between the curve's tangents at the step's ends and at its inflection point when that lies
//   inside (the equator on the sphere, the closest approach to the axis on the cylinder, a closed
//   form on the cone). Near the start, the isotropic bound applies as on the plane.
// - Misses: csm and acm stop when they are within cone_gap_epsilon, cross the surface, or reach
//   t_end; a ray that runs out of steps settles where it stopped (as on the plane) if it is certain
//   to hit, and is a miss otherwise.

struct QuadricRay {
  vec3 origin;     // the eye, relative to quadric_anchor()
  vec3 direction;  // unit, world
  float t_in;      // where the ray enters the outer surface (world distance from the eye)
  float t_end;     // where the search ends: the inner surface, the outer one again, or the relief's box
  bool certain;    // t_end is on the inner surface, so the ray meets the relief by then
};

// A bracket along t: the last point above the surface and the first at or below it, with the
// ray-minus-surface height differences there.
struct QuadricBracket {
  float t_above, t_below;
  float gap_above, gap_below;
};

// Where a cone march stopped (t), the gap there when it was read (gap_known), and the point read
// above the surface before it (t_above, gap_above).
struct QuadricMarch {
  float t, gap;
  bool gap_known;
  float t_above, gap_above;
};

// numerical guards
const float quadric_near_axis = 1e-4;  // fraction of R: a step this close to the axis reads no sector
const float quadric_min_distance = 1e-6;  // fraction of R: least distance used in the speed bound
const float sector_min_margin = 1e-4;  // radians: a smaller margin to the sector's edges reads no sector
const float quadric_fallback_texels = 0.25;  // (u, v) travel of a linear step where cones stall, texels

vec3 quadric_point(QuadricRay ray, float t) { return quadric_texture_point(ray.origin + t * ray.direction); }

float quadric_gap(QuadricRay ray, float t) {
  vec3 p = quadric_point(ray, t);
  return p.z - fetch_height(p.xy);
}

bool quadric_in_range(float v) { return SURFACE == SURFACE_SPHERE || (v >= 0.0 && v <= frame.surface.x); }

// The ray's span in the relief shell; false when it does not enter the outer surface's finite part.
bool quadric_setup(vec3 d, out QuadricRay ray) {
  ray.origin = frame.eye.xyz - quadric_anchor();
  ray.direction = d;
  ray.t_in = 0.0;
  ray.t_end = 0.0;
  ray.certain = false;
  vec2 outer = quadric_body_interval(ray.origin, d, 0.0);
  if (outer.x > outer.y || outer.x < 0.0) return false;  // it misses, or it starts inside the outer surface
  vec2 inner = quadric_body_interval(ray.origin, d, -frame.surface.y);
  ray.t_in = outer.x;
  ray.certain = inner.x <= inner.y && inner.x < outer.y;
  ray.t_end = ray.certain ? max(inner.x, outer.x) : outer.y;
  vec3 lo, hi;
  quadric_box(lo, hi);
  float leave = box_exit(frame.eye.xyz, d, lo, hi);  // nothing in range lies beyond the box
  if (leave < ray.t_end) {
    ray.t_end = max(leave, ray.t_in);
    ray.certain = false;
  }
  return quadric_in_range(quadric_point(ray, ray.t_in).y);
}

// Whether the ray stays in the finite part (v in [0, K]) from its entry to t, where v is v_end.
bool quadric_range_kept(QuadricRay ray, float t, float v_end, float tolerance) {
  if (SURFACE == SURFACE_SPHERE) return true;
  float tile = frame.surface.x;
  if (v_end < -tolerance || v_end > tile + tolerance) return false;
  if (SURFACE == SURFACE_CYLINDER) return true;  // v follows z, monotonic along a ray
  float least = cone_least_slant_t(ray.origin, ray.direction);  // where v is largest
  if (least <= ray.t_in || least >= t) return true;
  return quadric_point(ray, least).y <= tile + tolerance;
}

// The most height (in [0, 1] units) the ray can lose per world unit from t on: h(t) is convex.
float quadric_descent_rate(QuadricRay ray, float t) {
  vec3 q = ray.origin + t * ray.direction, d = ray.direction;
  float rho = length(q.xy);
  float rho_rate = rho > 0.0 ? dot(q.xy, d.xy) / rho : length(d.xy);
  float rate;  // dh/dt times D
  if (SURFACE == SURFACE_SPHERE) {
    float r = length(q);
    rate = r > 0.0 ? dot(q, d) / r : 1.0;
  } else if (SURFACE == SURFACE_CYLINDER) {
    rate = rho_rate;
  } else {
    rate = cone_cos * rho_rate + cone_sin * d.z;
  }
  return max(-rate / frame.surface.y, 0.0);
}

// Least |o + t d| over [t0, t1].
float least_distance(vec3 o, vec3 d, float t0, float t1) {
  float a = dot(d, d);
  float t = a > 0.0 ? clamp(-dot(o, d) / a, t0, t1) : t0;
  return length(o + t * d);
}

// The largest |d(u, v)/dt| over [t0, t1], texture units per world unit. du/dt = K / (2 pi) a / rho
// with a = d . e_phi the speed across the meridian (|a| <= |d_xy|, horizontal); dv/dt is K / pi
// b / r with b = d . e_theta, a^2 + b^2 <= 1 (sphere), K z' / (2 R) (cylinder), and -K cos s' / R
// with |s'| <= sin |rho'| + cos |z'| (cone). rho and r are bounded below by their least values over
// the step.
float quadric_uv_speed(QuadricRay ray, float t0, float t1) {
  float tile = frame.surface.x, radius = frame.quadric.x;
  vec3 o = ray.origin, d = ray.direction;
  float horizontal_squared = dot(d.xy, d.xy);
  float rho = max(least_distance(vec3(o.xy, 0.0), vec3(d.xy, 0.0), t0, t1), quadric_min_distance * radius);
  float u_rate = tile / (quadric_two_pi * rho);  // du/dt per unit of speed across the meridian
  if (SURFACE == SURFACE_SPHERE) {
    // the larger rate takes all the speed it may have, the other the rest
    float v_rate = tile / (quadric_pi * max(least_distance(o, d, t0, t1), quadric_min_distance * radius));
    float most = min(horizontal_squared, 1.0);
    return u_rate > v_rate ? sqrt(u_rate * u_rate * most + v_rate * v_rate * (1.0 - most)) : v_rate;
  }
  float v_speed = SURFACE == SURFACE_CYLINDER
                      ? tile * abs(d.z) / (2.0 * radius)
                      : tile * cone_cos * (cone_sin * sqrt(horizontal_squared) + cone_cos * abs(d.z)) / radius;
  return sqrt(u_rate * u_rate * horizontal_squared + v_speed * v_speed);
}

// d(u, v)/dt at t.
vec2 quadric_uv_velocity(QuadricRay ray, float t) {
  float tile = frame.surface.x, radius = frame.quadric.x;
  vec3 q = ray.origin + t * ray.direction, d = ray.direction;
  float rho_squared = dot(q.xy, q.xy);
  float rho = sqrt(rho_squared);
  float du = rho_squared > 0.0 ? tile * (q.x * d.y - q.y * d.x) / (quadric_two_pi * rho_squared) : 0.0;
  float rho_rate = rho > 0.0 ? dot(q.xy, d.xy) / rho : length(d.xy);
  float dv;
  if (SURFACE == SURFACE_SPHERE) {
    float r_squared = dot(q, q);
    dv = r_squared > 0.0 ? tile * (rho * d.z - q.z * rho_rate) / (quadric_pi * r_squared) : 0.0;
  } else if (SURFACE == SURFACE_CYLINDER) {
    dv = tile * d.z / (2.0 * radius);
  } else {
    dv = -tile * cone_cos * (cone_sin * rho_rate - cone_cos * d.z) / radius;
  }
  return vec2(du, dv);
}

// The t where the ray's (u, v) curve, a graph over the longitude, has its inflection point
// (quadric_far when it has none). Sphere: the curve is a great circle, v = atan(k cos(u + alpha))
// in Patterson's eq. 13, which inflects only at the equator. Cylinder: z is linear in t and
// t - t_m = (b / a) tan(psi), psi the longitude from the closest approach t_m: it inflects at t_m.
// Cone: the slant is b (sin sec psi + kappa tan psi) + const, kappa = cos w' / a (a = |d_xy|, b the
// least distance from the axis); its second derivative in psi vanishes where
// sin (2 T^2 + 1) + 2 kappa T sqrt(1 + T^2) = 0, T = tan psi, which has the one root below when
// kappa^2 > sin^2.
float quadric_inflection_t(QuadricRay ray) {
  vec3 o = ray.origin, d = ray.direction;
  if (SURFACE == SURFACE_SPHERE) return abs(d.z) > 0.0 ? -o.z / d.z : quadric_far;
  float a = dot(d.xy, d.xy);
  if (a <= 0.0) return quadric_far;
  float middle = -dot(o.xy, d.xy) / a;
  if (SURFACE == SURFACE_CYLINDER) return middle;
  float speed = sqrt(a);
  float kappa = -cone_cos * d.z / speed;
  float excess = kappa * kappa - cone_sin * cone_sin;
  if (excess <= 0.0) return quadric_far;
  float tangent = (kappa > 0.0 ? -1.0 : 1.0) * sqrt(0.5 * (sqrt(kappa * kappa / excess) - 1.0));
  return middle + length(o.xy + middle * d.xy) * tangent / speed;
}

// How far (radians) every direction from the point at t0 to a point of the curve over [t0, t1]
// stays inside sector `sector`; <= 0 when it may leave it.
float quadric_sector_margin(QuadricRay ray, float t0, float t1, int sector, int sectors) {
  vec2 start = quadric_uv_velocity(ray, t0);
  vec2 end = quadric_uv_velocity(ray, t1);
  if (dot(start, start) <= 0.0 || dot(end, end) <= 0.0) return -1.0;
  float base = atan(start.y, start.x);
  if (base < 0.0) base += quadric_two_pi;
  // turns relative to the start: all tangents lie in one half-plane (the longitude is monotonic)
  float turn = atan(start.x * end.y - start.y * end.x, dot(start, end));
  float low = min(0.0, turn), high = max(0.0, turn);
  float inflection = quadric_inflection_t(ray);
  if (inflection > t0 && inflection < t1) {
    vec2 middle = quadric_uv_velocity(ray, inflection);
    if (dot(middle, middle) <= 0.0) return -1.0;
    float middle_turn = atan(start.x * middle.y - start.y * middle.x, dot(start, middle));
    low = min(low, middle_turn);
    high = max(high, middle_turn);
  }
  float width = quadric_two_pi / float(sectors);
  return min(base + low - float(sector) * width, float(sector + 1) * width - (base + high));
}

float quadric_cone_step(float ratio, float apex_gap, float slack, float descent, float speed) {
  return max((ratio * apex_gap - slack) / max(ratio * descent + speed, min_denominator), 0.0);
}

// Where cones stall, the linear fallback step moves (u, v) by a quarter texel, as on the plane: its
// world length at the worst (u, v) speed over it, computed like the cone step (never below
// quadric_min_distance R, so that the march advances on the axis).
float quadric_fallback_step(QuadricRay ray, float t, float speed) {
  float travel = quadric_fallback_texels * min(frame.map_size.z, frame.map_size.w);
  float step = travel / speed;
  step = travel / quadric_uv_speed(ray, t, min(t + step, ray.t_end));
  return max(step, quadric_min_distance * frame.quadric.x);
}

// Cone stepping along the curve: the plane's safe bilinear step (methods.inc.glsl, cone_march) with
// the descent rate and the (u, v) speed of the quadric.
QuadricMarch quadric_cone_march(QuadricRay ray, int steps, int sectors) {
  vec2 texel = frame.map_size.zw;
  float half_diagonal = 0.5 * length(texel);
  QuadricMarch m = QuadricMarch(ray.t_in, 0.0, false, ray.t_in, 0.0);
  for (int i = 0; i < steps; ++i) {
    vec3 p = quadric_point(ray, m.t);
    m.gap = p.z - fetch_height(p.xy);
    m.gap_known = true;
    if (m.gap <= cone_gap_epsilon || m.t >= ray.t_end) break;
    g_iterations += 1u;
    // the cone map of the bilinear surface (bake_bilinear_cones): from any point of the texel's
    // square, layer k holds (r_k, apex height H_c), and with n > 1 sectors layer n holds
    // (min over k of r_k, H_c); no offset slack is needed
    ivec2 texel_index = cone_texel(p.xy);
    g_fetches += 1u;
    vec2 isotropic = cone_value(ivec3(texel_index, sectors > 1 ? sectors : 0));
    float apex_gap = p.z - isotropic.y;
    float slack = 0.0;
    int sector = sectors > 1 ? cone_sector(quadric_uv_velocity(ray, m.t), sectors) : 0;
    float ratio = isotropic.x, smallest = isotropic.x;
    if (sectors > 1) {
      g_fetches += 1u;
      ratio = cone_value(ivec3(texel_index, sector)).x;
    }
    // isotropic: every direction; the speed at the start, then the worst over that step
    float descent = quadric_descent_rate(ray, m.t);
    float speed = quadric_uv_speed(ray, m.t, m.t);
    float step = quadric_cone_step(smallest, apex_gap, slack, descent, speed);
    float worst = quadric_uv_speed(ray, m.t, min(m.t + step, ray.t_end));
    if (worst > speed) step = quadric_cone_step(smallest, apex_gap, slack, descent, worst);
    // the sector's ratio beyond near_radius of the start, where the texels that bound the surface lie
    // inside the sector; within it, the isotropic bound (the ray loses at most descent * step of height)
    if (sectors > 1 && ratio > smallest) {
      float end = min(m.t + quadric_cone_step(ratio, apex_gap, slack, descent, speed), ray.t_end);
      vec3 q = ray.origin + m.t * ray.direction;
      bool near_axis = least_distance(vec3(q.xy, 0.0), vec3(ray.direction.xy, 0.0), 0.0, end - m.t) <
                       quadric_near_axis * frame.quadric.x;
      float margin = near_axis ? -1.0 : quadric_sector_margin(ray, m.t, end, sector, sectors);
      if (end > m.t + step && margin > sector_min_margin) {
        float near_radius = 3.0 * half_diagonal / sin(min(margin, 1.5707963));
        float near_clearance = apex_gap - (near_radius + slack) / smallest;
        float near_step = near_clearance <= 0.0 ? 0.0 : (descent > 0.0 ? near_clearance / descent : quadric_far);
        float far_step = quadric_cone_step(ratio, apex_gap, slack, descent, quadric_uv_speed(ray, m.t, end));
        step = max(step, min(min(far_step, near_step), end - m.t));
      }
    }
    m.t_above = m.t;
    m.gap_above = m.gap;
    m.t = min(m.t + max(step, quadric_fallback_step(ray, m.t, speed)), ray.t_end);
    m.gap_known = false;
  }
  return m;
}

// Where a cone march ended: a hit when it got within cone_gap_epsilon or crossed the surface; a ray
// that ran out of steps or reached t_end above it hits only if it is certain to.
bool quadric_cone_hit(QuadricRay ray, QuadricMarch m, out float t) {
  if (m.gap_known && m.gap <= cone_gap_epsilon) {
    // below the surface after a linear step: the crossing interpolated in its bracket
    bool crossed = m.gap < 0.0 && m.t > m.t_above;
    t = crossed ? mix(m.t_above, m.t, crossing_fraction(m.gap_above, m.gap)) : m.t;
    return true;
  }
  t = m.t;
  return ray.certain;
}

// One search step at t: at or below the surface closes the bracket (true), above it moves its top.
bool quadric_probe(QuadricRay ray, float t, inout QuadricBracket b) {
  g_iterations += 1u;
  float gap = quadric_gap(ray, t);
  if (gap <= 0.0) {
    b.t_below = t;
    b.gap_below = gap;
    return true;
  }
  b.t_above = t;
  b.gap_above = gap;
  return false;
}

// Linear search over [t_in, t_end] in `steps` equal steps of t; false for a miss.
bool quadric_linear_search(QuadricRay ray, int steps, out QuadricBracket b) {
  b.t_above = ray.t_in;
  b.gap_above = quadric_gap(ray, ray.t_in);
  b.t_below = ray.t_in;
  b.gap_below = b.gap_above;
  if (b.gap_above <= 0.0) return true;
  for (int i = 1; i <= steps; ++i) {
    float t = i == steps ? ray.t_end : mix(ray.t_in, ray.t_end, float(i) / float(steps));
    if (quadric_probe(ray, t, b)) return true;
  }
  b.t_below = ray.t_end;  // the inner surface, where no height lies below the ray
  b.gap_below = 0.0;
  return ray.certain;
}

// After a cone march: the bracket of its last point above the surface and the first point found at
// or below it, stepping on by twice the distance a flat surface would need and doubling.
bool quadric_bracket_after_cones(QuadricRay ray, QuadricMarch m, out QuadricBracket b) {
  if (!m.gap_known) m.gap = quadric_gap(ray, m.t);
  if (m.gap <= 0.0) {
    b.t_above = m.t_above;
    b.gap_above = m.gap_above;
    b.t_below = m.t;
    b.gap_below = m.gap;
    return true;
  }
  b.t_above = m.t;
  b.gap_above = m.gap;
  b.t_below = ray.t_end;
  b.gap_below = 0.0;
  float descent = quadric_descent_rate(ray, m.t);
  float step = descent > 0.0 ? bracket_first_gap_factor * m.gap / descent : ray.t_end - m.t;
  step = max(step, bracket_min_step * frame.surface.y);
  for (int i = 0; i < bracket_max_steps && b.t_above < ray.t_end; ++i) {
    float t = (i == bracket_max_steps - 1) ? ray.t_end : min(b.t_above + step, ray.t_end);
    if (quadric_probe(ray, t, b)) return true;
    step *= bracket_growth;
  }
  b.t_below = ray.t_end;
  b.gap_below = 0.0;
  return ray.certain;
}

float quadric_binary_refine(QuadricRay ray, QuadricBracket b, int refine) {
  float above = b.t_above, below = b.t_below;
  for (int i = 0; i < refine; ++i) {
    g_iterations += 1u;
    float middle = 0.5 * (above + below);
    if (quadric_gap(ray, middle) > 0.0) above = middle; else below = middle;
  }
  return 0.5 * (above + below);
}

// Interval mapping's secant refinement (methods.inc.glsl, secant_refine) along t.
float quadric_secant_refine(QuadricRay ray, QuadricBracket b, int refine) {
  for (int i = 0; i < refine && b.t_below > b.t_above; ++i) {
    g_iterations += 1u;
    float t = mix(b.t_above, b.t_below, crossing_fraction(b.gap_above, b.gap_below));
    float gap = quadric_gap(ray, t);
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

// The hit's world distance t along the ray; false for a miss. Only the methods supports_surface
// lists reach here (the renderer refuses the others).
bool quadric_trace(QuadricRay ray, out float t) {
  t = ray.t_in;
  QuadricBracket b;
  if (METHOD == METHOD_BUMP) return true;
  if (METHOD == METHOD_POM) {
    if (!quadric_linear_search(ray, frame.counts.x, b)) return false;
    t = mix(b.t_above, b.t_below, crossing_fraction(b.gap_above, b.gap_below));
    return true;
  }
  if (METHOD == METHOD_RELIEF) {
    if (!quadric_linear_search(ray, frame.counts.x, b)) return false;
    t = quadric_binary_refine(ray, b, frame.counts.y);
    return true;
  }
  if (METHOD == METHOD_INTERVAL) {
    if (!quadric_linear_search(ray, frame.counts.x, b)) return false;
    t = quadric_secant_refine(ray, b, frame.counts.y);
    return true;
  }
  if (METHOD == METHOD_CSM) return quadric_cone_hit(ray, quadric_cone_march(ray, frame.counts.x, 1), t);
  if (METHOD == METHOD_ACM4) return quadric_cone_hit(ray, quadric_cone_march(ray, frame.counts.x, 4), t);
  if (METHOD == METHOD_ACM8) return quadric_cone_hit(ray, quadric_cone_march(ray, frame.counts.x, 8), t);
  if (METHOD == METHOD_ACM4_INTERVAL) {
    if (!quadric_bracket_after_cones(ray, quadric_cone_march(ray, frame.counts.x, 4), b)) return false;
    t = quadric_secant_refine(ray, b, frame.counts.y);
    return true;
  }
  return false;
}

// Self-shadowing on the quadrics: Patterson et al. (sec. 2) fire a ray from the hit towards the light,
// project it into texture space and apply "the same procedure as before". Here the light ray's part
// in the relief shell is searched in the other direction, as the plane's light_visibility does: from
// where it leaves the outer surface (or the relief's box, beyond which there is no relief) back
// towards the hit. The search then starts on the outer surface, above the relief, where the linear
// searches' first probe and the cone steps expect a ray to start (from the hit itself the gap is 0
// and cone steps stall), and it is quadric_trace on a QuadricRay over [0, s_far] unchanged: the
// frame's steps and refinement, its fetches and iterations counted in the AOVs.
// - The reversed ray ends on the relief, at the hit, so it is `certain` to meet it by t_end, as a
//   view ray that reaches the inner surface is: a search that finds no crossing before the end
//   settles at the hit (lit), and cone steps that run out settle where they stopped (a shadow when
//   that is before the hit, as on the plane).
// - The hit is in shadow when the search stops more than the bias before it: shadow_bias_height of
//   the light ray's change of height at the hit (its rate |N . L| / D, N the base surface's normal,
//   kept above quadric_shadow_min_cosine / D so that a light tangent to the base surface has a
//   bounded bias) plus half a texel of (u, v) travel at the hit's speed: a method's own error at
//   the hit does not shadow it.
// - The inner solid (below height 0, which no height lies under) shadows without a search when the
//   light ray passes through it over more than the bias: the quadric's own shadow beyond its
//   terminator. The outer and inner solids are convex, so each is one interval of the light ray.
// - A crossing outside the finite part (v beyond [0, K]: only at the cone's edges, where the box
//   leaves a sliver of the shell outside the range) does not shadow, nor does a stretch through the
//   inner solid with both ends there.
// - The reference (the tessellated surface, whose triangles are not the bilinear surface) starts the
//   light ray on the bilinear surface at its hit's (u, v), and probes it exactly enough instead of
//   with a method: steps of at most an eighth of a texel of (u, v) travel at the worst speed over the
//   step, then bisection. Like the plane reference's walk, its reads are not counted.
const float quadric_shadow_min_cosine = 0.05;  // least |N . L| in the bias: 3 degrees off the tangent plane
const float quadric_reference_shadow_texels = 0.125;  // (u, v) travel of a reference shadow step, texels
const int quadric_reference_shadow_bisections = 24;   // bisection steps after the reference's march

// The ray-minus-surface height at t, read without counting (the reference's probe).
float quadric_reference_gap(QuadricRay ray, float t) {
  vec3 p = quadric_point(ray, t);
  return p.z - bilinear_height_of(height_map, p.xy);
}

// The reference's light probe: the first t in [t_in, t_end] at or below the bilinear surface.
bool quadric_reference_shadow_trace(QuadricRay ray, out float t) {
  t = ray.t_in;
  if (quadric_reference_gap(ray, t) <= 0.0) return true;
  float travel = quadric_reference_shadow_texels * min(frame.map_size.z, frame.map_size.w);
  // guard: the (u, v) path of a chord is at most half a turn in u and twice the range in v, and steps
  // near the axis shrink with the distance from it
  float texels = frame.surface.x * (frame.map_size.x + frame.map_size.y);
  int max_steps = int(4.0 * texels / quadric_reference_shadow_texels) + 4096;
  float above = ray.t_in;
  for (int i = 0; i < max_steps && above < ray.t_end; ++i) {
    float step = travel / quadric_uv_speed(ray, above, above);
    step = travel / quadric_uv_speed(ray, above, min(above + step, ray.t_end));
    float below = min(above + max(step, quadric_min_distance * frame.quadric.x), ray.t_end);
    if (quadric_reference_gap(ray, below) <= 0.0) {
      for (int k = 0; k < quadric_reference_shadow_bisections; ++k) {
        float middle = 0.5 * (above + below);
        if (quadric_reference_gap(ray, middle) > 0.0) above = middle; else below = middle;
      }
      t = below;
      return true;
    }
    above = below;
  }
  return false;
}

// 1 where the light reaches the relief's point `point` (world), 0 where the relief or the inner
// solid lies between it and the light. normal: the base surface's unit outward normal there.
float quadric_light_visibility(vec3 point, vec3 normal) {
  vec3 l = normalize(frame.light.xyz);
  vec3 p = point - quadric_anchor();
  vec2 outer = quadric_body_interval(p, l, 0.0);
  if (outer.x > outer.y) return 1.0;  // the point lies outside the outer solid: nothing above it
  vec3 lo, hi;
  quadric_box(lo, hi);
  float s_far = max(min(outer.y, box_exit(point, l, lo, hi)), 0.0);
  QuadricRay ray;
  ray.origin = p + s_far * l;
  ray.direction = -l;
  ray.t_in = 0.0;
  ray.t_end = s_far;
  ray.certain = true;  // it ends on the relief, at the hit
  float rate = max(abs(dot(normal, l)), quadric_shadow_min_cosine) / frame.surface.y;  // heights / world unit
  float speed = max(quadric_uv_speed(ray, s_far, s_far), 1e-30);
  float bias = shadow_bias_height / rate + 0.5 * min(frame.map_size.z, frame.map_size.w) / speed;
  if (s_far <= bias) return 1.0;
  vec2 inner = quadric_body_interval(p, l, -frame.surface.y);
  if (inner.x <= inner.y && inner.x < s_far && min(inner.y, s_far) > bias) {
    // within the finite part: one end of the light ray's stretch through it is
    vec2 ends = vec2(max(inner.x, 0.0), min(inner.y, s_far));
    bool in_range = quadric_in_range(quadric_texture_point(p + ends.x * l).y) ||
                    quadric_in_range(quadric_texture_point(p + ends.y * l).y);
    if (in_range) return 0.0;
  }
  float t;
  bool found = METHOD == METHOD_REFERENCE ? quadric_reference_shadow_trace(ray, t) : quadric_trace(ray, t);
  if (!found || t >= s_far - bias) return 1.0;
  return quadric_in_range(quadric_point(ray, t).y) ? 0.0 : 1.0;
}

// The fragment shader on a quadric: the rasterized proxy (the relief's box, or the tessellated
// relief for the reference) only supplies the pixel, whose own ray (pixel_direction) is traced. The
// reference's point is where that ray meets the fragment's triangle: its plane through the
// interpolated point, its normal from the point's screen derivatives (taken before any discard).
void quadric_fragment() {
  vec3 d = pixel_direction();
  vec3 face = METHOD == METHOD_REFERENCE ? cross(dFdx(in_world), dFdy(in_world)) : vec3(0.0);
  QuadricRay ray;
  if (!quadric_setup(d, ray)) discard;
  float t;
  vec3 hit;
  if (METHOD == METHOD_REFERENCE) {
    // the tessellated surface's own point; the range allows for its chords (half a texel of v)
    float facing = dot(d, face);
    t = abs(facing) > 1e-20 ? dot(in_world - frame.eye.xyz, face) / facing : length(in_world - frame.eye.xyz);
    hit = vec3(in_uv, in_h);
    if (!quadric_range_kept(ray, t, hit.y, 0.5 * frame.map_size.w)) discard;
  } else {
    if (!quadric_trace(ray, t)) discard;
    hit = quadric_point(ray, t);
    if (!quadric_range_kept(ray, t, hit.y, 0.0)) discard;
  }
  QuadricFrame f = quadric_frame(hit.xy, hit.z);
  mat3 tangent_frame = mat3(f.along_u, f.along_v, f.normal * frame.surface.y);
  vec3 world_hit = frame.eye.xyz + t * d;
  vec4 clip = frame.view_projection * vec4(world_hit, 1.0);
  gl_FragDepth = clamp(clip.z / clip.w, 0.0, 1.0);
  float lit = 1.0;
  if ((frame.counts.z & FLAG_SHADOWS) != 0) {
    // the reference's light ray starts on the bilinear surface at its (u, v), not on its triangle
    vec3 shadow_point = METHOD == METHOD_REFERENCE
                            ? quadric_frame(hit.xy, bilinear_height_of(height_map, hit.xy)).position
                            : world_hit;
    lit = quadric_light_visibility(shadow_point, f.normal);
  }
  out_color = vec4(shade(hit.xy, tangent_frame, d, lit), 1.0);
  out_hit = vec4(hit.xy, 1.0, t);
  out_counters = vec4(float(g_iterations), float(g_fetches), 0.0, 0.0);
}
