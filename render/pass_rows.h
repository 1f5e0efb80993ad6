// render/pass_rows.h - the rows each pass of the unbounded plane can draw when it traces levels of
// detail (internal to render/; frame.cpp sets them as the passes' scissors, the tests check them
// against every pixel's level).
//
// Such a view is drawn in three passes (config.h, FLAG_LEVELS, FLAG_SKY): one pipeline for the pixels
// whose ray traces level 0, one for those of the coarser levels, one for the sky. Each discards the
// others' pixels, but lavapipe runs a discarded block of pixels through the rest of the shader under
// an empty mask (every loop's body once): drawn over the whole picture, two passes cost 1.4x what
// their pixels do. The level is a function of the pixel's ray alone (choose_level,
// surface.frag.glsl), so the rows where each pass has a pixel are found here, from bounds of that
// function over each row, widened by the float error of the shader's evaluation: a pass never loses
// a pixel to its scissor, and it still discards the others' pixels in the rows they share.
#pragma once

#include "render/render.h"

namespace displace::render::detail {

// Rows [begin, end) of the picture; empty when begin == end.
struct RowRange {
  int begin = 0, end = 0;
  bool empty() const { return begin >= end; }
};

struct PassRows {
  RowRange level_zero;  // rows holding a pixel that may trace level 0
  RowRange coarser;     // rows holding a pixel that may trace a coarser level
  RowRange sky;         // rows holding a pixel that may see the sky
};

// The rows of the two passes of a view of `camera`'s pixels on the unbounded plane, with
// `levels` levels held (0: level_zero also holds the rows of the sky, which its one pass draws), `pinned` the
// level every pixel traces (View::level) or -1 to choose it per pixel, `texels_per_unit` the level-0 texels
// per world unit of the widest side (tile times max(W, H)). Each range is the smallest that holds every row
// the pass may draw.
PassRows level_pass_rows(const Camera& camera, int levels, int pinned, double texels_per_unit);

}  // namespace displace::render::detail
