// render/cpu_trace_quadric.cpp - the exact ray / relief intersection on a quadric on the CPU, in
// double precision: from where the ray enters the outer surface, march the bilinear surface in steps
// that move (u, v) by at most 1/32 of a texel (the step is bounded by the largest (u, v) speed
// over it, which grows near the axis), then bisect. The light test (quadric::light_occluder) marches
// the light ray from a point of the relief the same way. Slow and plain on purpose; the tests measure
// the GPU methods and their shadows on quadrics against them.
#include <algorithm>
#include <cmath>
#include <numbers>

#include "render/quadric.h"
#include "render/render.h"

namespace displace::render {
namespace {

constexpr double texels_per_step = 1.0 / 32.0;  // largest (u, v) travel of one march step, in texels
constexpr double min_step = 1e-7;               // world units: the march always advances
constexpr int max_march_steps = 8 << 20;
constexpr int bisection_steps = 60;

// u always wraps around the axis; v wraps or clamps with the address mode.
double quadric_height(const HeightField& field, bake::Address address, double u, double v) {
  return bilinear_height_wrapping(field, true, address == bake::Address::wrap, u, v);
}

// Least distance from the axis (horizontal) or the anchor (3D) of o + t d over [t0, t1].
double least_distance(glm::dvec3 o, glm::dvec3 d, double t0, double t1, bool horizontal) {
  if (horizontal) {
    o.z = 0.0;
    d.z = 0.0;
  }
  const double a = glm::dot(d, d);
  const double t = a > 0.0 ? std::clamp(-glm::dot(o, d) / a, t0, t1) : t0;
  return glm::length(o + t * d);
}

// The largest |d(u, v)/dt| over [t0, t1], texture units per world unit.
double uv_speed(const quadric::Shape& shape, const glm::dvec3& o, const glm::dvec3& d, double t0, double t1) {
  const double tiny = 1e-9 * shape.radius;
  const double horizontal = std::hypot(d.x, d.y);
  const double rho = std::max(least_distance(o, d, t0, t1, true), tiny);
  const double u_speed = shape.tile * horizontal / (2.0 * std::numbers::pi * rho);
  double v_speed = 0.0;
  if (shape.surface == Surface::sphere) {
    v_speed = shape.tile / (std::numbers::pi * std::max(least_distance(o, d, t0, t1, false), tiny));
  } else if (shape.surface == Surface::cylinder) {
    v_speed = shape.tile * std::abs(d.z) / (2.0 * shape.radius);
  } else {
    v_speed = shape.tile * (horizontal + std::abs(d.z)) /
              shape.radius;  // |dv/dt| <= K cos (sin |rho'| + cos |z'|) / R
  }
  return std::hypot(u_speed, v_speed);
}

// The first t in [t0, t1] where gap(t) <= 0, with gap(t0) > 0: march in steps that move (u, v) by at
// most texels_per_step texels, then bisect; -1 when the ray stays above the surface.
template <class Gap>
double first_at_or_below(const HeightField& field, const quadric::Shape& shape, const glm::dvec3& o,
                         const glm::dvec3& d, double t0, double t1, Gap gap) {
  const double texel = texels_per_step * std::min(1.0 / field.width, 1.0 / field.height);
  double above = t0, below = -1.0;
  for (int i = 0; i < max_march_steps && above < t1; ++i) {
    double step = texel / uv_speed(shape, o, d, above, above);
    step = std::max(texel / uv_speed(shape, o, d, above, std::min(above + step, t1)), min_step);
    const double t = std::min(above + step, t1);
    if (gap(t) <= 0.0) {
      below = t;
      break;
    }
    above = t;
  }
  if (below < 0.0) return -1.0;
  for (int i = 0; i < bisection_steps; ++i) {
    const double mid = 0.5 * (above + below);
    (gap(mid) > 0.0 ? above : below) = mid;
  }
  return below;
}

}  // namespace

CpuHit cpu_trace_quadric(const HeightField& field, const View& view, double px, double py) {
  CpuHit result;
  const quadric::Shape shape = quadric::shape_of(view);
  const Ray ray = view.camera.pixel_ray(px, py);
  const glm::dvec3 o = ray.origin - quadric::anchor(shape), d = ray.direction;

  // the span of the ray in the relief shell
  const quadric::Interval outer = quadric::body_interval(shape, o, d, 0.0);
  if (outer.empty() || outer.enter < 0.0) return result;
  const quadric::Interval inner = quadric::body_interval(shape, o, d, -shape.depth);
  const double t_in = outer.enter;
  bool certain = !inner.empty() && inner.enter < outer.leave;  // the inner surface ends it: a hit by then
  double t_end = certain ? std::max(inner.enter, t_in) : outer.leave;
  glm::dvec3 lo, hi;
  quadric::relief_box(shape, lo, hi);
  const double box_exit = quadric::box_exit(ray.origin, d, lo, hi);
  if (box_exit < t_end) {
    t_end = std::max(box_exit, t_in);
    certain = false;
  }
  if (!quadric::range_kept(shape, o, d, t_in, t_in)) return result;

  // march, then bisect
  auto gap = [&](double t) {
    const glm::dvec3 p = quadric::texture_point(shape, o + t * d);
    return p.z - quadric_height(field, view.address, p.x, p.y);
  };
  double below = t_in;
  if (gap(t_in) > 0.0) {
    below = first_at_or_below(field, shape, o, d, t_in, t_end, gap);
    if (below < 0.0 && certain) below = t_end;  // on the inner surface, which no height lies below
    if (below < 0.0) return result;             // left the shell above the relief
  }
  if (!quadric::range_kept(shape, o, d, t_in, below)) return result;
  result.hit = true;
  result.texture = quadric::texture_point(shape, o + below * d);
  result.distance = below;
  return result;
}

}  // namespace displace::render

namespace displace::render::quadric {

double light_occluder(const HeightField& field, const View& view, const glm::dvec3& point,
                      const glm::dvec3& light, double start) {
  const Shape shape = shape_of(view);
  const glm::dvec3 o = point - anchor(shape), d = glm::normalize(light);
  // the light ray's part in the relief: up to where it leaves the outer solid or the relief's box
  const Interval outer = body_interval(shape, o, d, 0.0);
  if (outer.empty()) return -1.0;
  glm::dvec3 lo, hi;
  relief_box(shape, lo, hi);
  const double s_far = std::min(outer.leave, box_exit(point, d, lo, hi));
  if (s_far <= start) return -1.0;
  auto in_range = [&](double t) {  // within the finite part, v in [0, K]
    const double v = texture_point(shape, o + t * d).y;
    return shape.surface == Surface::sphere || (v >= 0.0 && v <= shape.tile);
  };
  // the inner solid, which every height lies on or above, where one end of the stretch through it
  // is within the finite part
  const Interval inner = body_interval(shape, o, d, -shape.depth);
  bool through_inner = !inner.empty() && inner.enter < s_far && inner.leave > start;
  const double inner_start = through_inner ? std::max(inner.enter, start) : far;
  through_inner = through_inner && (in_range(inner_start) || in_range(std::min(inner.leave, s_far)));
  // the relief within the finite part; beyond it (the cone's edges) nothing
  auto gap = [&](double t) {
    if (!in_range(t)) return 1.0;
    const glm::dvec3 p = texture_point(shape, o + t * d);
    return p.z - quadric_height(field, view.address, p.x, p.y);
  };
  if (gap(start) <= 0.0) return start;
  const double end = through_inner ? inner_start : s_far;
  const double first = first_at_or_below(field, shape, o, d, start, end, gap);
  if (first >= 0.0) return first;
  return through_inner ? inner_start : -1.0;
}

}  // namespace displace::render::quadric
