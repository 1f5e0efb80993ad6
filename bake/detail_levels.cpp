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

void gradient_moments(HeightView level0, std::span<float> moments) {
  const int width = level0.width, height = level0.height;
  if (level0.data == nullptr || width < 1 || height < 1 ||
      moments.size() != std::size_t(width) * std::size_t(height) * 3) {
    throw BakeError("gradient_moments: a " + std::to_string(width) + "x" + std::to_string(height) +
                    " map needs three moments a texel");
  }
  auto at = [&](int i, int j) {  // wrapped
    i = (i + height) % height;
    j = (j + width) % width;
    return level0.data[std::size_t(i) * std::size_t(width) + std::size_t(j)];
  };
  for (int i = 0; i < height; ++i)
    for (int j = 0; j < width; ++j) {
      const float gu = (at(i, j + 1) - at(i, j - 1)) * (0.5f * float(width));
      const float gv = (at(i + 1, j) - at(i - 1, j)) * (0.5f * float(height));
      float* out = moments.data() + (std::size_t(i) * std::size_t(width) + std::size_t(j)) * 3;
      out[0] = gu;
      out[1] = gv;
      out[2] = gu * gu + gv * gv;
    }
}

void downsample_moments(std::span<const float> fine, int width, int height, std::span<float> coarse) {
  const int half_width = width / 2, half_height = height / 2;
  if (width % 2 != 0 || height % 2 != 0 || half_width < 1 || half_height < 1 ||
      fine.size() != std::size_t(width) * std::size_t(height) * 3 ||
      coarse.size() != std::size_t(half_width) * std::size_t(half_height) * 3) {
    throw BakeError("downsample_moments: a " + std::to_string(width) + "x" + std::to_string(height) +
                    " level needs even sides and three moments a texel at each level");
  }
  for (int i = 0; i < half_height; ++i) {
    const float* top = fine.data() + std::size_t(2 * i) * std::size_t(width) * 3;
    const float* bottom = top + std::size_t(width) * 3;
    float* out = coarse.data() + std::size_t(i) * std::size_t(half_width) * 3;
    for (int j = 0; j < half_width; ++j)
      for (int c = 0; c < 3; ++c) {
        const std::size_t a = std::size_t(2 * j) * 3 + std::size_t(c), b = a + 3;
        out[std::size_t(j) * 3 + std::size_t(c)] = ((top[a] + top[b]) + (bottom[a] + bottom[b])) * 0.25f;
      }
  }
}

}  // namespace displace::bake
