// bake/search.h - exact branch-and-bound blocker search over the max pyramid (internal to bake/).
#pragma once

#include <functional>
#include <span>
#include <vector>

#include "bake/geometry.h"

namespace displace::bake::detail {

// A pyramid block in the unrolled (periodic) plane.
struct Node {
  int level = 0;
  int nx = 0;  // unrolled block index along u
  int ny = 0;  // unrolled block index along v
};

struct SearchContext {
  const Grid& grid;
  const Pyramid& pyramid;
};

Pyramid make_pyramid(HeightView heights);

// The top-level blocks whose texels can be blockers: the map itself, and for wrap its eight
// neighbouring images (images further away are more than uv distance 1 from any texel).
std::vector<Node> root_nodes(const SearchContext& context);

// Top-level-like nodes covering `rect` (in-map texel coordinates) at `level`, with their wrap images.
std::vector<Node> nodes_covering(const SearchContext& context, const Rect& rect, int level);

// Lowers best[k] (k < sector_count) to the minimum pair ratio over blockers of texel (ci, cj) at
// height hc inside the given nodes. Exact: every node is either expanded to texels or provably
// unable to lower any best[k]. Returns the work done (nodes and texels examined).
long long search_texel(const SearchContext& context, int ci, int cj, float hc, std::span<const Node> roots,
                       float* best);

// Approximate variant for a tolerance: a node whose bound lies in [keep * best[k], best[k]) is not
// opened; floor[k] receives the smallest such bound. min(best[k], floor[k]) is then a lower bound of
// the exact ratio and at least keep times it. keep = 1 is the exact search.
long long search_texel_within(const SearchContext& context, int ci, int cj, float hc,
                              std::span<const Node> roots, float keep, float* best, float* floor);

// The general search: a texel leaf at offset (dx, dy) with height hq contributes leaf(dx, dy, hq)
// instead of its pair ratio. The leaf value must never be below the pair ratio, so that the pair-ratio
// bounds of the pyramid still prune correctly (the relaxed baker uses this).
using LeafRatio = std::function<float(int dx, int dy, float hq)>;
long long search_texel_leaves(const SearchContext& context, int ci, int cj, float hc,
                              std::span<const Node> roots, float keep, float* best, float* floor,
                              const LeafRatio* leaf);

// Chen & Chuang's ring search for texel (ci, cj) of any W x H grid (a map or a pyramid level):
// best[] holds the initial short-circuit ratios and receives the result (cone_original.cpp).
// Returns the texels examined.
long long ring_search(const Grid& grid, const float* heights, float global_max, int ci, int cj, float* best);

}  // namespace displace::bake::detail
