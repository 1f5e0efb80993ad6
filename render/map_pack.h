// render/map_pack.h - the host's half of a map upload: a changed rectangle of heights or of a cone
// map packed into an image's layout (a staging slice or a host-written linear image), its values
// checked on the way (internal to render/; map_upload.cpp calls it, the tests compare the
// vectorised packing with the scalar one).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>

#include "render/render.h"

namespace displace::render::detail {

// Heights of `rect`, row after row, `row_floats` apart from `out` on; false when one is not finite
// or outside [0, 1]. vectorised false: the scalar loop alone (the reference of the SSE2 path).
bool pack_heights(std::span<const float> heights, int width, const bake::Rect& rect, float* out,
                  std::size_t row_floats, bool vectorised = true);

// The cone image (cone_format, R16G16_UINT) holds per layer and texel a (ratio, apex) pair of 16-bit
// values, so that what the shader reads claims no more empty space than what was baked:
// - the ratio as the bits of an IEEE half float, its mantissa truncated (rounded down exactly; the
//   shader's unpackHalf2x16 is exact): a relative step of at most 2^-10; ratios of 1 or more read
//   as 1 and those below 2^-14 as 0;
// - the apex as q / 65535 rounded up, with a unit of margin beyond the float roundings on either
//   side (the shader divides by 65535 in float).
constexpr float smallest_half_ratio = 0x1p-14f;   // below: stored as 0
inline std::uint16_t encode_ratio(float ratio) {  // ratio >= 0
  const float clamped = std::min(ratio, 1.0f);
  std::uint32_t bits;
  std::memcpy(&bits, &clamped, sizeof bits);
  // exponent rebased from 127 to 15, the mantissa's low 13 bits dropped
  return clamped < smallest_half_ratio ? std::uint16_t(0) : std::uint16_t((bits >> 13) - ((127 - 15) << 10));
}
inline std::uint16_t encode_apex(float apex) {  // apex in [0, 1]
  // a * 65535 + 2 in float is above the exact a * 65535 by more than 1.99, and truncation loses < 1
  const float scaled = std::min(apex * 65535.0f + 2.0f, 65535.0f);
  // NaN, and values int cannot hold, of maps the packer refuses (never drawn): 0, for a cast of them
  // to int is undefined (clang's UBSan, float-cast-overflow)
  if (!(scaled > -2147483648.0f)) return 0;
  return std::uint16_t(int(scaled));
}
// What the shader reads (the apex in float as a driver may convert: times the rounded 1 / 65535)
inline float decode_ratio(std::uint16_t value) {
  if (value == 0) return 0.0f;
  const std::uint32_t bits = (std::uint32_t(value) + ((127 - 15) << 10)) << 13;
  float ratio;
  std::memcpy(&ratio, &bits, sizeof ratio);
  return ratio;
}
inline float decode_apex(std::uint16_t value) { return float(value) * (1.0f / 65535.0f); }

// The cone image's layers of `rect` (cone_layer_count): (ratio, apex) pairs encoded as above, rows
// `row_values` and layers `layer_values` 16-bit values apart from `out` on - a layer per sector,
// then (with more than one sector) the smallest of the sectors, then the relaxed ratio where the map
// has one. False when a ratio is negative, above 1e30 or NaN, or an apex is outside [0, 1].
bool pack_cones(const ConeMapView& cones, int width, const bake::Rect& rect, std::uint16_t* out,
                std::size_t row_values, std::size_t layer_values, bool vectorised = true);

}  // namespace displace::render::detail
