// bake/cone_exact.cpp - the exact cone map: for every texel, a depth-first branch and bound over the
// max pyramid. A block's lower bound is (distance from the texel centre to the block's texel
// centres) / (block max - texel height); it never exceeds the pair ratio of any texel inside, bit for
// bit (see geometry.h), so a pruned block cannot hold a better blocker and the result is exact.

#include <chrono>

#include "bake/progress.h"
#include "bake/search.h"

namespace displace::bake::detail {

Pyramid make_pyramid(HeightView heights) {
  Pyramid pyramid;
  pyramid.max = build_max_pyramid(heights);
  pyramid.levels = int(pyramid.max.levels.size());
  return pyramid;
}

std::vector<Node> root_nodes(const SearchContext& context) {
  const int top = context.pyramid.levels - 1;
  std::vector<Node> roots;
  if (context.grid.address == Address::clamp) {
    roots.push_back({top, 0, 0});
    return roots;
  }
  for (int ty = -1; ty <= 1; ++ty)
    for (int tx = -1; tx <= 1; ++tx) roots.push_back({top, tx, ty});
  return roots;
}

std::vector<Node> nodes_covering(const SearchContext& context, const Rect& rect, int level) {
  const int cx = context.pyramid.count_x(level), cy = context.pyramid.count_y(level);
  const int bx0 = rect.x0 >> level, bx1 = (rect.x1 - 1) >> level;
  const int by0 = rect.y0 >> level, by1 = (rect.y1 - 1) >> level;
  const int tiles = context.grid.address == Address::wrap ? 1 : 0;
  std::vector<Node> nodes;
  for (int ty = -tiles; ty <= tiles; ++ty)
    for (int tx = -tiles; tx <= tiles; ++tx)
      for (int by = by0; by <= by1; ++by)
        for (int bx = bx0; bx <= bx1; ++bx) nodes.push_back({level, tx * cx + bx, ty * cy + by});
  return nodes;
}

namespace {

struct StackEntry {
  Node node;
  float bound;
  SectorMask mask;
  int dx, dy;  // offset of the block's first texel from the searching texel
  float block_max;
};

}  // namespace

long long search_texel(const SearchContext& context, int ci, int cj, float hc, std::span<const Node> roots,
                       float* best) {
  return search_texel_within(context, ci, cj, hc, roots, 1.0f, best, nullptr);
}

long long search_texel_within(const SearchContext& context, int ci, int cj, float hc,
                              std::span<const Node> roots, float keep, float* best, float* floor) {
  return search_texel_leaves(context, ci, cj, hc, roots, keep, best, floor, nullptr);
}

long long search_texel_leaves(const SearchContext& context, int ci, int cj, float hc,
                              std::span<const Node> roots, float keep, float* best, float* floor,
                              const LeafRatio* leaf) {
  const Grid& grid = context.grid;
  const Pyramid& pyramid = context.pyramid;
  const int sectors = grid.sector_count;
  long long work = 0;

  // lower bound and sector mask of a node; false when it cannot hold a blocker
  auto examine = [&](const Node& node, StackEntry& entry) {
    ++work;
    const int count_x = pyramid.count_x(node.level), count_y = pyramid.count_y(node.level);
    const int tile_x = floor_div(node.nx, count_x), tile_y = floor_div(node.ny, count_y);
    const float block_max = pyramid.value(node.level, node.ny - tile_y * count_y, node.nx - tile_x * count_x);
    if (!(block_max > hc)) return false;
    int x0, x1, y0, y1;
    block_range(node.nx, node.level, count_x, grid.width, x0, x1);
    block_range(node.ny, node.level, count_y, grid.height, y0, y1);
    x0 -= cj, x1 -= cj, y0 -= ci, y1 -= ci;
    const float bound = pair_ratio(grid.distance(interval_gap(x0, x1), interval_gap(y0, y1)), block_max - hc);
    const SectorMask mask =
        node.level == 0 ? point_sectors(grid, x0, y0) : rect_sectors(grid, x0, x1, y0, y1);
    SectorMask useful = 0;
    for (int k = 0; k < sectors; ++k) {
      if (!(mask >> k & 1u) || !(bound < best[k])) continue;
      if (node.level > 0 && !(bound < keep * best[k])) {
        floor[k] = std::min(floor[k], bound);  // close enough: left as a bound
        continue;
      }
      useful |= 1u << k;
    }
    if (!useful) return false;
    entry = {node, bound, useful, x0, y0, block_max};
    return true;
  };

  std::vector<StackEntry> stack;
  stack.reserve(256);
  StackEntry entry;
  for (const Node& root : roots)
    if (examine(root, entry)) stack.push_back(entry);

  while (!stack.empty()) {
    const StackEntry top = stack.back();
    stack.pop_back();
    // best may have dropped since the entry was pushed
    bool still_useful = false;
    for (int k = 0; k < sectors; ++k)
      if ((top.mask >> k & 1u) && top.bound < best[k]) still_useful = true;
    if (!still_useful) continue;
    if (top.node.level == 0) {
      const float ratio = leaf ? std::max(top.bound, (*leaf)(top.dx, top.dy, top.block_max)) : top.bound;
      for (int k = 0; k < sectors; ++k)
        if (top.mask >> k & 1u) best[k] = std::min(best[k], ratio);
      continue;
    }
    // push children, farthest first, so the nearest is searched first
    StackEntry children[4];
    int child_count = 0;
    const int level = top.node.level - 1;
    const int parent_count_x = pyramid.count_x(top.node.level),
              parent_count_y = pyramid.count_y(top.node.level);
    const int count_x = pyramid.count_x(level), count_y = pyramid.count_y(level);
    const int tile_x = floor_div(top.node.nx, parent_count_x),
              tile_y = floor_div(top.node.ny, parent_count_y);
    const int bx = top.node.nx - tile_x * parent_count_x, by = top.node.ny - tile_y * parent_count_y;
    for (int dy = 0; dy < 2; ++dy) {
      const int cy = 2 * by + dy;
      if (cy >= count_y) break;
      for (int dx = 0; dx < 2; ++dx) {
        const int cx = 2 * bx + dx;
        if (cx >= count_x) break;
        if (examine({level, tile_x * count_x + cx, tile_y * count_y + cy}, children[child_count]))
          ++child_count;
      }
    }
    for (int a = 1; a < child_count; ++a)  // insertion sort, largest bound first
      for (int b = a; b > 0 && children[b - 1].bound < children[b].bound; --b)
        std::swap(children[b - 1], children[b]);
    for (int c = 0; c < child_count; ++c) stack.push_back(children[c]);
  }
  return work;
}

}  // namespace displace::bake::detail

namespace displace::bake {

BakeStats bake_exact(HeightView heights, Address address, ConeView out, const Progress& progress) {
  validate(heights, out);
  const auto start = std::chrono::steady_clock::now();
  const detail::Grid grid(heights.width, heights.height, out.sector_count, address);
  const detail::Pyramid pyramid = detail::make_pyramid(heights);
  const detail::SearchContext context{grid, pyramid};
  const std::vector<detail::Node> roots = detail::root_nodes(context);
  const int sectors = out.sector_count;
  const long long work =
      detail::search_every_texel(heights, sectors, out.data, progress, [&](int i, int j, float* best) {
        return detail::search_texel(context, i, j, heights.data[std::size_t(i) * heights.width + j], roots,
                                    best);
      });

  return detail::whole_map_stats(Mode::exact, heights, sectors, work, start, out.data);
}

}  // namespace displace::bake
