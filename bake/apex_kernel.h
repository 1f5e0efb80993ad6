// bake/apex_kernel.h - the bilinear baker's apex heights (bake_bilinear_cones' arithmetic, term for
// term, so that they are its apexes bit for bit) for a span of texels, over a vector of N doubles:
// built per instruction set by the lane sweep's translation units (2 in any CPU's, 4 with AVX2, 8
// with AVX-512: 1.9, about 1 and 0.54 ms for a 512 x 512 map on one core here).
#pragma once

#include <cstdint>
#include <cstring>

#include "bake/lane_sweep.h"

namespace displace::bake::detail {

// The largest of s at Q_c's corners, edge midpoints and centre over the heights h[r][c] around a
// texel (rows before, at and after it, columns likewise): 0.25 (h11 + h1a + hb1 + hba) for a, b in
// {0, 1, 2} - for one texel (double) or several (a vector of doubles).
template <class D>
inline D highest_sample(const D (&h)[3][3]) {
  D highest = h[1][1] * 0.0;
  for (int b = 0; b < 3; ++b)
    for (int a = 0; a < 3; ++a) {
      const D value = 0.25 * (h[1][1] + h[1][a] + h[b][1] + h[b][a]);
      highest = highest < value ? value : highest;
    }
  return highest;
}

// Texels [first, first + N * blocks) of a row whose neighbours j - 1 and j + 1 lie in the row (rows[r]
// the rows before, at and after it): the apex rounded up to float (to the next float's bits where the
// nearest is below) into apex[j], and floor(apex * 65535) a little below, clamped, into bottom[j].
// F, D, I, U: vectors of N floats, doubles, 32-bit and 16-bit integers.
template <class F, class D, class I, class U>
inline void apex_blocks(const float* const (&rows)[3], int first, int blocks, float* apex,
                        std::uint16_t* bottom) {
  constexpr int N = int(sizeof(F) / sizeof(float));
  for (int j = first; j < first + N * blocks; j += N) {
    D h[3][3];
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) {
        F f;
        std::memcpy(&f, rows[r] + j - 1 + c, sizeof f);
        h[r][c] = __builtin_convertvector(f, D);
      }
    const D highest = highest_sample(h);
    const F nearest = __builtin_convertvector(highest, F);
    const I below =
        __builtin_convertvector(__builtin_convertvector(nearest, D) < highest, I);  // -1 where below
    I bits;
    std::memcpy(&bits, &nearest, sizeof bits);
    bits -= below;
    F rounded;
    std::memcpy(&rounded, &bits, sizeof rounded);
    std::memcpy(apex + j, &rounded, sizeof rounded);
    I floor_scaled = __builtin_convertvector(rounded * float(height_scale) - 0x1p-7f, I);
    floor_scaled = floor_scaled < 0 ? 0 : floor_scaled;
    floor_scaled = floor_scaled > 65535 ? 65535 : floor_scaled;
    const U low = __builtin_convertvector(floor_scaled, U);
    std::memcpy(bottom + j, &low, sizeof low);
  }
}

}  // namespace displace::bake::detail
