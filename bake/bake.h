// bake/bake.h - cone-map baking. The whole public API of the bake stage. No file I/O and no Vulkan:
// callers pass views of input and output memory.
//
// Conventions (normative: the tests, the exports and the renderer use exactly these)
// - A W x H height map is row-major: texel (i, j) is row i, column j, at data[i * W + j]; heights in
//   [0, 1], 1 = top. Its centre is u = (j + 0.5) / W, v = (i + 0.5) / H; distances are in uv.
// - The cone ratio of texel c in sector k is the minimum, over texels q with h(q) > h(c) whose
//   direction from c (azimuth atan2(dv, du) in [0, 2 pi)) lies in sector k of n equal sectors that
//   start at azimuth 0 (a direction on a sector boundary belongs to both sectors), of
//   |q - c| / (h(q) - h(c)), clamped to at most 1. With no such q the ratio is 1. n = 1 is cone step
//   mapping (Dummer); n = 4 and n = 8 are anisotropic cone maps (Chen & Chuang).
// - Address::wrap (the default): every periodic image of q counts; Address::clamp: outside is absent.
// - Cone maps (and relaxed ones, bake_relaxed) are interleaved: texel (i, j), sector k at
//   data[(i * W + j) * n + k]. A distance map (bake_distance_map) is 3D in texture space (u, v, h).
// In full: docs/design/conventions.md#bakebakeh-the-bakers-conventions
#pragma once

#include <functional>
#include <limits>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace displace::bake {

enum class Address { wrap, clamp };
enum class Mode { exact, original, paper_adaptive, budgeted, bilinear, bilinear_budgeted };

// Thrown for input the caller got wrong (NaN or out-of-range heights, empty maps, bad sector count).
struct BakeError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

inline constexpr int max_map_side = 32768;  // texels a side of a height map (and of a distance map)

struct HeightView {
  const float* data = nullptr;
  int width = 0;
  int height = 0;
};

struct ConeView {
  float* data = nullptr;
  int width = 0;
  int height = 0;
  int sector_count = 0;
};

// Texel rectangle: columns [x0, x1), rows [y0, y1).
struct Rect {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
};

struct BakeStats {
  Mode mode = Mode::exact;
  int width = 0, height = 0, sector_count = 0;
  long long texels_refined = 0;   // texels whose ratios came from a search at full resolution
  long long texels_fallback = 0;  // budgeted: texels whose ratio may still be looser than the tolerance
  long long work = 0;             // blocker tests: texel pairs plus pyramid nodes examined
  double milliseconds = 0.0;      // measured with the budget's clock (steady clock if none)
  double mean_ratio = 0.0;        // over all texels and sectors
};

// Throws BakeError unless the map is non-empty, at most 32768 texels on a side, and every height is
// finite and in [0, 1]; `product` names what is being baked ("a cone map") in the empty-map message.
void validate_heights(HeightView heights, const char* product);

// Throws BakeError unless the map is non-empty, every height is finite and in [0, 1], and the
// sector count is 1, 4 or 8 and the output view matches the map.
void validate(HeightView heights, const ConeView& out);

// The largest sector count a baker supports; the relaxed baker accepts 1 and 4.
bool is_valid_sector_count(int sector_count);

// Progress of a long bake, for a user watching it: called with the fraction of the call's work
// that is done, in (0, 1] and strictly increasing from call to call, the last call with exactly 1
// when the bake completes (none after a throw). Calls come from the baking threads, one at a time
// (never two at once), at most about max_progress_reports of them per bake; keep them cheap.
// An empty function is never called.
using Progress = std::function<void(double fraction_done)>;
inline constexpr int max_progress_reports = 200;  // calls per bake, besides the last one (1)

// Exact to the definition above (branch and bound over a max pyramid; tested against all pairs).
BakeStats bake_exact(HeightView heights, Address address, ConeView out, const Progress& progress = {});

// Chen & Chuang's per-texel search, as published: rings of growing radius, each sector stops when
// no texel further out can lower its ratio. A baseline for the speed figures; exact.
BakeStats bake_original(HeightView heights, Address address, ConeView out, const Progress& progress = {});

// Chen & Chuang, Algorithm 1, as published: a max pyramid; the top level is searched; going down,
// a texel whose height is within `similarity` of its parent's copies the parent's ratio, others
// search with the parent's ratio as the initial short circuit. NOT conservative (see the tests):
// the parent's ratio is measured between coarse texel centres.
struct PaperAdaptiveSettings {
  int levels = 3;            // coarse levels above the finest
  float similarity = 0.05f;  // height difference (in [0, 1] units) below which a child copies
};
BakeStats bake_paper_adaptive(HeightView heights, Address address, const PaperAdaptiveSettings& settings,
                              ConeView out);

// A time budget. The clock returns milliseconds and is injectable (tests use a fake clock); with no
// clock a steady clock is used. max_work, when >= 0, also ends the refinement once that many work
// units (see BakeStats::work) are spent - a deterministic budget for tests.
// tolerance: a texel is refined only while its conservative ratio may be below (1 - tolerance) times
// its exact ratio; every texel that refinement reaches is guaranteed within that factor of exact.
// The default, 0.25, is what the always-completed lane sweeps certify for 4 sectors (so an
// unlimited budget ends with them); tolerance 0 refines to the exact map.
// progress: reports of the call's progress (see Progress), for a user watching a long bake; for
// BilinearBaker, which is to report through it. BudgetedBaker ignores it (it ends in milliseconds).
inline constexpr float max_tolerance = 1.0f;  // Budget::tolerance lies in [0, max_tolerance), exclusive

struct Budget {
  double milliseconds = std::numeric_limits<double>::infinity();
  std::function<double()> clock;
  long long max_work = -1;
  float tolerance = 0.25f;
  std::function<void(double fraction_done)> progress = {};
};

// The product baker: every emitted ratio is a lower bound of the exact ratio at every budget
// (including zero). bake() always completes stage L - conservative lane sweeps over the whole map
// that also certify how loose each ratio may be - then refines hierarchically (max pyramid) the
// texels not yet within the tolerance while the budget lasts; refinement continues across calls,
// and update() rebakes only what a dirty region can have changed. Holds the state between frames.
class BudgetedBaker {
 public:
  BudgetedBaker(int width, int height, int sector_count, Address address);
  ~BudgetedBaker();
  BudgetedBaker(BudgetedBaker&&) noexcept;
  BudgetedBaker& operator=(BudgetedBaker&&) noexcept;

  // A new frame where anything may have changed.
  BakeStats bake(HeightView heights, const Budget& budget, ConeView out);
  // A new frame whose heights differ from the previous call's only inside `dirty`. `out` must hold
  // the map this baker emitted last time. The repair is incremental - the dirty groups get stage 0,
  // the groups a raised texel can reach an exact search over the dirty blocks, the groups a lowered
  // texel could have blocked are marked for refinement - unless that costs more than a whole new
  // stage L (bake()), which is what `cheaper` picks by an estimate of both.
  enum class UpdatePolicy { cheaper, incremental, rebake };
  BakeStats update(HeightView heights, std::span<const Rect> dirty, const Budget& budget, ConeView out,
                   UpdatePolicy policy = UpdatePolicy::cheaper);
  // Spends more budget refining the current frame; `out` must hold the map emitted last time.
  BakeStats refine(const Budget& budget, ConeView out);
  // Texels whose ratio may still be more than `tolerance` below exact (refinement would tighten them).
  long long pending(float tolerance = 0.0f) const;

  struct State;  // opaque: the previous frame's heights, pyramid and refinement queue

 private:
  std::unique_ptr<State> state_;
};

// Convenience: one budgeted bake from scratch.
BakeStats bake_budgeted(HeightView heights, Address address, const Budget& budget, ConeView out);

// Relaxed cone map (Policarpo & Oliveira, "Relaxed Cone Stepping for Relief Mapping"), for 1 or 4
// sectors. The relaxed ratio of texel c in sector k is the largest r <= 1 such that every ray that
// starts on the top plane (height 1) within the cone of ratio r above c and travels to c's apex
// (c, h(c)), through directions of sector k, crosses the height field at most once: it never leaves
// the relief after entering it. It is never smaller than the conservative ratio. As computed: for
// texel c and every higher texel d, the ray from (c, 1) through (d, h(d)) is followed until it
// leaves the bilinear relief at E (a ray that touches the surface leaves it); the ratio is the
// minimum over d in sector k of max(pair ratio of d, |E - c| / (h(E) - h(c))), a d whose E is not
// above c counting 1. bake_relaxed searches rings around each texel, pruned by pair ratios
// (bake/cone_relaxed.cpp); bake_relaxed_reference is the slow search it is tested against (the exact
// baker's pyramid search, following the ray to its exit for every blocker it reaches). Both emit
// the same map, bit for bit.
BakeStats bake_relaxed(HeightView heights, Address address, ConeView out, const Progress& progress = {});
BakeStats bake_relaxed_reference(HeightView heights, Address address, ConeView out,
                                 const Progress& progress = {});

// Relaxed cone maps within a budget, kept between frames like BudgetedBaker (1 or 4 sectors). At
// every budget (0 ms, a clock that runs out, a work limit of 0) every ratio bake() and refine() emit
// is at most bake_relaxed's for the same heights: bake() always completes BudgetedBaker's stage L
// for the whole map (conservative ratios, never above relaxed ones), then replaces pieces of 16
// texels of a row by their relaxed ratios (bake_relaxed's search) while the budget lasts (a piece
// begun is finished); refine() continues, and once nothing is pending the map is bake_relaxed's, bit
// for bit. `out` must hold what this baker emitted last time for refine(). Budget::tolerance and
// progress are not used. Stats: texels_refined = the call's texels replaced, texels_fallback =
// pending().
class RelaxedBaker {
 public:
  RelaxedBaker(int width, int height, int sector_count, Address address);
  ~RelaxedBaker();
  RelaxedBaker(RelaxedBaker&&) noexcept;
  RelaxedBaker& operator=(RelaxedBaker&&) noexcept;

  BakeStats bake(HeightView heights, const Budget& budget, ConeView out);
  BakeStats refine(const Budget& budget, ConeView out);
  // Texels whose ratios are still stage L's.
  long long pending() const;

  struct State;

 private:
  std::unique_ptr<State> state_;
};

// Cone map for the BILINEAR surface, conservative from anywhere in a texel's square, for cone
// stepping with no slack (the renderer's csm / acm4 / acm8 / acm4-interval). The cone maps above
// hold between texel centres; a ray samples the bilinear surface s between them (wrap: periodic;
// clamp: the edge texels extended over the half-texel border, nothing outside [0, 1]^2) from points
// p that are not texel centres. Here, for texel c with square Q_c = c plus or minus half a texel in u
// and v (the points whose nearest centre is c):
// - apex_heights[i * W + j] = H_c, the maximum of s over Q_c (rounded up to float);
// - the ratio of sector k (same sectors, layout and clamp to 1 as above) is an r_k such that for
//   EVERY p in Q_c and every point x (x in [0, 1]^2 with clamp) whose direction from p lies in
//   sector k (boundary directions in both sectors), s(x) <= H_c + |x - p| / r_k. So a ray point p at
//   height z in Q_c, travelling L uv per unit of descent with its azimuth in sector k, may descend
//   r_k (z - H_c) / (r_k + L) without meeting the surface.
// Each cell of the surface (and its periodic images) bounds the ratios it can reach by (distance
// from Q_c) / (cell max - H_c); cells within settings.slope_window cells of c, cut at Q_c's edge
// lines, also by how fast the surface can rise from Q_c's edge towards them, which is what keeps a
// texel next to a higher neighbour from a ratio of 0. The proof is in
// bake/cone_bilinear.cpp. Ratios are lower bounds, not the tightest r_k: a brute-force test checks
// the claim on dense samples of p and x. Stats as bake_exact's (mode bilinear).
inline constexpr int max_slope_window = 64;  // cells, BilinearConeSettings::slope_window, from 0

struct BilinearConeSettings {
  int slope_window = 4;  // cells: radius around a texel where the slope bound applies (0: none)
  std::function<void(double fraction_done)> progress = {};  // see Progress: rows done over all rows
  // false: the search skips nothing that cannot lower a ratio only by its bound - every block of the
  // pyramid opened, every window piece bounded. The same maps bit for bit, far slower: for tests.
  bool prune = true;
};
BakeStats bake_bilinear_cones(HeightView heights, Address address, ConeView out,
                              std::span<float> apex_heights, const BilinearConeSettings& settings = {});

// Relaxed cones for the bilinear surface, from anywhere in a texel's square: the same apex H_c and,
// per sector k, a ratio R_k >= bake_bilinear_cones' r_k such that a ray from any point p of Q_c at a
// height z >= H_c, descending in a direction of sector k at any slope, that takes the cone step to
// the cone of apex (p, H_c) and ratio R_k lands at or before the first point where it leaves the
// surface (a touch counts as a hit). So a step that lands above the surface crossed nothing, and one
// that lands below brackets the first crossing. R_k bounds |x - p| / (s(x) - H_c) only over the
// cells along whose sector's directions s may fall (where a ray can leave the surface): on a brick
// map the far, falling edges of the bricks, not the near, rising ones. Proof: docs/design/bakers.md.
BakeStats bake_bilinear_relaxed_cones(HeightView heights, Address address, ConeView out,
                                      std::span<float> apex_heights,
                                      const BilinearConeSettings& settings = {});

// The renderer's cone maps within a frame budget: exactly bake_bilinear_cones' contract (apex H_c =
// max of s over Q_c; r_k valid from every p in Q_c towards every x in sector k) for every ratio and
// apex it emits, at every budget (0 ms, a clock that runs out mid-stage, a work limit of 0). Kept
// between frames like BudgetedBaker: bake() always completes its first stage (conservative sweeps
// over the whole map, O(N)), then refines, while the budget lasts, the texels whose ratios are not
// certified within budget.tolerance of the best ratio the contract allows; refine() continues;
// update() takes the dirty rectangles of a frame whose heights changed only there. `out` and
// `apex_heights` (W x H floats) must hold what this baker emitted last time for refine() and
// update(). 1, 4 or 8 sectors, wrap or clamp, any size validate_heights accepts.
class BilinearBaker {
 public:
  BilinearBaker(int width, int height, int sector_count, Address address);
  ~BilinearBaker();
  BilinearBaker(BilinearBaker&&) noexcept;
  BilinearBaker& operator=(BilinearBaker&&) noexcept;

  BakeStats bake(HeightView heights, const Budget& budget, ConeView out, std::span<float> apex_heights);
  BakeStats update(HeightView heights, std::span<const Rect> dirty, const Budget& budget, ConeView out,
                   std::span<float> apex_heights);
  BakeStats refine(const Budget& budget, ConeView out, std::span<float> apex_heights);
  // Texels whose ratios refinement would still look at (not certified within the last tolerance).
  long long pending() const;

  // The first stage over several calls, for a caller that serves its last map while the next one is
  // made (the pipeline's lagged maps, pipeline/frame_pipeline.h): begin() copies the heights and
  // drops any stage under way; each advance() runs one of the first stage's steps (one with work)
  // and more until `at_least` of the stage is done (first_stage_done()) and while the budget lasts,
  // and after the last one emits what bake() would (bit for bit) - the stage's ratios, refined
  // within what is left of the budget - into `out`, `apex_heights` and `stats`, and returns true.
  // Until then it leaves them alone and returns false. While a stage is under way refine() throws,
  // update() rebakes everything and pending() counts the last emission.
  void begin(HeightView heights);
  bool advance(const Budget& budget, ConeView out, std::span<float> apex_heights, BakeStats& stats,
               double at_least = 0.0);
  bool in_progress() const;
  // The share of the stage under way that its steps so far have done, weighed by what each step
  // costs on a 512 x 512 ocean (1: none under way).
  double first_stage_done() const;
  static int first_stage_steps();

  struct State;

 private:
  std::unique_ptr<State> state_;
};

// Levels of detail (bake/detail_levels.cpp), for views where a pixel covers many texels. Level 0 is
// the map; level l + 1 is level l's 2 x 2 box mean, (W >> (l + 1)) x (H >> (l + 1)) texels: texel
// (i, j) of level l + 1 averages texels (2i + a, 2j + b), a, b in {0, 1}, of level l and is centred
// where they meet, so every level covers the same uv square (and tiles it with the same period).
// Each level is a height map under this file's conventions at its own size: its bilinear surface is
// what a renderer traces on that level, and its cone maps are a baker's for that map (the bilinear
// cones' contract then holds for that level's surface by their own proof). The mean, not the max:
// it is the box prefilter of the heights a far pixel averages, and keeps the sea's mean level.
inline constexpr int max_detail_levels = 13;  // coarser levels at most (level 0 not counted): 8192 to 1
inline constexpr int min_level_side = 1;      // texels a side of the coarsest level at least
// The coarser levels a W x H map has: halvings while both sides are even and the halves keep
// min_level_side texels, at most max_detail_levels.
int detail_level_count(int width, int height);
// One level down: `coarse` ((W / 2) x (H / 2), W and H even) gets the 2 x 2 box means of `fine`.
// Throws BakeError for odd sides or a coarse span of the wrong size.
void downsample_heights(HeightView fine, std::span<float> coarse);
// What a level's smoothing leaves out of the shading: the slopes of level 0 under each of its texels.
// gradient_moments gives level 0's, per texel (g_u, g_v, g_u^2 + g_v^2) for its gradient g by
// central differences, wrapped, in height units per uv unit (g_u = (h[j + 1] - h[j - 1]) W / 2);
// downsample_moments makes level l + 1's from level l's as downsample_heights does (2 x 2 means of
// each of the three), so that level l holds the means of level 0's over its texel's footprint. The
// slope variance that level l does not resolve is the last minus the square of the first two.
// Throws BakeError as downsample_heights does (and for a map under 1 x 1).
void gradient_moments(HeightView level0, std::span<float> moments);
void downsample_moments(std::span<const float> fine, int width, int height, std::span<float> coarse);

// Max pyramid (maximum mipmaps): level 0 is the map; level L has ceil(W / 2^L) x ceil(H / 2^L)
// texels, each the maximum of its (up to four) children; the last level is 1 x 1.
struct MaxPyramid {
  std::vector<int> widths, heights;
  std::vector<std::vector<float>> levels;
};
MaxPyramid build_max_pyramid(HeightView heights);
// The same into `pyramid`, reusing its buffers (no allocation when the size is the one it had).
void build_max_pyramid(HeightView heights, MaxPyramid& pyramid);

// Max pyramid of the BILINEAR surface, on the dual grid (Tevs, Ihrke & Seidel, "Maximum Mipmaps for
// Fast, Accurate, and Scalable Dynamic Height Field Rendering"), for the renderer's maxmip and qdm.
// - Cell coordinates: x = u W - 0.5 - origin, y = v H - 0.5 - origin, so texel centre (i, j) sits at
//   (j - origin, i - origin). Level-0 node (cell) (i, j) is the square [j, j + 1] x [i, i + 1]
//   between four texel centres, and holds the max of those four heights: the bilinear surface over
//   the cell is a convex combination of its corners, so that max is its max over the cell.
// - Address::wrap: origin 0, W x H cells, one period (cell (i, W - 1) joins texel W - 1 and
//   texel 0); the plane is tiled with it. Address::clamp: origin -1, (W + 1) x (H + 1) cells; the
//   first and last row and column hold the clamped-edge extension (their corners are edge texels
//   counted twice), so the cells cover x in [-1, W] and the patch [0, 1]^2 (x in [-0.5, W - 0.5])
//   with its half-texel borders.
// - Level L + 1 has ceil(n / 2) nodes along an axis where level L has n; node a of level L covers
//   cells [a 2^L, min((a + 1) 2^L, n0)) along that axis (n0 cells at level 0): footprints are
//   truncated at the grid's end, never padded. Each node holds the max of its existing children,
//   which is exactly the max of the bilinear surface over its footprint. The last level is 1 x 1.
// Throws BakeError for the maps validate_heights rejects.
struct DualMaxPyramid {
  int origin = 0;                    // 0 (wrap) or -1 (clamp), see above
  std::vector<int> widths, heights;  // nodes per level along u and along v
  std::vector<std::size_t> offsets;  // where each level starts in `values`
  // node (a, b) of level L (column a, row b) at values[offsets[L] + b * widths[L] + a]
  std::vector<float> values;
};
DualMaxPyramid build_dual_max_pyramid(HeightView heights, Address address);

// Distance map (Donnelly, "Per-Pixel Displacement Mapping with Distance Functions", GPU Gems 2
// ch. 8), for sphere tracing. W x H x D voxels, stored data[(k * H + i) * W + j]; voxel (k, i, j)
// has its centre at u = (j + 0.5) / W, v = (i + 0.5) / H, h = (k + 0.5) / D. W and H need not
// match the height map's size.
inline constexpr int max_distance_depth = 1024;              // voxels along h, DistanceView::depth
inline constexpr long long max_distance_voxels = 1ll << 30;  // voxels in one distance map (4 GiB of floats)

struct DistanceView {
  float* data = nullptr;
  int width = 0, height = 0, depth = 0;
};

// Throws BakeError unless the height map is valid (as above) and the view is non-null with
// 1 <= width, height <= 32768, 1 <= depth <= 1024 and at most 2^30 voxels.
void validate(HeightView heights, const DistanceView& out);

// Conventions of the distance map (normative: the renderer relies on them)
// - Space is texture space (u, v, h) with the Euclidean metric sqrt(du^2 + dv^2 + dh^2): one unit
//   of height (the whole [0, 1] range) equals one unit of uv (the whole texture width). Rays are
//   traced in this space, so the map does not depend on the render's depth scale.
// - The solid is {(u, v, h) : h <= s(u, v)}, s the bilinear interpolation of the texel heights
//   between texel centres. Address::wrap tiles the plane periodically in u and v; Address::clamp
//   extends the edge texels outward (s outside [0, 1]^2 is the clamped-edge extension). The solid
//   reaches down to h = -infinity, so every point with h <= 0 is inside it.
// - Stored values are in uv units and CONSERVATIVE FOR TRILINEAR FILTERING: sampled the way the
//   shader samples it (trilinear, voxel centres as above, clamp-to-edge in h, the address mode in
//   u and v), the map returns at every point p a value <= the Euclidean distance from p to the
//   solid (0 inside it), so a ray may always advance by the sampled value. This holds for every p:
//   h outside [0, 1] samples the bottom or top layer, which is safe because the distance never
//   decreases with h and is 0 for h <= 0 (the bottom layer is therefore all zero); with clamp, u or
//   v outside [0, 1] samples the edge voxels, which is safe because moving p onto [0, 1]^2 never
//   increases its distance to the clamped-edge solid.
// - The stored value of voxel c is a lower bound of the distance from its trilinear support box
//   B(c) (c plus or minus one voxel spacing along each axis; half the period along an axis of size
//   1) to the solid: the exact distance from B(c) to the union of boxes F x (-inf, max of s over F]
//   over the map's uv footprints F = [j / W, (j + 1) / W] x [i / H, (i + 1) / H] (and their periodic
//   images with wrap), which hold the solid, less 1e-6 uv and rounded down to float. Every voxel a
//   sample at p reads has p in its B, hence the guarantee, for ANY convex weights of those voxels:
//   it survives the GPU's low-precision filter weights. See bake/distance_map.cpp for the proof.
// Stats: width and height of the map, milliseconds (steady clock), mean_ratio = the mean stored
// distance over all voxels in uv units; the other counters are 0.
BakeStats bake_distance_map(HeightView heights, Address address, DistanceView out);

const char* mode_name(Mode mode);

}  // namespace displace::bake
