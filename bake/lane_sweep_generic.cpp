// bake/lane_sweep_generic.cpp - the lane sweep for any CPU: 32 lanes as a GCC/Clang vector type,
// which the compiler maps onto whatever vector unit the baseline target has.
// the vector type never crosses a function boundary that another translation unit sees
#pragma GCC diagnostic ignored "-Wpsabi"

#include "bake/apex_kernel.h"
#include "bake/lane_sweep.h"
#include "bake/near_field_kernel.h"
#include "bake/stage_l_combine_kernel.h"
#include "bake/sub_cell_kernel.h"

namespace displace::bake::detail {
namespace {

struct Ops {
  typedef std::uint16_t V __attribute__((vector_size(64), aligned(64)));
  static V load(const std::uint16_t* p) { return *reinterpret_cast<const V*>(p); }
  static void store(std::uint16_t* p, V v) { *reinterpret_cast<V*>(p) = v; }
  static V broadcast(std::uint16_t x) { return V{} + x; }
  static V max(V a, V b) { return a > b ? a : b; }
  static V subs(V a, V b) { return max(a, b) - b; }
  static bool same(V a, V b) {
    for (int l = 0; l < lane_count; ++l)
      if (a[l] != b[l]) return false;
    return true;
  }
  static unsigned mask_at_most(V a, V b) {
    unsigned mask = 0;
    for (int l = 0; l < lane_count; ++l) mask |= unsigned(a[l] <= b[l]) << l;
    return mask;
  }
  static void store_mask_at_most(std::uint32_t* p, V a, V b) { *p = mask_at_most(a, b); }
  static long long sum(const std::uint16_t* p, int texels) {
    long long total = 0;
    for (std::size_t n = 0; n < std::size_t(texels) * lane_count; ++n) total += p[n];
    return total;
  }
};

}  // namespace
}  // namespace displace::bake::detail

#include "bake/lane_sweep_kernel.h"

namespace displace::bake::detail {

void lane_sweep_generic(LaneSweepJob& job) { sweep_kernel<Ops>(job); }
void near_row_generic(const NearRowJob& job) { near_row_kernel(job); }

void apex_blocks_generic(const float* const (&rows)[3], int first, int blocks, float* apex,
                         std::uint16_t* bottom) {
  typedef float F __attribute__((vector_size(8)));
  typedef double D __attribute__((vector_size(16)));
  typedef std::int32_t I __attribute__((vector_size(8)));
  typedef std::uint16_t U __attribute__((vector_size(4)));
  apex_blocks<F, D, I, U>(rows, first, blocks, apex, bottom);
}
void lane_emit_generic(LaneEmitJob& job, std::size_t first, std::size_t last) {
  emit_texels(job, first, last);
}

void stage_l_combine_generic(const StageLCombineJob& job) { stage_l_combine_kernel(job, 0, job.width); }

void sub_cell_row_generic(const SubCellRowJob& job) {
  typedef float V __attribute__((vector_size(16)));
  typedef std::int32_t I __attribute__((vector_size(16)));
  typedef std::uint16_t U __attribute__((vector_size(8)));
  sub_cell_row_kernel<V, I, U>(job);
}

}  // namespace displace::bake::detail
