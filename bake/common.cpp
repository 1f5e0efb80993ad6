// bake/common.cpp - input validation and names shared by every baker.
#include <cmath>
#include <string>

#include "bake/bake.h"

namespace displace::bake {

bool is_valid_sector_count(int sector_count) {
  return sector_count == 1 || sector_count == 4 || sector_count == 8;
}

namespace {}  // namespace

void validate_heights(HeightView heights, const char* product) {
  if (heights.width <= 0 || heights.height <= 0 || heights.data == nullptr) {
    throw BakeError("height map is empty (" + std::to_string(heights.width) + "x" +
                    std::to_string(heights.height) + "): " + product + " needs at least one texel");
  }
  if (heights.width > max_map_side || heights.height > max_map_side) {
    throw BakeError("height map " + std::to_string(heights.width) + "x" + std::to_string(heights.height) +
                    " is larger than the supported " + std::to_string(max_map_side) + "x" +
                    std::to_string(max_map_side));
  }
  const std::size_t count = std::size_t(heights.width) * heights.height;
  // one branch-free pass (NaN fails both comparisons), then the slow one only to name the texel
  int bad = 0;
  for (std::size_t i = 0; i < count; ++i)
    bad |= int(!(heights.data[i] >= 0.0f)) | int(!(heights.data[i] <= 1.0f));
  if (bad == 0) return;
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

void validate(HeightView heights, const ConeView& out) {
  validate_heights(heights, "a cone map");
  if (!is_valid_sector_count(out.sector_count)) {
    throw BakeError("sector count " + std::to_string(out.sector_count) + " is not supported (use 1, 4 or 8)");
  }
  if (out.data == nullptr || out.width != heights.width || out.height != heights.height) {
    throw BakeError("cone map output does not match the height map size");
  }
}

void validate(HeightView heights, const DistanceView& out) {
  validate_heights(heights, "a distance map");
  const std::string size =
      std::to_string(out.width) + "x" + std::to_string(out.height) + "x" + std::to_string(out.depth);
  if (out.width <= 0 || out.height <= 0 || out.depth <= 0) {
    throw BakeError("distance map " + size + " is empty: it needs at least one voxel along each axis");
  }
  if (out.data == nullptr) throw BakeError("distance map output " + size + " has no memory (null data)");
  if (out.width > max_map_side || out.height > max_map_side) {
    throw BakeError("distance map " + size + " is wider than the supported " + std::to_string(max_map_side) +
                    " voxels along u or v");
  }
  if (out.depth > max_distance_depth) {
    throw BakeError("distance map " + size + " is deeper than the supported " +
                    std::to_string(max_distance_depth) + " layers");
  }
  if ((long long)out.width * out.height * out.depth > max_distance_voxels) {
    throw BakeError("distance map " + size + " has more than the supported " +
                    std::to_string(max_distance_voxels) + " voxels");
  }
}

const char* mode_name(Mode mode) {
  switch (mode) {
    case Mode::exact: return "exact";
    case Mode::original: return "original";
    case Mode::paper_adaptive: return "paper-adaptive";
    case Mode::budgeted: return "budgeted";
    case Mode::bilinear: return "bilinear";
    case Mode::bilinear_budgeted: return "bilinear-budgeted";
  }
  return "unknown";
}

}  // namespace displace::bake
