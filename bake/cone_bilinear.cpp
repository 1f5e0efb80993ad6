// bake/cone_bilinear.cpp - cone maps for the BILINEAR surface the renderer traces (bake.h,
// bake_bilinear_cones): texel c gets an apex height H_c = max of s over its square Q_c (c plus or
// minus half a texel) and per sector a ratio r_k such that for every p in Q_c and every surface point
// x whose horizontal direction from p lies in sector k, s(x) <= H_c + |x - p| / r_k. A ray point
// may then step from its own texel's cone with no slack for its offset from the centre.
//
// The one fact: the surface is bounded piece by piece, each piece P (a box inside one cell, where s
// is one bilinear patch) contributing a lower bound of |x - p| / (s(x) - H_c) over its points, to the
// sectors its directions can take: far cells (through a max pyramid) by their distance over their
// maximum, the cells within `slope_window` cut at Q_c's edge lines and bounded by their slope too.
// Arithmetic is in double, every bound rounded down to float and H_c rounded up.
//
// Proof: docs/design/bakers.md#bakecone_bilinearcpp-cones-for-the-bilinear-surface
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <atomic>
#include <chrono>
#include <limits>
#include <stdexcept>

#include "bake/bilinear_search.h"
#include "bake/progress.h"
#include "bake/search.h"

namespace displace::bake {
namespace {

constexpr double ratio_margin = 1e-9;  // relative: covers double rounding in distances, slopes and divisions
constexpr double height_margin = 1e-12;  // height units: covers double rounding of s at piece and Q_c points
constexpr double infinite_ratio = std::numeric_limits<double>::infinity();

// One axis of the cell grid, in half-texel units: texel t's centre at 2t, Q_c spans [2t - 1, 2t + 1].
// Cell n (an unrolled index with wrap: tile floor(n / cells)) lies between texel centres a and a + 1,
// a = n with wrap, a = n - 1 with clamp, where cells 0 and texels are the half-texel border cells.
struct Axis {
  int texels = 0;
  bool wrap = true;
  int cells = 0;

  Axis(int count, Address address)
      : texels(count), wrap(address == Address::wrap), cells(wrap ? count : count + 1) {}

  int left_centre(int n) const { return wrap ? n : n - 1; }
  int cell_of_left_centre(int a) const { return wrap ? a : a + 1; }
  bool exists(int n) const { return wrap || (n >= 0 && n < cells); }
  int texel(int a) const {
    if (!wrap) return std::clamp(a, 0, texels - 1);
    const int m = a % texels;
    return m < 0 ? m + texels : m;
  }
  int in_tile(int n) const {  // the stored cell of unrolled cell n
    if (n >= 0 && n < cells) return n;
    const int m = n % cells;
    return m < 0 ? m + cells : m;
  }
  int begin(int n) const { return wrap ? 2 * n : std::max(2 * n - 2, -1); }
  int end(int n) const { return wrap ? 2 * n + 2 : std::min(2 * n, 2 * texels - 1); }
};

// Gap between Q_c's span [2t - 1, 2t + 1] and [first, last] (half texels).
int span_gap(int t, int first, int last) { return std::max({0, first - (2 * t + 1), (2 * t - 1) - last}); }

// Largest rates of rise of s (uv units) over a box, towards +u, -u, +v and -v: max of ds/du, of
// -ds/du, of ds/dv, of -ds/dv.
struct Derivatives {
  double rise[4] = {0.0, 0.0, 0.0, 0.0};

  Derivatives() = default;
  Derivatives(double plus_u, double minus_u, double plus_v, double minus_v)
      : rise{plus_u, minus_u, plus_v, minus_v} {}
};

// The four corner heights of a cell (h[0] at (a, b), h[1] at (a + 1, b), h[2] at (a, b + 1), h[3] at
// (a + 1, b + 1)) and the bilinear patch on it, in cell coordinates f in [0, 1]^2 (half-texel
// position X = 2a + 2 fx).
struct Patch {
  double h[4];

  double value(double fx, double fy) const {
    return (h[0] * (1 - fx) + h[1] * fx) * (1 - fy) + (h[2] * (1 - fx) + h[3] * fx) * fy;
  }
  double maximum(double fx0, double fx1, double fy0, double fy1) const {
    return std::max(std::max(value(fx0, fy0), value(fx1, fy0)), std::max(value(fx0, fy1), value(fx1, fy1)));
  }
  // The extremes of ds/du = W * lerp(e0, e1, fy) and ds/dv = H * lerp(f0, f1, fx) over the box (uv
  // units): each is linear in one coordinate, so they lie at the box's edges.
  Derivatives derivatives(double fx0, double fx1, double fy0, double fy1, double width, double height) const {
    const double e0 = h[1] - h[0], e1 = h[3] - h[2], f0 = h[2] - h[0], f1 = h[3] - h[1];
    const double du0 = width * (e0 + (e1 - e0) * fy0), du1 = width * (e0 + (e1 - e0) * fy1);
    const double dv0 = height * (f0 + (f1 - f0) * fx0), dv1 = height * (f0 + (f1 - f0) * fx1);
    return {std::max(du0, du1), -std::min(du0, du1), std::max(dv0, dv1), -std::min(dv0, dv1)};
  }
};

// The sectors (of `sectors` in uv, each a closed wedge) with a direction w along which the patch may
// fall somewhere on its cell: w . grad s < 0. ds/du ranges over W [min(e0, e1), max(e0, e1)] (e0, e1
// its differences along u at the cell's two v edges; linear in between) and ds/dv likewise, so over
// a closed quadrant of directions the least of w . grad s is at the box's corner that the quadrant's
// signs pick, and over a wedge inside a quadrant at one of its two edges (w . g is a sinusoid in the
// angle, negative on an arc of half a turn, which an arc of a quarter turn cannot hold without one of
// its ends). So each sector is tested at its edges and at the axes inside it. The corner differences
// are exact in sign (a difference of two floats in double), so a sector that falls along an axis is
// never missed; along a diagonal (8 sectors) a sum within a relative 1e-12 of 0 counts as falling.
detail::SectorMask falling_sectors(const Patch& patch, double width, double height, int sectors) {
  const double e0 = patch.h[1] - patch.h[0], e1 = patch.h[3] - patch.h[2];
  const double f0 = patch.h[2] - patch.h[0], f1 = patch.h[3] - patch.h[1];
  const double du_min = width * std::min(e0, e1), du_max = width * std::max(e0, e1);
  const double dv_min = height * std::min(f0, f1), dv_max = height * std::max(f0, f1);
  // the eight directions at multiples of 45 degrees in uv, counterclockwise from +u
  constexpr int dir_u[8] = {1, 1, 0, -1, -1, -1, 0, 1}, dir_v[8] = {0, 1, 1, 1, 0, -1, -1, -1};
  auto falls_along = [&](int d) {
    const double gu = dir_u[d] > 0 ? du_min : du_max, gv = dir_v[d] > 0 ? dv_min : dv_max;
    const double along = dir_u[d] * gu + dir_v[d] * gv;
    const double size = std::abs(dir_u[d] * gu) + std::abs(dir_v[d] * gv);
    return along < 1e-12 * size;  // (size >= 0, so a negative `along` is below it)
  };
  detail::SectorMask mask = 0;
  const int span = 8 / sectors;  // a sector's width in eighths of a turn
  for (int k = 0; k < sectors; ++k)
    for (int d = k * span; d <= (k + 1) * span; ++d)
      if (falls_along(d % 8)) mask |= 1u << k;
  return mask;
}

struct Context {
  HeightView heights;
  detail::Grid grid;
  Axis along_u, along_v;
  int window = 0;                      // slope window radius in cells
  std::vector<float> cell_max;         // per cell: the pyramid's base
  std::vector<Derivatives> cell_rise;  // per cell (n_u + n_v * cells_u)
  detail::Pyramid pyramid;             // max pyramid over the cells' maxima
  detail::SectorMask beyond[4];        // sectors meeting the open half-planes u > 0, u < 0, v > 0, v < 0
  double half_texel_u = 0.0, half_texel_v = 0.0;  // uv per half texel
  bool prune = true;                              // BilinearConeSettings::prune
  // bake_bilinear_relaxed_cones: only the cells where s may fall along a direction of the sector count
  bool falling_only = false;
  // per cell: the sectors along whose directions s may fall
  std::vector<detail::SectorMask> cell_falling = {};
  // per sector: max pyramid over the maxima of those cells
  std::vector<detail::Pyramid> falling = {};

  float height(int i, int j) const { return heights.data[std::size_t(i) * heights.width + j]; }
  Patch patch(int nu, int nv) const {
    const int a = along_u.left_centre(nu), b = along_v.left_centre(nv);
    const int j0 = along_u.texel(a), j1 = along_u.texel(a + 1), i0 = along_v.texel(b),
              i1 = along_v.texel(b + 1);
    return {{height(i0, j0), height(i0, j1), height(i1, j0), height(i1, j1)}};
  }
};

// uv distance for gaps in half texels.
double gap_distance(const Context& context, int gap_u, int gap_v) {
  const double u = gap_u * context.half_texel_u, v = gap_v * context.half_texel_v;
  return std::sqrt(u * u + v * v);
}

// Sectors meeting the box of directions [u0, u1] x [v0, v1] (half texels; Grid scales to uv).
detail::SectorMask box_sectors(const Context& context, int u0, int u1, int v0, int v1) {
  return detail::rect_sectors(context.grid, u0, u1, v0, v1);
}

// The least of delta / min(rise, slope * delta - drop) over delta in [near, far]: the bound of a
// piece whose points x lie between near and far from Q_c, and rise above H_c by at most `rise` (its
// maximum) and by at most slope * delta(x) - drop (step 3, where s(y) <= H_c - drop on the clamp y of
// the piece onto Q_c). The first term falls with delta (drop >= 0), the second grows, so the least
// is where they cross, or the nearer end.
double piece_bound(double near, double far, double rise, double drop, double slope) {
  if (!(slope > 0.0)) return infinite_ratio;  // s never rises above its clamp, which is <= H_c
  if (drop <= 0.0) return std::max(near / rise, 1.0 / slope);
  const double delta = std::clamp((rise + drop) / slope, near, far);
  const double above = std::min(rise, slope * delta - drop);
  return above > 0.0 ? delta / above : infinite_ratio;
}

struct TexelSearch {
  const Context& context;
  int i, j;
  double apex;
  const double (&square)[3][3];  // s on Q_c's grid (square_values)
  double* best;
  long long work = 0;

  void lower(detail::SectorMask mask, double bound) {
    for (int k = 0; k < context.grid.sector_count; ++k)
      if ((mask >> k & 1u) && bound < best[k]) best[k] = bound;
  }

  // The largest of s over the clamp onto Q_c of the box [u0, u1] x [v0, v1]: an edge segment or a
  // corner of Q_c, on which s is linear between the grid points of `square`.
  double clamp_max(int u0, int u1, int v0, int v1) const {
    const int qu0 = 2 * j - 1, qv0 = 2 * i - 1;
    const int a0 = std::clamp(u0 - qu0, 0, 2), a1 = std::clamp(u1 - qu0, 0, 2);
    const int b0 = std::clamp(v0 - qv0, 0, 2), b1 = std::clamp(v1 - qv0, 0, 2);
    double m = -infinite_ratio;
    for (int b = b0; b <= b1; ++b)
      for (int a = a0; a <= a1; ++a) m = std::max(m, square[b][a]);
    return m;
  }

  // the largest ratio among the sectors of `mask` (0 for none): a bound at or above it lowers nothing
  double largest_in(detail::SectorMask mask) const {
    double largest = 0.0;
    for (int k = 0; k < context.grid.sector_count; ++k)
      if (mask >> k & 1u) largest = std::max(largest, best[k]);
    return largest;
  }

  // The cells (da, db) in [-R, R - 1]^2 around Q_c (steps 2 to 4), cut at Q_c's edge lines into
  // pieces before, across and beyond Q_c along each axis (a cell meets at most two of the three).
  // Slope bound (step 3): from x in a piece to its clamp y onto Q_c the segment runs along u for a
  // piece beyond the left or right edge and across Q_c in v, along v likewise, and towards a corner
  // of Q_c for a piece beyond two edges; so s(x) - s(y) <= rise_u |x_u - y_u| + rise_v |x_v - y_v|,
  // rise = the largest rate of rise of s along the segment's direction on it (0 where s only falls),
  // which is at most sqrt(rise_u^2 + rise_v^2) |x - y|. The rates: for the four cells overlapping Q_c
  // the piece's own (y lies in the piece); for the others the largest over the cells between them
  // and Q_c, da' in [0, da] (da >= 0) or [da, -1] (da < 0) and the same along v, kept as running
  // maxima outward from the centre. A cell with da >= 0 holds no piece before Q_c's left edge, so
  // it only needs the rise towards +u (and so on).
  void window_cells(std::vector<double>& hull) {
    const int R = context.window;
    const Axis& U = context.along_u;
    const Axis& V = context.along_v;
    const int side = 2 * R;
    const int qu0 = 2 * j - 1, qu1 = 2 * j + 1, qv0 = 2 * i - 1, qv1 = 2 * i + 1;
    hull.assign(std::size_t(2) * side * side, 0.0);  // rise along u, then rise along v
    auto at = [&](int axis, int da, int db) -> double& {
      return hull[(std::size_t(axis) * side + db + R) * side + da + R];
    };
    auto order = [&](int n) { return n < R ? n : R - 1 - n; };  // 0, 1, ..., R - 1, then -1, ..., -R
    for (int y = 0; y < side; ++y) {
      const int db = order(y);
      const int nv = V.cell_of_left_centre(i + db);
      for (int x = 0; x < side; ++x) {
        const int da = order(x);
        const int nu = U.cell_of_left_centre(j + da);
        const bool exists = U.exists(nu) && V.exists(nv);
        double rise_u = 0.0, rise_v = 0.0;
        const std::size_t stored = exists ? std::size_t(V.in_tile(nv)) * U.cells + U.in_tile(nu) : 0;
        if (exists) {
          const Derivatives& cell = context.cell_rise[stored];
          rise_u = std::max(cell.rise[da >= 0 ? 0 : 1], 0.0);
          rise_v = std::max(cell.rise[db >= 0 ? 2 : 3], 0.0);
        }
        if (da != 0 && da != -1) {
          const int inner = da > 0 ? da - 1 : da + 1;
          rise_u = std::max(rise_u, at(0, inner, db));
          rise_v = std::max(rise_v, at(1, inner, db));
        }
        if (db != 0 && db != -1) {
          const int inner = db > 0 ? db - 1 : db + 1;
          rise_u = std::max(rise_u, at(0, da, inner));
          rise_v = std::max(rise_v, at(1, da, inner));
        }
        at(0, da, db) = rise_u;
        at(1, da, db) = rise_v;
        if (!exists) continue;
        ++work;
        const double cell_max = context.pyramid.max.levels[0][stored];
        if (!(cell_max > apex)) continue;
        // every sector for the conservative cones; for the relaxed ones those along which s may fall
        const detail::SectorMask falls = context.falling_only ? context.cell_falling[stored] : ~0u;
        if (!falls) continue;
        const bool centre = (da == 0 || da == -1) && (db == 0 || db == -1);
        const int cu[2] = {U.begin(nu), U.end(nu)}, cv[2] = {V.begin(nv), V.end(nv)};
        if (!centre && context.prune) {
          // Each piece lies in the cell: no nearer to Q_c than the cell, no higher than its maximum
          // (a patch's corner; its other values are within 1e-15 of them), with no sector the cell's
          // box of directions misses, and piece_bound is at least near / rise, every rounding
          // monotone. So when the cell's gap over its rise (with twice the margin) reaches the
          // largest ratio of its sectors, no piece can lower one: the same ratios, fewer pieces.
          const detail::SectorMask cell_sectors =
              box_sectors(context, cu[0] - qu1, cu[1] - qu0, cv[0] - qv1, cv[1] - qv0) & falls;
          const double gap = gap_distance(context, span_gap(j, cu[0], cu[1]), span_gap(i, cv[0], cv[1]));
          if (gap / (cell_max + 2.0 * height_margin - apex) >= largest_in(cell_sectors)) continue;
        }
        const Patch patch = context.patch(nu, nv);
        const int origin_u = 2 * U.left_centre(nu), origin_v = 2 * V.left_centre(nv);
        // the three ranges along each axis: before Q_c, across it, beyond it (side -1, 0, +1)
        for (int sv = -1; sv <= 1; ++sv) {
          const int v0 = std::max(cv[0], sv < 0 ? cv[0] : sv == 0 ? qv0 : qv1);
          const int v1 = std::min(cv[1], sv < 0 ? qv0 : sv == 0 ? qv1 : cv[1]);
          if (v0 >= v1) continue;
          for (int su = -1; su <= 1; ++su) {
            if (su == 0 && sv == 0) continue;  // inside Q_c: s <= H_c
            const int u0 = std::max(cu[0], su < 0 ? cu[0] : su == 0 ? qu0 : qu1);
            const int u1 = std::min(cu[1], su < 0 ? qu0 : su == 0 ? qu1 : cu[1]);
            if (u0 >= u1) continue;
            const double fu0 = (u0 - origin_u) / 2.0, fu1 = (u1 - origin_u) / 2.0;
            const double fv0 = (v0 - origin_v) / 2.0, fv1 = (v1 - origin_v) / 2.0;
            const double top = patch.maximum(fu0, fu1, fv0, fv1);
            if (!(top > apex)) continue;
            double along_u = rise_u, along_v = rise_v;
            if (centre) {
              const Derivatives own =
                  patch.derivatives(fu0, fu1, fv0, fv1, context.grid.width, context.grid.height);
              along_u = std::max(own.rise[su > 0 ? 0 : 1], 0.0);
              along_v = std::max(own.rise[sv > 0 ? 2 : 3], 0.0);
            }
            const double slope = su == 0   ? along_v
                                 : sv == 0 ? along_u
                                           : std::sqrt(along_u * along_u + along_v * along_v);
            const int far_u = su > 0 ? u1 - qu1 : su < 0 ? qu0 - u0 : 0;
            const int far_v = sv > 0 ? v1 - qv1 : sv < 0 ? qv0 - v0 : 0;
            const double drop = std::max(0.0, apex - (clamp_max(u0, u1, v0, v1) + height_margin));
            const double bound =
                piece_bound(gap_distance(context, span_gap(j, u0, u1), span_gap(i, v0, v1)),
                            gap_distance(context, far_u, far_v), top + height_margin - apex, drop, slope);
            detail::SectorMask mask = box_sectors(context, u0 - qu1, u1 - qu0, v0 - qv1, v1 - qv0) & falls;
            if (su != 0) mask &= context.beyond[su > 0 ? 0 : 1];
            if (sv != 0) mask &= context.beyond[sv > 0 ? 2 : 3];
            lower(mask, bound);
          }
        }
      }
    }
  }

  // every other cell, through the max pyramid over cells, nearest first (step 2). A node is a block
  // of the pyramid's level in a tile of the periodic plane (tiles 0 with clamp): its tile and its
  // index in the tile along each axis, kept apart so that no step divides.
  struct Block {
    int level, tile_u, tile_v, bu, bv;
  };
  struct Entry {
    Block node;
    double bound;
    detail::SectorMask mask;  // the sectors it could lower when examined
  };

  // (over `pyramid`, for the sectors of `only`)
  void far_cells(std::vector<Entry>& stack, const detail::Pyramid& pyramid, detail::SectorMask only) {
    const Axis& U = context.along_u;
    const Axis& V = context.along_v;
    const int R = context.window;
    // the window in unrolled cell indices (empty for R = 0)
    const int wu0 = U.cell_of_left_centre(j - R), wu1 = U.cell_of_left_centre(j + R - 1);
    const int wv0 = V.cell_of_left_centre(i - R), wv1 = V.cell_of_left_centre(i + R - 1);
    // bound of a node; false when it cannot lower any ratio or lies inside the window
    auto examine = [&](const Block& node, Entry& entry) {
      ++work;
      const double top = pyramid.value(node.level, node.bv, node.bu);
      if (!(top > apex)) return false;
      // the block's cells, unrolled (detail::block_range without the division)
      const int first_u = node.tile_u * U.cells + (node.bu << node.level),
                last_u = node.tile_u * U.cells + std::min((node.bu + 1) << node.level, U.cells) - 1;
      const int first_v = node.tile_v * V.cells + (node.bv << node.level),
                last_v = node.tile_v * V.cells + std::min((node.bv + 1) << node.level, V.cells) - 1;
      if (R > 0 && first_u >= wu0 && last_u <= wu1 && first_v >= wv0 && last_v <= wv1) return false;
      const int u0 = U.begin(first_u), u1 = U.end(last_u), v0 = V.begin(first_v), v1 = V.end(last_v);
      // the sectors it can reach, and the largest ratio among them: the block is useful only if its
      // bound is below that
      const detail::SectorMask mask =
          box_sectors(context, u0 - (2 * j + 1), u1 - (2 * j - 1), v0 - (2 * i + 1), v1 - (2 * i - 1)) & only;
      const double largest = largest_in(mask);
      // the far bound (gap_distance over the rise, the same arithmetic), with a rejection first that
      // needs neither the root nor the division:
      // where distance^2 exceeds (largest * rise)^2 by a relative 1e-9 (far above the roundings of
      // either side), the bound is above every ratio it could lower, as the full test would find
      const double gap_u = span_gap(j, u0, u1) * context.half_texel_u,
                   gap_v = span_gap(i, v0, v1) * context.half_texel_v;
      const double squared = gap_u * gap_u + gap_v * gap_v, rise = top - apex, reach = largest * rise;
      if (context.prune && squared > reach * reach * (1.0 + 1e-9)) return false;
      const double bound = std::sqrt(squared) / rise;
      if (context.prune && !(bound < largest)) return false;
      detail::SectorMask useful = 0;
      for (int k = 0; k < context.grid.sector_count; ++k)
        if ((mask >> k & 1u) && (bound < best[k] || !context.prune)) useful |= 1u << k;
      if (!useful) return false;
      if (node.level == 0) {
        lower(useful, bound);
        return false;
      }
      entry = {node, bound, useful};
      return true;
    };
    stack.clear();
    Entry entry;
    const int top_level = pyramid.levels - 1;
    const int tiles = U.wrap ? 2 : 0;  // with wrap, images within uv distance 1 of Q_c lie in tiles -2..1
    for (int tv = -tiles; tv <= tiles; ++tv)
      for (int tu = -tiles; tu <= tiles; ++tu)
        if (examine({top_level, tu, tv, 0, 0}, entry)) stack.push_back(entry);  // one block a tile
    std::sort(stack.begin(), stack.end(), [](const Entry& a, const Entry& b) { return a.bound > b.bound; });
    while (!stack.empty()) {
      const Entry top = stack.back();
      stack.pop_back();
      if (!stack.empty()) {  // the next block's children, into the cache while this one's are examined
        const Block& next = stack.back().node;
        const int width = pyramid.count_x(next.level - 1), height = pyramid.count_y(next.level - 1);
        const float* children = pyramid.max.levels[std::size_t(next.level - 1)].data();
        __builtin_prefetch(children + std::size_t(2 * next.bv) * width + 2 * next.bu);
        if (2 * next.bv + 1 < height)
          __builtin_prefetch(children + std::size_t(2 * next.bv + 1) * width + 2 * next.bu);
      }
      // the ratios may have dropped since it was pushed
      bool useful = false;
      for (int k = 0; k < context.grid.sector_count; ++k)
        if ((top.mask >> k & 1u) && top.bound < best[k]) useful = true;
      if (!useful && context.prune) continue;
      const Block& node = top.node;
      Entry children[4];
      int child_count = 0;
      const int level = node.level - 1;
      const int count_u = pyramid.count_x(level), count_v = pyramid.count_y(level);
      for (int dv = 0; dv < 2 && 2 * node.bv + dv < count_v; ++dv)
        for (int du = 0; du < 2 && 2 * node.bu + du < count_u; ++du) {
          const Block child{level, node.tile_u, node.tile_v, 2 * node.bu + du, 2 * node.bv + dv};
          if (examine(child, children[child_count])) ++child_count;
        }
      for (int a = 1; a < child_count; ++a)  // largest bound first, so the nearest is searched first
        for (int b = a; b > 0 && children[b - 1].bound < children[b].bound; --b)
          std::swap(children[b - 1], children[b]);
      for (int c = 0; c < child_count; ++c) stack.push_back(children[c]);
    }
  }
};

// s at Q_c's corners, edge midpoints and centre: square[b][a] at half-texel position
// (2j - 1 + a, 2i - 1 + b). s is bilinear on each quarter of Q_c, so these bound it there.
void square_values(const Context& context, int i, int j, double (&square)[3][3]) {
  double h[3][3];
  for (int di = -1; di <= 1; ++di)
    for (int dj = -1; dj <= 1; ++dj)
      h[di + 1][dj + 1] = context.height(context.along_v.texel(i + di), context.along_u.texel(j + dj));
  for (int b = 0; b < 3; ++b)
    for (int a = 0; a < 3; ++a) {
      // the texels around the position: the centre's row / column and, off centre, its neighbour's
      const int rows[2] = {1, b == 1 ? 1 : b}, cols[2] = {1, a == 1 ? 1 : a};
      square[b][a] =
          0.25 * (h[rows[0]][cols[0]] + h[rows[0]][cols[1]] + h[rows[1]][cols[0]] + h[rows[1]][cols[1]]);
    }
}

// H_c: the largest of the nine, rounded up to float.
float apex_height(const double (&square)[3][3]) {
  double m = 0.0;
  for (const auto& row : square)
    for (double value : row) m = std::max(m, value);
  return detail::float_at_least(m);
}

// A ratio for the map: clamped to 1, shrunk by the margin and rounded down.
float stored_ratio(double ratio) {
  if (!(ratio < 1.0)) return 1.0f;
  return detail::float_at_most(ratio * (1.0 - ratio_margin));
}

// Cell maxima, slopes and their pyramid, and the half-plane sector masks: what every texel's search reads.
void prepare(Context& context) {
  const HeightView heights = context.heights;
  context.half_texel_u = 0.5 / heights.width;
  context.half_texel_v = 0.5 / heights.height;
  const Axis& U = context.along_u;
  const Axis& V = context.along_v;
  std::vector<float>& cell_max = context.cell_max;
  cell_max.resize(std::size_t(U.cells) * V.cells);
  context.cell_rise.resize(cell_max.size());
  if (context.falling_only) {
    context.cell_falling.resize(cell_max.size());
    context.falling.resize(std::size_t(context.grid.sector_count));
  }
  tbb::parallel_for(tbb::blocked_range<int>(0, V.cells), [&](const tbb::blocked_range<int>& rows) {
    for (int nv = rows.begin(); nv < rows.end(); ++nv)
      for (int nu = 0; nu < U.cells; ++nu) {
        const Patch patch = context.patch(nu, nv);
        const std::size_t n = std::size_t(nv) * U.cells + nu;
        cell_max[n] = float(std::max(std::max(patch.h[0], patch.h[1]), std::max(patch.h[2], patch.h[3])));
        context.cell_rise[n] = patch.derivatives(0.0, 1.0, 0.0, 1.0, heights.width, heights.height);
        if (context.falling_only)
          context.cell_falling[n] =
              falling_sectors(patch, heights.width, heights.height, context.grid.sector_count);
      }
  });
  build_max_pyramid({cell_max.data(), U.cells, V.cells}, context.pyramid.max);
  context.pyramid.levels = int(context.pyramid.max.levels.size());
  if (context.falling_only) {
    // a cell along whose sector's directions s never falls holds no exit there: -inf takes it out
    std::vector<float> falling_max(cell_max.size());
    for (int k = 0; k < context.grid.sector_count; ++k) {
      for (std::size_t n = 0; n < cell_max.size(); ++n)
        falling_max[n] =
            context.cell_falling[n] >> k & 1u ? cell_max[n] : -std::numeric_limits<float>::infinity();
      build_max_pyramid({falling_max.data(), U.cells, V.cells}, context.falling[std::size_t(k)].max);
      context.falling[std::size_t(k)].levels = int(context.falling[std::size_t(k)].max.levels.size());
    }
  }
  // open half-planes as boxes of directions strictly on their side, long enough to reach every sector
  // they meet (sector edges lie at multiples of 45 degrees in uv)
  const int reach = 4 * std::max(heights.width, heights.height);
  context.beyond[0] = box_sectors(context, 1, 1, -reach, reach);
  context.beyond[1] = box_sectors(context, -1, -1, -reach, reach);
  context.beyond[2] = box_sectors(context, -reach, reach, 1, 1);
  context.beyond[3] = box_sectors(context, -reach, reach, -1, -1);
}

Context make_context(HeightView heights, Address address, int sectors, int window, bool prune = true,
                     bool falling_only = false) {
  Context context{heights,
                  detail::Grid(heights.width, heights.height, sectors, address),
                  Axis(heights.width, address),
                  Axis(heights.height, address),
                  window,
                  {},
                  {},
                  {},
                  {}};
  context.prune = prune;
  context.falling_only = falling_only;
  prepare(context);
  return context;
}

// One texel: apex and ratios as stored; `best`, `hull` and `stack` are scratch.
long long search_texel(const Context& context, int i, int j, std::vector<double>& best,
                       std::vector<double>& hull, std::vector<TexelSearch::Entry>& stack, float& apex,
                       float* ratios) {
  double square[3][3];
  square_values(context, i, j, square);
  apex = apex_height(square);
  best.assign(std::size_t(context.grid.sector_count), 1.0);
  TexelSearch search{context, i, j, double(apex), square, best.data()};
  if (context.window > 0) search.window_cells(hull);
  if (!context.falling_only) {
    search.far_cells(stack, context.pyramid, ~0u);
  } else {
    for (int k = 0; k < context.grid.sector_count; ++k)
      search.far_cells(stack, context.falling[std::size_t(k)], 1u << k);
  }
  for (int k = 0; k < context.grid.sector_count; ++k) ratios[k] = stored_ratio(best[k]);
  return search.work;
}

// bake_bilinear_cones, or with falling_only bake_bilinear_relaxed_cones.
BakeStats bake_bilinear(HeightView heights, Address address, ConeView out, std::span<float> apex_heights,
                        const BilinearConeSettings& settings, bool falling_only) {
  validate(heights, out);
  const std::size_t texels = std::size_t(heights.width) * heights.height;
  if (apex_heights.size() != texels) {
    throw BakeError("bilinear cone map: the apex heights hold " + std::to_string(apex_heights.size()) +
                    " values for " + std::to_string(texels) + " texels");
  }
  if (settings.slope_window < 0 || settings.slope_window > max_slope_window) {
    throw BakeError("bilinear cone map: BilinearConeSettings::slope_window " +
                    std::to_string(settings.slope_window) + " is outside [0, " +
                    std::to_string(max_slope_window) + "] cells");
  }
  const auto start = std::chrono::steady_clock::now();
  const int sectors = out.sector_count;
  const Context context =
      make_context(heights, address, sectors, settings.slope_window, settings.prune, falling_only);

  std::atomic<long long> total_work{0};
  detail::RowProgress rows_done(settings.progress, heights.height);
  tbb::parallel_for(tbb::blocked_range<int>(0, heights.height), [&](const tbb::blocked_range<int>& rows) {
    std::vector<double> best(sectors), hull;
    std::vector<TexelSearch::Entry> stack;
    long long work = 0;
    for (int i = rows.begin(); i < rows.end(); ++i) {
      for (int j = 0; j < heights.width; ++j) {
        const std::size_t t = std::size_t(i) * heights.width + j;
        work += search_texel(context, i, j, best, hull, stack, apex_heights[t], out.data + t * sectors);
      }
      rows_done.row_done();
    }
    total_work += work;
  });
  rows_done.finish();

  return detail::whole_map_stats(Mode::bilinear, heights, sectors, total_work, start, out.data);
}

}  // namespace

BakeStats bake_bilinear_cones(HeightView heights, Address address, ConeView out,
                              std::span<float> apex_heights, const BilinearConeSettings& settings) {
  return bake_bilinear(heights, address, out, apex_heights, settings, false);
}

BakeStats bake_bilinear_relaxed_cones(HeightView heights, Address address, ConeView out,
                                      std::span<float> apex_heights, const BilinearConeSettings& settings) {
  return bake_bilinear(heights, address, out, apex_heights, settings, true);
}

namespace detail {

struct BilinearSearch::Context {
  bake::Context context;
};

BilinearSearch::BilinearSearch(HeightView heights, Address address, int sector_count, int slope_window)
    : context_(
          std::make_unique<Context>(Context{make_context(heights, address, sector_count, slope_window)})) {}
BilinearSearch::~BilinearSearch() = default;

void BilinearSearch::update(HeightView heights) {
  bake::Context& context = context_->context;
  if (heights.width != context.heights.width || heights.height != context.heights.height)
    throw std::invalid_argument("BilinearSearch::update: heights of another size");
  context.heights = heights;
  prepare(context);
}

long long BilinearSearch::texel(int i, int j, float& apex, float* ratios) const {
  thread_local std::vector<double> best, hull;
  thread_local std::vector<TexelSearch::Entry> stack;
  return search_texel(context_->context, i, j, best, hull, stack, apex, ratios);
}

}  // namespace detail
}  // namespace displace::bake
