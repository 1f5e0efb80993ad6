// bake/lane_sweep_avx512.cpp - the lane sweep for x86-64-v4 (AVX-512 BW): 32 lanes in one register.
// Compiled with -march=x86-64-v4 (bake/CMakeLists.txt); called only where the CPU has it.
// GCC 12 warns inside its own AVX-512 headers (a known false positive of the reduce intrinsics)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"
#include <immintrin.h>

#include "bake/apex_kernel.h"
#include "bake/lane_sweep.h"
#include "bake/near_field_kernel.h"
#include "bake/stage_l_combine_kernel.h"
#include "bake/sub_cell_kernel.h"

namespace displace::bake::detail {
namespace {

struct Ops {
  using V = __m512i;
  static V load(const std::uint16_t* p) { return _mm512_load_si512(p); }
  static void store(std::uint16_t* p, V v) { _mm512_store_si512(p, v); }
  static V broadcast(std::uint16_t x) { return _mm512_set1_epi16(short(x)); }
  static V max(V a, V b) { return _mm512_max_epu16(a, b); }
  static V subs(V a, V b) { return _mm512_subs_epu16(a, b); }
  static bool same(V a, V b) { return _mm512_cmpneq_epu16_mask(a, b) == 0; }
  static unsigned mask_at_most(V a, V b) { return unsigned(_mm512_cmple_epu16_mask(a, b)); }
  static void store_mask_at_most(std::uint32_t* p, V a, V b) {
    _store_mask32(reinterpret_cast<__mmask32*>(p), _mm512_cmple_epu16_mask(a, b));
  }
  static long long sum(const std::uint16_t* p, int texels) {
    // (value - 32768) fits a signed 16-bit number; madd adds neighbours into 32-bit ones, and a row
    // of up to 32768 texels stays within 32 bits per part
    const __m512i bias = _mm512_set1_epi16(short(0x8000)), ones = _mm512_set1_epi16(1);
    __m512i parts = _mm512_setzero_si512();
    for (int t = 0; t < texels; ++t)
      parts = _mm512_add_epi32(
          parts, _mm512_madd_epi16(_mm512_xor_si512(load(p + std::size_t(t) * 32), bias), ones));
    // the 16 parts added in 64 bits: their sum can pass 2^31 (a 32-bit reduction overflowed, found by UBSan)
    alignas(64) int part[16];
    _mm512_store_si512(part, parts);
    long long total = 32768ll * 32 * texels;
    for (int k = 0; k < 16; ++k) total += part[k];
    return total;
  }
};

}  // namespace
}  // namespace displace::bake::detail

#include "bake/lane_sweep_kernel.h"

namespace displace::bake::detail {

namespace {

// Four vectors of 16 values, one per quadrant, stored texel by texel: out[4 t + q] = ratio[q][t] (a
// 4 x 4 transpose per 128-bit lane and one across them).
void store_interleaved(const __m512 (&ratio)[4], float* out) {
  const __m512 t0 = _mm512_unpacklo_ps(ratio[0], ratio[1]), t1 = _mm512_unpackhi_ps(ratio[0], ratio[1]);
  const __m512 t2 = _mm512_unpacklo_ps(ratio[2], ratio[3]), t3 = _mm512_unpackhi_ps(ratio[2], ratio[3]);
  const __m512 u0 = _mm512_shuffle_ps(t0, t2, 0x44), u1 = _mm512_shuffle_ps(t0, t2, 0xEE);
  const __m512 u2 = _mm512_shuffle_ps(t1, t3, 0x44), u3 = _mm512_shuffle_ps(t1, t3, 0xEE);
  const __m512 v0 = _mm512_shuffle_f32x4(u0, u1, 0x44), v1 = _mm512_shuffle_f32x4(u2, u3, 0x44);
  const __m512 v2 = _mm512_shuffle_f32x4(u0, u1, 0xEE), v3 = _mm512_shuffle_f32x4(u2, u3, 0xEE);
  _mm512_storeu_ps(out, _mm512_shuffle_f32x4(v0, v1, 0x88));
  _mm512_storeu_ps(out + 16, _mm512_shuffle_f32x4(v0, v1, 0xDD));
  _mm512_storeu_ps(out + 32, _mm512_shuffle_f32x4(v2, v3, 0x88));
  _mm512_storeu_ps(out + 48, _mm512_shuffle_f32x4(v2, v3, 0xDD));
}

}  // namespace

void lane_sweep_avx512(LaneSweepJob& job) { sweep_kernel<Ops>(job); }
void near_row_avx512(const NearRowJob& job) { near_row_kernel(job); }

void apex_blocks_avx512(const float* const (&rows)[3], int first, int blocks, float* apex,
                        std::uint16_t* bottom) {
  typedef float F __attribute__((vector_size(32)));
  typedef double D __attribute__((vector_size(64)));
  typedef std::int32_t I __attribute__((vector_size(32)));
  typedef std::uint16_t U __attribute__((vector_size(16)));
  apex_blocks<F, D, I, U>(rows, first, blocks, apex, bottom);
}

// Sixteen texels at a time: the count from the mask's leading zeros (the mask is 2^count - 1), the
// ratio from a 32-entry table in two registers (count 32 blended in), and the four quadrants'
// ratios interleaved with a 4 x 4 transpose per 128-bit lane and one across them. A block with a
// texel below the lowest lane goes to the scalar emit_texels.
void lane_emit_avx512(LaneEmitJob& job, std::size_t first, std::size_t last) {
  const __m512 ratios_low = _mm512_loadu_ps(job.lane_ratio),
               ratios_high = _mm512_loadu_ps(job.lane_ratio + 16);
  alignas(64) int pending_table[32];
  for (int c = 0; c < 32; ++c) pending_table[c] = job.pending_count[c];
  const __m512i pending_low = _mm512_load_si512(pending_table),
                pending_high = _mm512_load_si512(pending_table + 16);
  const __m512 top_ratio = _mm512_set1_ps(job.lane_ratio[32]);
  const __m512i all_lanes = _mm512_set1_epi32(32), none = _mm512_setzero_si512();
  const __m512i pending_all = _mm512_set1_epi32(job.pending_count[32]);
  __m512 sum = _mm512_setzero_ps();
  __m512i pending = _mm512_setzero_si512();
  double ratio_sum = 0.0;
  std::size_t t = first;
  for (; t + 16 <= last; t += 16) {
    __m512i count[4];
    __mmask16 empty = 0;
    for (int q = 0; q < 4; ++q) {
      count[q] = _mm512_sub_epi32(all_lanes, _mm512_lzcnt_epi32(_mm512_loadu_si512(job.masks[q] + t)));
      empty |= _mm512_cmpeq_epi32_mask(count[q], none);
    }
    if (empty) {  // a texel below the lowest lane: its neighbours decide (lane_floor), one at a time
      emit_texels(job, t, t + 16);
      continue;
    }
    __m512 ratio[4];
    for (int q = 0; q < 4; ++q) {
      const __mmask16 full = _mm512_cmpeq_epi32_mask(count[q], all_lanes);
      const __m512 r =
          _mm512_mask_blend_ps(full, _mm512_permutex2var_ps(ratios_low, count[q], ratios_high), top_ratio);
      ratio[q] = r;
      sum = _mm512_add_ps(sum, r);
      const __m512i p = _mm512_permutex2var_epi32(pending_low, count[q], pending_high);
      pending = _mm512_add_epi32(pending, _mm512_mask_blend_epi32(full, p, pending_all));
    }
    store_interleaved(ratio, job.out + t * 4);
    if (((t - first) & 1023) == 1008) {  // every 64 steps, into double before float sums drift
      ratio_sum += _mm512_reduce_add_ps(sum);
      sum = _mm512_setzero_ps();
    }
  }
  job.ratio_sum += ratio_sum + _mm512_reduce_add_ps(sum);
  job.pending += _mm512_reduce_add_epi32(pending);
  emit_texels(job, t, last);
}

// Sixteen texels at a time: the floor's quotient in two vectors of 8 doubles (the scalar loop's
// operations: a difference of floats, exact in double, a quotient, a product, a rounding to float),
// the lane table in two registers (count 32 blended in), and the quadrants interleaved as
// lane_emit_avx512 does. The rest of the row goes to the scalar loop.
void stage_l_combine_avx512(const StageLCombineJob& job) {
  const __m512 ratios_low = _mm512_loadu_ps(job.lane_ratio),
               ratios_high = _mm512_loadu_ps(job.lane_ratio + 16);
  const __m512 top_ratio = _mm512_set1_ps(job.lane_ratio[32]), one = _mm512_set1_ps(1.0f);
  const __m512 lipschitz = _mm512_set1_ps(job.lipschitz), highest = _mm512_set1_ps(job.highest);
  const __m512d highest_double = _mm512_set1_pd(double(job.highest)),
                half_texel = _mm512_set1_pd(job.half_texel);
  const __m512d shrink = _mm512_set1_pd(1.0 - 1e-6), one_double = _mm512_set1_pd(1.0);
  const __m512i all_lanes = _mm512_set1_epi32(32);
  int j = 0;
  for (; j + 16 <= job.width; j += 16) {
    const __m512 apex = _mm512_loadu_ps(job.apex + j);
    const __mmask16 below = _mm512_cmp_ps_mask(apex, highest, _CMP_LT_OQ);  // highest > apex
    __m256 quotient[2];
    for (int half = 0; half < 2; ++half) {
      const __m512d apex_double =
          _mm512_cvtps_pd(half == 0 ? _mm512_castps512_ps256(apex) : _mm512_extractf32x8_ps(apex, 1));
      const __m512d gap = _mm512_sub_pd(highest_double, apex_double);
      const __mmask8 used = __mmask8(half == 0 ? below : below >> 8);
      const __m512d divisor = _mm512_mask_blend_pd(used, one_double, gap);  // 1 where not used
      quotient[half] = _mm512_cvtpd_ps(_mm512_mul_pd(_mm512_div_pd(half_texel, divisor), shrink));
    }
    const __m512 floor = _mm512_mask_blend_ps(
        below, one, _mm512_insertf32x8(_mm512_castps256_ps512(quotient[0]), quotient[1], 1));
    __m512 ratio[4];
    for (int q = 0; q < 4; ++q) {
      auto lanes = [&](const std::uint8_t* counts) {
        const __m512i count =
            _mm512_cvtepu8_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(counts + j)));
        const __mmask16 full = _mm512_cmpeq_epi32_mask(count, all_lanes);
        return _mm512_mask_blend_ps(full, _mm512_permutex2var_ps(ratios_low, count, ratios_high), top_ratio);
      };
      const __m512 beyond2 = _mm512_max_ps(floor, lanes(job.passed[q]));
      const __m512 beyond3 = _mm512_max_ps(floor, lanes(job.passed3[q]));
      const __m512 slope3 = _mm512_loadu_ps(job.slope3[q] + j), near = _mm512_loadu_ps(job.near[q] + j);
      ratio[q] = _mm512_max_ps(
          _mm512_min_ps(_mm512_min_ps(beyond3, _mm512_max_ps(beyond2, slope3)), _mm512_min_ps(near, one)),
          lipschitz);
    }
    store_interleaved(ratio, job.out + std::size_t(j) * 4);
  }
  stage_l_combine_kernel(job, j, job.width);
}

void sub_cell_row_avx512(const SubCellRowJob& job) {
  typedef float V __attribute__((vector_size(64)));
  typedef std::int32_t I __attribute__((vector_size(64)));
  typedef std::uint16_t U __attribute__((vector_size(32)));
  sub_cell_row_kernel<V, I, U>(job);
}

}  // namespace displace::bake::detail
