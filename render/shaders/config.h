// render/shaders/config.h - every layout and constant shared by the GLSL shaders and the C++ host.
// Included by GLSL (after #version) and by C++ (render/renderer.cpp, with static_asserts there).
#ifndef DISPLACE_RENDER_CONFIG_H
#define DISPLACE_RENDER_CONFIG_H

#ifdef __cplusplus
#include <cstdint>
#include <glm/glm.hpp>
namespace displace::render::gpu {
using vec4 = glm::vec4;
using ivec4 = glm::ivec4;
using mat4 = glm::mat4;
#endif

// method ids (specialization constant 0 of the surface fragment shader)
#define METHOD_BUMP 0
#define METHOD_PARALLAX 1
#define METHOD_PARALLAX_LIMITED 2
#define METHOD_PARALLAX_SLOPE 3
#define METHOD_POM 4
#define METHOD_RELIEF 5
#define METHOD_INTERVAL 6
#define METHOD_SPHERE 7
#define METHOD_CSM 8
#define METHOD_ACM4 9
#define METHOD_ACM8 10
#define METHOD_ACM4_INTERVAL 11
#define METHOD_RELAXED 12
#define METHOD_MAXMIP 13
#define METHOD_QDM 14
#define METHOD_REFERENCE 15

// surfaces (specialization constant 1 of the shaders; geometry in render/render.h and quadric.inc.glsl)
#define SURFACE_PLANE 0
#define SURFACE_SPHERE 1
#define SURFACE_CYLINDER 2
#define SURFACE_CONE 3
#define SURFACE_MESH 4      // render/mesh.h, mesh.vert.glsl, mesh.inc.glsl
#define QUADRIC_AXIS_X 0.5  // every quadric's axis is the vertical line x = y = 0.5 (world units)
#define QUADRIC_AXIS_Y 0.5
#define CONE_APEX_HEIGHT 1.5  // the cone's apex is at z = 1.5 R
#define CONE_SLOPE 0.5        // tan of the cone's half-angle: radius gained per unit of descent

// descriptor bindings (set 0)
#define BINDING_FRAME 0   // read-only storage buffer: FrameUniforms (frame_block.inc.glsl)
#define BINDING_HEIGHT 1  // sampler2D, R32F heights, linear, the address mode
#define BINDING_CONES \
  2  // usampler2DArray, RG16UI: layer k = (ratio of sector k, apex height) encoded, nearest
#define RELAXED_CONE_SECTORS \
  4  // relaxed: layers 0-3 its bilinear cones, 4 their minimum, 5 (relaxed ratio, apex)
#define BINDING_DISTANCE \
  3  // sampler3D, R32F distance map (u, v, h), trilinear, the address mode in u, v, clamp in h
#define BINDING_MAX_PYRAMID 4  // storage buffer: MaxPyramidHeader, then float values[] (bake::DualMaxPyramid)
#define BINDING_ALBEDO 5       // sampler2D, RGBA8 albedo image, linear, the address mode (1x1 when none)
#define BINDING_FOAM \
  6  // sampler2D, R32F foam coverage in [0, 1] (the water material), linear, the address mode
// levels of detail 1 .. L (MapSet::levels) in one atlas each, (W / 2 + W / 4) x (H / 2) texels (W / 2
// wide with one level): level 1's (W / 2) x (H / 2) texels from (0, 0), level l >= 2's (W >> l) x (H >> l)
// stacked beside it from column W / 2, row H / 2 - (H >> (l - 1)); read with texelFetch, wrapped in the
// shader
#define BINDING_HEIGHT_LEVELS 7  // sampler2D, R32F
#define BINDING_CONE_LEVELS 8    // usampler2DArray, RG16UI, the same atlas, the cone image's layers

// FrameUniforms.flags bits
#define FLAG_WRAP 1
#define FLAG_SHADOWS 2     // self-shadowing: trace from the hit towards the light with the same method
#define FLAG_ALBEDO 4      // shade with the albedo image instead of the procedural grid
#define FLAG_WATER 8       // the water material (shading.inc.glsl) instead of the grid or albedo
#define FLAG_FOAM 16       // the water material reads foam coverage at BINDING_FOAM
#define FLAG_UNBOUNDED 32  // the plane tiled to the horizon under the sky (View::unbounded)
// The flags that choose code are also specialization constant 2 (FEATURES) of the fragment shaders,
// so that a pipeline holds no code of a feature its view does not use: lavapipe (llvmpipe) runs both
// sides of every branch under a lane mask and each loop's body at least once, so code behind a
// uniform flag that is off still costs its instructions in every pixel (a discard that empties a
// block of pixels does end it). FLAG_WRAP, FLAG_ALBEDO and FLAG_FOAM cost a read or a select each and
// stay uniforms: as constants they would multiply the pipelines to compile for next to nothing; so
// does FLAG_SHADOWS on meshes and quadrics, whose every method is drawn with and without shadows.
// FLAG_LEVELS is a pipeline feature only: a view that traces levels of detail (FrameUniforms::levels.x
// > 0) is drawn three times: by a pipeline without it for the pixels that trace level 0, by one with it
// for those that trace a coarser level, and by one with FLAG_SKY as well for the sky, which holds
// nothing but the sky. Each discards the others' pixels first, so none holds the others' reads and
// shading, and each is drawn over the rows where it has pixels only (render/pass_rows.h: lavapipe
// runs a discarded block of pixels through the rest of the shader). A view without levels draws
// its sky in its one pass.
#define FLAG_LEVELS 64
#define FLAG_SKY 128
#define FEATURE_FLAGS (FLAG_SHADOWS | FLAG_WATER | FLAG_UNBOUNDED | FLAG_LEVELS | FLAG_SKY)
#define AERIAL_DISTANCE 40.0  // world units: light from that far keeps 1/e of its colour (unbounded)
// the level a pixel traces (View::level_auto): log2 of the texels of level 0 its footprint spans where
// its ray enters the relief, across the ray times (1 / |d.z|)^LEVEL_ANISOTROPY along it (0: the
// footprint's short side, 1: its long side), plus LEVEL_BIAS (levels), rounded down
#define LEVEL_ANISOTROPY 0.75
#define LEVEL_BIAS 0.0

// the water material's sky at the horizon (shading.inc.glsl), also the background of water frames
#define SKY_HORIZON_R 0.72
#define SKY_HORIZON_G 0.80
#define SKY_HORIZON_B 0.88

// color attachments
#define ATTACHMENT_COLOR 0     // RGBA8: the shaded picture
#define ATTACHMENT_HIT 1       // RGBA32F: u, v, hit, depth
#define ATTACHMENT_COUNTERS 2  // RG32F: iterations, fetches

struct FrameUniforms {
  mat4 view_projection;
  vec4 eye;         // xyz: world position of the eye
  vec4 light;       // xyz: unit direction towards the light
  vec4 surface;     // x: tile K, y: depth scale D, z: 1 / K, w: linear filtering's weight step
                    // 2^-subTexelPrecisionBits
  vec4 map_size;    // x: W, y: H, z: 1 / W, w: 1 / H
  ivec4 counts;     // x: steps, y: refine, z: flags, w: cone sectors
  vec4 background;  // rgba of pixels off the relief
  vec4 quadric;     // x: radius R of the quadric's outer surface, yzw: unused (quadric surfaces only)
  // the camera's pixel rays (Camera::pixel_rays): the direction through gl_FragCoord (x, y) is
  // ray_corner + x ray_along_x + y ray_along_y, unnormalised (xyz; w unused)
  vec4 ray_corner;
  vec4 ray_along_x;
  vec4 ray_along_y;
  vec4 foam;  // the water material's foam: rgb colour, a intensity (View::foam_color, foam_intensity)
  // levels of detail: x the coarser levels L the view traces (0: level 0 only), y the level every
  // pixel traces (-1: from its footprint, LEVEL_ANISOTROPY), zw unused
  vec4 levels;
  // the highest height of level l = 1 .. L at level_tops[(l - 1) / 4][(l - 1) % 4]: a ray on level l
  // starts its march there (nothing of that level's surface lies above it)
  vec4 level_tops[4];
};

// The dual-grid max pyramid (bake::build_dual_max_pyramid) at BINDING_MAX_PYRAMID, std430: this
// header, then every level's node maxima as floats, row-major, level after level.
#define MAX_PYRAMID_LEVELS 24  // levels the header holds: enough for 2^23 cells per side
struct MaxPyramidHeader {
  ivec4 shape;                       // x: levels (0: no pyramid bound), y: cell origin (0 wrap, -1 clamp)
  ivec4 levels[MAX_PYRAMID_LEVELS];  // x: first value of the level, y: nodes along u, z: nodes along v
};

#ifdef __cplusplus
}  // namespace displace::render::gpu
#endif

#endif
