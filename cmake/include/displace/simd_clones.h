// cmake/include/displace/simd_clones.h - DISPLACE_SIMD_CLONES: a function compiled for AVX-512,
// AVX2 and the baseline, the best picked when the program loads (GCC's target_clones). The hot
// loops of sim/ and bake/ that the compiler vectorises by itself use it; kernels written for one
// instruction set have their own files (bake/lane_sweep_avx*.cpp).
//
// Not under ThreadSanitizer: it instruments the clones' resolvers, which the dynamic loader runs
// before TSan's runtime is up (the program dies at load). Not with clang (its target_clones needs
// the names written differently) nor off x86-64.
#pragma once

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(__SANITIZE_THREAD__)
#define DISPLACE_SIMD_CLONES __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#else
#define DISPLACE_SIMD_CLONES
#endif
