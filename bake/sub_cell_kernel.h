// bake/sub_cell_kernel.h - one row of the bilinear baker's sub-cells (cone_bilinear_budgeted.cpp,
// make_sub_cells: a half-texel square's maximum raised by top_slack and its largest rates of rise
// along +u, -u, +v and -v raised by a relative 2^-20 and the slack) over a vector of floats, built per
// instruction set by the lane sweep's translation units; elementwise, so every width gives the same
// bits (LaneSweep.SubCellKernelsAgree). Stored in 16 bits (lane_sweep.h, SubCellRowJob): the float
// value times its scale plus 2, truncated - above the exact product, as the float product is within
// a relative 2^-24 of it and the value below 65535 - and clamped to 65535.
#pragma once

#include <cstddef>
#include <cstring>

#include "bake/lane_sweep.h"

namespace displace::bake::detail {

// V: a vector of floats; I and U: as many 32-bit and 16-bit integers.
template <class V, class I, class U>
inline void sub_cell_row_kernel(const SubCellRowJob& job) {
  constexpr int width = int(sizeof(V) / sizeof(float));
  constexpr float raise = 1.0f + 0x1p-20f;
  const float per_u = job.per_u, per_v = job.per_v, slack_u = job.slack_u, slack_v = job.slack_v;
  const float top_slack = job.top_slack;
  const float top_scale = float(height_scale), rate_scale = job.rate_scale;
  auto quantize = [](auto value, float scale) {
    const auto scaled = value * scale + 2.0f;
    return scaled < 65535.0f ? scaled : scaled * 0.0f + 65535.0f;
  };
  for (int parity = 0; parity < 2; ++parity) {
    // corners X and X + 1 of the sub-cells of this parity
    const float* __restrict left0 = parity ? job.odd0 : job.even0;
    const float* __restrict right0 = parity ? job.even0 + 1 : job.odd0;
    const float* __restrict left1 = parity ? job.odd1 : job.even1;
    const float* __restrict right1 = parity ? job.even1 + 1 : job.odd1;
    std::uint16_t* __restrict top = job.out[0][parity];
    std::uint16_t* __restrict plus_u = job.out[1][parity];
    std::uint16_t* __restrict minus_u = job.out[2][parity];
    std::uint16_t* __restrict plus_v = job.out[3][parity];
    std::uint16_t* __restrict minus_v = job.out[4][parity];
    auto larger = [](auto a, auto b) { return a > b ? a : b; };
    auto load = [](const float* p) {
      V v;
      std::memcpy(&v, p, sizeof v);
      return v;
    };
    auto store = [&](std::uint16_t* p, V v, float scale) {
      const U stored = __builtin_convertvector(__builtin_convertvector(quantize(v, scale), I), U);
      std::memcpy(p, &stored, sizeof stored);
    };
    auto store_one = [&](std::uint16_t* p, float v, float scale) {
      *p = std::uint16_t(int(quantize(v, scale)));
    };
    const V zero = V{} + 0.0f;
    int k = 0;
    for (; k + width <= job.count; k += width) {
      const V a = load(left0 + k), b = load(right0 + k), c = load(left1 + k), d = load(right1 + k);
      const V du0 = (b - a) * per_u, du1 = (d - c) * per_u, dv0 = (c - a) * per_v, dv1 = (d - b) * per_v;
      store(top + k, larger(larger(a, b), larger(c, d)) + top_slack, top_scale);
      store(plus_u + k, larger(zero, larger(du0, du1)) * raise + slack_u, rate_scale);
      store(minus_u + k, larger(zero, larger(-du0, -du1)) * raise + slack_u, rate_scale);
      store(plus_v + k, larger(zero, larger(dv0, dv1)) * raise + slack_v, rate_scale);
      store(minus_v + k, larger(zero, larger(-dv0, -dv1)) * raise + slack_v, rate_scale);
    }
    for (; k < job.count; ++k) {
      const float a = left0[k], b = right0[k], c = left1[k], d = right1[k];
      const float du0 = (b - a) * per_u, du1 = (d - c) * per_u, dv0 = (c - a) * per_v, dv1 = (d - b) * per_v;
      store_one(top + k, larger(larger(a, b), larger(c, d)) + top_slack, top_scale);
      store_one(plus_u + k, larger(0.0f, larger(du0, du1)) * raise + slack_u, rate_scale);
      store_one(minus_u + k, larger(0.0f, larger(-du0, -du1)) * raise + slack_u, rate_scale);
      store_one(plus_v + k, larger(0.0f, larger(dv0, dv1)) * raise + slack_v, rate_scale);
      store_one(minus_v + k, larger(0.0f, larger(-dv0, -dv1)) * raise + slack_v, rate_scale);
    }
  }
}

}  // namespace displace::bake::detail
