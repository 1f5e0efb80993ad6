// render/shaders/relaxed_march.inc.glsl - relaxed cone stepping (Policarpo & Oliveira, "Relaxed Cone
// Stepping for Relief Mapping", GPU Gems 3 ch. 18), made exact on the bilinear surface. Included by
// methods.inc.glsl after root_search.inc.glsl (it uses cone_sector, cone_texel, cell_at and cell_step).
//
// The one fact: a relaxed cone only promises that a ray through its texel centre's apex crosses the
// relief at most once inside it. Rays sample the BILINEAR surface from arbitrary points, so a relaxed
// step can enter and leave a thin brick edge and land above the surface (published, the method
// plateaued at rmse 2.88 on the built-in bricks). Here a relaxed step is only a candidate, accepted
// when the conservative bilinear cones (bake::bake_bilinear_cones, RELAXED_CONE_SECTORS sectors, read
// from both ends of the step) prove the whole step above the surface; a candidate that lands below
// brackets the first crossing, which the conservative march then finds exactly.
//
// Proof. bake_bilinear_cones guarantees, for texel c with apex H_c and sector ratio r_k: from ANY
// point p of c's square Q_c, every surface point x whose horizontal direction from p lies in sector k
// has s(x) <= H_c + |x - p| / r_k. The ray is p(s) = origin + s * descent, descent.z = -1, L =
// |descent.xy|. Let p_a = p(s_a) be known above the surface and p_b = p(s_b), s_b > s_a, the
// candidate, with z_a, z_b their heights.
// - Forward from p_a (its texel's cone, sector k of descent.xy): p(s_a + t) is above the surface
//   under it, x = p_a.xy + t descent.xy, |x - p_a| = t L, whenever z_a - t > H_a + t L / r_k, i.e.
//   for t < s_c = r_k (z_a - H_a) / (r_k + L) (the conservative step of cone_march).
// - Backward from p_b (its texel's cone, sector k' of the OPPOSITE direction -descent.xy): the ray
//   point p(s_b - t) lies over x = p_b.xy - t descent.xy, whose direction from p_b is in sector k'
//   and |x - p_b| = t L; it is above the surface whenever z_b + t > H_b + t L / r_k'. With
//   z_b > H_b that holds for every t >= 0 when L <= r_k', and for t < t_b = (z_b - H_b) r_k' /
//   (L - r_k') when L > r_k'; with z_b <= H_b the cone proves nothing (t_b = 0).
// So if s_a + s_c >= s_b - t_b, every point of [s_a, s_b] is above the surface (the point where the
// two ranges meet is at worst on it, as a cone step's end is) and the first crossing lies beyond
// s_b: moving to p_b skips nothing. Otherwise the march takes the conservative step s_c from p_a,
// or an exact cell step where s_c is under fallback_step_texels of travel (as cone_march does), and
// keeps the candidate as a verified tail: [s_b - t_b, s_b] is above the surface, so once these
// steps reach s_b - t_b (every point before them proven above) the march moves on to p_b.
// When p_b is below the surface, the first crossing lies in [s_a, s_b], possibly among several:
// from there the march is cone_march's conservative steps and exact cell steps, bounded by s_b, so
// it ends on the first crossing or, with the steps run out, on a point above it. The binary search
// of the published method could land on a later crossing of the bracket, so --refine is unused.
//
// Fetches (each counted): a relaxed step reads the relaxed ratio at p_a and the backward cone at
// p_b, whose apex H_b tells whether p_b is above the surface (the height at p_b is read only when
// z_b <= H_b; above, z_b - H_b is the gap the next relaxed step uses, a lower bound, and the height
// is read when that bound gives no relaxed step); a step that is not accepted at once reads the
// forward cone at p_a; a conservative step reads the forward cone, a cell step it and one gather,
// and the height at its end is read before the next relaxed step.

// Layer of the relaxed ratios: after the sector layers and their minimum (render/renderer.cpp).
const int relaxed_ratio_layer = RELAXED_CONE_SECTORS + 1;

// (ratio, apex height) of the cone map texel holding uv, in `layer`: one counted fetch.
vec2 fetch_cone_texel(vec2 uv, int layer) {
  g_fetches += 1u;
  return cone_value(ivec3(cone_texel(uv), layer));
}

// How far back along the ray (in s) from p the bilinear cone (ratio, apex) read at p in the
// direction -descent.xy proves the ray above the surface; 2 (more than any ray's length) when the
// ray climbs more slowly than the cone.
float backward_safe_length(vec3 p, vec2 cone, float travel) {
  float above = p.z - cone.y;
  if (above <= 0.0) return 0.0;
  if (travel <= cone.x) return 2.0;
  return above * cone.x / (travel - cone.x);
}

float relaxed_march(vec3 origin, vec3 descent, int steps) {
  float travel = length(descent.xy);
  vec2 texel = frame.map_size.zw;
  int sector = cone_sector(descent.xy, RELAXED_CONE_SECTORS);
  int back_sector = cone_sector(-descent.xy, RELAXED_CONE_SECTORS);
  float fallback = travel > 0.0 ? fallback_step_texels * min(texel.x, texel.y) / travel : 1.0;
  float s = 0.0;  // the last point known above the surface
  float gap = origin.z - fetch_height(origin.xy);  // the ray's height above the surface at s
  bool gap_known = true;
  bool gap_exact = true;  // gap is the height above the surface, not a lower bound of it
  if (gap <= 0.0) return 0.0;
  float end = 1.0;         // the first crossing lies in [s, end]
  bool bracketed = false;  // a relaxed candidate landed below the surface at `end`
  bool walking = false;    // the last step was a cell step: `cell` is the cell the ray entered
  ivec2 cell = ivec2(0);
  // a verified tail: a relaxed candidate whose end is proven above over [pending_from, pending]
  // (backward cone), reached as soon as the march from s gets to pending_from
  float pending = 0.0, pending_from = 0.0, pending_gap = 0.0;
  bool pending_exact = false;
  for (int i = 0; i < steps && s < end; ++i) {
    g_iterations += 1u;
    vec3 p = origin + s * descent;
    // relaxed candidate (a ratio is at most 1, so a gap under fallback * (1 + L) cannot give a
    // step of fallback or more: no ratio read then)
    bool relax = !bracketed && pending <= s;
    if (relax && (!gap_known || (!gap_exact && gap < fallback * (1.0 + travel)))) {
      gap = max(p.z - fetch_height(p.xy), 0.0);
      gap_known = true;
      gap_exact = true;
    }
    if (relax && gap >= fallback * (1.0 + travel)) {
      float ratio = fetch_cone_texel(p.xy, relaxed_ratio_layer).x;
      float step = ratio * gap / max(ratio + travel, min_denominator);
      if (step >= fallback) {
        float candidate = min(s + step, 1.0);
        vec3 q = origin + candidate * descent;
        // backward from the candidate; above its texel's apex the candidate is above the surface,
        // by at least its height over the apex
        vec2 back = fetch_cone_texel(q.xy, back_sector);
        float covered_from = candidate;
        float candidate_gap = q.z - back.y;
        bool candidate_exact = false;
        if (candidate_gap > 0.0) {
          covered_from = candidate - backward_safe_length(q, back, travel);
        } else {
          candidate_gap = q.z - fetch_height(q.xy);
          candidate_exact = true;
        }
        if (candidate_gap <= 0.0) {
          bracketed = true;
          end = candidate;
        } else if (covered_from <= s) {
          s = candidate;
          gap = candidate_gap;
          gap_exact = candidate_exact;
          walking = false;
          continue;
        } else {
          pending = candidate;
          pending_from = covered_from;
          pending_gap = candidate_gap;
          pending_exact = candidate_exact;
        }
      }
    }
    // forward from p: the conservative step, or an exact cell step; either may reach the tail
    vec2 cone = fetch_cone_texel(p.xy, sector);
    float safe = max(cone.x * (p.z - cone.y) / max(cone.x + travel, min_denominator), 0.0);
    bool stepped = safe >= fallback;
    if (stepped) {
      s = min(s + safe, end);
      gap_known = false;
      walking = false;
    } else {
      if (!walking) cell = cell_at(origin, descent, s);
      walking = true;
      bool exact = false;
      float exit_gap = 0.0;
      float next = cell_step(origin, descent, s, cell, exact, exit_gap);
      if (exact) return next;
      s = min(next, end);
      gap = max(exit_gap, 0.0);
      gap_known = true;
      gap_exact = true;
    }
    if (pending > s && s >= pending_from) {
      s = pending;
      gap = pending_gap;
      gap_known = true;
      gap_exact = pending_exact;
      walking = false;
    }
  }
  return min(s, end);
}
