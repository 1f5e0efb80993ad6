// bake/near_field_kernel.h - the bilinear baker's near field for a row of texels (lane_sweep.h,
// NearRowJob), written once over a 16-float vector type and built per instruction set by the lane
// sweep's translation units. Rates are finite and >= 0, so rate * flag (0 or 1) selects them.
#pragma once

#include <cmath>
#include <cstring>
#include <limits>
#if defined(__AVX__)
#include <immintrin.h>
#endif

#include "bake/lane_sweep.h"

namespace displace::bake::detail {
namespace {

typedef float Floats __attribute__((vector_size(64)));
typedef int Ints __attribute__((vector_size(64)));
constexpr int near_lanes = near_block;

inline Floats load_floats(const float* p) {
  Floats v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
inline Floats larger(Floats a, Floats b) { return a > b ? a : b; }
inline Floats smaller(Floats a, Floats b) { return a < b ? a : b; }

inline Floats square_root(Floats x) {
#if defined(__AVX512F__)
  __m512 v;
  std::memcpy(&v, &x, sizeof v);
  v = _mm512_sqrt_ps(v);
  std::memcpy(&x, &v, sizeof v);
#elif defined(__AVX__)
  __m256 halves[2];
  std::memcpy(halves, &x, sizeof halves);
  halves[0] = _mm256_sqrt_ps(halves[0]);
  halves[1] = _mm256_sqrt_ps(halves[1]);
  std::memcpy(&x, halves, sizeof halves);
#else
  for (int l = 0; l < near_lanes; ++l) x[l] = std::sqrt(x[l]);
#endif
  return x;
}

// The accumulators of 16 texels: the largest rates along u and v over box 2 and over box 3 (of the
// sub-cells above the apex and beyond Q_c's edge along that axis), the largest (top - apex) / gap of
// box 2 (the inverse of its smallest gap bound), and flags: a box-2 sub-cell touching Q_c above the
// apex, anything above the apex in box 2, in box 3.
struct NearSums {
  Floats ru, rv, ru3, rv3, steep, touch, any, any3;
};

// One group of offsets, all of one kind (near_row sorts them so): in box 2 or only in box 3,
// touching Q_c (gap 0) or not, beyond Q_c's edge along u, along v.
template <bool box2, bool touching, bool along_u, bool along_v>
inline void near_group(const NearOffset* offsets, int count, int j0, Floats apex, NearSums& sums) {
  const Floats zero = Floats{} + 0.0f, one = Floats{} + 1.0f;
  for (int o = 0; o < count; ++o) {
    const NearOffset& offset = offsets[o];
    const Floats top = load_floats(offset.top + j0);
    const Floats flag = top > apex ? one : zero;
    sums.any3 = larger(sums.any3, flag);
    if (along_u) {
      const Floats u = load_floats(offset.along_u + j0) * flag;
      sums.ru3 = larger(sums.ru3, u);
      if (box2) sums.ru = larger(sums.ru, u);
    }
    if (along_v) {
      const Floats v = load_floats(offset.along_v + j0) * flag;
      sums.rv3 = larger(sums.rv3, v);
      if (box2) sums.rv = larger(sums.rv, v);
    }
    if (box2) {
      sums.any = larger(sums.any, flag);
      if (touching)
        sums.touch = larger(sums.touch, flag);
      else  // at or below the apex the quotient is <= 0 and leaves steep (from 0) as it is
        sums.steep = larger(sums.steep, (top - apex) * offset.inverse_gap);
    }
  }
}

// The bounds of 16 texels from their accumulators, in float: 1 / G and gap / (top - apex) carry a
// few roundings of 2^-24 each (squares, sum, root, product with the rounded-up 1 / gap, quotient),
// all within near_shrink.
inline void finish_texels(const NearSums& sums, float* near, float* slope3) {
  constexpr float infinite = std::numeric_limits<float>::infinity();
  const Floats zero = Floats{} + 0.0f, inf = Floats{} + infinite, shrink = Floats{} + (1.0f - 4e-6f);
  const Floats g3 = square_root(sums.ru3 * sums.ru3 + sums.rv3 * sums.rv3);
  const Floats g = square_root(sums.ru * sums.ru + sums.rv * sums.rv);
  const Floats slope3_bound = sums.any3 == zero ? inf : g3 > zero ? shrink / g3 : zero;
  const Floats slope_bound = g > zero ? shrink / g : zero;
  const Floats far = sums.touch != zero ? zero : shrink / sums.steep;  // steep 0: infinity
  const Floats near_bound = sums.any == zero ? inf : larger(far, slope_bound);
  std::memcpy(near, &near_bound, sizeof near_bound);
  std::memcpy(slope3, &slope3_bound, sizeof slope3_bound);
}

void near_row_kernel(const NearRowJob& job) {
  const int width = job.width;
  const int* counts = job.group_counts;
  // the groups in near_row's order: box 2 touching, box 2 not touching, box 3 only; each beyond u
  // only, v only, both
  int first[near_groups + 1] = {0};
  for (int g = 0; g < near_groups; ++g) first[g + 1] = first[g] + counts[g];
  const NearOffset* offsets = job.offsets;
  auto block = [&](int j0, const float* apex_values, float* near, float* slope3) {
    const Floats zero = Floats{} + 0.0f;
    NearSums sums{zero, zero, zero, zero, zero, zero, zero, zero};
    const Floats apex = load_floats(apex_values + j0);
    near_group<true, true, true, false>(offsets + first[0], counts[0], j0, apex, sums);
    near_group<true, true, false, true>(offsets + first[1], counts[1], j0, apex, sums);
    near_group<true, true, true, true>(offsets + first[2], counts[2], j0, apex, sums);
    near_group<true, false, true, false>(offsets + first[3], counts[3], j0, apex, sums);
    near_group<true, false, false, true>(offsets + first[4], counts[4], j0, apex, sums);
    near_group<true, false, true, true>(offsets + first[5], counts[5], j0, apex, sums);
    near_group<false, false, true, false>(offsets + first[6], counts[6], j0, apex, sums);
    near_group<false, false, false, true>(offsets + first[7], counts[7], j0, apex, sums);
    near_group<false, false, true, true>(offsets + first[8], counts[8], j0, apex, sums);
    finish_texels(sums, near, slope3);
  };
  int j0 = 0;
  for (; j0 + near_lanes <= width; j0 += near_lanes) block(j0, job.apex, job.near + j0, job.slope3 + j0);
  if (j0 < width) {
    // the tail: 16 texels ending at the row's end where the row has them (recomputing a few),
    // else through a padded copy (the planes hold near_lanes values past every texel they serve)
    if (width >= near_lanes) {
      block(width - near_lanes, job.apex, job.near + width - near_lanes, job.slope3 + width - near_lanes);
    } else {
      float apex[near_lanes], near[near_lanes], slope3[near_lanes];
      for (int l = 0; l < near_lanes; ++l) apex[l] = job.apex[l < width ? l : width - 1];
      // the offsets' planes are read at j < near_lanes: near_row pads them for it
      block(0, apex, near, slope3);
      for (int l = 0; l < width; ++l) {
        job.near[l] = near[l];
        job.slope3[l] = slope3[l];
      }
    }
  }
}

}  // namespace
}  // namespace displace::bake::detail
