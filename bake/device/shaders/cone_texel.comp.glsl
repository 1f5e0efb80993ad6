#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
// bake/device/shaders/cone_texel.comp.glsl - the device cone maps' search, one invocation per texel
// (bake/device/device_cones.cpp): bake.h's bake_bilinear_cones contract - apex H_c = max of the bilinear
// surface s over the texel's square Q_c, and per sector k an r_k with s(x) <= H_c + |x - p| / r_k for
// every p in Q_c and x in sector k from p - in float, with the margins below.
//
// The one fact: every ratio is the largest of three lower bounds, each valid alone: the Lipschitz
// floor 1 / L (s rises at most L per uv from any p, which lies at or below H_c); the slope window
// (the 2w x 2w cells around c, w = window_radius: 4 but in a first pass that asks fewer; cut at Q_c's
// edge lines, bounded by their distance and by how fast s can rise from Q_c's edge towards them:
// bake/cone_bilinear.cpp's window_cells, ported); and a top-down
// search of the max pyramid over cells for the rest, each block bounding its cells outside the window
// by (distance from Q_c) / (block max - H_c). The first pass either opens no node at or below
// first_pass_level (it bounds them whole, which is valid, and is "cut") or, with ring_radius > 0,
// bounds fixed rings of nodes around the texel (ring_tile), perhaps with a smaller window; a cut
// texel that gets one of refine_limit tickets is searched again down to the cells. Proof and margins:
// docs/design/device-cones.md.
#include "cones.h"
#include "cone_axis.inc.glsl"

layout(local_size_x = CONE_TILE, local_size_y = CONE_TILE, local_size_z = 1) in;

layout(binding = 0, r32f) uniform readonly image2D heights;
layout(std430, binding = 1) readonly buffer Pyramid { float node_max[]; };
layout(std430, binding = 2) buffer Counters { uint counters[]; };
// layer l, texel (i, j) at l * W * H + i * W + j: (ratio as a half rounded down) | (apex q) << 16
layout(std430, binding = 3) writeonly buffer Cones { uint cone_values[]; };
// a group first pass: per 8 x 8 texel group and level q < CONE_GROUP_LEVELS, at (group * levels + q) *
// (1 + sectors): the apex h_q, then the group's far ratio per sector from h_q. Written by the module
// built with CONE_GROUP_FAR_MODULE = 1 (the groups' far ratios), read by the texel module's group form.
#if CONE_GROUP_FAR_MODULE
layout(std430, binding = 4) writeonly buffer GroupFar { float group_far[]; };
#else
layout(std430, binding = 4) readonly buffer GroupFar { float group_far[]; };
#endif

layout(push_constant) uniform Push { ConeTexelPush push; };

// The kernel's form (bake/device/device_cones.cpp's texel_form), so that a pipeline holds only what it runs:
// the first pass bounds rings (ring_tile) rather than searching the pyramid, or takes its group's far
// ratios and bounds only the cells near the group (GROUP); cut texels may be refined. The groups' far
// ratios are a module of their own (CONE_GROUP_FAR_MODULE): as a fourth form of this one, with a third
// call of the search and a written buffer in the module, the search ran 2.1 times slower on an H200
// (512, first pass: 3.40 ms against 1.64 apart; unlimited at 2048: 226 against 95), though no form of
// it ran the groups' code.
layout(constant_id = 0) const bool FIRST_PASS_RINGS = false;
layout(constant_id = 1) const bool REFINES = true;
layout(constant_id = 2) const bool FIRST_PASS_GROUP = false;

// margins (docs/design/device-cones.md#rounding): float surface values are within 5e-7 of s
const float height_margin = 2e-6;   // height units: raises every computed maximum of s, and H_c
const float slope_margin = 2e-6;    // height units per cell: raises every rate of rise (before x W, H)
const float guard = 4e-6;           // relative: rounds the ill-conditioned far term of piece_bound safely
const float ratio_margin = 1e-5;    // relative: shrinks every ratio before it is stored (covers roundings)
const float unclaimed = 1.0001;     // a ratio no bound has lowered: stores as 1 after the margin
const float infinite_bound = 3.0e38;
const int R = CONE_SLOPE_WINDOW;  // the window's radius at most (its arrays' size)

bool wrap;
int W, H, sectors;
int window;                  // the window's radius in cells, 1..R
int i, j;                    // the texel: row, column
int qu0, qu1, qv0, qv1;      // Q_c in half texels
float half_u, half_v;        // uv per half texel
float apex;                  // H_c, raised by height_margin
float floor_ratio;           // 1 / L
float best[8];               // per sector: the least bound so far
float square[3][3];          // s at Q_c's corners, edge midpoints and centre
uint beyond[4];              // sectors meeting the open half-planes u > 0, u < 0, v > 0, v < 0
bool cut;                    // the search bounded a node it would have opened
int level_width(int level) { return (push.cells_u + (1 << level) - 1) >> level; }
int level_height(int level) { return (push.cells_v + (1 << level) - 1) >> level; }

// ---- geometry

// Gap between the span [q0, q1] (Q's along one axis: Q_c's, or a group's) and [first, last] (half
// texels); span_gap for Q_c's span [2t - 1, 2t + 1].
int box_gap(int q0, int q1, int first, int last) { return max(0, max(first - q1, q0 - last)); }
int span_gap(int t, int first, int last) { return box_gap(2 * t - 1, 2 * t + 1, first, last); }

float gap_distance(int gap_u, int gap_v) {
  const float u = float(gap_u) * half_u, v = float(gap_v) * half_v;
  return sqrt(u * u + v * v);
}

// a * a_scale <= b * b_scale for a, b >= 0 (integers below 2^24, scales below 2^16): true wherever the
// exact products say so (float products round by 6e-8 relative), so a mask only gains sectors
bool at_most(int a, int b, int a_scale, int b_scale) {
  return float(a) * float(a_scale) <= float(b) * float(b_scale) * (1.0 + 1e-6);
}

// Sectors whose closed wedge meets the box of directions [x0, x1] x [y0, y1] (half texels; the uv
// direction of (x, y) is that of (x H, y W)): bake/geometry.h's rect_sectors, a superset in float.
uint rect_sectors(int x0, int x1, int y0, int y1) {
  if (sectors == 1) return 1u;
  uint mask = 0u;
  if (sectors == 4) {
    if (x1 >= 0 && y1 >= 0) mask |= 1u;
    if (x0 <= 0 && y1 >= 0) mask |= 2u;
    if (x0 <= 0 && y0 <= 0) mask |= 4u;
    if (x1 >= 0 && y0 <= 0) mask |= 8u;
    return mask;
  }
  if (x1 >= 0 && y1 >= 0 && at_most(max(y0, 0), x1, W, H)) mask |= 1u << 0;
  if (x1 >= 0 && y1 >= 0 && at_most(max(x0, 0), y1, H, W)) mask |= 1u << 1;
  if (x0 <= 0 && y1 >= 0 && at_most(-min(x1, 0), y1, H, W)) mask |= 1u << 2;
  if (x0 <= 0 && y1 >= 0 && at_most(max(y0, 0), -x0, W, H)) mask |= 1u << 3;
  if (x0 <= 0 && y0 <= 0 && at_most(-min(y1, 0), -x0, W, H)) mask |= 1u << 4;
  if (x0 <= 0 && y0 <= 0 && at_most(-min(x1, 0), -y0, H, W)) mask |= 1u << 5;
  if (x1 >= 0 && y0 <= 0 && at_most(max(x0, 0), -y0, H, W)) mask |= 1u << 6;
  if (x1 >= 0 && y0 <= 0 && at_most(-min(y1, 0), x1, W, H)) mask |= 1u << 7;
  return mask;
}

// ---- ratios

bool improves(int k, float bound) { return bound < best[k] && best[k] > floor_ratio; }

// The sector loops run over all 8 with constant indices (unrolled), so that best[] stays in
// registers; a sector past `sectors` is never in a mask.
void lower(uint mask, float bound) {
  [[unroll]] for (int k = 0; k < 8; ++k)
    if ((mask >> k & 1u) != 0u && bound < best[k]) best[k] = bound;
}

// the largest ratio a bound could still lower (0: none); a bound at or above it lowers nothing
float ceiling() {
  float most = 0.0;
  [[unroll]] for (int k = 0; k < 8; ++k)
    if (k < sectors && best[k] > floor_ratio) most = max(most, best[k]);
  return most;
}

// the sectors of `mask` that `bound` could still lower
uint useful_sectors(uint mask, float bound) {
  uint useful = 0u;
  [[unroll]] for (int k = 0; k < 8; ++k)
    if ((mask >> k & 1u) != 0u && improves(k, bound)) useful |= 1u << k;
  return useful;
}

// ---- the slope window (bake/cone_bilinear.cpp's window_cells)

// the height of texel (i + db, j + da), read where it is (no private copy: a GPU keeps an array
// indexed at run time in slow per-invocation memory, while neighbouring invocations share these reads
// in the cache)
float height_at(int da, int db) {
  int a = j + da, b = i + db;
  if (a < 0 || a >= W) a = axis_texel(a, W, wrap);  // a division only at the map's edges
  if (b < 0 || b >= H) b = axis_texel(b, H, wrap);
  return imageLoad(heights, ivec2(a, b)).r;
}

// s on a cell with corner heights h = (lower left, lower right, upper left, upper right), at cell
// coordinates (fx, fy) in [0, 1]^2
float patch_value(vec4 h, float fx, float fy) {
  return (h.x * (1.0 - fx) + h.y * fx) * (1.0 - fy) + (h.z * (1.0 - fx) + h.w * fx) * fy;
}

// The largest rates of rise of s (uv units) over the box [fx0, fx1] x [fy0, fy1] of that cell, towards
// +u, -u, +v, -v, raised by slope_margin: ds/du = W lerp(e0, e1, fy) and ds/dv = H lerp(f0, f1, fx)
// are linear in one coordinate, so their extremes lie at the box's edges.
vec4 patch_rise(vec4 h, float fx0, float fx1, float fy0, float fy1) {
  const float e0 = h.y - h.x, e1 = h.w - h.z, f0 = h.z - h.x, f1 = h.w - h.y;
  const float du0 = e0 + (e1 - e0) * fy0, du1 = e0 + (e1 - e0) * fy1;
  const float dv0 = f0 + (f1 - f0) * fx0, dv1 = f0 + (f1 - f0) * fx1;
  return vec4((max(du0, du1) + slope_margin) * float(W), (slope_margin - min(du0, du1)) * float(W),
              (max(dv0, dv1) + slope_margin) * float(H), (slope_margin - min(dv0, dv1)) * float(H));
}

// The largest of s over the clamp onto Q_c of the box [u0, u1] x [v0, v1] (an edge segment or a
// corner of Q_c, where s is linear between the points of `square`).
float clamp_max(int u0, int u1, int v0, int v1) {
  const int a0 = clamp(u0 - qu0, 0, 2), a1 = clamp(u1 - qu0, 0, 2);
  const int b0 = clamp(v0 - qv0, 0, 2), b1 = clamp(v1 - qv0, 0, 2);
  float m = -infinite_bound;
  // all nine with constant indices: an array indexed at run time would leave the registers
  [[unroll]] for (int b = 0; b < 3; ++b)
    [[unroll]] for (int a = 0; a < 3; ++a)
      if (a >= a0 && a <= a1 && b >= b0 && b <= b1) m = max(m, square[b][a]);
  return m;
}

// A lower bound of delta / min(rise, slope delta - drop) over delta in [near, far]: a piece whose
// points lie between near and far from Q_c, at most `rise` above H_c and at most slope delta - drop
// (s(y) <= H_c - drop at the clamp y onto Q_c). Evaluated in closed form at the kink, never at a
// rounded argmin: delta* / rise (the least over every delta > 0) in between, near / rise before,
// far / (slope far - drop) past it with the denominator rounded up (it may cancel).
float piece_bound(float near, float far, float rise, float drop, float slope) {
  if (drop <= 0.0) return max(near / rise, 1.0 / slope);
  const float crossing = (rise + drop) / slope;  // chooses the branch only
  if (crossing <= near) return near / rise;
  if (crossing < far) return (rise + drop) / (slope * rise);
  const float far_up = far * (1.0 + guard);
  const float denominator = (slope * far_up * (1.0 + guard) - drop) * (1.0 + guard);
  return denominator > 0.0 ? far_up / denominator : infinite_bound;
}

void window_cells() {
  // The running largest rates outward from Q_c: cell (da, db)'s takes in those of the cells between it
  // and Q_c's row and column, (da -+ 1, db) and (da, db -+ 1). Rows and columns are visited outward
  // from Q_c (0, 1, ..., window - 1, then -1, ..., -window), so the first is the cell visited just
  // before in this row, and the second is at the same place in the row visited just before: one
  // running value and one row of them.
  float row_u[2 * R], row_v[2 * R];
  [[dont_unroll]] for (int y = 0; y < 2 * window; ++y) {
    const int db = y < window ? y : window - 1 - y;  // 0, 1, ..., window - 1, then -1, ..., -window
    const int nv = cell_of_left_centre(i + db, wrap);
    float run_u = 0.0, run_v = 0.0;
    [[dont_unroll]] for (int x = 0; x < 2 * window; ++x) {
      const int da = x < window ? x : window - 1 - x;
      const int nu = cell_of_left_centre(j + da, wrap);
      const bool exists = cell_exists(nu, push.cells_u, wrap) && cell_exists(nv, push.cells_v, wrap);
      vec4 h = vec4(0.0);
      float rise_u = 0.0, rise_v = 0.0;
      if (exists) {
        h = vec4(height_at(da, db), height_at(da + 1, db), height_at(da, db + 1), height_at(da + 1, db + 1));
        const vec4 cell = patch_rise(h, 0.0, 1.0, 0.0, 1.0);
        rise_u = max(da >= 0 ? cell.x : cell.y, 0.0);
        rise_v = max(db >= 0 ? cell.z : cell.w, 0.0);
      }
      if (da != 0 && da != -1) {
        rise_u = max(rise_u, run_u);
        rise_v = max(rise_v, run_v);
      }
      if (db != 0 && db != -1) {
        rise_u = max(rise_u, row_u[x]);
        rise_v = max(rise_v, row_v[x]);
      }
      run_u = row_u[x] = rise_u;
      run_v = row_v[x] = rise_v;
      if (!exists) continue;
      const float cell_max = max(max(h.x, h.y), max(h.z, h.w));  // exact: a patch peaks at a corner
      if (!(cell_max > apex)) continue;
      const bool centre = (da == 0 || da == -1) && (db == 0 || db == -1);
      const int cu0 = cell_begin(nu, wrap), cu1 = cell_end(nu, W, wrap);
      const int cv0 = cell_begin(nv, wrap), cv1 = cell_end(nv, H, wrap);
      if (!centre) {
        // every piece is at least the cell's gap away and at most its maximum (plus the margin twice)
        // high: when that bound reaches every ratio it could lower, no piece lowers one
        const uint cell_sectors = rect_sectors(cu0 - qu1, cu1 - qu0, cv0 - qv1, cv1 - qv0);
        const float gap = gap_distance(span_gap(j, cu0, cu1), span_gap(i, cv0, cv1));
        if (useful_sectors(cell_sectors, gap / (cell_max + 2.0 * height_margin - apex)) == 0u) continue;
      }
      const int origin_u = 2 * cell_left_centre(nu, wrap), origin_v = 2 * cell_left_centre(nv, wrap);
      // the ranges along each axis before Q_c, across it and beyond it (side -1, 0, +1)
      [[dont_unroll]] for (int sv = -1; sv <= 1; ++sv) {
        const int v0 = max(cv0, sv < 0 ? cv0 : (sv == 0 ? qv0 : qv1));
        const int v1 = min(cv1, sv < 0 ? qv0 : (sv == 0 ? qv1 : cv1));
        if (v0 >= v1) continue;
        [[dont_unroll]] for (int su = -1; su <= 1; ++su) {
          if (su == 0 && sv == 0) continue;  // inside Q_c: s <= H_c
          const int u0 = max(cu0, su < 0 ? cu0 : (su == 0 ? qu0 : qu1));
          const int u1 = min(cu1, su < 0 ? qu0 : (su == 0 ? qu1 : cu1));
          if (u0 >= u1) continue;
          const float fu0 = float(u0 - origin_u) * 0.5, fu1 = float(u1 - origin_u) * 0.5;
          const float fv0 = float(v0 - origin_v) * 0.5, fv1 = float(v1 - origin_v) * 0.5;
          const float top = max(max(patch_value(h, fu0, fv0), patch_value(h, fu1, fv0)),
                                max(patch_value(h, fu0, fv1), patch_value(h, fu1, fv1))) +
                            height_margin;
          if (!(top > apex)) continue;
          float along_u = rise_u, along_v = rise_v;
          if (centre) {
            const vec4 own = patch_rise(h, fu0, fu1, fv0, fv1);
            along_u = max(su > 0 ? own.x : own.y, 0.0);
            along_v = max(sv > 0 ? own.z : own.w, 0.0);
          }
          const float slope = su == 0 ? along_v : (sv == 0 ? along_u : sqrt(along_u * along_u + along_v * along_v));
          const int far_u = su > 0 ? u1 - qu1 : (su < 0 ? qu0 - u0 : 0);
          const int far_v = sv > 0 ? v1 - qv1 : (sv < 0 ? qv0 - v0 : 0);
          // shrunk so that it never exceeds the exact drop (a cancelling term divides by it)
          const float drop = max(0.0, (apex - (clamp_max(u0, u1, v0, v1) + height_margin)) * (1.0 - guard));
          const float bound = piece_bound(gap_distance(span_gap(j, u0, u1), span_gap(i, v0, v1)),
                                          gap_distance(far_u, far_v), top - apex, drop, slope);
          uint mask = rect_sectors(u0 - qu1, u1 - qu0, v0 - qv1, v1 - qv0);
          if (su != 0) mask &= su > 0 ? beyond[0] : beyond[1];
          if (sv != 0) mask &= sv > 0 ? beyond[2] : beyond[3];
          lower(mask, bound);
        }
      }
    }
  }
}

// ---- the pyramid search

// The window in unrolled cells.
int wu0, wu1, wv0, wv1;

// uv distance from Q (Q_c; a group's square for GROUP_FAR) to the cells [fu, lu] x [fv, lv] (unrolled)
float cells_gap(int fu, int lu, int fv, int lv) {
  return gap_distance(box_gap(qu0, qu1, cell_begin(fu, wrap), cell_end(lu, W, wrap)),
                      box_gap(qv0, qv1, cell_begin(fv, wrap), cell_end(lv, H, wrap)));
}

// Whether node (level, bu, bv) of tile (tile_u, tile_v) is to be opened; a node it need not open it
// bounds here, or skips when it can lower nothing. floor_level: nodes at or below it are not opened.
bool examine(int level, int tile_u, int tile_v, int bu, int bv, int floor_level) {
  const float top = node_max[push.level_offset[level] + bv * level_width(level) + bu];
  if (!(top > apex)) return false;
  const int first_u = tile_u * push.cells_u + (bu << level);
  const int last_u = tile_u * push.cells_u + min((bu + 1) << level, push.cells_u) - 1;
  const int first_v = tile_v * push.cells_v + (bv << level);
  const int last_v = tile_v * push.cells_v + min((bv + 1) << level, push.cells_v) - 1;
  if (first_u >= wu0 && last_u <= wu1 && first_v >= wv0 && last_v <= wv1) return false;  // the window's
  // its cells outside the window: left and right of it, then below and above it within its columns
  float gap;
  if (first_u <= wu1 && last_u >= wu0 && first_v <= wv1 && last_v >= wv0) {
    gap = infinite_bound;
    if (first_u < wu0) gap = min(gap, cells_gap(first_u, wu0 - 1, first_v, last_v));
    if (last_u > wu1) gap = min(gap, cells_gap(wu1 + 1, last_u, first_v, last_v));
    const int inner_u0 = max(first_u, wu0), inner_u1 = min(last_u, wu1);
    if (first_v < wv0) gap = min(gap, cells_gap(inner_u0, inner_u1, first_v, wv0 - 1));
    if (last_v > wv1) gap = min(gap, cells_gap(inner_u0, inner_u1, wv1 + 1, last_v));
  } else {
    gap = cells_gap(first_u, last_u, first_v, last_v);
  }
  const uint all = rect_sectors(cell_begin(first_u, wrap) - qu1, cell_end(last_u, W, wrap) - qu0,
                                cell_begin(first_v, wrap) - qv1, cell_end(last_v, H, wrap) - qv0);
  const float bound = gap / (top - apex);
  const uint mask = useful_sectors(all, bound);
  if (mask == 0u) return false;
  if (level == 0) {
    lower(mask, bound);
    return false;
  }
  if (level <= floor_level) {
    lower(mask, bound);
    cut = true;
    return false;
  }
  return true;
}

// The texel's centre in unrolled cells (the left edge of the cell whose left centre it is).
int centre_u, centre_v;

// The child of node (level, bu, bv) of a tile on the texel's side of its middle along each axis, as a
// quadrant (bit 0: the upper half along u, bit 1 along v): its children are examined in the order
// nearest, across u, across v, diagonal - quadrant k ^ nearest for k = 0..3.
int nearest_child(int level, int tile_u, int tile_v, int bu, int bv) {
  const int half_side = 1 << (level - 1);
  const int middle_u = tile_u * push.cells_u + (bu << level) + half_side;
  const int middle_v = tile_v * push.cells_v + (bv << level) + half_side;
  return (centre_u >= middle_u ? 1 : 0) | (centre_v >= middle_v ? 2 : 0);
}

// One tile's pyramid, depth first without a stack: a node's children are examined one at a time, in
// nearest_child's order, each against the ratios as they stand when it is reached; after a node that
// is not opened comes its next sibling that exists, or its parent's. Every node that could lower a
// ratio is opened (its children's bounds are never below its own), so with no floor the result is
// the least bound of every cell whatever the order; the order only makes the ratios drop sooner.
void far_tile(int tile_u, int tile_v, int floor_level) {
  const int top_level = push.levels - 1;
  int level = top_level, bu = 0, bv = 0;
  bool open = examine(level, tile_u, tile_v, 0, 0, floor_level);
  [[dont_unroll]] while (true) {
    int parent_u, parent_v, k;
    if (open) {  // its first child
      parent_u = bu;
      parent_v = bv;
      --level;
      k = 0;
    } else {  // its next sibling
      if (level == top_level) return;
      parent_u = bu >> 1;
      parent_v = bv >> 1;
      k = (((bu & 1) | ((bv & 1) << 1)) ^ nearest_child(level + 1, tile_u, tile_v, parent_u, parent_v)) + 1;
    }
    const int nearest = nearest_child(level + 1, tile_u, tile_v, parent_u, parent_v);
    int child_u = -1, child_v = -1;
    for (; k < 4; ++k) {
      const int quadrant = k ^ nearest;
      const int u = 2 * parent_u + (quadrant & 1), v = 2 * parent_v + (quadrant >> 1);
      if (u < level_width(level) && v < level_height(level)) {
        child_u = u;
        child_v = v;
        break;
      }
    }
    if (child_u < 0) {  // the parent is done
      ++level;
      bu = parent_u;
      bv = parent_v;
      open = false;
      continue;
    }
    bu = child_u;
    bv = child_v;
    open = examine(level, tile_u, tile_v, bu, bv, floor_level);
  }
}

// ---- the first pass's rings

// One tile's pyramid from the top down, visiting the same nodes whatever the heights (so the
// invocations of a group keep in step): at each level, the children of the level above's near box (at
// the top, every node) are examined; those outside this level's near box - the nodes within
// ring_radius of the texel's own node along both axes - are bounded whole (examine, opening nothing:
// a useful one lowers its sectors and marks the texel cut), and the near box's children are the next
// level's. At level 0 the near box is bounded too (its nodes are cells). So every cell of the tile
// lies in a node bounded whole or skipped (below H_c, lowering nothing, or in the window), and with
// ring_radius 1 and the full window the near box of level 1 lies inside the window: the levels stop
// once the next level's nodes all do. Proof: docs/design/device-cones.md, "The first pass's rings".
// ring_descent: the same from level `top`'s nodes [first_u, last_u] x [first_v, last_v] of the tile
// (the cells they hold are the ones covered).
void ring_descent(int tile_u, int tile_v, int top, int first_u, int last_u, int first_v, int last_v, int radius) {
  const int tile_first_u = tile_u * push.cells_u, tile_first_v = tile_v * push.cells_v;
  const int centre_in_u = centre_u - tile_first_u, centre_in_v = centre_v - tile_first_v;
  [[dont_unroll]] for (int level = top; level >= 0; --level) {
    // the near box (>> rounds towards minus infinity: a texel left of or below the tile has a node < 0)
    const int near_u0 = (centre_in_u >> level) - radius, near_u1 = (centre_in_u >> level) + radius;
    const int near_v0 = (centre_in_v >> level) - radius, near_v1 = (centre_in_v >> level) + radius;
    const int side = 1 << level, offset = push.level_offset[level], row_width = level_width(level);
    // the level's cells (unrolled): where they meet the window, examine() cuts nodes at its edges
    const int cells_u0 = tile_first_u + first_u * side;
    const int cells_u1 = tile_first_u + min((last_u + 1) * side, push.cells_u) - 1;
    const int cells_v0 = tile_first_v + first_v * side;
    const int cells_v1 = tile_first_v + min((last_v + 1) * side, push.cells_v) - 1;
    const bool meets_window = cells_u0 <= wu1 && cells_u1 >= wu0 && cells_v0 <= wv1 && cells_v1 >= wv0;
    const float most = ceiling();  // as it stands before the level: a bound at or above it lowers nothing
    [[dont_unroll]] for (int bv = first_v; bv <= last_v; ++bv) {
      const int row_begin = cell_begin(tile_first_v + bv * side, wrap);
      const int row_end = cell_end(tile_first_v + min((bv + 1) * side, push.cells_v) - 1, H, wrap);
      const float gap_v = float(span_gap(i, row_begin, row_end)) * half_v;
      const bool near_row = level > 0 && bv >= near_v0 && bv <= near_v1;
      [[dont_unroll]] for (int bu = first_u; bu <= last_u; ++bu) {
        if (near_row && bu >= near_u0 && bu <= near_u1) continue;  // opened: its children come next
        if (meets_window) {
          examine(level, tile_u, tile_v, bu, bv, push.levels);
          continue;
        }
        // examine()'s bound for a node away from the window, the row's part of it computed once. Not
        // examine() itself: through it, rings 2 took 12% longer on an H200 (1.53 ms at 512 against
        // 1.36: f162d1b and the commit before it), and 13% less on lavapipe (1807 ms against 2080)
        const float top = node_max[offset + bv * row_width + bu];
        if (!(top > apex)) continue;
        const int column_begin = cell_begin(tile_first_u + bu * side, wrap);
        const int column_end = cell_end(tile_first_u + min((bu + 1) * side, push.cells_u) - 1, W, wrap);
        const float gap_u = float(span_gap(j, column_begin, column_end)) * half_u;
        const float bound = sqrt(gap_u * gap_u + gap_v * gap_v) / (top - apex);
        if (!(bound < most)) continue;
        const uint all = rect_sectors(column_begin - qu1, column_end - qu0, row_begin - qv1, row_end - qv0);
        const uint mask = useful_sectors(all, bound);
        if (mask == 0u) continue;
        lower(mask, bound);
        if (level > 0) cut = true;
      }
    }
    if (level == 0) return;
    // the children that exist of the near box's nodes examined here
    first_u = 2 * max(near_u0, first_u);
    last_u = min(2 * min(near_u1, last_u) + 1, level_width(level - 1) - 1);
    first_v = 2 * max(near_v0, first_v);
    last_v = min(2 * min(near_v1, last_v) + 1, level_height(level - 1) - 1);
    if (first_u > last_u || first_v > last_v) return;
    const int child_side = 1 << (level - 1);
    const bool in_window_u = tile_first_u + first_u * child_side >= wu0 &&
                             tile_first_u + min((last_u + 1) * child_side, push.cells_u) - 1 <= wu1;
    const bool in_window_v = tile_first_v + first_v * child_side >= wv0 &&
                             tile_first_v + min((last_v + 1) * child_side, push.cells_v) - 1 <= wv1;
    if (in_window_u && in_window_v) return;  // all in the window: nothing left to bound
  }
}

void ring_tile(int tile_u, int tile_v) {
  const int top = push.levels - 1;
  ring_descent(tile_u, tile_v, top, 0, level_width(top) - 1, 0, level_height(top) - 1, push.ring_radius);
}

// With wrap, the images whose cells come within uv distance 1 of Q_c: tiles -2..1. Tile -2's last
// cells reach to 1 - 1/(2W) of texel 0's square; tile 2's first begin 1 + 1/(2W) past texel W - 1's,
// so its bounds are at least (1 + 1/(2W)) / (1 - height_margin): ratios that store as 1 for every
// side up to 62500 (and a ratio of 1 holds there: s rises at most 1 over a distance of at least 1).
// The texel's own tile first, then the nearer neighbour along each axis.
void far_cells(int floor_level, bool rings) {
  if (!wrap) {
    if (rings) ring_tile(0, 0);
    else far_tile(0, 0, floor_level);
    return;
  }
  // the side of Q's middle (half texels; for Q_c, 2j + 1 >= W): the order only
  const int side_u = qu0 + qu1 + 2 >= 2 * W ? 1 : -1, side_v = qv0 + qv1 + 2 >= 2 * H ? 1 : -1;
  [[dont_unroll]] for (int b = 0; b < 4; ++b) {
    const int tile_v = b == 0 ? 0 : (b == 1 ? side_v : (b == 2 ? -side_v : -2));
    [[dont_unroll]] for (int a = 0; a < 4; ++a) {
      const int tile_u = a == 0 ? 0 : (a == 1 ? side_u : (a == 2 ? -side_u : -2));
      if (rings) ring_tile(tile_u, tile_v);
      else far_tile(tile_u, tile_v, floor_level);
    }
  }
}

// ---- what both kinds of invocation set up

// The map's shape from the push constants, and the Lipschitz floor.
void read_map() {
  W = push.width;
  H = push.height;
  wrap = push.wrap != 0;
  sectors = push.sectors;
  half_u = 0.5 / float(W);
  half_v = 0.5 / float(H);
  const float lipschitz = uintBitsToFloat(counters[CONE_COUNTER_LIPSCHITZ]);
  floor_ratio = lipschitz > 0.0 ? 1.0 / lipschitz : infinite_bound;
}

// Q: the squares of texels [j0, j1] x [i0, i1] (half texels).
void set_square(int j0, int j1, int i0, int i1) {
  qu0 = 2 * j0 - 1;
  qu1 = 2 * j1 + 1;
  qv0 = 2 * i0 - 1;
  qv1 = 2 * i1 + 1;
}

// ---- a group first pass (docs/design/device-cones.md, "The group's first pass")

// The cells that the texels of group (gu, gv) bound themselves, in unrolled cells: their centre cells
// widened by CONE_GROUP_NEAR (so every texel's window lies inside). The group's far ratios bound the
// rest.
void group_near(int gu, int gv, out int u0, out int u1, out int v0, out int v1) {
  u0 = cell_of_left_centre(gu * CONE_TILE, wrap) - CONE_GROUP_NEAR;
  u1 = cell_of_left_centre(min(gu * CONE_TILE + CONE_TILE, W) - 1, wrap) + CONE_GROUP_NEAR;
  v0 = cell_of_left_centre(gv * CONE_TILE, wrap) - CONE_GROUP_NEAR;
  v1 = cell_of_left_centre(min(gv * CONE_TILE + CONE_TILE, H) - 1, wrap) + CONE_GROUP_NEAR;
}

int group_stride() { return 1 + sectors; }
// where group (gu, gv)'s records begin in group_far (level 0's)
int group_record(int gu, int gv) {
  return (gv * ((W + CONE_TILE - 1) / CONE_TILE) + gu) * CONE_GROUP_LEVELS * group_stride();
}

#if CONE_GROUP_FAR_MODULE
// The module's invocations, one per group and level q: Q is the group's square (the union of its texels'),
// the apex h_q = lo + (hi - lo) q / levels (lo, hi: the least and largest height of its texels; every
// texel's apex is at least its own height, so at least h_0), the window is the group's near cells, and
// the pyramid is searched to the cells (first_pass_level -1) or cut (>= 0) as a texel's is. For texel c
// of the group with apex H_c >= h_q and a cell x outside the near cells, |x - p| >= gap(Q, x) for p in
// Q_c and s(x) - H_c <= max - h_q, so each ratio holds for c; Q's boxes of directions hold c's.
void group_far_main() {
  read_map();
  const int groups_u = (W + CONE_TILE - 1) / CONE_TILE;
  // a dispatch row per group row, each group's levels side by side along it
  const int id = int(gl_WorkGroupID.x * gl_WorkGroupSize.x * gl_WorkGroupSize.y + gl_LocalInvocationIndex);
  const int q = id % CONE_GROUP_LEVELS;
  const int gu = id / CONE_GROUP_LEVELS;
  if (gu >= groups_u) return;
  const int gv = int(gl_WorkGroupID.y) + push.first_row / CONE_TILE;
  const int j0 = gu * CONE_TILE, j1 = min(j0 + CONE_TILE, W) - 1;
  const int i0 = gv * CONE_TILE, i1 = min(i0 + CONE_TILE, H) - 1;
  float lo = 1.0, hi = 0.0;
  [[dont_unroll]] for (int b = i0; b <= i1; ++b)
    [[dont_unroll]] for (int a = j0; a <= j1; ++a) {
      const float h = imageLoad(heights, ivec2(a, b)).r;
      lo = min(lo, h);
      hi = max(hi, h);
    }
  apex = lo + (hi - lo) * (float(q) / float(CONE_GROUP_LEVELS));
  set_square(j0, j1, i0, i1);
  group_near(gu, gv, wu0, wu1, wv0, wv1);
  centre_u = cell_of_left_centre((j0 + j1) / 2, wrap);
  centre_v = cell_of_left_centre((i0 + i1) / 2, wrap);
  [[unroll]] for (int k = 0; k < 8; ++k) best[k] = unclaimed;
  far_cells(push.first_pass_level, false);
  const int at = group_record(gu, gv) + q * group_stride();
  group_far[at] = apex;
  [[unroll]] for (int k = 0; k < 8; ++k) {  // constant indices: best[] stays in registers
    if (k >= sectors) break;
    group_far[at + 1 + k] = best[k];
  }
}
#else

// A group first pass's texel: rings of radius 1 (ring_descent) from the level-L nodes (L = 2, or the
// top for a small map) that hold its group's near cells, in each tile they reach, then the group's
// far ratios of the highest apex h_q at or below the texel's. Either lowering a ratio cuts the texel.
void group_first_pass() {
  int nu0, nu1, nv0, nv1;
  group_near(j / CONE_TILE, i / CONE_TILE, nu0, nu1, nv0, nv1);
  const int level = min(2, push.levels - 1);
  const int tu0 = wrap ? floor_div(nu0, push.cells_u) : 0, tu1 = wrap ? floor_div(nu1, push.cells_u) : 0;
  const int tv0 = wrap ? floor_div(nv0, push.cells_v) : 0, tv1 = wrap ? floor_div(nv1, push.cells_v) : 0;
  [[dont_unroll]] for (int tv = tv0; tv <= tv1; ++tv) {
    const int v0 = max(nv0 - tv * push.cells_v, 0), v1 = min(nv1 - tv * push.cells_v, push.cells_v - 1);
    [[dont_unroll]] for (int tu = tu0; tu <= tu1; ++tu) {
      const int u0 = max(nu0 - tu * push.cells_u, 0), u1 = min(nu1 - tu * push.cells_u, push.cells_u - 1);
      ring_descent(tu, tv, level, u0 >> level, u1 >> level, v0 >> level, v1 >> level, 1);
    }
  }
  const int first = group_record(j / CONE_TILE, i / CONE_TILE);
  int at = first;
  [[dont_unroll]] for (int q = 1; q < CONE_GROUP_LEVELS; ++q)
    if (group_far[first + q * group_stride()] <= apex) at = first + q * group_stride();
  [[unroll]] for (int k = 0; k < 8; ++k) {
    if (k >= sectors) break;
    const float far = group_far[at + 1 + k];
    if (far < best[k]) {
      best[k] = far;
      cut = true;
    }
  }
}

#endif

// ---- the stored values (render/map_pack.h's encode_ratio and encode_apex)

uint encode_ratio(float ratio) {
  const float clamped = min(ratio, 1.0);
  if (!(clamped >= 6.103515625e-05)) return 0u;  // 2^-14: map_pack.h's smallest_half_ratio
  return (floatBitsToUint(clamped) >> 13) - ((127u - 15u) << 10);
}
uint encode_apex(float height) { return uint(min(height * 65535.0 + 2.0, 65535.0)); }

#if CONE_GROUP_FAR_MODULE
void main() { group_far_main(); }
#else
void main() {
  j = int(gl_GlobalInvocationID.x);
  i = int(gl_GlobalInvocationID.y) + push.first_row;
  if (j >= push.width || i >= push.height) return;
  read_map();
  window = push.window_radius;
  set_square(j, j, i, i);
  const int reach = 4 * max(W, H);
  beyond[0] = rect_sectors(1, 1, -reach, reach);
  beyond[1] = rect_sectors(-1, -1, -reach, reach);
  beyond[2] = rect_sectors(-reach, reach, 1, 1);
  beyond[3] = rect_sectors(-reach, reach, -1, -1);

  // the heights around c, and H_c: s is bilinear on each quarter of Q_c, so its nine grid points bound it
  float around[3][3];  // the heights of texels (i + b - 1, j + a - 1)
  [[unroll]] for (int b = 0; b < 3; ++b)
    [[unroll]] for (int a = 0; a < 3; ++a) around[b][a] = height_at(a - 1, b - 1);
  float highest = 0.0;
  [[unroll]] for (int b = 0; b < 3; ++b)
    [[unroll]] for (int a = 0; a < 3; ++a) {
      square[b][a] = 0.25 * (around[1][1] + around[1][a] + around[b][1] + around[b][a]);
      highest = max(highest, square[b][a]);
    }
  apex = highest + height_margin;
  wu0 = cell_of_left_centre(j - window, wrap);
  wu1 = cell_of_left_centre(j + window - 1, wrap);
  wv0 = cell_of_left_centre(i - window, wrap);
  wv1 = cell_of_left_centre(i + window - 1, wrap);
  centre_u = cell_of_left_centre(j, wrap);
  centre_v = cell_of_left_centre(i, wrap);

  // the window, then the pyramid: the first pass, and the texels it cut searched again if they may
  [[unroll]] for (int k = 0; k < 8; ++k) best[k] = unclaimed;
  window_cells();
  float window_best[8] = best;
  cut = false;
  if (FIRST_PASS_GROUP) group_first_pass();
  else far_cells(push.first_pass_level, FIRST_PASS_RINGS);
  if (cut) {  // every cut texel takes a ticket (read_back counts them), refined or not
    const bool ticket = atomicAdd(counters[CONE_COUNTER_TICKETS], 1u) < uint(push.refine_limit);
    if (REFINES && ticket) {
      const float first_pass[8] = best;
      best = window_best;
      far_cells(-1, false);
      [[unroll]] for (int k = 0; k < 8; ++k) best[k] = max(best[k], first_pass[k]);
    }
  }

  // stored: each ratio raised to the floor, shrunk by the margin, clamped to 1 and rounded down
  const uint apex_bits = encode_apex(apex) << 16;
  const int texels = W * H, texel = i * W + j;
  uint least = 0xffffu;
  [[unroll]] for (int k = 0; k < 8; ++k) {  // constant indices: best[] stays in registers
    if (k >= sectors) break;
    const uint ratio = encode_ratio(max(best[k], floor_ratio) * (1.0 - ratio_margin));
    least = min(least, ratio);
    cone_values[k * texels + texel] = ratio | apex_bits;
  }
  if (sectors > 1) cone_values[sectors * texels + texel] = least | apex_bits;
}
#endif
