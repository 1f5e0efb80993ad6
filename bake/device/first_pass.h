// bake/device/first_pass.h - the shape of bake::DeviceCones' first pass (bake/device/device_cones.h)
// as plain values, which a scene's [backend] keys set: no Vulkan header, so that a scene
// (pipeline/scene.h) names a first pass without pulling in Vulkan. Its proof:
// docs/design/device-cones.md; its figures: docs/figures.md.
#pragma once

namespace displace::bake {

// How a DeviceCones first pass bounds a texel: from its slope window (the window_radius cells around
// it on each side, bounded by the surface's slopes), the Lipschitz floor and the max pyramid. The
// pyramid either by a search (ring_radius 0) that opens nodes down to blocks of 4 x 4 cells, bounding
// those whole, or by rings (ring_radius r > 0): at every level, the nodes more than r nodes from the
// texel's own are bounded whole, the same nodes for every texel (no search: the device runs a group's
// texels in step). r = 1 examines about 220 nodes a texel, r = 2 about 660 and bounds more tightly.
// Or by its group (group = true, ring_radius 0): each 8 x 8 texel group searches the pyramid once for
// the cells more than 8 cells from its texels, from the group's square at a few apex heights, and each
// texel bounds the cells nearer than that itself, by rings of radius 1 from blocks of 4 x 4 cells down
// (54 nodes a texel with the full window, 90 with a window of 2; the same nodes for a group's texels).
// The default, rings of radius 2 with the full window, is the fastest shape on a GPU of those that keep
// the search's mean ratio; on lavapipe, which runs a group's texels as lanes of a CPU, the search and
// the group are faster (docs/figures.md).
inline constexpr int max_first_pass_window = 4;  // cells (the search's window: CONE_SLOPE_WINDOW)
inline constexpr int max_first_pass_rings = 8;   // nodes: (4 r + 2)^2 examined a level, 1156 at 8
inline constexpr int default_first_pass_rings = 2;
struct DeviceFirstPass {
  int window_radius = max_first_pass_window;   // 1 .. max_first_pass_window
  int ring_radius = default_first_pass_rings;  // 0 .. max_first_pass_rings
  bool group = false;                          // the group's first pass (with ring_radius 0)
};

}  // namespace displace::bake
