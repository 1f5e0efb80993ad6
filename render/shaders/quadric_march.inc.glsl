// render/shaders/quadric_march.inc.glsl - the quadrics' side of the shared root searches
// (root_search.inc.glsl): the ray as a curve (u(t), v(t), h(t)) of the world distance t
// (quadric.inc.glsl maps points to it), how fast it can fall and move in (u, v), and the safe cone
// step along it. Included by root_search.inc.glsl after its types.
//
// Cone steps. A cone map bounds heights by uv distances of the flat map. Along the curve, h falls at
// most at the rate it falls at the step's start (h(t) is convex in t: a distance to a point or an
// axis, or that minus a linear term on the cone), and (u, v) moves at most `speed` texture units per
// world unit, bounded over the whole step by the step's least distance from the axis and the centre,
// where the longitude and the polar angle turn fastest. The step is computed with the speed at its
// start, then again with the worst speed over that step, which only shortens it. The anisotropic
// sector must hold every direction from the start to a point of the step: the curve in (u, v) is a
// graph over the longitude, so by the mean value theorem those directions lie between the curve's
// tangents at the step's ends and at its inflection point when that lies inside (the equator on the
// sphere, the closest approach to the axis on the cylinder, a closed form on the cone). Near the
// start, the isotropic bound applies as on the plane. Where cones stall, the march takes a linear
// step of a quarter texel of (u, v) travel, which may cross the surface.

// numerical guards
const float quadric_near_axis = 1e-4;  // fraction of R: a step this close to the axis reads no sector
const float quadric_min_distance = 1e-6;  // fraction of R: least distance used in the speed bound
const float sector_min_margin = 1e-4;  // radians: a smaller margin to the sector's edges reads no sector
const float quadric_fallback_texels = 0.25;  // (u, v) travel of a linear step where cones stall, texels

vec3 quadric_point(SearchRay ray, float t) { return quadric_texture_point(ray.origin + t * ray.direction); }

// The most height (in [0, 1] units) the ray can lose per world unit from t on: h(t) is convex.
float quadric_descent_rate(SearchRay ray, float t) {
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
float quadric_uv_speed(SearchRay ray, float t0, float t1) {
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
vec2 quadric_uv_velocity(SearchRay ray, float t) {
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
float quadric_inflection_t(SearchRay ray) {
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
float quadric_sector_margin(SearchRay ray, float t0, float t1, int sector, int sectors) {
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
float quadric_fallback_step(SearchRay ray, float t, float speed) {
  float travel = quadric_fallback_texels * min(frame.map_size.z, frame.map_size.w);
  float step = travel / speed;
  step = travel / quadric_uv_speed(ray, t, min(t + step, ray.t_end));
  return max(step, quadric_min_distance * frame.quadric.x);
}

// The safe cone step from t along the curve: the plane's safe bilinear step (methods.inc.glsl,
// plane_safe_cone_step) with the descent rate and the (u, v) speed of the quadric; `stall`, the
// linear fallback step, where cones stall.
float quadric_safe_cone_step(SearchRay ray, float t, int sectors, out float stall) {
  vec2 texel = frame.map_size.zw;
  float half_diagonal = 0.5 * length(texel);
  vec3 p = quadric_point(ray, t);
  // the cone map of the bilinear surface (bake_bilinear_cones): from any point of the texel's
  // square, layer k holds (r_k, apex height H_c), and with n > 1 sectors layer n holds
  // (min over k of r_k, H_c); no offset slack is needed
  ivec2 texel_index = cone_texel(p.xy);
  g_fetches += 1u;
  vec2 isotropic = cone_value(ivec3(texel_index, sectors > 1 ? sectors : 0));
  float apex_gap = p.z - isotropic.y;
  float slack = 0.0;
  int sector = sectors > 1 ? cone_sector(quadric_uv_velocity(ray, t), sectors) : 0;
  float ratio = isotropic.x, smallest = isotropic.x;
  if (sectors > 1) {
    g_fetches += 1u;
    ratio = cone_value(ivec3(texel_index, sector)).x;
  }
  // isotropic: every direction; the speed at the start, then the worst over that step
  float descent = quadric_descent_rate(ray, t);
  float speed = quadric_uv_speed(ray, t, t);
  float step = quadric_cone_step(smallest, apex_gap, slack, descent, speed);
  float worst = quadric_uv_speed(ray, t, min(t + step, ray.t_end));
  if (worst > speed) step = quadric_cone_step(smallest, apex_gap, slack, descent, worst);
  // the sector's ratio beyond near_radius of the start, where the texels that bound the surface lie
  // inside the sector; within it, the isotropic bound (the ray loses at most descent * step of height)
  if (sectors > 1 && ratio > smallest) {
    float end = min(t + quadric_cone_step(ratio, apex_gap, slack, descent, speed), ray.t_end);
    vec3 q = ray.origin + t * ray.direction;
    bool near_axis = least_distance(vec3(q.xy, 0.0), vec3(ray.direction.xy, 0.0), 0.0, end - t) <
                     quadric_near_axis * frame.quadric.x;
    float margin = near_axis ? -1.0 : quadric_sector_margin(ray, t, end, sector, sectors);
    if (end > t + step && margin > sector_min_margin) {
      float near_radius = 3.0 * half_diagonal / sin(min(margin, 1.5707963));
      float near_clearance = apex_gap - (near_radius + slack) / smallest;
      float near_step = near_clearance <= 0.0 ? 0.0 : (descent > 0.0 ? near_clearance / descent : quadric_far);
      float far_step = quadric_cone_step(ratio, apex_gap, slack, descent, quadric_uv_speed(ray, t, end));
      step = max(step, min(min(far_step, near_step), end - t));
    }
  }
  stall = quadric_fallback_step(ray, t, speed);
  return step;
}
