// render/cpu_trace.cpp - the exact ray / height-field intersection on the CPU, in double precision.
// The bilinear surface is a quadratic patch over each cell between four texel centres, so the ray
// is walked cell by cell (a 2D grid traversal) and, in each cell, the first zero of the ray's height
// above the patch - a quadratic in the ray parameter - is found by splitting the cell's segment at
// the quadratic's extremum and bisecting the first monotone piece that changes sign. Nothing is
// skipped, however thin: this is the truth the tests measure the GPU methods against. The reference
// method's fragment shader (render/shaders/reference.inc.glsl) runs the same walk in float.
#include <algorithm>
#include <cmath>
#include <limits>

#include "render/quadric.h"
#include "render/render.h"

namespace displace::render {
namespace {

constexpr int bisection_steps = 60;  // halvings of a monotone piece: far below double precision of s

// Texel (i, j), each axis wrapped or clamped.
double texel_at(const HeightField& field, bool wrap_u, bool wrap_v, long long i, long long j) {
  j = wrap_u ? ((j % field.width) + field.width) % field.width : std::clamp<long long>(j, 0, field.width - 1);
  i = wrap_v ? ((i % field.height) + field.height) % field.height
             : std::clamp<long long>(i, 0, field.height - 1);
  return field.heights[std::size_t(i * field.width + j)];
}
double texel_at(const HeightField& field, bake::Address address, long long i, long long j) {
  const bool wrap = address == bake::Address::wrap;
  return texel_at(field, wrap, wrap, i, j);
}

// The ray's height above the bilinear patch of one cell: g(s) = z0 - s - b(fx(s), fy(s)), with
// fx, fy the position inside the cell (0..1 between its texel centres), linear in s.
struct CellGap {
  double z0, fx0, fy0, dfx, dfy;
  double h00, h10, h01, h11;

  double operator()(double s) const {
    const double fx = fx0 + s * dfx, fy = fy0 + s * dfy;
    const double top = h00 + (h10 - h00) * fx, bottom = h01 + (h11 - h01) * fx;
    return z0 - s - (top + (bottom - top) * fy);
  }
  // where g' = 0 (g is quadratic in s), or NaN when g is linear
  double extremum() const {
    const double twist = h00 - h10 - h01 + h11;
    const double a = -twist * dfx * dfy;
    const double b = -1.0 - (h10 - h00) * dfx - (h01 - h00) * dfy - twist * (fx0 * dfy + fy0 * dfx);
    return a != 0.0 ? -b / (2.0 * a) : std::numeric_limits<double>::quiet_NaN();
  }
};

// The first s in [s0, s1] with g(s) <= 0, given that g is monotone on it, or -1.
double monotone_root(const CellGap& g, double s0, double s1) {
  if (g(s0) <= 0.0) return s0;
  if (g(s1) > 0.0) return -1.0;
  for (int i = 0; i < bisection_steps; ++i) {
    const double mid = 0.5 * (s0 + s1);
    (g(mid) > 0.0 ? s0 : s1) = mid;
  }
  return s1;
}

}  // namespace

double bilinear_height_wrapping(const HeightField& field, bool wrap_u, bool wrap_v, double u, double v) {
  const double x = u * field.width - 0.5, y = v * field.height - 0.5;
  const double x0 = std::floor(x), y0 = std::floor(y);
  const double fx = x - x0, fy = y - y0;
  const long long j = (long long)x0, i = (long long)y0;
  auto texel = [&](long long row, long long column) { return texel_at(field, wrap_u, wrap_v, row, column); };
  const double top = texel(i, j) * (1 - fx) + texel(i, j + 1) * fx;
  const double bottom = texel(i + 1, j) * (1 - fx) + texel(i + 1, j + 1) * fx;
  return top * (1 - fy) + bottom * fy;
}

// Bilinear height at texture coordinates (u, v), texel centres at (j + 0.5) / W.
double bilinear_height(const HeightField& field, bake::Address address, double u, double v) {
  const bool wrap = address == bake::Address::wrap;
  return bilinear_height_wrapping(field, wrap, wrap, u, v);
}

double first_crossing(const HeightField& field, bake::Address address, double tile, const glm::dvec3& origin,
                      const glm::dvec3& descent) {
  // cell coordinates: texel centre (i, j) sits at (x, y) = (j, i)
  const double x0 = origin.x * field.width - 0.5, y0 = origin.y * field.height - 0.5;
  const double dx = descent.x * field.width, dy = descent.y * field.height;
  long long cx = (long long)std::floor(x0), cy = (long long)std::floor(y0);
  const int step_x = dx > 0.0 ? 1 : dx < 0.0 ? -1 : 0;
  const int step_y = dy > 0.0 ? 1 : dy < 0.0 ? -1 : 0;
  const double inf = std::numeric_limits<double>::infinity();
  // s at which the ray crosses the next cell boundary along each axis
  auto next_boundary = [&](double start, double delta, long long cell, int step) {
    if (step == 0) return inf;
    return ((step > 0 ? double(cell + 1) : double(cell)) - start) / delta;
  };
  double next_x = next_boundary(x0, dx, cx, step_x), next_y = next_boundary(y0, dy, cy, step_y);
  double s0 = 0.0;
  while (true) {
    const double s1 = std::min({next_x, next_y, 1.0});
    CellGap g{origin.z,
              x0 - double(cx),
              y0 - double(cy),
              dx,
              dy,
              texel_at(field, address, cy, cx),
              texel_at(field, address, cy, cx + 1),
              texel_at(field, address, cy + 1, cx),
              texel_at(field, address, cy + 1, cx + 1)};
    const double split = g.extremum();
    if (split > s0 && split < s1) {
      if (const double s = monotone_root(g, s0, split); s >= 0.0) return s;
      if (const double s = monotone_root(g, split, s1); s >= 0.0) return s;
    } else if (const double s = monotone_root(g, s0, s1); s >= 0.0) {
      return s;
    }
    if (s1 >= 1.0) return 1.0;  // heights are >= 0: the floor h = 0 is reached at s = 1 at the latest
    s0 = s1;
    // beyond the patch's side the ray has left the relief: report where (the caller sees a miss)
    const glm::dvec2 p = glm::dvec2(origin) + s0 * glm::dvec2(descent);
    if (p.x < 0.0 || p.x > tile || p.y < 0.0 || p.y > tile) return s0;
    if (next_x <= s1) {
      cx += step_x;
      next_x = next_boundary(x0, dx, cx, step_x);
    }
    if (next_y <= s1) {
      cy += step_y;
      next_y = next_boundary(y0, dy, cy, step_y);
    }
  }
}

CpuHit cpu_trace(const HeightField& field, const View& view, double px, double py) {
  const Ray ray = view.camera.pixel_ray(px, py);
  CpuHit result;
  if (ray.origin.z <= 0.0 || ray.direction.z >= 0.0) return result;
  const double t_entry = -ray.origin.z / ray.direction.z;
  const glm::dvec3 entry = ray.origin + t_entry * ray.direction;
  if (entry.x < 0.0 || entry.x > 1.0 || entry.y < 0.0 || entry.y > 1.0) return result;
  const double tile = view.tile, depth = view.depth_scale;
  // texture space: (u, v, h) = (K x, K y, 1 + z / D); descent per unit of height lost
  const glm::dvec3 origin(entry.x * tile, entry.y * tile, 1.0);
  const glm::dvec3 direction(ray.direction.x * tile, ray.direction.y * tile, ray.direction.z / depth);
  const glm::dvec3 descent = direction / -direction.z;
  const double s = first_crossing(field, view.address, tile, origin, descent);
  const glm::dvec3 p = origin + s * descent;
  if (p.x < 0.0 || p.x > tile || p.y < 0.0 || p.y > tile) return result;
  result.hit = true;
  result.texture = p;
  result.distance = t_entry + s / -direction.z;
  return result;
}

}  // namespace displace::render
