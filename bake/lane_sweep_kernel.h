// bake/lane_sweep_kernel.h - the quadrant sweep of lane_sweep.cpp, written once over a lane type and
// included by one translation unit per instruction set after it defines its Ops in an unnamed
// namespace; all here is in that namespace too and uses no standard-library templates, so no function
// compiled for one instruction set is shared with a translation unit built for another.
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

// carry: the move (0, 1) along the row (an octant next to the v axis has none, and so no wrap
// fix-up); fixed_rows and fixed_columns: the number of row moves (1, k) and column moves (k, 1) when
// known at compile time (their steps stay in registers), -1 for the job's; bilinear: the mode of
// LaneSweepJob::bilinear.
template <class Ops, bool carry_move, int fixed_rows, int fixed_columns, bool bilinear>
void sweep_kernel(LaneSweepJob& job) {
  using V = typename Ops::V;
  const int W = job.width, H = job.height;
  const bool wrap = job.wrap;
  const bool flip_x = job.flip_x;
  const int row_count = fixed_rows >= 0 ? fixed_rows : job.row_count;
  const int column_count = fixed_columns >= 0 ? fixed_columns : job.column_count;
  const int depth = job.depth, padding = job.padding;
  const std::size_t row_values = std::size_t(W + padding) * lane_stride;
  // Row buffers for local rows a + 1 .. a + depth. Row a is written over row a + depth as the sweep
  // goes (each texel of row a + depth is read once more, one texel later, so it is kept in a
  // register), and the buffers then move down a row. Nothing lies below the first row swept.
  // (A split sweep's part goes on from the buffers as the part before it left them at first_step:
  // after s steps buffer k - 1 - s, mod depth, holds row a + k.)
  const bool split = job.split;
  const bool fresh = !split || job.fresh;
  const int first_step = split ? job.first_step : 0;
  std::uint16_t* below[lane_reach_limit + 1];
  for (int k = 1; k <= depth; ++k)
    below[k] = job.scratch + std::size_t(((k - 1 - first_step) % depth + depth) % depth) * row_values;
  if (fresh)
    for (std::size_t n = 0; n < std::size_t(depth) * row_values; ++n) job.scratch[n] = 0;

  const V step_row = Ops::load(job.steps + lane_move_carry * lane_count);
  const std::uint16_t* row_steps = job.steps + std::size_t(lane_move_row + job.row_first) * lane_count;
  const std::uint16_t* column_steps =
      job.steps + std::size_t(lane_move_column + job.column_first - 2) * lane_count;
  V fixed_row_step[fixed_rows > 0 ? fixed_rows : 1], fixed_column_step[fixed_columns > 0 ? fixed_columns : 1];
  for (int k = 0; k < fixed_rows; ++k) fixed_row_step[k] = Ops::load(row_steps + k * lane_count);
  for (int k = 0; k < fixed_columns; ++k) fixed_column_step[k] = Ops::load(column_steps + k * lane_count);
  // the longest column move reads the row being overwritten (depth is that move's rows); the others
  // read their buffers
  const int column_in_buffers = column_count > 0 ? column_count - 1 : 0;
  const V nothing = Ops::broadcast(0);

  // With wrap, the first lap's rows miss the blockers past the seam; its last `depth` rows miss
  // none within uv distance 1, so a second lap from them sweeps the map again with everything.
  // Dilations only grow from the first lap to the second, so a row of the second lap equals the
  // first lap's exactly when their sums are equal; after `depth` equal rows in a row, every later
  // row is equal too (a row depends only on the `depth` below it), and the first lap's masks there
  // stand. The first lap's sums are kept for the rows the second lap may reach before that; past
  // them it goes on to the end of the map.
  // Bilinear mode: the row's dilations over blockers e (with the wrap fix-up) are kept in a ring of
  // the last four rows swept (cell n at n + 1; one padding cell before and four after, wrapped or
  // empty; rows not swept yet are empty). Cell row a tests texel row a (shifted by cell_offset_y):
  // its box {0, 1, 2}^2 reads the cells two past it in row a + 2 and the cell two columns on in rows
  // a and a + 1, its box {0, ..., 3}^2 the cells three past it in row a + 3 and the cell three columns
  // on in rows a, a + 1 and a + 2 - the rows swept in the three steps before - each row's cells in
  // registers as the test slides along it.
  std::uint16_t* ring[4] = {};
  const int texel_width = job.texel_width, texel_height = job.texel_height;
  if (bilinear) {
    for (int k = 0; k < 4; ++k)
      ring[k] = job.bilinear_scratch + std::size_t(k) * (std::size_t(W) + 5) * lane_stride;
    if (fresh)
      for (std::size_t n = 0; n < 4 * (std::size_t(W) + 5) * lane_stride; ++n) job.bilinear_scratch[n] = 0;
  }

  const int tracked = wrap ? (H + 1) / 2 + 1 : 0;  // first-lap rows whose sums are kept
  // Equal rows needed before the second lap stops. A row's dilations (with and without its own
  // cells) depend on the `depth` rows swept before it, so after `depth` equal rows every later row
  // is equal. In bilinear mode the box tests of the first row the second lap leaves also read the
  // dilations of the three rows swept before it, which are equal only when the `depth` rows before
  // each of them are: depth + 3 equal rows (with depth alone, 13 of 120 small maps had texels whose
  // first-lap counts passed more lanes than a whole second lap's - LaneSweep.BilinearSecondLap...;
  // it also makes the second lap re-test the first lap's first three rows, which read rows not
  // swept yet).
  const int stop_rows = bilinear ? depth + 3 : depth;
  // bilinear: first-lap rows whose box tests are left to the second lap (it stops only past them;
  // it can stop only within the first `tracked` rows, whose sums are kept, so no more than those)
  const int skip_tests =
      bilinear && wrap && job.stop_early ? (job.skip_tests < tracked ? job.skip_tests : tracked) : 0;
  job.second_lap_rows = wrap ? H : 0;  // unless it stops early
  long long* row_sums = job.row_sums;
  int equal_rows = 0;
  long long work = 0;
  // Bilinear mode: a texel row tested at the start of the second lap reads the dilations of the
  // first lap's last three rows, which may still miss blockers past the seam. They are complete when
  // the second lap stops before reaching them (equal to its rows); otherwise the sweep goes on for
  // three rows of a third lap, which re-test those texel rows from the second lap's complete rows.
  const int swept_rows = wrap ? (bilinear ? 2 * H + 3 : 2 * H) : H;
  const int last_step = split ? job.last_step : swept_rows;
  job.converged = false;
  for (int step = first_step; step < last_step; ++step) {
    const bool second_lap = step >= H;
    const int a = H - 1 - (step % H);
    const int physical_row = job.flip_y ? H - 1 - a : a;
    const std::uint16_t* top_row = job.top + std::size_t(physical_row) * W;
    const std::uint16_t* bottom_row = bilinear ? nullptr : job.bottom + std::size_t(physical_row) * W;
    std::uint16_t* const dilations = bilinear ? ring[step & 3] : nullptr;
    std::uint32_t* mask_row = bilinear ? nullptr : job.masks + std::size_t(physical_row) * W;
    const int first = flip_x ? W - 1 : 0, stride = flip_x ? -1 : 1;

    // The row from its last texel to its first. A texel's dilation over its blockers e comes from
    // the row below (row moves), the texel after it in the rows further below (column moves) and
    // the texel after it in its own row (carry); with the texel itself it is what the texels before
    // it see. The texel passes lane l when nothing in the quadrant rises above its cone of ratio
    // lane l (bit l of its mask); lanes pass from the smallest ratio up.
    V carry = nothing;
    std::uint16_t* const written = below[depth];
    V deepest_source = column_count > 0 ? Ops::load(written + std::size_t(W) * lane_stride) : nothing;
    const std::uint16_t* row_source = below[1] + std::size_t(job.row_first) * lane_stride;
    const std::uint16_t* column_source[lane_reach_limit];  // texel b + 1 of each column move's row
    for (int k = 0; k < column_in_buffers; ++k) column_source[k] = below[job.column_first + k] + lane_stride;
    // row moves with a fixed count: window[k] holds texel b + k of row_source, kept from texel to texel
    V window[fixed_rows > 0 ? fixed_rows : 1];
    for (int k = 1; k < fixed_rows; ++k)
      window[k] = Ops::load(row_source + std::size_t(W - 1 + k) * lane_stride);
    for (int b = W - 1; b >= 0; --b) {
      std::uint16_t* target = written + std::size_t(b) * lane_stride;
      const std::size_t here = std::size_t(b) * lane_stride;
      // every sweep has a row move (row_count >= 1)
      V e;
      if (fixed_rows > 0) {
        window[0] = Ops::load(row_source + here);
        e = Ops::subs(window[0], fixed_row_step[0]);
        for (int k = 1; k < fixed_rows; ++k) e = Ops::max(e, Ops::subs(window[k], fixed_row_step[k]));
        for (int k = fixed_rows - 1; k > 0; --k) window[k] = window[k - 1];
      } else {
        e = Ops::subs(Ops::load(row_source + here), Ops::load(row_steps));
        for (int k = 1; k < row_count; ++k)
          e = Ops::max(e, Ops::subs(Ops::load(row_source + here + k * lane_stride),
                                    Ops::load(row_steps + k * lane_count)));
      }
      if (fixed_columns > 0) {
        for (int k = 0; k + 1 < fixed_columns; ++k)
          e = Ops::max(e, Ops::subs(Ops::load(column_source[k] + here), fixed_column_step[k]));
        e = Ops::max(e, Ops::subs(deepest_source, fixed_column_step[fixed_columns - 1]));
      } else if (fixed_columns < 0 && column_count > 0) {
        for (int k = 0; k < column_in_buffers; ++k)
          e = Ops::max(
              e, Ops::subs(Ops::load(column_source[k] + here), Ops::load(column_steps + k * lane_count)));
        e = Ops::max(e, Ops::subs(deepest_source, Ops::load(column_steps + column_in_buffers * lane_count)));
      }
      if (column_count > 0) deepest_source = Ops::load(target);
      if (carry_move) e = Ops::max(e, carry);  // last: the carry is the chain from texel to texel
      const int column = first + stride * b;
      const V d = Ops::max(e, Ops::broadcast(top_row[column]));
      Ops::store(target, d);
      if (bilinear)
        Ops::store(dilations + std::size_t(b + 1) * lane_stride, e);
      else
        Ops::store_mask_at_most(mask_row + column, e, Ops::broadcast(bottom_row[column]));
      if (carry_move) carry = Ops::subs(d, step_row);
    }
    work += W;
    if (wrap && carry_move) {
      // Blockers past the row's first texel come round from its last: at most one more lap. A
      // texel's dilation over blockers becomes max(old, carry), and so does its dilation with
      // itself; a lane passes now when it passed before and the carry passes it. Once the carry
      // does not raise a texel's dilation, nothing after it changes.
      for (int b = W - 1; b >= 0; --b) {
        std::uint16_t* target = written + std::size_t(b) * lane_stride;
        const V old_d = Ops::load(target);
        const V d = Ops::max(old_d, carry);
        const int column = first + stride * b;
        if (bilinear) {
          std::uint16_t* kept = dilations + std::size_t(b + 1) * lane_stride;
          Ops::store(kept, Ops::max(Ops::load(kept), carry));
        } else {
          mask_row[column] &= Ops::mask_at_most(carry, Ops::broadcast(bottom_row[column]));
        }
        ++work;
        if (Ops::same(d, old_d)) break;
        Ops::store(target, d);
        carry = Ops::subs(d, step_row);
      }
    }
    // the padding: the row's start again (wrap) or nothing (clamp)
    for (int k = 0; k < padding; ++k)
      Ops::store(written + std::size_t(W + k) * lane_stride,
                 wrap ? Ops::load(written + std::size_t(k % W) * lane_stride) : nothing);

    if (bilinear) {
      // padding: the cell before the first and the two after the last, wrapped or empty
      Ops::store(dilations, wrap ? Ops::load(dilations + std::size_t(W) * lane_stride) : nothing);
      for (int k = 0; k < 4; ++k)
        Ops::store(dilations + std::size_t(W + 1 + k) * lane_stride,
                   wrap ? Ops::load(dilations + std::size_t(1 + k % W) * lane_stride) : nothing);
      // the texel row tested by cell row a (unrolled with wrap)
      auto texel_row = [&](int row) {
        return wrap ? ((row % texel_height) + texel_height) % texel_height : row;
      };
      const int tested = texel_row(a - job.cell_offset_y);
      // the second lap (or another part) tests this row
      const bool left_to_second_lap = split ? step < job.skip_until : wrap && step < skip_tests;
      if (tested >= 0 && tested < texel_height && !left_to_second_lap) {
        const int physical_texel_row = job.flip_y ? texel_height - 1 - tested : tested;
        const std::uint16_t* apex_row = job.texel_bottom + std::size_t(physical_texel_row) * texel_width;
        std::uint8_t* texel_passed = job.passed + std::size_t(physical_texel_row) * texel_width;
        std::uint8_t* texel_passed3 = job.passed3 + std::size_t(physical_texel_row) * texel_width;
        const V bonus = Ops::load(job.bonus), bonus3 = Ops::load(job.bonus3);
        // cells b + offset, + 1, ... of rows a .. a + 3 are at row[k][b + offset + 1 ...]
        const std::size_t shift = std::size_t(1 + job.cell_offset_x) * lane_stride;
        const std::uint16_t* row0 = dilations + shift;
        const std::uint16_t* row1 = ring[(step + 3) & 3] + shift;
        const std::uint16_t* row2 = ring[(step + 2) & 3] + shift;
        const std::uint16_t* row3 = ring[(step + 1) & 3] + shift;
        // windows: cells b + 2 of rows a, a + 1; b .. b + 2 of row a + 2; b .. b + 3 of row a + 3
        V near0 = Ops::load(row0 + 2 * lane_stride), near1 = Ops::load(row1 + 2 * lane_stride);
        V w20 = Ops::load(row2), w21 = Ops::load(row2 + lane_stride), w22 = Ops::load(row2 + 2 * lane_stride);
        V w30 = Ops::load(row3), w31 = Ops::load(row3 + lane_stride), w32 = Ops::load(row3 + 2 * lane_stride);
        for (int b = 0; b < texel_width; ++b) {
          const std::size_t next = std::size_t(b + 3) * lane_stride;
          const V x0 = Ops::load(row0 + next), x1 = Ops::load(row1 + next), x2 = Ops::load(row2 + next),
                  x3 = Ops::load(row3 + next);
          const V box2 = Ops::max(Ops::max(Ops::max(w20, w21), w22), Ops::max(near0, near1));
          const V box3 =
              Ops::max(Ops::max(Ops::max(w30, w31), Ops::max(w32, x3)), Ops::max(Ops::max(x0, x1), x2));
          const int column = job.flip_x ? texel_width - 1 - b : b;
          const V apex = Ops::broadcast(apex_row[column]);
          // lanes pass from the lowest up: the count of set bits says which
          texel_passed[column] =
              std::uint8_t(__builtin_popcount(Ops::mask_at_most(Ops::subs(box2, bonus), apex)));
          texel_passed3[column] =
              std::uint8_t(__builtin_popcount(Ops::mask_at_most(Ops::subs(box3, bonus3), apex)));
          near0 = x0;
          near1 = x1;
          w20 = w21;
          w21 = w22;
          w22 = x2;
          w30 = w31;
          w31 = w32;
          w32 = x3;
        }
      }
      work += texel_width;
    }

    const int lap_row = step % H;  // rows into the lap
    if (split) {
      const int index = step - first_step;
      if (index < job.sums_count) {
        const long long row_sum = Ops::sum(written, W);
        if (job.record_sums) {
          job.record_sums[index] = row_sum;
        } else {
          equal_rows = row_sum == job.compare_sums[index] ? equal_rows + 1 : 0;
          if (equal_rows >= stop_rows && index + 1 >= job.compare_skip) {
            job.converged = true;
            job.split_rows = index + 1;
            job.work = work;
            return;
          }
        }
      }
    } else if (lap_row < tracked) {
      const long long row_sum = Ops::sum(written, W);
      if (!second_lap) {
        row_sums[lap_row] = row_sum;
      } else {
        equal_rows = row_sum == row_sums[lap_row] ? equal_rows + 1 : 0;
        if (equal_rows >= stop_rows && lap_row + 1 >= skip_tests && job.stop_early &&
            (!bilinear || (step < 2 * H && a >= 3))) {
          job.second_lap_rows = lap_row + 1;
          break;
        }
      }
    }
    for (int k = depth; k > 1; --k) below[k] = below[k - 1];  // row a is now the one below
    below[1] = written;
  }
  if (split) job.split_rows = last_step - first_step;
  job.work = work;
}

// Compile-time counts for the move sets of maps up to twice as wide as tall (row moves) or as
// tall as wide (column moves); longer ones loop.
template <class Ops, bool carry_move, int fixed_columns, bool bilinear>
void sweep_rows(LaneSweepJob& job) {
  switch (job.row_count) {
    case 1: sweep_kernel<Ops, carry_move, 1, fixed_columns, bilinear>(job); break;
    case 2: sweep_kernel<Ops, carry_move, 2, fixed_columns, bilinear>(job); break;
    case 3: sweep_kernel<Ops, carry_move, 3, fixed_columns, bilinear>(job); break;
    case 4: sweep_kernel<Ops, carry_move, 4, fixed_columns, bilinear>(job); break;
    case 5: sweep_kernel<Ops, carry_move, 5, fixed_columns, bilinear>(job); break;
    default: sweep_kernel<Ops, carry_move, -1, fixed_columns, bilinear>(job); break;
  }
}

template <class Ops, bool carry_move, bool bilinear>
void sweep_columns(LaneSweepJob& job) {
  switch (job.column_count) {
    case 0: sweep_rows<Ops, carry_move, 0, bilinear>(job); break;
    case 1: sweep_rows<Ops, carry_move, 1, bilinear>(job); break;
    case 2: sweep_rows<Ops, carry_move, 2, bilinear>(job); break;
    case 3: sweep_rows<Ops, carry_move, 3, bilinear>(job); break;
    default: sweep_kernel<Ops, carry_move, -1, -1, bilinear>(job); break;
  }
}

template <class Ops>
void sweep_kernel(LaneSweepJob& job) {
  if (job.bilinear)
    sweep_columns<Ops, true, true>(job);
  else
    job.carry ? sweep_columns<Ops, true, false>(job) : sweep_columns<Ops, false, false>(job);
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
      float ratio = job.lane_ratio[passed];
      if (passed == 0) {  // the floor, pending unless within floor_keep of its certified bound
        const LaneFloor floor = lane_floor(*job.plan, job.heights, t, q, 4);
        const float upper = job.plan->lane_upper[0] < floor.upper ? job.plan->lane_upper[0] : floor.upper;
        ratio = floor.floor;
        pending += ratio / upper < job.floor_keep ? 1 : 0;
      } else {
        pending += job.pending_count[passed];
      }
      job.out[t * 4 + q] = ratio;
      sums[q] += ratio;
    }
  }
  job.ratio_sum += double(sums[0] + sums[1]) + double(sums[2] + sums[3]);
  job.pending += pending;
}

}  // namespace
}  // namespace displace::bake::detail
