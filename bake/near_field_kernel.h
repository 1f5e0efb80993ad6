// bake/near_field_kernel.h - the bilinear baker's near field for a row of texels (lane_sweep.h,
// NearRowJob), written once over vectors of 16-bit integers and of 16 floats and built per
// instruction set by the lane sweep's translation units. A flag is 0xffff or 0, so rate & flag
// selects a rate.
//
// A block is as many texels as one register holds in 16-bit lanes: 32 with AVX-512, 16 with AVX2
// and below. Its eight accumulators and their temporaries then stay in registers; 32-texel blocks
// on AVX2 (each vector two ymm registers, 16 of them) spilled the accumulators at every offset,
// and stage L took 34.9 ms at 512 x 512 against 8.0 with AVX-512 on the same machine.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#if defined(__SSE2__)
#include <immintrin.h>
#endif

#include "bake/lane_sweep.h"

namespace displace::bake::detail {
namespace {

#if defined(__AVX512BW__)
#define DISPLACE_NEAR_LANES 32  // texels a block: one zmm register of 16-bit lanes
#else
#define DISPLACE_NEAR_LANES 16  // one ymm register (two xmm, or what the target has)
#endif
constexpr int near_lanes = DISPLACE_NEAR_LANES;
static_assert(near_lanes <= near_block, "the planes are padded for near_block values past a texel");
typedef float Floats __attribute__((vector_size(64)));
typedef std::uint16_t Shorts __attribute__((vector_size(2 * near_lanes)));
typedef std::uint16_t HalfShorts __attribute__((vector_size(32)));
constexpr int float_lanes = 16;

inline Shorts load_shorts(const std::uint16_t* p) {
  Shorts v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
inline Shorts larger(Shorts a, Shorts b) { return a > b ? a : b; }
inline Floats larger(Floats a, Floats b) { return a > b ? a : b; }
inline Shorts bits(Shorts a, Shorts b) { return (Shorts)(a > b); }  // 0xffff where a > b, else 0

// An instruction on native registers applied across a vector: the vector is split into as many
// registers as it holds (memcpy in and out; GCC keeps them in registers).
template <class Register, class Vector, class Op>
__attribute__((always_inline)) inline Vector by_registers(Vector a, Vector b, Op op) {
  constexpr int count = int(sizeof(Vector) / sizeof(Register));
  Register x[count], y[count];
  std::memcpy(x, &a, sizeof x);
  std::memcpy(y, &b, sizeof y);
  for (int h = 0; h < count; ++h) x[h] = op(x[h], y[h]);
  std::memcpy(&a, x, sizeof a);
  return a;
}

// floor(a * b / 65536) per lane.
__attribute__((always_inline)) inline Shorts high_product(Shorts a, Shorts b) {
#if defined(__AVX512BW__)
  return by_registers<__m512i>(a, b, [](__m512i x, __m512i y) { return _mm512_mulhi_epu16(x, y); });
#elif defined(__AVX2__)
  return by_registers<__m256i>(a, b, [](__m256i x, __m256i y) { return _mm256_mulhi_epu16(x, y); });
#elif defined(__SSE2__)
  return by_registers<__m128i>(a, b, [](__m128i x, __m128i y) { return _mm_mulhi_epu16(x, y); });
#else
  for (int l = 0; l < near_lanes; ++l) a[l] = std::uint16_t((std::uint32_t(a[l]) * b[l]) >> 16);
  return a;
#endif
}

inline Floats square_root(Floats x) {
#if defined(__AVX512F__)
  return by_registers<__m512>(x, x, [](__m512 v, __m512) { return _mm512_sqrt_ps(v); });
#elif defined(__AVX__)
  return by_registers<__m256>(x, x, [](__m256 v, __m256) { return _mm256_sqrt_ps(v); });
#else
  for (int l = 0; l < float_lanes; ++l) x[l] = std::sqrt(x[l]);
  return x;
#endif
}

// The accumulators of a block's texels: the largest rates along u and v over box 2 and over box 3 (of the
// sub-cells above the apex and beyond Q_c's edge along that axis), the largest gap term of box 2
// (floor((top - apex) * inverse_gap / 65536) + 1, 0 where nothing apart from Q_c is above the apex),
// and flags (0xffff or 0): a box-2 sub-cell touching Q_c above the apex, anything above the apex in
// box 2, in box 3.
struct NearSums {
  Shorts ru, rv, ru3, rv3, steep, touch, any, any3;
};

// One group of offsets, all of one kind (near_row sorts them so): in box 2 or only in box 3,
// touching Q_c (gap 0) or not, beyond Q_c's edge along u, along v.
template <bool box2, bool touching, bool along_u, bool along_v>
__attribute__((always_inline)) inline void near_group(const NearOffset* offsets, int count, int j0,
                                                      Shorts apex, NearSums& sums) {
  // the accumulators in locals for the loop (kept in the struct, GCC stores them back every offset)
  Shorts ru = sums.ru, rv = sums.rv, ru3 = sums.ru3, rv3 = sums.rv3, steep = sums.steep;
  Shorts touch = sums.touch, any = sums.any, any3 = sums.any3;
  for (int o = 0; o < count; ++o) {
    const NearOffset& offset = offsets[o];
    const Shorts top = load_shorts(offset.top + j0);
    const Shorts flag = bits(top, apex);
    any3 |= flag;
    if (along_u) {
      const Shorts u = load_shorts(offset.along_u + j0) & flag;
      ru3 = larger(ru3, u);
      if (box2) ru = larger(ru, u);
    }
    if (along_v) {
      const Shorts v = load_shorts(offset.along_v + j0) & flag;
      rv3 = larger(rv3, v);
      if (box2) rv = larger(rv, v);
    }
    if (box2) {
      any |= flag;
      if (touching) {
        touch |= flag;
      } else {  // + 1 where above (flag is -1 there): below the apex the term stays 0
        const Shorts rise = (top - apex) & flag;
        steep = larger(steep, high_product(rise, Shorts{} + offset.inverse_gap) - flag);
      }
    }
  }
  sums = {ru, rv, ru3, rv3, steep, touch, any, any3};
}

// Lanes [16 h, 16 h + 16) of an accumulator as floats (exact: below 2^16). A shuffle, not a copy
// through memory: taking the accumulators' addresses kept them on the stack in the loops.
inline Floats half_floats(Shorts v, [[maybe_unused]] int h) {
#if DISPLACE_NEAR_LANES == 16
  return __builtin_convertvector(v, Floats);
#else
  const HalfShorts half =
      h == 0 ? __builtin_shufflevector(v, v, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15)
             : __builtin_shufflevector(v, v, 16, 17, 18, 19, 20, 21, 22, 23, 24, 25, 26, 27, 28, 29, 30, 31);
  return __builtin_convertvector(half, Floats);
#endif
}

// The bounds of a block's texels from their accumulators, in float, 16 at a time: 1 / G and 1 / (the gap
// term) carry a few roundings of 2^-24 each (squares, sum, root, the products with the units,
// quotient), all within near_shrink; the units are rounded up.
inline void finish_texels(const NearSums& sums, float rate_unit, float steep_unit, float* near,
                          float* slope3) {
  constexpr float infinite = std::numeric_limits<float>::infinity();
  const Floats zero = Floats{} + 0.0f, inf = Floats{} + infinite, shrink = Floats{} + (1.0f - 4e-6f);
  for (int h = 0; h < near_lanes / float_lanes; ++h) {
    const Floats ru = half_floats(sums.ru, h), rv = half_floats(sums.rv, h);
    const Floats ru3 = half_floats(sums.ru3, h), rv3 = half_floats(sums.rv3, h);
    const Floats g3 = square_root(ru3 * ru3 + rv3 * rv3) * rate_unit;
    const Floats g = square_root(ru * ru + rv * rv) * rate_unit;
    const Floats steep = half_floats(sums.steep, h) * steep_unit;
    const Floats any3 = half_floats(sums.any3, h), any = half_floats(sums.any, h),
                 touch = half_floats(sums.touch, h);
    const Floats slope3_bound = any3 == zero ? inf : g3 > zero ? shrink / g3 : zero;
    const Floats slope_bound = g > zero ? shrink / g : zero;
    const Floats far = touch != zero ? zero : shrink / steep;  // steep 0: infinity
    const Floats near_bound = any == zero ? inf : larger(far, slope_bound);
    std::memcpy(near + h * float_lanes, &near_bound, sizeof near_bound);
    std::memcpy(slope3 + h * float_lanes, &slope3_bound, sizeof slope3_bound);
  }
}

void near_row_kernel(const NearRowJob& job) {
  const int width = job.width;
  const int* counts = job.group_counts;
  // the groups in near_row's order: box 2 touching, box 2 not touching, box 3 only; each beyond u
  // only, v only, both
  int first[near_groups + 1] = {0};
  for (int g = 0; g < near_groups; ++g) first[g + 1] = first[g] + counts[g];
  const NearOffset* offsets = job.offsets;
  auto block = [&](int j0, const std::uint16_t* apex_values, float* near, float* slope3) {
    const Shorts zero = Shorts{} + 0;
    NearSums sums{zero, zero, zero, zero, zero, zero, zero, zero};
    // one unit below floor(H_c * 65535): a sub-cell maximum that saturated at 65535 (above 1 by its
    // slack) still has its rise counted in full
    const Shorts raw = load_shorts(apex_values + j0), apex = raw > 0 ? raw - 1 : raw;
    near_group<true, true, true, false>(offsets + first[0], counts[0], j0, apex, sums);
    near_group<true, true, false, true>(offsets + first[1], counts[1], j0, apex, sums);
    near_group<true, true, true, true>(offsets + first[2], counts[2], j0, apex, sums);
    near_group<true, false, true, false>(offsets + first[3], counts[3], j0, apex, sums);
    near_group<true, false, false, true>(offsets + first[4], counts[4], j0, apex, sums);
    near_group<true, false, true, true>(offsets + first[5], counts[5], j0, apex, sums);
    near_group<false, false, true, false>(offsets + first[6], counts[6], j0, apex, sums);
    near_group<false, false, false, true>(offsets + first[7], counts[7], j0, apex, sums);
    near_group<false, false, true, true>(offsets + first[8], counts[8], j0, apex, sums);
    finish_texels(sums, job.rate_unit, job.steep_unit, near, slope3);
  };
  int j0 = 0;
  for (; j0 + near_lanes <= width; j0 += near_lanes) block(j0, job.apex, job.near + j0, job.slope3 + j0);
  if (j0 < width) {
    // the tail: a block ending at the row's end where the row has them (recomputing a few),
    // else through a padded copy (the planes hold near_lanes values past every texel they serve)
    if (width >= near_lanes) {
      block(width - near_lanes, job.apex, job.near + width - near_lanes, job.slope3 + width - near_lanes);
    } else {
      std::uint16_t apex[near_lanes];
      float near[near_lanes], slope3[near_lanes];
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
