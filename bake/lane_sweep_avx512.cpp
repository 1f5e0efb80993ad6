// bake/lane_sweep_avx512.cpp - the lane sweep for x86-64-v4 (AVX-512 BW): 32 lanes in one register.
// Compiled with -march=x86-64-v4 (bake/CMakeLists.txt); called only where the CPU has it.
// GCC 12 warns inside its own AVX-512 headers (a known false positive of the reduce intrinsics)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#include <immintrin.h>

#include "bake/lane_sweep.h"

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
  static long long sum(const std::uint16_t* p, int texels) {
    // (value - 32768) fits a signed 16-bit number; madd adds neighbours into 32-bit ones, and a row
    // of up to 32768 texels stays within 32 bits per part
    const __m512i bias = _mm512_set1_epi16(short(0x8000)), ones = _mm512_set1_epi16(1);
    __m512i parts = _mm512_setzero_si512();
    for (int t = 0; t < texels; ++t)
      parts = _mm512_add_epi32(parts, _mm512_madd_epi16(_mm512_xor_si512(load(p + std::size_t(t) * 32), bias), ones));
    return 32768ll * 32 * texels + _mm512_reduce_add_epi32(parts);
  }
};

}  // namespace
}  // namespace displace::bake::detail

#include "bake/lane_sweep_kernel.h"

namespace displace::bake::detail {

void lane_sweep_avx512(LaneSweepJob& job) { sweep_kernel<Ops>(job); }

}  // namespace displace::bake::detail
