// sim/mapping.cpp - raw heights in metres to the [0, 1] range the baker and renderer read
// (the SCALE/BIAS of Premecz's iterative parallax mapping, inverted).
// A NaN sample maps to 0 and counts as clamped, so a broken source never passes silently.
#include <stdexcept>

#include "sim/sim.h"

namespace displace::sim {

std::size_t apply_mapping(const HeightMapping& mapping, std::span<const float> raw, std::span<float> out) {
  if (raw.size() != out.size()) {
    throw std::invalid_argument("apply_mapping: raw and out differ in length");
  }
  std::size_t clamped = 0;
  for (std::size_t index = 0; index < raw.size(); ++index) {
    const float value = raw[index] * mapping.scale + mapping.bias;
    if (value >= 0.0f && value <= 1.0f) {
      out[index] = value;
    } else {
      out[index] = value > 1.0f ? 1.0f : 0.0f;
      ++clamped;
    }
  }
  return clamped;
}

}  // namespace displace::sim
