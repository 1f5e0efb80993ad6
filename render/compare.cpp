// render/compare.cpp - image error against the reference, in 8-bit output units.
#include <algorithm>
#include <cmath>
#include <cstdlib>

#include "render/render.h"

namespace displace::render {

ImageError compare(const Frame& frame, const Frame& reference) {
  if (frame.width != reference.width || frame.height != reference.height) {
    throw RenderError("compare: frames differ in size");
  }
  const std::size_t pixel_count = std::size_t(frame.width) * std::size_t(frame.height);
  for (const Frame* one : {&frame, &reference}) {
    if (one->color.size() != pixel_count * 4 || one->uv.size() != pixel_count * 3) {
      throw RenderError("compare: both frames need their colour and uv read back (output_color | output_uv)");
    }
  }
  constexpr int off_threshold = 10;  // 8-bit units: a pixel counts as "off" above this
  ImageError error;
  double sum_squares = 0.0;
  long long channels = 0, off = 0;
  const long long pixels = (long long)frame.width * frame.height;
  for (long long p = 0; p < pixels; ++p) {
    const bool frame_hit = frame.uv[p * 3 + 2] > 0.5f;
    const bool reference_hit = reference.uv[p * 3 + 2] > 0.5f;
    if (!frame_hit && !reference_hit) continue;
    int worst = 0;
    for (int c = 0; c < 3; ++c) {
      const int difference = std::abs(int(frame.color[p * 4 + c]) - int(reference.color[p * 4 + c]));
      sum_squares += double(difference) * difference;
      worst = std::max(worst, difference);
      ++channels;
    }
    error.max_error = std::max(error.max_error, double(worst));
    if (worst > off_threshold) ++off;
    ++error.pixels;
  }
  if (channels > 0) {
    error.rmse = std::sqrt(sum_squares / double(channels));
    error.fraction_over_10 = double(off) / double(error.pixels);
  }
  return error;
}

}  // namespace displace::render
