// render/shaders/quadric.inc.glsl - the quadric surfaces of inverse displacement mapping (Patterson,
// Hoggar & Logie, "Inverse Displacement Mapping", 1991): their parameterisations, the relief shell
// between the outer and the inner bounding surface, and ray / bounding-surface intersections.
// Geometry only (no texture reads), so the vertex shaders include it too; the including shader
// declares `frame` and the SURFACE specialization constant.
//
// Geometry (normative; render/render.h and docs/design/conventions.md say the same). R = frame.quadric.x,
// D = depth scale, K = tile. Every axis is the vertical line x = y = 0.5; phi = atan2(y - 0.5,
// x - 0.5) in [0, 2 pi) and u = K phi / (2 pi) on all three.
// - sphere: centre (0.5, 0.5, 0); v = K theta / pi, theta the angle from the -z pole (v = 0 at the
//   south pole, K at the north pole).
// - cylinder: radius R, z in [-R, R]; v = K (z + R) / (2 R).
// - cone: apex (0.5, 0.5, 1.5 R), half-angle atan(1/2): radius (1.5 R - z) / 2, from z = -R/2
//   (radius R) up to z = R/2 (radius R/2); v = K (z + R/2) / R of the foot point on the outer cone.
// The outer surface is height 1 (the base surface, like the plane's polygon); a point at height h
// lies (1 - h) D inward along the outer surface's normal from its foot point (u, v). So the inner
// surface (height 0) is a sphere or cylinder of radius R - D, or the same cone with its apex D / sin
// lower (Patterson sec. 3: the bounding volumes are scaled or translated versions of the surface).
// (dP/du, dP/dv, N) is right-handed with N outward, as (x, y, z) is on the plane, so v grows with z.

const float quadric_pi = 3.14159265358979;
const float quadric_two_pi = 6.28318530717959;
const float quadric_far = 1e30;  // world units: "no end" of a ray interval
const float cone_sin = 0.447213595499958;  // sin of the cone's half-angle, 1 / sqrt(1 + 1 / CONE_SLOPE^2)
const float cone_cos = 0.894427190999916;

// The point the quadric's local frame is centred on: the centre (sphere, cylinder) or the apex (cone).
vec3 quadric_anchor() {
  return vec3(QUADRIC_AXIS_X, QUADRIC_AXIS_Y, SURFACE == SURFACE_CONE ? CONE_APEX_HEIGHT * frame.quadric.x : 0.0);
}

// The world box that holds the whole relief of the finite quadric (and so its outer surface).
void quadric_box(out vec3 lo, out vec3 hi) {
  float radius = frame.quadric.x;
  lo = vec3(QUADRIC_AXIS_X - radius, QUADRIC_AXIS_Y - radius, -radius);
  hi = vec3(QUADRIC_AXIS_X + radius, QUADRIC_AXIS_Y + radius, radius);
  if (SURFACE == SURFACE_CONE) {
    lo.z = -0.5 * radius - cone_sin * frame.surface.y;  // the bottom edge's relief reaches below z = -R/2
    hi.z = 0.5 * radius;
  }
}

// Texture point (u, v, h) of a point q given relative to quadric_anchor(). u in [0, K].
vec3 quadric_texture_point(vec3 q) {
  float tile = frame.surface.x, depth = frame.surface.y, radius = frame.quadric.x;
  float rho = length(q.xy);
  float u = 0.0;  // on the axis, where the longitude is undefined
  if (rho > 0.0) {
    float phi = atan(q.y, q.x);
    u = tile * (phi < 0.0 ? phi + quadric_two_pi : phi) / quadric_two_pi;
  }
  if (SURFACE == SURFACE_SPHERE) {
    float polar = (rho > 0.0 || q.z != 0.0) ? atan(rho, -q.z) : 0.0;
    return vec3(u, tile * polar / quadric_pi, (length(q) - radius) / depth + 1.0);
  }
  if (SURFACE == SURFACE_CYLINDER) return vec3(u, tile * (q.z + radius) / (2.0 * radius), (rho - radius) / depth + 1.0);
  float below_apex = -q.z;
  float slant = cone_sin * rho + cone_cos * below_apex;     // the foot point's distance from the apex
  float distance = cone_cos * rho - cone_sin * below_apex;  // signed distance from the outer cone
  return vec3(u, tile * (2.0 * radius - cone_cos * slant) / radius, distance / depth + 1.0);
}

// The world point at texture point (u, v, h) and the frame shading needs there: dP/du and dP/dv at
// that height and the unit outward normal.
struct QuadricFrame {
  vec3 position;
  vec3 along_u;
  vec3 along_v;
  vec3 normal;
};

const float min_polar_sine = 1e-4;  // dP/du keeps this much length at the sphere's poles (unitless)

QuadricFrame quadric_frame(vec2 uv, float h) {
  float tile = frame.surface.x, depth = frame.surface.y, radius = frame.quadric.x;
  float phi = quadric_two_pi * uv.x / tile;
  vec2 radial = vec2(cos(phi), sin(phi));
  vec3 east = vec3(-radial.y, radial.x, 0.0);
  float inset = (1.0 - h) * depth;
  QuadricFrame f;
  if (SURFACE == SURFACE_SPHERE) {
    float polar = quadric_pi * uv.y / tile;
    float s = sin(polar), c = cos(polar);
    float r = radius - inset;
    f.normal = vec3(s * radial, -c);
    f.position = quadric_anchor() + r * f.normal;
    f.along_u = (quadric_two_pi / tile) * r * max(s, min_polar_sine) * east;
    f.along_v = (quadric_pi / tile) * r * vec3(c * radial, s);
  } else if (SURFACE == SURFACE_CYLINDER) {
    float rho = radius - inset;
    f.normal = vec3(radial, 0.0);
    f.position = quadric_anchor() + vec3(rho * radial, 2.0 * radius * uv.y / tile - radius);
    f.along_u = (quadric_two_pi / tile) * rho * east;
    f.along_v = vec3(0.0, 0.0, 2.0 * radius / tile);
  } else {
    float slant = (2.0 * radius - radius * uv.y / tile) / cone_cos;
    vec3 generator = vec3(cone_sin * radial, -cone_cos);  // from the apex down the cone
    f.normal = vec3(cone_cos * radial, cone_sin);
    f.position = quadric_anchor() + slant * generator - inset * f.normal;
    f.along_u = (quadric_two_pi / tile) * (slant * cone_sin - inset * cone_cos) * east;
    f.along_v = -(radius / (tile * cone_cos)) * generator;
  }
  return f;
}

// The interval of t where o + t d (d unit, o relative to the anchor) lies inside the solid bounded
// by the surface at `offset` along the normal from the outer one (0: outer, -D: inner). Empty when
// x > y; +-quadric_far for an end the ray never reaches. Each solid is convex, so a ray is inside
// it over one interval.
vec2 quadric_body_interval(vec3 o, vec3 d, float offset) {
  const vec2 empty = vec2(quadric_far, -quadric_far);
  float radius = frame.quadric.x;
  // shift the origin to the ray's point nearest the anchor: smaller terms, less cancellation
  float shift = -dot(o, d);
  o += shift * d;
  if (SURFACE == SURFACE_SPHERE) {
    float r = radius + offset;
    float disc = r * r - dot(o, o);
    if (disc < 0.0) return empty;
    float half_chord = sqrt(disc);
    return vec2(shift - half_chord, shift + half_chord);
  }
  float a = dot(d.xy, d.xy);
  if (SURFACE == SURFACE_CYLINDER) {
    float r = radius + offset;
    if (a < 1e-12) return dot(o.xy, o.xy) <= r * r ? vec2(-quadric_far, quadric_far) : empty;  // along the axis
    float middle = -dot(o.xy, d.xy) / a;
    vec2 nearest = o.xy + middle * d.xy;
    float disc = r * r - dot(nearest, nearest);
    if (disc < 0.0) return empty;
    float half_chord = sqrt(disc / a);
    return vec2(shift + middle - half_chord, shift + middle + half_chord);
  }
  // cone: f(t) = cos * rho(t) - sin * w(t) - offset <= 0, w = -z the depth below the apex. f is
  // convex; its zeros are the roots of cos^2 rho^2 = (sin w + offset)^2 where sin w + offset >= 0
  // (the other roots lie on the mirrored nappe).
  float w0 = -o.z, w1 = -d.z;
  float e0 = cone_sin * w0 + offset, e1 = cone_sin * w1;
  float qa = cone_cos * cone_cos * a - e1 * e1;
  float qb = cone_cos * cone_cos * dot(o.xy, d.xy) - e0 * e1;
  float qc = cone_cos * cone_cos * dot(o.xy, o.xy) - e0 * e0;
  float disc = qb * qb - qa * qc;
  if (disc < 0.0) return empty;
  float root_a = quadric_far, root_b = quadric_far;
  bool have_a = false, have_b = false;
  float q = -(qb + (qb < 0.0 ? -1.0 : 1.0) * sqrt(disc));  // the stable quadratic formula
  if (abs(qa) > 1e-12 * max(abs(qb), 1e-30)) {
    root_a = q / qa;
    have_a = true;
  }
  if (abs(q) > 1e-30) {
    root_b = qc / q;
    have_b = true;
  }
  have_a = have_a && e0 + e1 * root_a >= 0.0;
  have_b = have_b && e0 + e1 * root_b >= 0.0;
  if (have_a && have_b) return vec2(shift + min(root_a, root_b), shift + max(root_a, root_b));
  if (!have_a && !have_b) return empty;  // a line cannot stay inside a cone: it never enters
  float root = have_a ? root_a : root_b;
  vec2 horizontal = o.xy + root * d.xy;
  float rho = length(horizontal);
  float rho_rate = rho > 0.0 ? dot(horizontal, d.xy) / rho : sqrt(a);
  bool entering = cone_cos * rho_rate - cone_sin * w1 < 0.0;
  return entering ? vec2(shift + root, quadric_far) : vec2(-quadric_far, shift + root);
}

// Where the ray e + t d leaves the world box [lo, hi] (slab test; quadric_far when it stays inside).
float box_exit(vec3 e, vec3 d, vec3 lo, vec3 hi) {
  float exit = quadric_far;
  for (int axis = 0; axis < 3; ++axis) {
    if (abs(d[axis]) < 1e-12) continue;  // parallel to this slab: it never leaves through it
    exit = min(exit, ((d[axis] > 0.0 ? hi[axis] : lo[axis]) - e[axis]) / d[axis]);
  }
  return exit;
}

// The cone's slant distance of the foot point is convex along a ray: the t where it is smallest
// (quadric_far when it only decreases, -quadric_far when it only grows).
float cone_least_slant_t(vec3 o, vec3 d) {
  float a = dot(d.xy, d.xy);
  float k = cone_cos * d.z / cone_sin;  // the rate of rho at which the slant's rate is 0: sin rho' = cos z'
  if (a <= k * k) return d.z > 0.0 ? quadric_far : -quadric_far;  // the slant only falls (rising ray) or only grows
  float middle = -dot(o.xy, d.xy) / a;
  vec2 nearest = o.xy + middle * d.xy;
  // rho(t)^2 = |nearest|^2 + a (t - middle)^2, so rho' = a tau / rho = k at tau = k |nearest| / sqrt(a (a - k^2))
  return middle + k * length(nearest) / sqrt(a * (a - k * k));
}
