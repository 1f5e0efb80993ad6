// render/quadric.cpp - the quadric surfaces' geometry on the CPU (Patterson, Hoggar & Logie, "Inverse
// Displacement Mapping", 1991, sec. 3: the bounding volumes of a sphere, cylinder or cone are scaled or
// translated versions of the surface, so every bound is one quadratic). Mirrors
// render/shaders/quadric.inc.glsl in double precision.
#include "render/quadric.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>

#include "render/shaders/config.h"

namespace displace::render::quadric {
namespace {

const double cone_sin = 1.0 / std::sqrt(1.0 + 1.0 / (CONE_SLOPE * CONE_SLOPE));
const double cone_cos = cone_sin / CONE_SLOPE;

}  // namespace

Shape shape_of(const View& view) { return {view.surface, view.radius, view.depth_scale, double(view.tile)}; }

void validate(const View& view) {
  const char* name = surface_name(view.surface);
  if (!(view.radius >= min_radius && view.radius <= max_radius)) {
    char message[128];
    std::snprintf(message, sizeof message,
                  "View::radius must be between %g and %g world units on View::surface %s",
                  double(min_radius), double(max_radius), name);
    throw RenderError(message);
  }
  if (!(view.depth_scale <= max_depth_per_radius * view.radius)) {
    throw RenderError(std::string("View::depth_scale must be at most half View::radius on View::surface ") +
                      name + " (the inner surface keeps R - D >= R / 2)");
  }
  const Shape shape = shape_of(view);
  glm::dvec3 lo, hi;
  relief_box(shape, lo, hi);
  const glm::dvec3 eye(view.camera.eye);
  const bool in_box = glm::all(glm::greaterThanEqual(eye, lo)) && glm::all(glm::lessThanEqual(eye, hi));
  if (in_box && texture_point(shape, eye - anchor(shape)).z <= 1.0) {
    char radius[32];
    std::snprintf(radius, sizeof radius, "%g", double(view.radius));
    throw RenderError(std::string("Camera::eye must be outside the ") + name +
                      " (its outer surface, radius " + radius + ")");
  }
}

glm::dvec3 anchor(const Shape& shape) {
  return {QUADRIC_AXIS_X, QUADRIC_AXIS_Y,
          shape.surface == Surface::cone ? CONE_APEX_HEIGHT * shape.radius : 0.0};
}

void relief_box(const Shape& shape, glm::dvec3& lo, glm::dvec3& hi) {
  const double r = shape.radius;
  lo = {QUADRIC_AXIS_X - r, QUADRIC_AXIS_Y - r, -r};
  hi = {QUADRIC_AXIS_X + r, QUADRIC_AXIS_Y + r, r};
  if (shape.surface == Surface::cone) {
    lo.z = -0.5 * r - cone_sin * shape.depth;  // the bottom edge's relief reaches below z = -R/2
    hi.z = 0.5 * r;
  }
}

glm::dvec3 texture_point(const Shape& shape, const glm::dvec3& q) {
  const double tile = shape.tile, r = shape.radius, depth = shape.depth;
  const double rho = std::hypot(q.x, q.y);
  double u = 0.0;
  if (rho > 0.0) {
    double phi = std::atan2(q.y, q.x);
    if (phi < 0.0) phi += 2.0 * std::numbers::pi;
    u = tile * phi / (2.0 * std::numbers::pi);
  }
  switch (shape.surface) {
    case Surface::sphere: {
      const double polar = (rho > 0.0 || q.z != 0.0) ? std::atan2(rho, -q.z) : 0.0;
      return {u, tile * polar / std::numbers::pi, (glm::length(q) - r) / depth + 1.0};
    }
    case Surface::cylinder: return {u, tile * (q.z + r) / (2.0 * r), (rho - r) / depth + 1.0};
    case Surface::cone: {
      const double below_apex = -q.z;
      const double slant = cone_sin * rho + cone_cos * below_apex;
      const double distance = cone_cos * rho - cone_sin * below_apex;
      return {u, tile * (2.0 * r - cone_cos * slant) / r, distance / depth + 1.0};
    }
    case Surface::plane:
    case Surface::mesh: break;
  }
  throw std::logic_error("quadric::texture_point on a surface that is not a quadric");
}

glm::dvec3 surface_point(const Shape& shape, double u, double v, double h) {
  const double tile = shape.tile, r = shape.radius, inset = (1.0 - h) * shape.depth;
  const double phi = 2.0 * std::numbers::pi * u / tile;
  const glm::dvec2 radial(std::cos(phi), std::sin(phi));
  switch (shape.surface) {
    case Surface::sphere: {
      const double polar = std::numbers::pi * v / tile;
      return anchor(shape) + (r - inset) * glm::dvec3(std::sin(polar) * radial, -std::cos(polar));
    }
    case Surface::cylinder: return anchor(shape) + glm::dvec3((r - inset) * radial, 2.0 * r * v / tile - r);
    case Surface::cone: {
      const double slant = (2.0 * r - r * v / tile) / cone_cos;
      return anchor(shape) + slant * glm::dvec3(cone_sin * radial, -cone_cos) -
             inset * glm::dvec3(cone_cos * radial, cone_sin);
    }
    case Surface::plane:
    case Surface::mesh: break;
  }
  throw std::logic_error("quadric::surface_point on a surface that is not a quadric");
}

Interval body_interval(const Shape& shape, const glm::dvec3& origin, const glm::dvec3& d, double offset) {
  const Interval empty{far, -far};
  const double shift = -glm::dot(origin, d);
  const glm::dvec3 o = origin + shift * d;
  const double a = d.x * d.x + d.y * d.y;
  const double oh_dh = o.x * d.x + o.y * d.y, oh_oh = o.x * o.x + o.y * o.y;
  if (shape.surface == Surface::sphere) {
    const double r = shape.radius + offset, disc = r * r - glm::dot(o, o);
    if (disc < 0.0) return empty;
    return {shift - std::sqrt(disc), shift + std::sqrt(disc)};
  }
  if (shape.surface == Surface::cylinder) {
    const double r = shape.radius + offset;
    if (a < 1e-24) return oh_oh <= r * r ? Interval{-far, far} : empty;
    const double middle = -oh_dh / a;
    const double nx = o.x + middle * d.x, ny = o.y + middle * d.y;
    const double disc = r * r - (nx * nx + ny * ny);
    if (disc < 0.0) return empty;
    const double half = std::sqrt(disc / a);
    return {shift + middle - half, shift + middle + half};
  }
  // cone: cos rho - sin w - offset <= 0 (w = -z), convex along a line; its zeros are the roots of
  // cos^2 rho^2 = (sin w + offset)^2 with sin w + offset >= 0
  const double w0 = -o.z, w1 = -d.z;
  const double e0 = cone_sin * w0 + offset, e1 = cone_sin * w1;
  const double qa = cone_cos * cone_cos * a - e1 * e1;
  const double qb = cone_cos * cone_cos * oh_dh - e0 * e1;
  const double qc = cone_cos * cone_cos * oh_oh - e0 * e0;
  const double disc = qb * qb - qa * qc;
  if (disc < 0.0) return empty;
  const double q = -(qb + std::copysign(std::sqrt(disc), qb));
  double roots[2];
  int count = 0;
  if (std::abs(qa) > 1e-15 * std::max(std::abs(qb), 1e-300)) roots[count++] = q / qa;
  if (std::abs(q) > 1e-300) roots[count++] = qc / q;
  int valid = 0;
  double kept[2];
  for (int i = 0; i < count; ++i) {
    if (e0 + e1 * roots[i] >= 0.0) kept[valid++] = roots[i];
  }
  if (valid == 2) return {shift + std::min(kept[0], kept[1]), shift + std::max(kept[0], kept[1])};
  if (valid == 0) return empty;  // a line cannot stay inside a cone, so it never enters
  const double root = kept[0];
  const double hx = o.x + root * d.x, hy = o.y + root * d.y, rho = std::hypot(hx, hy);
  const double rho_rate = rho > 0.0 ? (hx * d.x + hy * d.y) / rho : std::sqrt(a);
  const bool entering = cone_cos * rho_rate - cone_sin * w1 < 0.0;
  return entering ? Interval{shift + root, far} : Interval{-far, shift + root};
}

double box_exit(const glm::dvec3& e, const glm::dvec3& d, const glm::dvec3& lo, const glm::dvec3& hi) {
  double exit = far;
  for (int axis = 0; axis < 3; ++axis) {
    if (std::abs(d[axis]) < 1e-300) continue;
    exit = std::min(exit, ((d[axis] > 0.0 ? hi[axis] : lo[axis]) - e[axis]) / d[axis]);
  }
  return exit;
}

bool range_kept(const Shape& shape, const glm::dvec3& o, const glm::dvec3& d, double t_in, double t) {
  if (shape.surface == Surface::sphere) return true;
  auto in_range = [&](double at) {
    const double v = texture_point(shape, o + at * d).y;
    return v >= 0.0 && v <= shape.tile;
  };
  if (!in_range(t_in) || !in_range(t)) return false;
  if (shape.surface == Surface::cylinder) return true;
  // the slant is smallest (v largest) where sin rho' = cos z'
  const double a = d.x * d.x + d.y * d.y, k = cone_cos * d.z / cone_sin;
  if (a <= k * k) return true;  // monotonic: the ends hold the extremes
  const double middle = -(o.x * d.x + o.y * d.y) / a;
  const double nearest = std::hypot(o.x + middle * d.x, o.y + middle * d.y);
  const double least = middle + k * nearest / std::sqrt(a * (a - k * k));
  return least <= t_in || least >= t || in_range(least);
}

}  // namespace displace::render::quadric
