// bake/cone_paper_adaptive.cpp - Chen & Chuang, "Anisotropic Cone Mapping", Algorithm 1 (adaptive
// hierarchical preprocessing), as published. Kept as a baseline: it is NOT conservative. A parent's
// ratio is measured between coarse texel centres, and a child can sit up to half a coarse texel
// closer to the blocker than its parent's centre, so a copied ratio can claim space that is not
// empty (the tests count the violations).
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>

#include "bake/search.h"

namespace displace::bake {

BakeStats bake_paper_adaptive(HeightView heights, Address address, const PaperAdaptiveSettings& settings,
                              ConeView out) {
  validate(heights, out);
  if (settings.levels < 0 || !(settings.similarity >= 0.0f)) {
    throw BakeError("paper-adaptive settings need levels >= 0 and a similarity >= 0");
  }
  const auto start = std::chrono::steady_clock::now();
  const MaxPyramid pyramid = build_max_pyramid(heights);
  const int top = std::min(settings.levels, int(pyramid.levels.size()) - 1);
  const int sectors = out.sector_count;
  const float global_max = pyramid.levels.back()[0];
  std::atomic<long long> total_work{0}, copied{0};

  // regular cone ratio search for the top level
  std::vector<float> parent(std::size_t(pyramid.widths[top]) * pyramid.heights[top] * sectors, 1.0f);
  {
    const detail::Grid grid(pyramid.widths[top], pyramid.heights[top], sectors, address);
    tbb::parallel_for(tbb::blocked_range<int>(0, grid.height), [&](const tbb::blocked_range<int>& rows) {
      long long work = 0;
      for (int i = rows.begin(); i < rows.end(); ++i)
        for (int j = 0; j < grid.width; ++j)
          work += detail::ring_search(grid, pyramid.levels[top].data(), global_max, i, j,
                                      parent.data() + (std::size_t(i) * grid.width + j) * sectors);
      total_work += work;
    });
  }

  // from top to bottom: copy where similar, search with the parent's ratio as short circuit otherwise
  for (int level = top - 1; level >= 0; --level) {
    const detail::Grid grid(pyramid.widths[level], pyramid.heights[level], sectors, address);
    const int parent_width = pyramid.widths[level + 1];
    const std::vector<float>& h = pyramid.levels[level];
    const std::vector<float>& parent_h = pyramid.levels[level + 1];
    std::vector<float> current(std::size_t(grid.width) * grid.height * sectors);
    tbb::parallel_for(tbb::blocked_range<int>(0, grid.height), [&](const tbb::blocked_range<int>& rows) {
      long long work = 0, copies = 0;
      for (int i = rows.begin(); i < rows.end(); ++i)
        for (int j = 0; j < grid.width; ++j) {
          const std::size_t p = std::size_t(i / 2) * parent_width + j / 2;
          float* ratios = current.data() + (std::size_t(i) * grid.width + j) * sectors;
          std::copy_n(parent.data() + p * sectors, sectors, ratios);
          if (std::fabs(h[std::size_t(i) * grid.width + j] - parent_h[p]) <= settings.similarity) {
            ++copies;
          } else {
            work += detail::ring_search(grid, h.data(), global_max, i, j, ratios);
          }
        }
      total_work += work;
      if (level == 0) copied += copies;
    });
    parent.swap(current);
  }
  std::copy(parent.begin(), parent.end(), out.data);

  BakeStats stats;
  stats.mode = Mode::paper_adaptive;
  stats.width = heights.width;
  stats.height = heights.height;
  stats.sector_count = sectors;
  stats.texels_fallback = top > 0 ? (long long)copied : 0;
  stats.texels_refined = (long long)heights.width * heights.height - stats.texels_fallback;
  stats.work = total_work;
  stats.milliseconds =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  stats.mean_ratio = detail::mean_of(out.data, parent.size());
  return stats;
}

}  // namespace displace::bake
