// render/shaders/quadric_trace.inc.glsl - the per-pixel methods on the quadrics, after Patterson,
// Hoggar & Logie, "Inverse Displacement Mapping" (1991): intersect the view ray analytically with the
// outer and the inner bounding surface, then trace between them in parameter space, where the ray
// is a curve (u(t), v(t), h(t)) of the world distance t (quadric.inc.glsl maps points to it).
// Included by surface.frag.glsl after methods.inc.glsl, shading.inc.glsl and the plane's shadow
// block; it shares their counted fetch_height, crossing_fraction, tuning constants, shade() and
// shadow_bias_height, and searches with the root searches every surface shares
// (root_search.inc.glsl, with the quadrics' bounds of quadric_march.inc.glsl). quadric_fragment() is
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
// - Cone steps follow the curve with bounds on its descent and its (u, v) speed
//   (quadric_march.inc.glsl); where they stall, linear steps.
// - Misses: csm and acm stop when they are within cone_gap_epsilon, cross the surface, or reach
//   t_end; a ray that runs out of steps settles where it stopped (as on the plane) if it is certain
//   to hit, and is a miss otherwise.

bool quadric_in_range(float v) { return SURFACE == SURFACE_SPHERE || (v >= 0.0 && v <= frame.surface.x); }

// The ray's span in the relief shell; false when it does not enter the outer surface's finite part.
bool quadric_setup(vec3 d, out SearchRay ray) {
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
bool quadric_range_kept(SearchRay ray, float t, float v_end, float tolerance) {
  if (SURFACE == SURFACE_SPHERE) return true;
  float tile = frame.surface.x;
  if (v_end < -tolerance || v_end > tile + tolerance) return false;
  if (SURFACE == SURFACE_CYLINDER) return true;  // v follows z, monotonic along a ray
  float least = cone_least_slant_t(ray.origin, ray.direction);  // where v is largest
  if (least <= ray.t_in || least >= t) return true;
  return quadric_point(ray, least).y <= tile + tolerance;
}

// The hit's world distance t along the ray; false for a miss. Only the methods supports_surface
// lists reach here (the renderer refuses the others).
bool quadric_trace(SearchRay ray, out float t) {
  t = ray.t_in;
  if (METHOD == METHOD_BUMP) return true;
  return root_search(ray, t);
}

// Self-shadowing on the quadrics: Patterson et al. (sec. 2) fire a ray from the hit towards the light,
// project it into texture space and apply "the same procedure as before". Here the light ray's part
// in the relief shell is searched in the other direction, as the plane's light_visibility does: from
// where it leaves the outer surface (or the relief's box, beyond which there is no relief) back
// towards the hit. The search then starts on the outer surface, above the relief, where the linear
// searches' first probe and the cone steps expect a ray to start (from the hit itself the gap is 0
// and cone steps stall), and it is quadric_trace on a SearchRay over [0, s_far] unchanged: the
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
float quadric_reference_gap(SearchRay ray, float t) {
  vec3 p = quadric_point(ray, t);
  return p.z - bilinear_height_of(height_map, p.xy);
}

// The reference's light probe: the first t in [t_in, t_end] at or below the bilinear surface.
bool quadric_reference_shadow_trace(SearchRay ray, out float t) {
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
  SearchRay ray;
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
  SearchRay ray;
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
  if (shadows_on()) {
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
