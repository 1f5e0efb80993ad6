// bake/common.cpp - input validation and names shared by every baker.
#include <cmath>
#include <string>

#include "bake/bake.h"

namespace displace::bake {

bool is_valid_sector_count(int sector_count) {
  return sector_count == 1 || sector_count == 4 || sector_count == 8;
}

void validate(HeightView heights, const ConeView& out) {
  if (heights.width <= 0 || heights.height <= 0 || heights.data == nullptr) {
    throw BakeError("height map is empty (" + std::to_string(heights.width) + "x" +
                    std::to_string(heights.height) + "): a cone map needs at least one texel");
  }
  if (heights.width > (1 << 15) || heights.height > (1 << 15)) {
    throw BakeError("height map " + std::to_string(heights.width) + "x" + std::to_string(heights.height) +
                    " is larger than the supported 32768x32768");
  }
  if (!is_valid_sector_count(out.sector_count)) {
    throw BakeError("sector count " + std::to_string(out.sector_count) + " is not supported (use 1, 4 or 8)");
  }
  if (out.data == nullptr || out.width != heights.width || out.height != heights.height) {
    throw BakeError("cone map output does not match the height map size");
  }
  const std::size_t count = std::size_t(heights.width) * heights.height;
  for (std::size_t i = 0; i < count; ++i) {
    const float h = heights.data[i];
    if (!std::isfinite(h)) {
      throw BakeError("height map has a non-finite height (NaN or Inf) at texel (" +
                      std::to_string(i / heights.width) + ", " + std::to_string(i % heights.width) + ")");
    }
    if (h < 0.0f || h > 1.0f) {
      throw BakeError("height map has a height outside [0, 1] (" + std::to_string(h) + ") at texel (" +
                      std::to_string(i / heights.width) + ", " + std::to_string(i % heights.width) + ")");
    }
  }
}

const char* mode_name(Mode mode) {
  switch (mode) {
    case Mode::exact: return "exact";
    case Mode::original: return "original";
    case Mode::paper_adaptive: return "paper-adaptive";
    case Mode::budgeted: return "budgeted";
  }
  return "unknown";
}

}  // namespace displace::bake
