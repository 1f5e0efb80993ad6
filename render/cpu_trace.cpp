// render/cpu_trace.cpp - the exact ray / height-field intersection on the CPU, in double precision:
// march the bilinear surface in steps of at most an eighth of a texel, then bisect. Slow and plain on
// purpose; the tests measure the GPU methods against it.
#include <algorithm>
#include <cmath>

#include "render/render.h"

namespace displace::render {
namespace {

constexpr double steps_per_texel = 8.0;   // march steps per texel of horizontal travel
constexpr int min_march_steps = 256;
constexpr int max_march_steps = 4 << 20;
constexpr int bisection_steps = 60;

double texel_at(const HeightField& field, bake::Address address, long long i, long long j) {
  if (address == bake::Address::wrap) {
    i = ((i % field.height) + field.height) % field.height;
    j = ((j % field.width) + field.width) % field.width;
  } else {
    i = std::clamp<long long>(i, 0, field.height - 1);
    j = std::clamp<long long>(j, 0, field.width - 1);
  }
  return field.heights[std::size_t(i * field.width + j)];
}

}  // namespace

// Bilinear height at texture coordinates (u, v), texel centres at (j + 0.5) / W.
double bilinear_height(const HeightField& field, bake::Address address, double u, double v) {
  const double x = u * field.width - 0.5, y = v * field.height - 0.5;
  const double x0 = std::floor(x), y0 = std::floor(y);
  const double fx = x - x0, fy = y - y0;
  const long long j = (long long)x0, i = (long long)y0;
  const double top = texel_at(field, address, i, j) * (1 - fx) + texel_at(field, address, i, j + 1) * fx;
  const double bottom = texel_at(field, address, i + 1, j) * (1 - fx) + texel_at(field, address, i + 1, j + 1) * fx;
  return top * (1 - fy) + bottom * fy;
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
  const double travel_texels = std::hypot(descent.x * field.width, descent.y * field.height);
  const int steps = std::clamp(int(std::ceil(travel_texels * steps_per_texel)), min_march_steps, max_march_steps);
  auto gap = [&](double s) {
    const glm::dvec3 p = origin + s * descent;
    return p.z - bilinear_height(field, view.address, p.x, p.y);
  };
  double lo = 0.0, hi = 0.0;
  if (gap(0.0) > 0.0) {
    for (int i = 1; i <= steps; ++i) {
      const double s = double(i) / steps;
      if (gap(s) <= 0.0) {
        hi = s;
        break;
      }
      lo = s;
    }
    for (int i = 0; i < bisection_steps; ++i) {
      const double mid = 0.5 * (lo + hi);
      (gap(mid) > 0.0 ? lo : hi) = mid;
    }
  }
  const glm::dvec3 p = origin + hi * descent;
  if (p.x < 0.0 || p.x > tile || p.y < 0.0 || p.y > tile) return result;
  result.hit = true;
  result.texture = p;
  result.distance = t_entry + hi / -direction.z;
  return result;
}

}  // namespace displace::render
