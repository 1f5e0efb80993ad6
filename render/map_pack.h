// render/map_pack.h - the host's half of a map upload: a changed rectangle of heights or of a cone
// map packed into an image's layout (a staging slice or a host-written linear image), its values
// checked on the way (internal to render/; map_upload.cpp calls it, the tests compare the
// vectorised packing with the scalar one).
#pragma once

#include <cstddef>
#include <span>

#include "render/render.h"

namespace displace::render::detail {

// Heights of `rect`, row after row, `row_floats` apart from `out` on; false when one is not finite
// or outside [0, 1]. vectorised false: the scalar loop alone (the reference of the SSE2 path).
bool pack_heights(std::span<const float> heights, int width, const bake::Rect& rect, float* out,
                  std::size_t row_floats, bool vectorised = true);

// The cone image's layers of `rect` (cone_layer_count): (ratio, apex) pairs, rows `row_floats` and
// layers `layer_floats` apart from `out` on - a layer per sector, then (with more than one sector)
// the smallest of the sectors, then the relaxed ratio where the map has one. False when a ratio is
// negative, above 1e30 or NaN, or an apex is outside [0, 1].
bool pack_cones(const ConeMapView& cones, int width, const bake::Rect& rect, float* out,
                std::size_t row_floats, std::size_t layer_floats, bool vectorised = true);

}  // namespace displace::render::detail
