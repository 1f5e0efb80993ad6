// bake/dual_max_pyramid.cpp - maximum mipmaps of the BILINEAR surface (Tevs, Ihrke & Seidel,
// "Maximum Mipmaps for Fast, Accurate, and Scalable Dynamic Height Field Rendering", I3D 2008): the
// pyramid is built on the dual grid, whose cells lie between texel centres, because a bilinear patch
// is a convex combination of its four corner texels and so reaches its maximum at a corner.
// Footprints are truncated at the grid's end, never padded (see bake.h), so every node is exactly
// the surface's maximum over its footprint.
#include <algorithm>

#include "bake/bake.h"

namespace displace::bake {

DualMaxPyramid build_dual_max_pyramid(HeightView heights, Address address) {
  validate_heights(heights, "a max pyramid");
  const int width = heights.width, height = heights.height;
  DualMaxPyramid pyramid;
  pyramid.origin = address == Address::wrap ? 0 : -1;
  // cells along an axis of `size` texels: one period with wrap, the half-texel borders added with clamp
  const int cells_x = address == Address::wrap ? width : width + 1;
  const int cells_y = address == Address::wrap ? height : height + 1;
  auto texel = [&](int i, int j) {
    if (address == Address::wrap) {
      i = (i % height + height) % height;
      j = (j % width + width) % width;
    } else {
      i = std::clamp(i, 0, height - 1);
      j = std::clamp(j, 0, width - 1);
    }
    return heights.data[std::size_t(i) * width + j];
  };

  // level 0: cell (i, j) spans texel centres (i + origin .. i + origin + 1, j + origin .. j + origin + 1)
  pyramid.widths.push_back(cells_x);
  pyramid.heights.push_back(cells_y);
  pyramid.offsets.push_back(0);
  pyramid.values.resize(std::size_t(cells_x) * cells_y);
  for (int i = 0; i < cells_y; ++i) {
    const int row = i + pyramid.origin;
    for (int j = 0; j < cells_x; ++j) {
      const int column = j + pyramid.origin;
      pyramid.values[std::size_t(i) * cells_x + j] =
          std::max(std::max(texel(row, column), texel(row, column + 1)),
                   std::max(texel(row + 1, column), texel(row + 1, column + 1)));
    }
  }

  // coarser levels: the max of the (up to four) existing children
  int w = cells_x, h = cells_y;
  while (w > 1 || h > 1) {
    const int cw = (w + 1) / 2, ch = (h + 1) / 2;
    const std::size_t fine = pyramid.offsets.back(), coarse = pyramid.values.size();
    pyramid.values.resize(coarse + std::size_t(cw) * ch);
    for (int i = 0; i < ch; ++i) {
      const int i0 = 2 * i, i1 = std::min(2 * i + 1, h - 1);
      for (int j = 0; j < cw; ++j) {
        const int j0 = 2 * j, j1 = std::min(2 * j + 1, w - 1);
        const float* values = pyramid.values.data() + fine;
        pyramid.values[coarse + std::size_t(i) * cw + j] =
            std::max(std::max(values[std::size_t(i0) * w + j0], values[std::size_t(i0) * w + j1]),
                     std::max(values[std::size_t(i1) * w + j0], values[std::size_t(i1) * w + j1]));
      }
    }
    pyramid.widths.push_back(cw);
    pyramid.heights.push_back(ch);
    pyramid.offsets.push_back(coarse);
    w = cw;
    h = ch;
  }
  return pyramid;
}

}  // namespace displace::bake
