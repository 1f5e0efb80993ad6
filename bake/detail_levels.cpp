// bake/detail_levels.cpp - the levels of detail's height chain: each level the 2 x 2 box mean of the
// one below (bake.h). The four texels of a mean are summed in one fixed order in float, so a level
// is the same bits on every machine (bake/ builds without fused multiply-adds).
#include <string>

#include "bake/bake.h"

namespace displace::bake {

int detail_level_count(int width, int height) {
  int levels = 0;
  while (levels < max_detail_levels && width % 2 == 0 && height % 2 == 0 && width / 2 >= min_level_side &&
         height / 2 >= min_level_side) {
    width /= 2;
    height /= 2;
    ++levels;
  }
  return levels;
}

void downsample_heights(HeightView fine, std::span<float> coarse) {
  const int width = fine.width / 2, height = fine.height / 2;
  if (fine.data == nullptr || fine.width % 2 != 0 || fine.height % 2 != 0 || width < 1 || height < 1 ||
      coarse.size() != std::size_t(width) * std::size_t(height)) {
    throw BakeError("downsample_heights: a " + std::to_string(fine.width) + "x" +
                    std::to_string(fine.height) +
                    " level needs even sides and a coarse level of half its size a side");
  }
  for (int i = 0; i < height; ++i) {
    const float* top = fine.data + std::size_t(2 * i) * std::size_t(fine.width);
    const float* bottom = top + fine.width;
    float* out = coarse.data() + std::size_t(i) * std::size_t(width);
    for (int j = 0; j < width; ++j) {
      // the mean of four values in [0, 1] stays in [0, 1]: the sum is exact to a half ulp each step
      out[j] = ((top[2 * j] + top[2 * j + 1]) + (bottom[2 * j] + bottom[2 * j + 1])) * 0.25f;
    }
  }
}

}  // namespace displace::bake
