// bake/lane_sweep_avx2.cpp - the lane sweep for x86-64-v3 (AVX2): 32 lanes in two 256-bit registers.
// Compiled with -march=x86-64-v3 (bake/CMakeLists.txt); called only where the CPU has it.
// the 16-float vectors of the near field are 512 bits wide, two registers here
#pragma GCC diagnostic ignored "-Wpsabi"
#include <immintrin.h>

#include "bake/apex_kernel.h"
#include "bake/lane_sweep.h"
#include "bake/near_field_kernel.h"
#include "bake/stage_l_combine_kernel.h"
#include "bake/sub_cell_kernel.h"

namespace displace::bake::detail {
namespace {

struct Ops {
  struct V {
    __m256i lo, hi;
  };
  static V load(const std::uint16_t* p) {
    return {_mm256_load_si256(reinterpret_cast<const __m256i*>(p)),
            _mm256_load_si256(reinterpret_cast<const __m256i*>(p + 16))};
  }
  static void store(std::uint16_t* p, V v) {
    _mm256_store_si256(reinterpret_cast<__m256i*>(p), v.lo);
    _mm256_store_si256(reinterpret_cast<__m256i*>(p + 16), v.hi);
  }
  static V broadcast(std::uint16_t x) {
    const __m256i v = _mm256_set1_epi16(short(x));
    return {v, v};
  }
  static V max(V a, V b) { return {_mm256_max_epu16(a.lo, b.lo), _mm256_max_epu16(a.hi, b.hi)}; }
  static V subs(V a, V b) { return {_mm256_subs_epu16(a.lo, b.lo), _mm256_subs_epu16(a.hi, b.hi)}; }
  static bool same(V a, V b) {
    const __m256i equal = _mm256_and_si256(_mm256_cmpeq_epi16(a.lo, b.lo), _mm256_cmpeq_epi16(a.hi, b.hi));
    return _mm256_movemask_epi8(equal) == -1;
  }
  // bit l set where lane l of a is at most lane l of b
  static unsigned mask_at_most(V a, V b) {
    const __m256i lo = _mm256_cmpeq_epi16(_mm256_max_epu16(a.lo, b.lo), b.lo);
    const __m256i hi = _mm256_cmpeq_epi16(_mm256_max_epu16(a.hi, b.hi), b.hi);
    // the pack interleaves the 128-bit halves; the permute puts the lanes back in order
    const __m256i bytes = _mm256_permute4x64_epi64(_mm256_packs_epi16(lo, hi), 0xD8);
    return unsigned(_mm256_movemask_epi8(bytes));
  }
  static void store_mask_at_most(std::uint32_t* p, V a, V b) { *p = mask_at_most(a, b); }
  static long long sum(const std::uint16_t* p, int texels) {
    // (value - 32768) fits a signed 16-bit number; madd adds neighbours into 32-bit ones, and a row
    // of up to 32768 texels stays within 32 bits per part
    const __m256i bias = _mm256_set1_epi16(short(0x8000)), ones = _mm256_set1_epi16(1);
    __m256i low = _mm256_setzero_si256(), high = _mm256_setzero_si256();
    for (int t = 0; t < texels; ++t) {
      const V v = load(p + std::size_t(t) * 32);
      low = _mm256_add_epi32(low, _mm256_madd_epi16(_mm256_xor_si256(v.lo, bias), ones));
      high = _mm256_add_epi32(high, _mm256_madd_epi16(_mm256_xor_si256(v.hi, bias), ones));
    }
    alignas(32) int part[16];
    _mm256_store_si256(reinterpret_cast<__m256i*>(part), low);
    _mm256_store_si256(reinterpret_cast<__m256i*>(part + 8), high);
    long long total = 32768ll * 32 * texels;
    for (int k = 0; k < 16; ++k) total += part[k];
    return total;
  }
};

}  // namespace
}  // namespace displace::bake::detail

#include "bake/lane_sweep_kernel.h"

namespace displace::bake::detail {

void lane_sweep_avx2(LaneSweepJob& job) { sweep_kernel<Ops>(job); }
void near_row_avx2(const NearRowJob& job) { near_row_kernel(job); }

void apex_blocks_avx2(const float* const (&rows)[3], int first, int blocks, float* apex,
                      std::uint16_t* bottom) {
  typedef float F __attribute__((vector_size(16)));
  typedef double D __attribute__((vector_size(32)));
  typedef std::int32_t I __attribute__((vector_size(16)));
  typedef std::uint16_t U __attribute__((vector_size(8)));
  apex_blocks<F, D, I, U>(rows, first, blocks, apex, bottom);
}
void lane_emit_avx2(LaneEmitJob& job, std::size_t first, std::size_t last) { emit_texels(job, first, last); }

void stage_l_combine_avx2(const StageLCombineJob& job) { stage_l_combine_kernel(job, 0, job.width); }

void sub_cell_row_avx2(const SubCellRowJob& job) {
  typedef float V __attribute__((vector_size(32)));
  typedef std::int32_t I __attribute__((vector_size(32)));
  typedef std::uint16_t U __attribute__((vector_size(16)));
  sub_cell_row_kernel<V, I, U>(job);
}

}  // namespace displace::bake::detail
