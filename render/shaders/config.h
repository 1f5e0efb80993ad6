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
#define METHOD_CSM 8
#define METHOD_ACM4 9
#define METHOD_ACM8 10
#define METHOD_ACM4_INTERVAL 11
#define METHOD_RELAXED 12
#define METHOD_REFERENCE 15

// descriptor bindings (set 0)
#define BINDING_FRAME 0    // uniform FrameUniforms
#define BINDING_HEIGHT 1   // sampler2D, R32F heights, linear, the address mode
#define BINDING_CONES 2    // sampler2DArray, RG32F: layer k = (ratio of sector k, apex height), nearest

// FrameUniforms.flags bits
#define FLAG_WRAP 1

// color attachments
#define ATTACHMENT_COLOR 0     // RGBA8: the shaded picture
#define ATTACHMENT_HIT 1       // RGBA32F: u, v, hit, depth
#define ATTACHMENT_COUNTERS 2  // RG32F: iterations, fetches

struct FrameUniforms {
  mat4 view_projection;
  vec4 eye;          // xyz: world position of the eye
  vec4 light;        // xyz: unit direction towards the light
  vec4 surface;      // x: tile K, y: depth scale D, z: 1 / K, w: unused
  vec4 map_size;     // x: W, y: H, z: 1 / W, w: 1 / H
  ivec4 counts;      // x: steps, y: refine, z: flags, w: cone sectors
  vec4 background;   // rgba of pixels off the relief
};

#ifdef __cplusplus
}  // namespace displace::render::gpu
#endif

#endif
