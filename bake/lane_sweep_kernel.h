// bake/lane_sweep_kernel.h - the quadrant sweep of lane_sweep.cpp, written once over a lane type.
//
// Included by one translation unit per instruction set, after it defines its Ops inside an unnamed
// namespace; everything here is in that unnamed namespace too and uses no standard-library
// templates, so that no function compiled for one instruction set is shared with a translation
// unit built for another.
//
// Ops provides, for V = 32 unsigned 16-bit lanes:
//   static V load(const std::uint16_t* p);    p 64-byte aligned
//   static void store(std::uint16_t* p, V v);
//   static V broadcast(std::uint16_t x);
//   static V max(V a, V b);
//   static V subs(V a, V b);                  saturating a - b
//   static bool same(V a, V b);               every lane equal
//   static unsigned mask_at_most(V a, V b);   bit l set where lane l of a <= lane l of b
//   static void store_mask_at_most(std::uint32_t* p, V a, V b);  the same, stored
//   static long long sum(const std::uint16_t* p, int texels);  the sum of texels * 32 values
#pragma once

#include <cstdint>

#include "bake/lane_sweep.h"

namespace displace::bake::detail {
namespace {

constexpr int lane_stride = lane_count;  // u16 per texel in a row buffer

// octant: only the moves that advance a row - (1, 0), (1, 1) and the knight (2, 1) - whose paths
// reach exactly the octant 0 <= db <= da of the quadrant; no carry along the row, so no wrap fix-up.
template <class Ops, bool knights, bool octant, bool bilinear>
void sweep_kernel(LaneSweepJob& job) {
  using V = typename Ops::V;
  const int W = job.width, H = job.height;
  const bool wrap = job.wrap;
  const bool flip_x = job.flip_x;
  const std::size_t row_values = std::size_t(W + 2) * lane_stride;  // two padding texels past the end
  // Two row buffers: local rows a + 1 and a + 2. Row a is written over row a + 2 as the sweep goes
  // (each texel of row a + 2 is read once more, one texel later, so it is kept in a register), and
  // the two then swap roles. Nothing lies below the first row swept.
  std::uint16_t* below1 = job.scratch;
  std::uint16_t* below2 = below1 + row_values;
  for (std::size_t n = 0; n < 2 * row_values; ++n) job.scratch[n] = 0;

  const V step_row = Ops::load(job.steps + 0 * lane_count);
  const V step_up = Ops::load(job.steps + 1 * lane_count);
  const V step_diagonal = Ops::load(job.steps + 2 * lane_count);
  const V step_knight_row = Ops::load(job.steps + 3 * lane_count);
  const V step_knight_up = Ops::load(job.steps + 4 * lane_count);
  const V nothing = Ops::broadcast(0);

  // With wrap, the first lap's rows miss the blockers past the seam; its last two rows miss none
  // within uv distance 1, so a second lap from them sweeps the map again with everything. Dilations
  // only grow from the first lap to the second, so a row of the second lap equals the first lap's
  // exactly when their sums are equal; after two equal rows in a row, every later row is equal too
  // (a row depends only on the two below it), and the first lap's masks there stand. The first
  // lap's sums are kept for the rows the second lap may reach before that; past them it goes on to
  // the end of the map.
  // Bilinear mode: the row's dilations over blockers e (with the wrap fix-up) are kept in
  // `dilations` (cell n at n + 1; one padding cell before and four after, wrapped or empty), and
  // three rows of texel accumulators take them: a texel row is begun by the cell row two past it
  // (its three face cells there), gets the face cell two columns on from the two rows after, and is
  // tested when the last of them is done. The accumulators go round by step, so a row begun at
  // step s is tested at step s + 2. The box {0, ..., 3}^2 does the same with four rows.
  std::uint16_t* dilations = bilinear ? job.bilinear_scratch : nullptr;
  std::uint16_t* accumulators = bilinear ? dilations + (std::size_t(W) + 5) * lane_stride : nullptr;
  const int texel_width = job.texel_width, texel_height = job.texel_height;
  std::uint16_t* accumulators3 = bilinear ? accumulators + 3 * std::size_t(texel_width) * lane_stride : nullptr;
  if (bilinear)
    for (std::size_t n = 0; n < (std::size_t(W) + 5 + 7 * std::size_t(texel_width)) * lane_stride; ++n)
      dilations[n] = 0;

  const int tracked = wrap ? (H + 1) / 2 + 1 : 0;  // first-lap rows whose sums are kept
  long long* row_sums = job.row_sums;
  int equal_rows = 0;
  long long work = 0;
  // Bilinear mode: a texel row tested at the start of the second lap reads the dilations of the
  // first lap's last three rows, which may still miss blockers past the seam. They are complete when
  // the second lap stops before reaching them (equal to its rows); otherwise the sweep goes on for
  // three rows of a third lap, which re-test those texel rows from the second lap's complete rows.
  const int swept_rows = wrap ? (bilinear ? 2 * H + 3 : 2 * H) : H;
  for (int step = 0; step < swept_rows; ++step) {
    const bool second_lap = step >= H;
    const int a = H - 1 - (step % H);
    const int physical_row = job.flip_y ? H - 1 - a : a;
    const std::uint16_t* top_row = job.top + std::size_t(physical_row) * W;
    const std::uint16_t* bottom_row = bilinear ? nullptr : job.bottom + std::size_t(physical_row) * W;
    // masks go where the caller wants them: a transposed sweep writes them back in the map's layout
    std::uint32_t* mask_row = bilinear ? nullptr : job.masks + std::size_t(physical_row) * job.mask_row_stride;
    const std::size_t mask_step = job.mask_column_stride;
    const int first = flip_x ? W - 1 : 0, stride = flip_x ? -1 : 1;

    // The row from its last texel to its first. A texel's dilation over its blockers e comes from
    // the two rows below and from the texel after it (carry); with the texel itself it is what the
    // texels before it see. The texel passes lane l when nothing in the quadrant rises above its
    // cone of ratio lane l (bit l of its mask); lanes pass from the smallest ratio up. Row a + 1's
    // texels b + 1 and b + 2 and row a + 2's texel b + 1 come in registers from the texels before.
    V carry = nothing;
    V next1 = Ops::load(below1 + std::size_t(W) * lane_stride),
      next2 = Ops::load(below1 + std::size_t(W + 1) * lane_stride);
    V knight_source = knights ? Ops::load(below2 + std::size_t(W) * lane_stride) : nothing;
    for (int b = W - 1; b >= 0; --b) {
      const V here = Ops::load(below1 + std::size_t(b) * lane_stride);
      std::uint16_t* target = below2 + std::size_t(b) * lane_stride;
      V e = Ops::max(Ops::subs(here, step_up), Ops::subs(next1, step_diagonal));
      if (knights) {
        if (!octant) e = Ops::max(e, Ops::subs(next2, step_knight_row));
        e = Ops::max(e, Ops::subs(knight_source, step_knight_up));
        knight_source = Ops::load(target);
      }
      if (!octant) e = Ops::max(e, carry);
      const int column = first + stride * b;
      const V d = Ops::max(e, Ops::broadcast(top_row[column]));
      Ops::store(target, d);
      if (bilinear)
        Ops::store(dilations + std::size_t(b + 1) * lane_stride, e);
      else
        Ops::store_mask_at_most(mask_row + column * mask_step, e, Ops::broadcast(bottom_row[column]));
      if (!octant) carry = Ops::subs(d, step_row);
      next2 = next1;
      next1 = here;
    }
    work += W;
    if (wrap && !octant) {
      // Blockers past the row's first texel come round from its last: at most one more lap. A
      // texel's dilation over blockers becomes max(old, carry), and so does its dilation with
      // itself; a lane passes now when it passed before and the carry passes it. Once the carry
      // does not raise a texel's dilation, nothing after it changes.
      for (int b = W - 1; b >= 0; --b) {
        std::uint16_t* target = below2 + std::size_t(b) * lane_stride;
        const V old_d = Ops::load(target);
        const V d = Ops::max(old_d, carry);
        const int column = first + stride * b;
        if (bilinear) {
          std::uint16_t* kept = dilations + std::size_t(b + 1) * lane_stride;
          Ops::store(kept, Ops::max(Ops::load(kept), carry));
        } else {
          mask_row[column * mask_step] &= Ops::mask_at_most(carry, Ops::broadcast(bottom_row[column]));
        }
        ++work;
        if (Ops::same(d, old_d)) break;
        Ops::store(target, d);
        carry = Ops::subs(d, step_row);
      }
    }
    if (wrap) {
      for (int k = 0; k < 2; ++k)
        Ops::store(below2 + std::size_t(W + k) * lane_stride,
                   Ops::load(below2 + std::size_t(k % W) * lane_stride));
    } else {
      Ops::store(below2 + std::size_t(W) * lane_stride, nothing);
      Ops::store(below2 + std::size_t(W + 1) * lane_stride, nothing);
    }

    if (bilinear) {
      // padding: the cell before the first and the two after the last, wrapped or empty
      Ops::store(dilations, wrap ? Ops::load(dilations + std::size_t(W) * lane_stride) : nothing);
      for (int k = 0; k < 4; ++k)
        Ops::store(dilations + std::size_t(W + 1 + k) * lane_stride,
                   wrap ? Ops::load(dilations + std::size_t(1 + k % W) * lane_stride) : nothing);
      // local texel rows begun, continued and tested by cell row a (unrolled with wrap)
      auto texel_row = [&](int row) { return wrap ? ((row % texel_height) + texel_height) % texel_height : row; };
      const int begun = texel_row(a - 2 - job.cell_offset_y), continued = texel_row(a - 1 - job.cell_offset_y),
                tested = texel_row(a - job.cell_offset_y);
      const bool begin = begun >= 0 && begun < texel_height, go_on = continued >= 0 && continued < texel_height,
                 test = tested >= 0 && tested < texel_height;
      std::uint16_t* begin_row = accumulators + std::size_t((step + 2) % 3) * texel_width * lane_stride;
      std::uint16_t* go_on_row = accumulators + std::size_t((step + 1) % 3) * texel_width * lane_stride;
      std::uint16_t* test_row = accumulators + std::size_t(step % 3) * texel_width * lane_stride;
      const int physical_texel_row = job.flip_y ? texel_height - 1 - tested : tested;
      const std::uint16_t* apex_row = job.texel_bottom + std::size_t(test ? physical_texel_row : 0) * texel_width;
      std::uint32_t* texel_masks = job.masks + std::size_t(test ? physical_texel_row : 0) * texel_width;
      const V bonus = Ops::load(job.bonus);
      // cells b + offset, + 1, + 2 of this row are at dilations[b + offset + 1 ...]
      const std::uint16_t* cells = dilations + std::size_t(1 + job.cell_offset_x) * lane_stride;
      // the box {0, ..., 3}^2: begun three rows before its test, four accumulators round by step
      const int begun3 = texel_row(a - 3 - job.cell_offset_y);
      const int middle[2] = {texel_row(a - 2 - job.cell_offset_y), texel_row(a - 1 - job.cell_offset_y)};
      const bool begin3 = begun3 >= 0 && begun3 < texel_height;
      std::uint16_t* begin3_row = accumulators3 + std::size_t((step + 3) % 4) * texel_width * lane_stride;
      std::uint16_t* middle_rows[2] = {accumulators3 + std::size_t((step + 2) % 4) * texel_width * lane_stride,
                                       accumulators3 + std::size_t((step + 1) % 4) * texel_width * lane_stride};
      const bool middle_valid[2] = {middle[0] >= 0 && middle[0] < texel_height,
                                    middle[1] >= 0 && middle[1] < texel_height};
      std::uint16_t* test3_row = accumulators3 + std::size_t(step % 4) * texel_width * lane_stride;
      std::uint32_t* texel_masks3 = job.masks3 + std::size_t(test ? physical_texel_row : 0) * texel_width;
      const V bonus3 = Ops::load(job.bonus3);
      if (begin && go_on && test && begin3 && middle_valid[0] && middle_valid[1]) {
        // every row in the map (all of them with wrap): both boxes in one pass, the four cells in
        // registers as the window slides
        V c0 = Ops::load(cells), c1 = Ops::load(cells + lane_stride), c2 = Ops::load(cells + 2 * lane_stride);
        for (int b = 0; b < texel_width; ++b) {
          const V c3 = Ops::load(cells + std::size_t(b + 3) * lane_stride);
          const std::size_t at = std::size_t(b) * lane_stride;
          const V first3 = Ops::max(Ops::max(c0, c1), c2);
          Ops::store(begin_row + at, first3);
          Ops::store(go_on_row + at, Ops::max(Ops::load(go_on_row + at), c2));
          Ops::store(begin3_row + at, Ops::max(first3, c3));
          Ops::store(middle_rows[0] + at, Ops::max(Ops::load(middle_rows[0] + at), c3));
          Ops::store(middle_rows[1] + at, Ops::max(Ops::load(middle_rows[1] + at), c3));
          const int column = job.flip_x ? texel_width - 1 - b : b;
          const V apex = Ops::broadcast(apex_row[column]);
          Ops::store_mask_at_most(texel_masks + column, Ops::subs(Ops::max(Ops::load(test_row + at), c2), bonus), apex);
          Ops::store_mask_at_most(texel_masks3 + column, Ops::subs(Ops::max(Ops::load(test3_row + at), c3), bonus3),
                                  apex);
          c0 = c1;
          c1 = c2;
          c2 = c3;
        }
      } else {
        for (int b = 0; b < texel_width; ++b) {
          const V c0 = Ops::load(cells + std::size_t(b) * lane_stride), c1 = Ops::load(cells + std::size_t(b + 1) * lane_stride),
                  c2 = Ops::load(cells + std::size_t(b + 2) * lane_stride);
          const std::size_t at = std::size_t(b) * lane_stride;
          if (begin) Ops::store(begin_row + at, Ops::max(Ops::max(c0, c1), c2));
          if (go_on) Ops::store(go_on_row + at, Ops::max(Ops::load(go_on_row + at), c2));
          if (test) {
            const V all = Ops::max(Ops::load(test_row + at), c2);
            const int column = job.flip_x ? texel_width - 1 - b : b;
            Ops::store_mask_at_most(texel_masks + column, Ops::subs(all, bonus), Ops::broadcast(apex_row[column]));
          }
        }
        if (!begin)  // a row that begins past the end of the cells (clamp) starts empty
          for (std::size_t n = 0; n < std::size_t(texel_width) * lane_stride; ++n) begin_row[n] = 0;
        for (int b = 0; b < texel_width; ++b) {
          const V c3 = Ops::load(cells + std::size_t(b + 3) * lane_stride);
          const std::size_t at = std::size_t(b) * lane_stride;
          if (begin3)
            Ops::store(begin3_row + at,
                       Ops::max(Ops::max(Ops::load(cells + std::size_t(b) * lane_stride),
                                         Ops::load(cells + std::size_t(b + 1) * lane_stride)),
                                Ops::max(Ops::load(cells + std::size_t(b + 2) * lane_stride), c3)));
          for (int k = 0; k < 2; ++k)
            if (middle_valid[k]) Ops::store(middle_rows[k] + at, Ops::max(Ops::load(middle_rows[k] + at), c3));
          if (test) {
            const V all = Ops::max(Ops::load(test3_row + at), c3);
            const int column = job.flip_x ? texel_width - 1 - b : b;
            Ops::store_mask_at_most(texel_masks3 + column, Ops::subs(all, bonus3), Ops::broadcast(apex_row[column]));
          }
        }
        if (!begin3)
          for (std::size_t n = 0; n < std::size_t(texel_width) * lane_stride; ++n) begin3_row[n] = 0;
      }
      work += texel_width;
    }

    const int lap_row = step % H;  // rows into the lap
    if (lap_row < tracked) {
      const long long row_sum = Ops::sum(below2, W);
      if (!second_lap) {
        row_sums[lap_row] = row_sum;
      } else {
        equal_rows = row_sum == row_sums[lap_row] ? equal_rows + 1 : 0;
        if (equal_rows == 2 && job.stop_early && (!bilinear || (step < 2 * H && a >= 3))) break;
      }
    }
    std::uint16_t* done = below2;  // now row a
    below2 = below1;
    below1 = done;
  }
  job.work = work;
}

template <class Ops>
void sweep_kernel(LaneSweepJob& job) {
  if (job.bilinear)
    job.knights ? sweep_kernel<Ops, true, false, true>(job) : sweep_kernel<Ops, false, false, true>(job);
  else if (job.octant)
    job.knights ? sweep_kernel<Ops, true, true, false>(job) : sweep_kernel<Ops, false, true, false>(job);
  else
    job.knights ? sweep_kernel<Ops, true, false, false>(job) : sweep_kernel<Ops, false, false, false>(job);
}

// The 4-sector output, texels [first, last) one at a time (the AVX-512 translation unit has its own,
// sixteen at a time, and leaves this one the tail and the blocks where a texel passes no lane).
void emit_texels(LaneEmitJob& job, std::size_t first, std::size_t last) {
  float sums[4] = {0.0f, 0.0f, 0.0f, 0.0f};
  long long pending = 0;
  for (std::size_t t = first; t < last; ++t) {
    for (int q = 0; q < 4; ++q) {
      const std::uint32_t mask = job.masks[q][t];
      // lanes pass from the lowest up, so the mask is 2^count - 1
      const int passed = mask == 0 ? 0 : 32 - __builtin_clz(mask);
      const float ratio =
          passed == 0 ? lane_floor(*job.plan, job.heights, t, q, 4).floor : job.lane_ratio[passed];
      job.out[t * 4 + q] = ratio;
      sums[q] += ratio;
      pending += job.pending_count[passed];
    }
  }
  job.ratio_sum += double(sums[0] + sums[1]) + double(sums[2] + sums[3]);
  job.pending += pending;
}

}  // namespace
}  // namespace displace::bake::detail
