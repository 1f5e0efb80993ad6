// vulkan/device_maps.h - the maps a device stage writes and the renderer samples, as one layer hands
// them to the next: handles to images on one Frames' device (map_set.h names them opaquely), the cone
// image's format and texel encoding, and where each level of detail lies in the levels' atlases. Not
// installed.
//
// A handle names the Frames whose device holds its images; the stage that made it clears its image
// pointers when it goes, so that a frame that still names them is refused instead of sampling freed
// memory.
#pragma once

#include <vulkan/vulkan.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <glm/vec2.hpp>

namespace displace::vulkan {

class Frames;
class Image;

// Heights (R32F) and foam coverage (R32F; null: no foam), in the GENERAL layout.
struct DeviceHeightImages {
  const Frames* owner = nullptr;
  const Image* heights = nullptr;
  const Image* foam = nullptr;
};

// A cone map (cone_format, a layer per sector; cone_layer_count), in the GENERAL layout.
struct DeviceConeImage {
  const Frames* owner = nullptr;
  const Image* image = nullptr;
  int width = 0, height = 0, sectors = 0;
  bool wrap = true;  // baked with the wrap address mode, else clamp
  // the bake's max pyramid and the byte offset of its top (the map's highest height), which a level
  // of detail's top is copied from
  VkBuffer pyramid = VK_NULL_HANDLE;
  VkDeviceSize top_offset = 0;
};

// The levels of detail: heights (RGBA32F: height and slope moments) and cones (cone_format) of levels
// 1 .. count in one atlas each (level_atlas_origin), and each level's highest height, `tops`: 16
// floats laid out as the frame uniforms' level tops, copied into a frame's uniforms on the device.
struct DeviceLevelImages {
  const Frames* owner = nullptr;
  const Image* heights = nullptr;
  const Image* cones = nullptr;
  VkBuffer tops = VK_NULL_HANDLE;
  int width = 0, height = 0;  // level 0's
  int count = 0, sectors = 0;
  bool wrap = true;  // the levels' cones baked with the wrap address mode, else clamp
};

// Layers of a cone image: layer k < n holds (r_k, H_c); with n > 1 sectors layer n holds (min over k
// of r_k, H_c), the isotropic bound the quadric cone march needs near a step's start; with relaxed
// ratios one more layer holds (relaxed ratio, H_c).
inline int cone_layer_count(int sectors, bool relaxed) {
  return (sectors > 1 ? sectors + 1 : 1) + (relaxed ? 1 : 0);
}
constexpr VkFormat cone_format = VK_FORMAT_R16G16_UINT;
constexpr std::size_t cone_texel_bytes = 4;

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

// The levels of detail's atlases: level 1 from (0, 0), level l >= 2 from (W / 2, H / 2 - (H >> (l -
// 1))), (W / 2 + W / 4) x (H / 2) texels in all (W / 2 wide with one level).
inline glm::ivec2 level_atlas_origin(int width, int height, int level) {
  return level == 1 ? glm::ivec2(0) : glm::ivec2(width / 2, height / 2 - (height >> (level - 1)));
}
inline glm::ivec2 level_atlas_size(int width, int height, int level_count) {
  return {width / 2 + (level_count >= 2 ? width / 4 : 0), height / 2};
}

}  // namespace displace::vulkan
