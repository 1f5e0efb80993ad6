// bake/cone_original.cpp - Chen & Chuang, "Anisotropic Cone Mapping", Sec. II-C, the original
// preprocessing as published: for each texel, square rings of growing radius; each ring's texels
// lower the ratios of the sectors they fall in, and the search short-circuits once no texel further
// out can beat the largest current ratio. Exact (same pair formula as every baker); a speed baseline.

#include <algorithm>
#include <chrono>

#include "bake/progress.h"
#include "bake/search.h"

namespace displace::bake {

namespace detail {

long long ring_search(const Grid& grid, const float* heights, float global_max, int ci, int cj, float* best) {
  const float hc = heights[std::size_t(ci) * grid.width + cj];
  const int sectors = grid.sector_count;
  if (!(global_max > hc)) return 0;
  const float gap_max = global_max - hc;
  const int max_radius = std::max(grid.width, grid.height);
  long long work = 0;
  auto visit = [&](int dy, int dx) {
    int qi = ci + dy, qj = cj + dx;
    if (grid.address == Address::clamp) {
      if (qi < 0 || qi >= grid.height || qj < 0 || qj >= grid.width) return;
    } else {
      qi = ((qi % grid.height) + grid.height) % grid.height;
      qj = ((qj % grid.width) + grid.width) % grid.width;
    }
    ++work;
    const float hq = heights[std::size_t(qi) * grid.width + qj];
    if (!(hq > hc)) return;
    const float ratio = pair_ratio(grid.distance(dx, dy), hq - hc);
    const SectorMask mask = point_sectors(grid, dx, dy);
    for (int k = 0; k < sectors; ++k)
      if ((mask >> k & 1u) && ratio < best[k]) best[k] = ratio;
  };
  for (int radius = 1; radius <= max_radius; ++radius) {
    // short circuit: the nearest texel of this ring, at the largest possible gap
    const float nearest = std::min(grid.distance(radius, 0), grid.distance(0, radius));
    const float ring_bound = pair_ratio(nearest, gap_max);
    float largest = 0.0f;
    for (int k = 0; k < sectors; ++k) largest = std::max(largest, best[k]);
    if (ring_bound >= largest) break;
    for (int dx = -radius; dx <= radius; ++dx) {
      visit(-radius, dx);
      visit(radius, dx);
    }
    for (int dy = -radius + 1; dy <= radius - 1; ++dy) {
      visit(dy, -radius);
      visit(dy, radius);
    }
  }
  return work;
}

}  // namespace detail

BakeStats bake_original(HeightView heights, Address address, ConeView out, const Progress& progress) {
  validate(heights, out);
  const auto start = std::chrono::steady_clock::now();
  const detail::Grid grid(heights.width, heights.height, out.sector_count, address);
  const std::size_t count = std::size_t(heights.width) * heights.height;
  const float global_max = *std::max_element(heights.data, heights.data + count);
  const int sectors = out.sector_count;
  const long long work =
      detail::search_every_texel(heights, sectors, out.data, progress, [&](int i, int j, float* best) {
        return detail::ring_search(grid, heights.data, global_max, i, j, best);
      });
  return detail::whole_map_stats(Mode::original, heights, sectors, work, start, out.data);
}

}  // namespace displace::bake
