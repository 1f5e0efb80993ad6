// bake/cone_relaxed_reference.cpp - the relaxed cone maps' reference search (Policarpo & Oliveira,
// "Relaxed Cone Stepping for Relief Mapping", GPU Gems 3), for 1 and 4 sectors: slow, kept for the
// tests of bake_relaxed (cone_relaxed.cpp), which must emit the same map.
//
// A relaxed cone may contain relief, as long as a viewing ray inside it crosses the height field at
// most once: a renderer that steps to the cone's edge then lands at most one crossing past the first
// hit, which a binary search finds. As in their preprocessing, for texel c and every other texel d
// we follow the ray from the top of c's axis, (c, 1), through the surface point (d, h(d)) and on
// until it leaves the bilinear relief at E (found exactly, cell by cell, not by marching:
// relaxed_ray.h); the cone must not contain E, so its ratio is at most |E - c| / (h(E) - h(c)) when
// E lies above c. Because E is beyond d and no higher than d, that bound is never below d's pair
// ratio: the max pyramid search of the exact baker prunes the texels d (search.h), and follows the
// ray of every texel it reaches to its exit.

#include <algorithm>
#include <chrono>
#include <cmath>

#include "bake/progress.h"
#include "bake/relaxed_ray.h"
#include "bake/search.h"

namespace displace::bake {

BakeStats bake_relaxed_reference(HeightView heights, Address address, ConeView out,
                                 const Progress& progress) {
  validate(heights, out);
  if (out.sector_count != 1 && out.sector_count != 4)
    throw BakeError("relaxed cone maps support 1 or 4 sectors, not " + std::to_string(out.sector_count));
  const auto start = std::chrono::steady_clock::now();
  const detail::Grid grid(heights.width, heights.height, out.sector_count, address);
  const detail::Pyramid pyramid = detail::make_pyramid(heights);
  const detail::SearchContext context{grid, pyramid};
  const std::vector<detail::Node> roots = detail::root_nodes(context);
  // (the same walk as bake_relaxed's, block jumps included, so that a V both compute is the same float)
  const detail::CellLows lows = detail::make_cell_lows(heights.data, heights.width, heights.height, address);
  const detail::RelaxedSurface surface{heights.data, heights.width, heights.height, address, nullptr, 0,
                                       &lows};
  const int sectors = out.sector_count;
  const long long work =
      detail::search_every_texel(heights, sectors, out.data, progress, [&](int i, int j, float* best) {
        const float hc = heights.data[std::size_t(i) * heights.width + j];
        long long walked = 0;  // cells of the rays followed
        // the exit point of the ray from (c, 1) through (d, hq), d at texel offset (dx, dy)
        const detail::LeafRatio leaf = [&](int dx, int dy, float hq) {
          const float pair = detail::pair_ratio(grid.distance(dx, dy), hq - hc);
          return detail::relaxed_value(surface, grid, i, j, hc, dx, dy, hq, pair, 2.0f, walked);
        };
        const long long searched =
            detail::search_texel_leaves(context, i, j, hc, roots, 1.0f, best, nullptr, &leaf);
        return searched + walked;
      });

  return detail::whole_map_stats(Mode::exact, heights, sectors, work, start, out.data);
}

}  // namespace displace::bake
