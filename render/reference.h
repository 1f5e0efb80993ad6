// render/reference.h - the exact answers the renderer's pictures are checked against, on the CPU:
// the image error of a frame against a reference frame, and the exact first crossing of a pixel's ray
// with the bilinear height surface (plane and quadrics) in double (render/cpu_trace.cpp,
// render/cpu_trace_quadric.cpp, render/compare.cpp). Slow and exact: the tests and the report use them.
#pragma once

#include <glm/glm.hpp>

#include "bake/bake.h"
#include "render/map_set.h"
#include "render/view.h"

namespace displace::render {

// Image error of a frame against a reference frame, over the pixels where either frame hit the
// relief, in 8-bit output units (each channel of RGB counted; a pixel where only one frame hit
// counts its full difference against the background). Both frames need their colour and uv read
// back (throws RenderError otherwise).
struct ImageError {
  double rmse = 0.0;
  double max_error = 0.0;
  double fraction_over_10 = 0.0;  // pixels with any channel off by more than 10
  long long pixels = 0;
};
ImageError compare(const Frame& frame, const Frame& reference);

// The exact ray-height-field intersection on the CPU (a cell-by-cell walk of the bilinear surface,
// solving the quadratic in each cell) for the plane, for tests: the texture coordinates (u, v, h) of the
// first hit of the ray through pixel (px, py), or hit = false when the ray misses the relief of the [0,
// tile]^2 patch.
struct CpuHit {
  bool hit = false;
  glm::dvec3 texture;  // u, v, h
  double distance = 0.0;
};
CpuHit cpu_trace(const HeightField& field, const View& view, double px, double py);
// The same exact intersection on a quadric surface (View::surface other than plane): march the
// bilinear surface from where the ray enters the outer surface in steps of at most 1/32 of a
// texel of (u, v) travel, then bisect; the texture point is (u, v, h), distance the world distance.
CpuHit cpu_trace_quadric(const HeightField& field, const View& view, double px, double py);
// The bilinear height the renderer samples at texture coordinates (u, v) (texel centres at
// (j + 0.5) / W), with the address mode.
double bilinear_height(const HeightField& field, bake::Address address, double u, double v);
// The smallest s in [0, 1] where the ray p(s) = origin + s * descent (texture space, descent.z = -1,
// origin inside the [0, tile]^2 patch) is at or below the bilinear surface; where the ray leaves the
// patch first, an s whose point lies outside the patch. Exact up to double rounding.
double first_crossing(const HeightField& field, bake::Address address, double tile, const glm::dvec3& origin,
                      const glm::dvec3& descent);

}  // namespace displace::render
