// bake/lane_sweep.h - quadrant cone ratios from chamfer dilation sweeps over 32 ratio lanes in 16-bit
// integers: the budgeted baker's stage L (internal to bake/; the method and its proofs are in
// lane_sweep.cpp).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

namespace displace::bake::detail {

constexpr int lane_count = 32;  // ratio lanes tested per sweep
// Chamfer moves (da, db) = (rows, columns): the carry (0, 1) along the row, the row moves (1, k)
// for k = 0 .. lane_reach_limit and the column moves (k, 1) for k = 2 .. lane_reach_limit. steps
// holds one row of lane_count values per move, in this order.
constexpr int lane_reach_limit = 64;  // the longest row or column move, in texels
constexpr int lane_move_carry = 0;
constexpr int lane_move_row = 1;                                        // (1, k): lane_move_row + k
constexpr int lane_move_column = lane_move_row + lane_reach_limit + 1;  // (k, 1): lane_move_column + k - 2
constexpr int lane_move_limit = lane_move_column + lane_reach_limit - 1;
constexpr double height_scale = 65535.0;  // heights and dilations are in units of 1 / 65535

// One sweep. The map is seen from the sweep's quadrant: local (a, b) is physical row
// flip_y ? H - 1 - a : a, column flip_x ? W - 1 - b : b, and the blockers of local texel (a, b) that
// the sweep sees are the texels (a + da, b + db) that paths of its moves reach: (0, 1) with carry,
// (1, k) for row_first <= k < row_first + row_count and (k, 1) for column_first <= k <
// column_first + column_count (column_first >= 2).
struct LaneSweepJob {
  int width = 0, height = 0;
  bool wrap = true;
  bool flip_x = false, flip_y = false;
  bool carry = true;                       // move (0, 1): the dilation runs along the row
  int row_first = 0, row_count = 3;        // row moves (1, k); at least one
  int column_first = 2, column_count = 1;  // column moves (k, 1)
  int depth = 2, padding = 2;             // row buffers kept, texels past a buffer's end (lane_sweep_scratch)
  const std::uint16_t* top = nullptr;     // ceil(h * 65535) or a little above, physical row-major
  const std::uint16_t* bottom = nullptr;  // floor(h * 65535) or a little below, physical row-major
  // steps[m * lane_count + l]: what the dilation loses over move m at lane l, rounded down (m as
  // above: lane_move_carry, lane_move_row + k, lane_move_column + k - 2)
  const std::uint16_t* steps = nullptr;
  std::uint16_t* scratch = nullptr;  // lane_sweep_scratch(job) values, 64-byte aligned
  long long* row_sums = nullptr;     // height / 2 + 2 values
  // out: per physical texel, bit l set when lane l passes. Lanes pass from the lowest up, so the
  // count of set bits says which; the first lane that fails (if any) failed on a real blocker, so it
  // bounds the exact ratio from above.
  std::uint32_t* masks = nullptr;
  bool stop_early = true;  // the second lap stops where it meets the first (false: tests only)
  long long work = 0;      // out: texel updates performed (rows x columns, wrap fix-ups included)

  // Bilinear mode (bilinear_sweep.cpp): the map is the grid of CELLS between texel centres (cell n
  // between texels n - 1 and n along each axis; wrap: W x H of them, clamp: (W + 1) x (H + 1) with
  // the half-texel border cells), `top` their maxima, and the tested points are the TEXELS: local
  // texel (t, b) passes lane l when every cell in the quadrant of one of its five face cells - local
  // cells (t + 2, b + k) for k = 0, 1, 2 and (t + k, b + 2) for k = 0, 1, shifted by cell_offset_y
  // and cell_offset_x - other than that face cell lies below its cone: max of the five dilations less
  // bonus[l] <= texel_bottom. Masks go per physical texel (row stride texel_width); `bottom` is
  // unused, and the sweep is a quadrant's (the carry and the plan's row and column moves).
  bool bilinear = false;
  int texel_width = 0, texel_height = 0;
  int cell_offset_x = 0, cell_offset_y = 0;     // 0 or -1 (wrap with a flipped axis)
  const std::uint16_t* texel_bottom = nullptr;  // floor(apex * 65535) or a little below, physical
  const std::uint16_t* bonus = nullptr;         // lane_count values, rounded down
  std::uint16_t* bilinear_scratch = nullptr;    // bilinear_sweep_scratch(width, texel_width) values
  // the same test through the seven face cells of the box {0, ..., 3}^2 - cells (t + 3, b + k),
  // k = 0..3, and (t + k, b + 3), k = 0..2 - with its own bonus, into passed3
  std::uint8_t* passed = nullptr;
  std::uint8_t* passed3 = nullptr;
  const std::uint16_t* bonus3 = nullptr;
  // With wrap: the first lap leaves the box tests of its first skip_tests rows to the second lap,
  // which then sweeps at least that many rows (the caller's guess of where it stops: the same
  // counts either way, only the work differs); out: second_lap_rows, the rows the second lap swept.
  int skip_tests = 0;
  int second_lap_rows = 0;

  // A part of a split sweep (bilinear mode, sweep_bilinear_quadrants on many threads): only steps
  // [first_step, last_step) of the sweep (step s sweeps local row H - 1 - s mod H; lap 1 is steps 0 ..
  // H - 1, lap 2 from H on), from zeros (fresh) or from the row buffers and ring that the part before
  // step first_step left in `scratch` and `bilinear_scratch`; the box tests of steps before
  // skip_until are left to another part. record_sums gets the row sums of its first sums_count steps;
  // with compare_sums instead, the part stops once stop-test many rows in a row equal them (the lap
  // logic above, against that part's first pass) and it has swept at least compare_skip steps: out
  // converged, and split_rows, the steps swept.
  bool split = false;
  bool fresh = true;
  int first_step = 0, last_step = 0, skip_until = 0;
  long long* record_sums = nullptr;
  const long long* compare_sums = nullptr;
  int sums_count = 0, compare_skip = 0;
  bool converged = false;
  int split_rows = 0;
};

// Extra scratch of a bilinear sweep: a ring of four rows of dilations, each with one padding cell
// before and four after.
inline std::size_t bilinear_sweep_scratch(int cell_width, int /*texel_width*/) {
  return 4 * (std::size_t(cell_width) + 5) * lane_count;
}

struct LanePlan;

// The 4-sector output of the four quadrants' masks, for texels [first, last):
// out[texel * 4 + quadrant] = lane_ratio[count], or below the lowest lane lane_floor's floor; adds
// the ratios to ratio_sum and to pending pending_count[count], or below the lowest lane 1 where the
// floor is below floor_keep times its certified bound (lane_upper[0] or the floor's upper).
struct LaneEmitJob {
  const std::uint32_t* masks[4] = {};
  const LanePlan* plan = nullptr;
  const float* heights = nullptr;
  float* out = nullptr;
  const float* lane_ratio = nullptr;            // lane_count + 1 entries
  const std::uint8_t* pending_count = nullptr;  // lane_count + 1 entries ([0] unused)
  float floor_keep = 1.0f;
  double ratio_sum = 0.0;
  long long pending = 0;
};

// Sets the job's depth (the rows below that the moves read: the longest column move, at least 2)
// and padding (the texels past a row's end that they read: the longest row move, at least 2), and
// returns the scratch its row buffers need, in values.
std::size_t lane_sweep_scratch(LaneSweepJob& job);

// The same kernel compiled for three instruction sets (sweep_sectors picks the best the CPU runs).
void lane_sweep_generic(LaneSweepJob& job);
void lane_sweep_avx2(LaneSweepJob& job);
void lane_sweep_avx512(LaneSweepJob& job);
void lane_emit_generic(LaneEmitJob& job, std::size_t first, std::size_t last);
void lane_emit_avx2(LaneEmitJob& job, std::size_t first, std::size_t last);
void lane_emit_avx512(LaneEmitJob& job, std::size_t first, std::size_t last);
// 0: generic, 3: x86-64-v3 (AVX2), 4: x86-64-v4 (AVX-512): what this build and CPU can run, or
// lower where $DISPLACE_BAKE_ISA asks for it (lane_sweep_level_for; read once per process).
int lane_sweep_best_level();
// The level for a $DISPLACE_BAKE_ISA setting ("avx512", "avx2" or "generic"; null or empty: the
// CPU's) on a CPU that runs `cpu_level` at most: never above it, so that a benchmark can time the
// kernels an AVX2 or an older CPU would run. Throws std::invalid_argument for any other word.
int lane_sweep_level_for(const char* setting, int cpu_level);

// 64-byte aligned 16-bit values, kept between calls: grows to the largest size asked for.
class AlignedScratch {
 public:
  std::uint16_t* get(std::size_t values);

 private:
  struct Free {
    void operator()(std::uint16_t* p) const;
  };
  std::unique_ptr<std::uint16_t[], Free> data_;
  std::size_t size_ = 0;
};

// The buffers of one sweep job (a quadrant or octant), kept with its plan so that a plan kept from
// frame to frame sweeps again without allocating.
struct LaneScratch {
  AlignedScratch rows, bilinear;
  std::vector<long long> row_sums;
  int second_lap_rows = 0;  // bilinear sweeps: rows the last sweep's second lap took (a prediction)
};

// Lane ratios, steps and 16-bit heights for a map; built once per frame, shared by the sweeps.
struct LanePlan {
  int width = 0, height = 0;
  bool wrap = true;
  // the moves (lane_sweep.cpp): row moves (1, 0 .. row_reach), column moves (2 .. column_reach, 1)
  // (none when column_reach is 1), and the carry (0, 1)
  int row_reach = 2, column_reach = 2;
  // octants: 0 = none (only quadrants); else the move (1, n) (a map n times as wide as tall) or
  // (n, 1) (n times as tall as wide), which runs along the uv diagonal between a quadrant's octants
  int octant_split = 0;
  double scale = 1.0;  // the chamfer scale
  std::vector<std::uint16_t> top, bottom;
  float highest = 0.0f;  // the largest height
  float nearest = 0.0f;  // uv distance between a texel and its nearest neighbour
  alignas(64) std::uint16_t steps[lane_move_limit * lane_count];
  float lane_ratio[lane_count + 1];  // [count]: the ratio that count passing lanes prove (0 for none)
  // [count]: when lane `count` failed on a real blocker, the exact ratio is below this (1 for all)
  float lane_upper[lane_count + 1];
  // job n of a sweep of this plan uses scratch[n] (a sweep's jobs never share one); so two sweeps
  // of one plan must not run at the same time
  mutable std::array<LaneScratch, 8> scratch;
};
// Geometric lanes to just above 1, from min(lowest_ratio, the smallest ratio the map can have).
// knights: the moves fitted to the map's aspect (else only (0, 1), (1, 0), (1, 1)); octants: plan
// octant sweeps where the map allows them (square maps; with knights, one side a multiple of the
// other), see octant_split.
void make_lane_plan(const float* heights, int width, int height, bool wrap, float lowest_ratio, bool knights,
                    bool octants, LanePlan& plan);

// Other lanes for a plan: ratios[l] increasing; lane_ratio, steps and lane_upper remade as
// make_lane_plan makes them.
void set_lane_ratios(LanePlan& plan, const double (&ratios)[lane_count]);

// Below the lowest lane, texel n's ratio in sector k of `sectors`: the exact ratio over a window in
// the sector - two texels each way along the map's shorter side, as far in uv along the longer
// (5 x 5 on a square map) - against (the nearest texel outside it) / (highest - h) for everything
// further, rounded down (floor); and the smallest pair ratio of a texel of the window that blocks
// (upper, 1 when none), a real upper bound of the exact ratio.
struct LaneFloor {
  float floor = 1.0f, upper = 1.0f;
};
LaneFloor lane_floor(const LanePlan& plan, const float* heights, std::size_t n, int sector, int sectors);

// How many lanes a mask passes (lanes pass from the lowest up, so the mask is 2^count - 1).
inline int lanes_passed(std::uint32_t mask) { return mask == 0 ? 0 : 32 - __builtin_clz(mask); }

struct LaneSweepTotals {
  double ratio_sum = 0.0;  // of the ratios written
  long long pending = 0;   // of pending_count over the texel sectors written
  long long work = 0;
  // the two halves of a parallel reduction, added (defined in lane_sweep.cpp)
  static LaneSweepTotals add(LaneSweepTotals a, const LaneSweepTotals& b);
};
// The sweeps of 4 sectors (quadrants) or, where the plan has octants, of 8 (octants: per quadrant,
// the half next to the v axis without the carry and the half next to the u axis with it), in
// parallel: sector k's lane masks go to masks[k]; with out4 (4 sectors) the ratios go there too,
// and the pending texel sectors are counted (LaneEmitJob: pending_count, lane_count + 1 entries, and
// floor_keep below the lowest lane). Tests pick the instruction set (level: -1 the best, 0, 3 or 4)
// and can make the second lap whole.
struct LaneSweepOptions {
  int level = -1;
  bool stop_early = true;
  float floor_keep = 1.0f;
};
LaneSweepTotals sweep_sectors(const LanePlan& plan, const float* heights, int sectors,
                              std::uint32_t* const masks[], float* out4, const std::uint8_t* pending_count,
                              const LaneSweepOptions& options = {});

// The bilinear sweeps (LaneSweepJob::bilinear) of the four quadrants in parallel, over a plan made
// for the cell grid (make_lane_plan on the cell maxima: W x H cells with wrap, (W + 1) x (H + 1) with
// clamp, cell n between texels n - 1 and n) with texel_bottom the W x H texels' floor(apex * 65535):
// quadrant q's counts of passing lanes (per texel) to passed[q] and passed3[q]. bonus, bonus3:
// lane_count values (see LaneSweepJob). Only quadrants first_quadrant .. + quadrant_count - 1 when
// asked (stage L in steps). `split`: each quadrant in two strips of rows, twice the tasks and about
// a quarter more work for the same bits (lane_sweep.cpp; maps of split_sweep_rows cell rows or more
// and strips of twice the rows the stop test needs, with stop_early): for many threads. Returns the work.
constexpr int split_sweep_rows = 32;
long long sweep_bilinear_quadrants(const LanePlan& cells, int width, int height,
                                   const std::uint16_t* texel_bottom, const std::uint16_t* bonus,
                                   std::uint8_t* const passed[4], const std::uint16_t* bonus3,
                                   std::uint8_t* const passed3[4], int level = -1, bool stop_early = true,
                                   int first_quadrant = 0, int quadrant_count = 4, bool split = false);

// The bilinear baker's near field for one row of texels and one quadrant (cone_bilinear_budgeted.cpp
// says what it computes). Each sub-cell offset gives, per texel j, the sub-cell's maximum top[j] and
// its rates of rise along_u[j], along_v[j]; where top[j] > apex[j] the sub-cell raises the rates
// along the axes it lies beyond Q_c's edge for (box 2 and box 3 apart), and, in box 2, bounds by
// gap / (top - apex) or, at gap 0, touches Q_c. Out per texel: near[j] (box 2) and slope3[j]
// (1 / G over box 3, infinity where nothing there is above the apex). Built per instruction set
// like the sweeps; near_block texels at a time with the accumulators in registers, the offsets in
// near_groups groups of one kind each (no test per offset): box 2 touching Q_c, box 2 apart, box 3
// only, each beyond Q_c's edge along u only, along v only, along both. A row narrower than
// near_block reads near_block values of each plane from the texel's index on.
// In unsigned 16-bit integers, 32 texels to an AVX-512 register: heights in units of 1 / 65535
// (height_scale; the sub-cells' maxima rounded up, the apexes down, so that a sub-cell above the
// apex always counts), rates in units of rate_unit (rounded up), the gap term as
// floor(dtop * inverse_gap / 65536) + 1 in units of steep_unit (an upper bound: dtop and inverse_gap
// are rounded up); the bounds are finished in float from these upper bounds.
constexpr int near_block = 32;
constexpr int near_groups = 9;
struct NearOffset {
  const std::uint16_t* top = nullptr;
  const std::uint16_t* along_u = nullptr;
  const std::uint16_t* along_v = nullptr;
  std::uint16_t inverse_gap = 0;  // 1 / (the uv gap to Q_c), scaled and rounded up (0 where touching)
};
struct NearRowJob {
  const NearOffset* offsets = nullptr;  // group by group
  int group_counts[near_groups] = {};
  const std::uint16_t* apex = nullptr;  // floor(H_c * 65535), a little below
  float rate_unit = 0.0f;               // a rate per unit of the planes' rates
  float steep_unit = 0.0f;              // (top - apex) / gap per unit of the gap term
  int width = 0;
  float* near = nullptr;
  float* slope3 = nullptr;
};
void near_row_generic(const NearRowJob& job);
void near_row_avx2(const NearRowJob& job);
void near_row_avx512(const NearRowJob& job);

// The bilinear baker's apexes (apex_kernel.h's apex_blocks) for `blocks` blocks of texels from
// `first` on, whose neighbours both lie in the row: 2 texels a block in any CPU's build, 4 with AVX2,
// 8 with AVX-512 (apex_block_texels).
void apex_blocks_generic(const float* const (&rows)[3], int first, int blocks, float* apex,
                         std::uint16_t* bottom);
void apex_blocks_avx2(const float* const (&rows)[3], int first, int blocks, float* apex,
                      std::uint16_t* bottom);
void apex_blocks_avx512(const float* const (&rows)[3], int first, int blocks, float* apex,
                        std::uint16_t* bottom);
inline int apex_block_texels(int level) { return level >= 4 ? 8 : level == 3 ? 4 : 2; }

// The bilinear baker's stage L ratios of a row of texels from one sweep's lanes
// (stage_l_combine_kernel.h): per quadrant q, out[4 j + q].
struct StageLCombineJob {
  int width = 0;
  const float* apex = nullptr;
  float highest = 0.0f;                 // the map's highest cell
  double half_texel = 0.0;              // half the smaller texel side, in uv
  const float* lane_ratio = nullptr;    // lane_count + 1 entries: the ratio a count of passing lanes proves
  const std::uint8_t* passed[4] = {};   // per quadrant: lanes passed beyond box 2
  const std::uint8_t* passed3[4] = {};  // beyond box 3
  const float* near[4] = {};
  const float* slope3[4] = {};
  float lipschitz = 0.0f;
  float* out = nullptr;
};
// One row of the bilinear baker's sub-cells (sub_cell_kernel.h) from the samples of rows Y and Y + 1
// split by parity (even[k] at X = 2 k - near_reach, odd[k] at X = 2 k + 1 - near_reach), into
// out[field][parity] (fields: maximum, rise +u, -u, +v, -v), count sub-cells per parity; stored in
// 16 bits for the near field: the maximum as floor(top * 65535 + 2), the rates as
// floor(rate * rate_scale + 2), both at most 65535 (rate_scale is made so that no rate reaches it).
struct SubCellRowJob {
  const float* even0 = nullptr;
  const float* odd0 = nullptr;
  const float* even1 = nullptr;
  const float* odd1 = nullptr;
  int count = 0;
  float per_u = 0.0f, per_v = 0.0f;      // 1 / (half a texel) in uv
  float slack_u = 0.0f, slack_v = 0.0f;  // added to the rates
  float top_slack = 0.0f;                // added to the maxima
  float rate_scale = 0.0f;               // 16-bit units of rate per unit of uv rate
  std::uint16_t* out[5][2] = {};
};
void sub_cell_row_generic(const SubCellRowJob& job);
void sub_cell_row_avx2(const SubCellRowJob& job);
void sub_cell_row_avx512(const SubCellRowJob& job);

void stage_l_combine_generic(const StageLCombineJob& job);
void stage_l_combine_avx2(const StageLCombineJob& job);
void stage_l_combine_avx512(const StageLCombineJob& job);

}  // namespace displace::bake::detail
