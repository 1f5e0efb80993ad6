// render/view.h - what a frame shows and how: the per-pixel methods and their table, the camera, the
// view (surface, tiling, material, the unbounded plane, levels), a method's settings and the frame
// read back. Plain values, no Vulkan: a scene (pipeline/scene.h) describes a view without the
// renderer, which draws it (render/render.h).
//
// Geometry and camera (normative; in full, with shading and the quadric surfaces of View::surface:
// docs/design/conventions.md#renderrenderh-the-renderers-geometry)
// - World is z-up; the plane covers x, y in [0, 1] (texture u, v), `tile` K repeats the texture K
//   times. Height 1 lies on the base polygon (z = 0), height 0 `depth_scale` D below; heights are
//   bilinear between texel centres with the bake's address mode (bake/bake.h).
// - The camera looks from `eye` at `look_at`, `up` gives the image's up, `fov_y_degrees` the full
//   vertical field of view; pixels are sampled at their centres, image row 0 is the top.
// - Methods trace in texture space (u, v, h) through the tangent frame (dP/du, dP/dv, D * N), so ray
//   parameters are world distances.
#pragma once

#include <cstdint>
#include <glm/glm.hpp>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "bake/bake.h"
#include "vulkan/error.h"

namespace displace::render {

// What the environment or the caller got wrong: no Vulkan device, a failed Vulkan call, bad input
// (the error every device layer throws, vulkan/error.h).
using RenderError = vulkan::Error;

enum class Method {
  bump,
  parallax,
  parallax_limited,
  parallax_slope,
  pom,
  relief,
  interval,
  csm,
  acm4,
  acm8,
  acm4_interval,
  relaxed,
  maxmip,
  qdm,
  sphere,
  reference,
};

enum class MethodFamily {
  surface,        // no search: bump and the parallax family (one formula per pixel, or a few iterations)
  linear_search,  // fixed steps along the ray, then a refinement
  cone,           // steps bounded by a cone map
  pyramid,        // traversal of the dual-grid max pyramid (bake::build_dual_max_pyramid)
  distance,       // steps bounded by a 3D distance map (sphere tracing)
  reference,      // the tessellated height field, rasterized
};

enum class Surface { plane, sphere, cylinder, cone, mesh };
inline bool is_quadric(Surface surface) {
  return surface == Surface::sphere || surface == Surface::cylinder || surface == Surface::cone;
}
const char* surface_name(Surface surface);  // "plane", "sphere", ...: the name a caller shows

struct MethodInfo {
  Method method;
  const char* name;  // the method's name ("relief", "acm4"), the word a caller spells it with
  int shader_id;     // METHOD_* in render/shaders/config.h
  MethodFamily family;
  int cone_sectors;            // 0: the method reads no cone map
  bool exact_class;            // converges to the true hit as steps grow
  bool relaxed_cones = false;  // a relaxed ratio layer (bake::bake_relaxed) follows the bilinear cones
};

// The method table: one row per Method enumerator, in display order.
std::span<const MethodInfo> method_table();
const MethodInfo& method_info(Method method);
const MethodInfo* find_method(std::string_view name);  // nullptr when unknown
// Whether a method renders on a surface: every method on the plane; bump, pom, relief, interval,
// csm, acm4, acm8, acm4-interval and reference on the quadrics.
bool supports_surface(Method method, Surface surface);

struct Ray {
  glm::dvec3 origin;
  glm::dvec3 direction;  // unit length
};

// Limits Camera::validate checks (a front end bounds its own input with these too).
inline constexpr int max_image_side = 16384;       // pixels, Camera::width and Camera::height
inline constexpr float min_fov_y_degrees = 0.01f;  // degrees, Camera::fov_y_degrees
inline constexpr float max_fov_y_degrees = 179.0f;

struct Camera {
  glm::vec3 eye{0.5f, -0.35f, 0.75f};
  glm::vec3 look_at{0.5f, 0.45f, -0.05f};
  glm::vec3 up{0.0f, 0.0f, 1.0f};
  float fov_y_degrees = 45.0f;
  int width = 512;
  int height = 512;

  // Throws RenderError, naming the field, when the camera is degenerate: a size or fov_y_degrees outside
  // the limits above, eye at look_at, up zero or parallel to the view.
  void validate() const;
  // Vulkan clip space: depth in [0, 1], y down (row 0 of the image is the top).
  glm::mat4 view_projection(float near_plane, float far_plane) const;
  // The world-space ray through pixel (px, py) (pixel centres at +0.5).
  Ray pixel_ray(double px, double py) const;
  // That ray's direction before normalisation is corner + px * along_x + py * along_y. The fragment
  // shader builds every method's ray from the same three vectors and gl_FragCoord, so that a pixel
  // traces this ray and not one from interpolated vertex attributes (on an NVIDIA H200 those were
  // off by about 1e-5, which moved grazing hits by a thousandth of a texel and more).
  struct PixelRays {
    glm::dvec3 corner, along_x, along_y;
  };
  PixelRays pixel_rays() const;
};

// How a hit is shaded: the procedural grid (or the albedo image, Renderer::set_albedo), or water:
// the sky reflected with Fresnel's law, sun glint, light scattered from the water body (darker over
// deeper water) and foam where MapSet::foam says so.
enum class Material { grid, water };

// Limits render() checks on a View (quadric::validate for the radius), the same for every caller.
inline constexpr int max_tile = 64;                  // View::tile, texture repeats, from 1
inline constexpr float min_depth_scale = 1e-4f;      // world units, View::depth_scale
inline constexpr float max_depth_scale = 10.0f;      // world units
inline constexpr float min_radius = 0.01f;           // world units, View::radius (quadrics)
inline constexpr float max_radius = 10.0f;           // world units
inline constexpr float max_depth_per_radius = 0.5f;  // View::depth_scale / View::radius on quadrics

struct View {
  Camera camera;
  Material material = Material::grid;
  int tile = 1;              // texture repeats over the plane; > 1 needs Address::wrap
  float depth_scale = 0.1f;  // world units between height 1 and height 0
  bake::Address address = bake::Address::wrap;
  glm::vec3 light_direction{0.35f, 0.25f, 1.0f};  // towards the light; normalized when used
  Surface surface = Surface::plane;
  float radius = 0.25f;  // the quadric's outer radius R, world units (quadrics only)
  bool shadows = false;  // self-shadowing, traced towards the light with the frame's method
  // the water material's foam (MapSet::foam): its colour (linear RGB in [0, 1]) and how much of it
  // covers a texel of full coverage (0: none shows)
  glm::vec3 foam_color{0.92f, 0.95f, 0.96f};
  float foam_intensity = 1.0f;
  // The plane without edges: the map tiled in every direction to the horizon (wrap, the plane, a method
  // other than the reference), under a sky with a gradient and the sun, with aerial perspective
  // towards the horizon. Every pixel whose ray points below the horizon hits the relief.
  bool unbounded = false;
  // Levels of detail (MapSet::levels; unbounded views of the cone methods csm, acm4, acm8 and
  // acm4-interval only, every other view traces level 0): level_auto picks each pixel's level from
  // its footprint where its ray enters the relief; a level >= 0 traces that level (at most the
  // coarsest given) for every pixel; level_off (0) traces level 0 only, as without levels.
  int level = level_auto;
  static constexpr int level_auto = -1;
  static constexpr int level_off = 0;
};

inline constexpr int max_steps = 4096;  // MethodSettings::steps, from 1
inline constexpr int max_refine = 64;   // MethodSettings::refine, from 0

struct MethodSettings {
  Method method = Method::relief;
  int steps = 32;  // linear-search steps, the maximum number of cone steps, or iterations
  int refine = 8;  // binary or secant refinement steps after the search
};

// One rendered frame read back to the CPU. Row 0 is the top of the image.
struct Frame {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> color;  // RGBA8, 4 per pixel
  std::vector<float> uv;     // u, v, hit: 3 per pixel; u, v unwrapped in [0, tile]; 0, 0, 0 off the relief
  std::vector<float> depth;  // world distance from the eye to the hit; 0 off the relief
  std::vector<float> iterations;  // search-loop iterations per pixel
  std::vector<float> fetches;     // height and cone texture reads per pixel
  double gpu_milliseconds = 0.0;  // the draw, from GPU timestamps (0 when the device has none)
};

// Which per-pixel outputs a frame reads back (Frame's vectors; the others stay empty). None: the
// frame is submitted and not waited for (at most frames_in_flight frames are in flight).
enum Output : unsigned {
  output_none = 0,
  output_color = 1u << 0,
  output_uv = 1u << 1,
  output_depth = 1u << 2,
  output_iterations = 1u << 3,
  output_fetches = 1u << 4,
  output_all = 31u,
};
inline constexpr int frames_in_flight = 2;

}  // namespace displace::render
