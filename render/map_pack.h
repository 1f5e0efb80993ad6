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
#include "vulkan/device_maps.h"

namespace displace::render::detail {

// Heights of `rect`, row after row, `row_floats` apart from `out` on; false when one is not finite
// or outside [0, 1]. vectorised false: the scalar loop alone (the reference of the SSE2 path).
bool pack_heights(std::span<const float> heights, int width, const bake::Rect& rect, float* out,
                  std::size_t row_floats, bool vectorised = true);

// The cone image's texel encoding (vulkan/device_maps.h).
using vulkan::decode_apex;
using vulkan::decode_ratio;
using vulkan::encode_apex;
using vulkan::encode_ratio;
using vulkan::smallest_half_ratio;

// The cone image's layers of `rect` (cone_layer_count): (ratio, apex) pairs encoded as above, rows
// `row_values` and layers `layer_values` 16-bit values apart from `out` on - a layer per sector,
// then (with more than one sector) the smallest of the sectors, then the relaxed ratio where the map
// has one. False when a ratio is negative, above 1e30 or NaN, or an apex is outside [0, 1].
bool pack_cones(const ConeMapView& cones, int width, const bake::Rect& rect, std::uint16_t* out,
                std::size_t row_values, std::size_t layer_values, bool vectorised = true);

}  // namespace displace::render::detail
