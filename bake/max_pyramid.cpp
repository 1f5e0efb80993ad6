// bake/max_pyramid.cpp - maximum mipmaps (Tevs et al.; Chen & Chuang's Algorithm 1, lines 2-7).
// Odd sizes round up: the last block of a row or column has fewer children.
#include <algorithm>

#include "bake/bake.h"

namespace displace::bake {

void build_max_pyramid(HeightView heights, MaxPyramid& pyramid) {
  int w = heights.width, h = heights.height;
  std::size_t level = 0;
  auto next_level = [&](int lw, int lh) -> std::vector<float>& {
    if (pyramid.levels.size() <= level) pyramid.levels.emplace_back();
    if (pyramid.widths.size() <= level) pyramid.widths.push_back(0), pyramid.heights.push_back(0);
    pyramid.widths[level] = lw;
    pyramid.heights[level] = lh;
    std::vector<float>& values = pyramid.levels[level++];
    values.resize(std::size_t(lw) * lh);
    return values;
  };
  std::vector<float>& base = next_level(w, h);
  std::copy(heights.data, heights.data + std::size_t(w) * h, base.begin());
  while (w > 1 || h > 1) {
    const int cw = (w + 1) / 2, ch = (h + 1) / 2;
    std::vector<float>& coarse = next_level(cw, ch);
    const std::vector<float>& fine = pyramid.levels[level - 2];
    for (int i = 0; i < ch; ++i) {
      const int i0 = 2 * i, i1 = std::min(2 * i + 1, h - 1);
      for (int j = 0; j < cw; ++j) {
        const int j0 = 2 * j, j1 = std::min(2 * j + 1, w - 1);
        coarse[std::size_t(i) * cw + j] =
            std::max(std::max(fine[std::size_t(i0) * w + j0], fine[std::size_t(i0) * w + j1]),
                     std::max(fine[std::size_t(i1) * w + j0], fine[std::size_t(i1) * w + j1]));
      }
    }
    w = cw;
    h = ch;
  }
  pyramid.levels.resize(level);
  pyramid.widths.resize(level);
  pyramid.heights.resize(level);
}

MaxPyramid build_max_pyramid(HeightView heights) {
  MaxPyramid pyramid;
  build_max_pyramid(heights, pyramid);
  return pyramid;
}

}  // namespace displace::bake
