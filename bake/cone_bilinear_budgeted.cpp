// bake/cone_bilinear_budgeted.cpp - the renderer's cone maps (bake_bilinear_cones' contract) within a
// frame budget, kept between frames (bake.h, BilinearBaker).
//
// Interim version: every call is a full bake_bilinear_cones (conservative at every budget, never
// within one).
#include <algorithm>
#include <string>
#include <vector>

#include "bake/bake.h"

namespace displace::bake {

struct BilinearBaker::State {
  int width = 0, height = 0, sector_count = 0;
  Address address = Address::wrap;
  std::vector<float> heights;
};

BilinearBaker::BilinearBaker(int width, int height, int sector_count, Address address)
    : state_(std::make_unique<State>()) {
  if (!is_valid_sector_count(sector_count)) {
    throw BakeError("bilinear cone map: " + std::to_string(sector_count) + " sectors (use 1, 4 or 8)");
  }
  state_->width = width;
  state_->height = height;
  state_->sector_count = sector_count;
  state_->address = address;
}
BilinearBaker::~BilinearBaker() = default;
BilinearBaker::BilinearBaker(BilinearBaker&&) noexcept = default;
BilinearBaker& BilinearBaker::operator=(BilinearBaker&&) noexcept = default;

BakeStats BilinearBaker::bake(HeightView heights, const Budget&, ConeView out, std::span<float> apex_heights) {
  State& state = *state_;
  if (heights.width != state.width || heights.height != state.height) {
    throw BakeError("bilinear baker: the map is " + std::to_string(heights.width) + " x " +
                    std::to_string(heights.height) + " but the baker was made for " + std::to_string(state.width) +
                    " x " + std::to_string(state.height));
  }
  state.heights.assign(heights.data, heights.data + std::size_t(heights.width) * heights.height);
  BakeStats stats = bake_bilinear_cones(heights, state.address, out, apex_heights);
  stats.mode = Mode::bilinear_budgeted;
  return stats;
}

BakeStats BilinearBaker::update(HeightView heights, std::span<const Rect>, const Budget& budget, ConeView out,
                                std::span<float> apex_heights) {
  return bake(heights, budget, out, apex_heights);
}

BakeStats BilinearBaker::refine(const Budget& budget, ConeView out, std::span<float> apex_heights) {
  State& state = *state_;
  return bake({state.heights.data(), state.width, state.height}, budget, out, apex_heights);
}

long long BilinearBaker::pending() const { return 0; }

}  // namespace displace::bake
