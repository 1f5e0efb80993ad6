// bake/max_pyramid.cpp - maximum mipmaps (Tevs et al.; Chen & Chuang's Algorithm 1, lines 2-7).
// Odd sizes round up: the last block of a row or column has fewer children.
#include <algorithm>

#include "bake/bake.h"

namespace displace::bake {

MaxPyramid build_max_pyramid(HeightView heights) {
  MaxPyramid pyramid;
  int w = heights.width, h = heights.height;
  pyramid.widths.push_back(w);
  pyramid.heights.push_back(h);
  pyramid.levels.emplace_back(heights.data, heights.data + std::size_t(w) * h);
  while (w > 1 || h > 1) {
    const int cw = (w + 1) / 2, ch = (h + 1) / 2;
    const std::vector<float>& fine = pyramid.levels.back();
    std::vector<float> coarse(std::size_t(cw) * ch);
    for (int i = 0; i < ch; ++i) {
      const int i0 = 2 * i, i1 = std::min(2 * i + 1, h - 1);
      for (int j = 0; j < cw; ++j) {
        const int j0 = 2 * j, j1 = std::min(2 * j + 1, w - 1);
        coarse[std::size_t(i) * cw + j] =
            std::max(std::max(fine[std::size_t(i0) * w + j0], fine[std::size_t(i0) * w + j1]),
                     std::max(fine[std::size_t(i1) * w + j0], fine[std::size_t(i1) * w + j1]));
      }
    }
    pyramid.widths.push_back(cw);
    pyramid.heights.push_back(ch);
    pyramid.levels.push_back(std::move(coarse));
    w = cw;
    h = ch;
  }
  return pyramid;
}

}  // namespace displace::bake
