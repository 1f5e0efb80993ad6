// bake/device/shaders/cones.h - the device cone maps' push constants and limits (cone_cells.comp.glsl,
// cone_reduce.comp.glsl, cone_texel.comp.glsl), shared by GLSL and C++ (bake/device/device_cones.cpp, with
// static_asserts).
#ifndef DISPLACE_BAKE_CONES_H
#define DISPLACE_BAKE_CONES_H

#ifdef __cplusplus
#include <cstdint>
namespace displace::bake::gpu {
#endif

#define CONE_TILE 8  // the kernels' groups: 8 x 8 texels, cells or nodes
#define CONE_SLOPE_WINDOW \
  4  // cells: radius around a texel where the slope bound applies (bake.h's default), at most
#define CONE_GROUP_LEVELS 4  // a group first pass: the far values of an 8 x 8 texel group at this many apexes
#define CONE_GROUP_NEAR \
  8  // ... and the cells its texels bound themselves: their centre cells widened by this
#define CONE_MAX_LEVELS 17        // pyramid levels at most: 32769 cells a side (a clamped 32768 map)
#define CONE_COUNTER_LIPSCHITZ 0  // counters[]: the surface's Lipschitz constant (float bits), uv units
#define CONE_COUNTER_BAD 1        // counters[]: 1 when a height is not a finite value in [0, 1]
#define CONE_COUNTER_TICKETS 2    // counters[]: texels whose first pass was cut, asking for refinement
#define CONE_COUNTER_LIFT 3       // counters[]: lagged maps: the most a texel rose since (float bits)
#define CONE_COUNTERS 4

struct ConeCellsPush {
  int width, height;     // texels
  int cells_u, cells_v;  // W x H (wrap) or (W + 1) x (H + 1) (clamp)
  int wrap;              // 1: Address::wrap
  int pad0, pad1, pad2;
};

struct ConeReducePush {
  int source_offset, source_width, source_height;  // level L in the pyramid buffer (floats)
  int target_offset, target_width, target_height;  // level L + 1
  int pad0, pad1;
};

struct ConeTexelPush {
  int width, height;
  int cells_u, cells_v;
  int wrap;
  int sectors;           // 1, 4 or 8
  int levels;            // pyramid levels (the last one 1 x 1)
  int first_pass_level;  // nodes at or below it are bounded, not opened, in the first pass; < 0: none
  int refine_limit;      // texels whose cut first pass is searched again to the cells, at most
  int first_row;         // the dispatch's rows begin at this texel row (lagged maps: a band a frame)
  int window_radius;     // cells around the texel bounded by the slope window, 1..CONE_SLOPE_WINDOW
  int ring_radius;       // first pass: 0 searches the pyramid cut at first_pass_level; r > 0 bounds rings
                         // (the texel kernel's FIRST_PASS_RINGS form)
  int pad0;
  int level_offset[CONE_MAX_LEVELS];  // where level l's nodes begin in the pyramid buffer (floats)
};

struct LevelDownPush {
  int fine_width, fine_height;       // level l - 1's texels (level l has half as many a side)
  int origin_x, origin_y;            // level l's texels in the heights atlas
  int fine_origin_x, fine_origin_y;  // level l - 1's (l >= 2; level 1 makes level 0's moments itself)
  int from_level0;                   // 1: l = 1
  int pad0;
};

struct ConeLiftPush {
  int width, height;
  int pad0, pad1;
};

struct ConeComposePush {
  int width, height;
  int layers;  // values per texel
  int pad0;
};

#ifdef __cplusplus
}  // namespace displace::bake::gpu
#endif
#endif
