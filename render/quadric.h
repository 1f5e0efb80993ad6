// render/quadric.h - internal: the quadric surfaces' geometry on the CPU in double precision, the
// same formulas as render/shaders/quadric.inc.glsl (render/render.h states the geometry). Used by
// the renderer (view checks, near and far planes) and by the exact CPU trace.
#pragma once

#include <glm/glm.hpp>

#include "render/render.h"

namespace displace::render {

// The bilinear height at (u, v) with each axis wrapped or clamped separately (quadrics: u always
// wraps around the axis, v follows the address mode); bilinear_height is the case of one mode.
double bilinear_height_wrapping(const HeightField& field, bool wrap_u, bool wrap_v, double u, double v);

}  // namespace displace::render

namespace displace::render::quadric {

struct Shape {
  Surface surface = Surface::sphere;
  double radius = 0.25;  // R, world units
  double depth = 0.1;    // D, world units
  double tile = 1.0;     // K
};
Shape shape_of(const View& view);

// Throws RenderError when the view cannot show the quadric: a bad radius, D above R / 2, the eye
// inside the quadric.
void validate(const View& view);

// The local frame's origin: the centre (sphere, cylinder) or the apex (cone).
glm::dvec3 anchor(const Shape& shape);
// The world box holding the whole relief of the finite quadric.
void relief_box(const Shape& shape, glm::dvec3& lo, glm::dvec3& hi);
// (u, v, h) of the point q given relative to anchor(); u in [0, K].
glm::dvec3 texture_point(const Shape& shape, const glm::dvec3& q);
// The world point at texture point (u, v, h): its foot point on the outer surface moved (1 - h) D
// inward along the normal (the inverse of texture_point).
glm::dvec3 surface_point(const Shape& shape, double u, double v, double h);

struct Interval {
  double enter = 0.0, leave = -1.0;  // empty when enter > leave; +-far for an end never reached
  bool empty() const { return enter > leave; }
};
constexpr double far = 1e300;
// Where o + t d (d unit, o relative to anchor()) lies inside the solid bounded by the surface at
// `offset` along the normal from the outer one (0: outer surface, -D: inner surface).
Interval body_interval(const Shape& shape, const glm::dvec3& o, const glm::dvec3& d, double offset);
// Where the ray e + t d leaves the world box [lo, hi] (far when it stays inside).
double box_exit(const glm::dvec3& e, const glm::dvec3& d, const glm::dvec3& lo, const glm::dvec3& hi);
// Whether the part of the ray from the entry t_in to t stays inside v in [0, K] (v follows z on the
// cylinder; on the cone the foot point's slant is convex along the ray).
bool range_kept(const Shape& shape, const glm::dvec3& o, const glm::dvec3& d, double t_in, double t);

// The exact light test on the CPU, for tests (render/cpu_trace_quadric.cpp, the same march as
// cpu_trace_quadric): the world distance from `point` (world) along the direction `light` to the
// first point the light ray meets at or below the bilinear surface within the finite part (v in
// [0, K]), or inside the inner solid, before it leaves the outer solid or the relief's box; -1 when
// it meets none. The ray is followed from `start` world units on (a point on the surface is at it).
double light_occluder(const HeightField& field, const View& view, const glm::dvec3& point,
                      const glm::dvec3& light, double start);

}  // namespace displace::render::quadric
