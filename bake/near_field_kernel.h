// bake/near_field_kernel.h - the bilinear baker's near field for a row of texels (lane_sweep.h,
// NearRowJob), written once over a 16-float vector type and built per instruction set by the lane
// sweep's translation units. Rates are finite and >= 0, so rate * flag (0 or 1) selects them.
#pragma once

#include <cmath>
#include <cstring>
#include <limits>

#include "bake/lane_sweep.h"

namespace displace::bake::detail {
namespace {

typedef float Floats __attribute__((vector_size(64)));
typedef int Ints __attribute__((vector_size(64)));
constexpr int near_lanes = 16;

inline Floats load_floats(const float* p) {
  Floats v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
inline Floats larger(Floats a, Floats b) { return a > b ? a : b; }
inline Floats smaller(Floats a, Floats b) { return a < b ? a : b; }

// The bounds of one texel from its accumulators (double arithmetic, shrunk by a relative 1e-6).
inline void finish_texel(float ru, float rv, float ru3, float rv3, float fa, float touch, float any, float any3,
                         float& near, float& slope3) {
  constexpr float infinite = std::numeric_limits<float>::infinity();
  const double g3 = std::sqrt(double(ru3) * ru3 + double(rv3) * rv3);
  slope3 = any3 == 0.0f ? infinite : g3 > 0.0 ? float((1.0 / g3) * (1.0 - 1e-6)) : 0.0f;
  if (any == 0.0f) {
    near = infinite;
    return;
  }
  const double g = std::sqrt(double(ru) * ru + double(rv) * rv);
  const double slope_bound = g > 0.0 ? (1.0 / g) * (1.0 - 1e-6) : 0.0;
  const double far = touch != 0.0f ? 0.0 : double(fa) * (1.0 - 1e-6);
  near = float(far > slope_bound ? far : slope_bound);
}

void near_row_kernel(const NearRowJob& job) {
  constexpr float infinite = std::numeric_limits<float>::infinity();
  const int width = job.width;
  int j0 = 0;
  for (; j0 + near_lanes <= width; j0 += near_lanes) {
    const Floats zero = Floats{} + 0.0f, one = Floats{} + 1.0f, inf = Floats{} + infinite;
    Floats ru = zero, rv = zero, ru3 = zero, rv3 = zero, fa = inf, touch = zero, any = zero, any3 = zero;
    const Floats apex = load_floats(job.apex + j0);
    for (int o = 0; o < job.offset_count; ++o) {
      const NearOffset& offset = job.offsets[o];
      const Floats top = load_floats(offset.top + j0);
      const Ints above = top > apex;
      const Floats flag = above ? one : zero;
      any3 = larger(any3, flag);
      Floats u = zero, v = zero;
      if (offset.beyond_u) u = load_floats(offset.along_u + j0) * flag;
      if (offset.beyond_v) v = load_floats(offset.along_v + j0) * flag;
      ru3 = larger(ru3, u);
      rv3 = larger(rv3, v);
      if (!offset.box2) continue;
      any = larger(any, flag);
      ru = larger(ru, u);
      rv = larger(rv, v);
      if (offset.gap > 0.0f) {
        const Floats bound = (Floats{} + offset.gap) / (top - apex);
        fa = smaller(fa, above ? bound : inf);
      } else {
        touch = larger(touch, flag);
      }
    }
    for (int l = 0; l < near_lanes; ++l)
      finish_texel(ru[l], rv[l], ru3[l], rv3[l], fa[l], touch[l], any[l], any3[l], job.near[j0 + l],
                   job.slope3[j0 + l]);
  }
  for (int j = j0; j < width; ++j) {  // the tail, one texel at a time
    float ru = 0.0f, rv = 0.0f, ru3 = 0.0f, rv3 = 0.0f, fa = infinite, touch = 0.0f, any = 0.0f, any3 = 0.0f;
    const float apex = job.apex[j];
    for (int o = 0; o < job.offset_count; ++o) {
      const NearOffset& offset = job.offsets[o];
      const float top = offset.top[j];
      if (!(top > apex)) continue;
      any3 = 1.0f;
      const float u = offset.beyond_u ? offset.along_u[j] : 0.0f, v = offset.beyond_v ? offset.along_v[j] : 0.0f;
      ru3 = u > ru3 ? u : ru3;
      rv3 = v > rv3 ? v : rv3;
      if (!offset.box2) continue;
      any = 1.0f;
      ru = u > ru ? u : ru;
      rv = v > rv ? v : rv;
      if (offset.gap > 0.0f) {
        const float bound = offset.gap / (top - apex);
        fa = bound < fa ? bound : fa;
      } else {
        touch = 1.0f;
      }
    }
    finish_texel(ru, rv, ru3, rv3, fa, touch, any, any3, job.near[j], job.slope3[j]);
  }
}

}  // namespace
}  // namespace displace::bake::detail
