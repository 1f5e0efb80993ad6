// render/render.h - the Vulkan renderer. The whole public API of the render stage.
//
// Every per-pixel displacement method of render/shaders/methods.inc.glsl, side by side with a
// true-displacement reference, on the same camera and the same shading, so that differences in the
// pictures come only from the hit points.
//
// Geometry and camera (normative: the tests and the README use exactly these)
// - World is z-up. The plane surface covers world x in [0, 1] (texture u) and y in [0, 1] (texture v);
//   `tile` K repeats the texture K times over it, so texture coordinates run over [0, K].
// - The base polygon is the TOP of the relief: height 1 lies on the polygon (z = 0), height 0 lies
//   `depth_scale` D below it. Heights are bilinearly interpolated between texel centres with the
//   bake's address mode (bake/bake.h has the texel conventions).
// - The camera looks from `eye` at `look_at`, `up` gives the image's up direction, `fov_y_degrees` is
//   the full vertical field of view. Pixel (px, py) is sampled at its centre; image row 0 is the top.
// - Methods trace in texture space (u, v, h): a world direction d becomes (du, dv, dh) through the
//   tangent frame (dP/du, dP/dv, D * N), so that ray parameters are world distances.
// - Shading is the same for every method: a procedural grid albedo, Lambert + Blinn-Phong with one
//   directional light, the normal taken from the height field at the hit.
//
// Quadric surfaces (View::surface; Patterson, Hoggar & Logie, "Inverse Displacement Mapping", 1991).
// R = View::radius, D = depth_scale, K = tile. Every quadric's axis is the vertical line
// x = y = 0.5; u = K phi / (2 pi) with phi = atan2(y - 0.5, x - 0.5) in [0, 2 pi) (u wraps around the
// axis). The outer surface is height 1 (the base surface, as the plane's polygon is); a point at
// height h lies (1 - h) D inward along the outer surface's normal from its foot point (u, v).
// - sphere: centre (0.5, 0.5, 0), radius R; v = K theta / pi, theta the angle from the -z pole (the
//   south pole is v = 0, the north pole v = K). The inner surface is the sphere of radius R - D.
// - cylinder: radius R, z in [-R, R]; v = K (z + R) / (2 R). Inner surface: radius R - D.
// - cone: apex (0.5, 0.5, 1.5 R), half-angle atan(1/2) (radius (1.5 R - z) / 2), from z = -R/2
//   (radius R) up to z = R/2 (radius R/2); v = K (z + R/2) / R of the foot point. The inner surface
//   is the same cone with its apex D / sin(half-angle) lower.
// - (dP/du, dP/dv, N) is right-handed with N outward, like (x, y, z) on the plane, so v grows with z.
// - The relief is seen through the outer surface only: a ray is traced from where it enters the
//   outer surface (the eye must be outside the quadric), and only if it enters within the finite
//   part (v in [0, K]); its hit must stay in that part (caps are not drawn). It ends where it enters
//   the inner surface (it has hit the relief by then) or leaves the outer one (a miss).
// - Address modes: u always wraps around the axis; --address clamp clamps v only (each pole of the
//   sphere, each end of the cylinder and cone takes its edge row). Cone maps are baked with wrap
//   for quadrics, which is conservative for a clamped v as well.
// - D must be at most R / 2. Methods that do not support quadrics are refused (supports_surface).
// - `reference` on a quadric is the height field tessellated at one vertex per texel centre (plus
//   the seam and the poles), displaced along the normal and rasterized: the tessellated surface
//   itself, without the plane reference's snap to the bilinear surface.
// - Shadows: the light ray from the hit is searched with the frame's method from where it leaves the
//   outer surface back to the hit; passing through the inner solid is a shadow too (the terminator).
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include <glm/glm.hpp>

#include "bake/bake.h"
#include "render/mesh.h"

namespace displace::render {

// What the environment or the caller got wrong: no Vulkan device, a failed Vulkan call, bad input.
struct RenderError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

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
const char* surface_name(Surface surface);  // the --surface word

struct MethodInfo {
  Method method;
  const char* name;   // the --method word
  int shader_id;      // METHOD_* in render/shaders/config.h
  MethodFamily family;
  int cone_sectors;   // 0: the method reads no cone map
  bool exact_class;   // converges to the true hit as steps grow
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

struct Camera {
  glm::vec3 eye{0.5f, -0.35f, 0.75f};
  glm::vec3 look_at{0.5f, 0.45f, -0.05f};
  glm::vec3 up{0.0f, 0.0f, 1.0f};
  float fov_y_degrees = 45.0f;
  int width = 512;
  int height = 512;

  // Throws RenderError when the camera is degenerate (eye at look_at, up parallel to the view, bad fov).
  void validate() const;
  // Vulkan clip space: depth in [0, 1], y down (row 0 of the image is the top).
  glm::mat4 view_projection(float near_plane, float far_plane) const;
  // The world-space ray through pixel (px, py) (pixel centres at +0.5).
  Ray pixel_ray(double px, double py) const;
};

struct View {
  Camera camera;
  int tile = 1;                  // texture repeats over the plane; > 1 needs Address::wrap
  float depth_scale = 0.1f;      // world units between height 1 and height 0
  bake::Address address = bake::Address::wrap;
  glm::vec3 light_direction{0.35f, 0.25f, 1.0f};  // towards the light; normalized when used
  Surface surface = Surface::plane;
  float radius = 0.25f;  // the quadric's outer radius R, world units (quadrics only)
  bool shadows = false;          // self-shadowing, traced towards the light with the frame's method
};

struct MethodSettings {
  Method method = Method::relief;
  int steps = 32;   // linear-search steps, the maximum number of cone steps, or iterations
  int refine = 8;   // binary or secant refinement steps after the search
};

// One rendered frame read back to the CPU. Row 0 is the top of the image.
struct Frame {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> color;  // RGBA8, 4 per pixel
  std::vector<float> uv;            // u, v, hit: 3 per pixel; u, v unwrapped in [0, tile]; 0, 0, 0 off the relief
  std::vector<float> depth;         // world distance from the eye to the hit; 0 off the relief
  std::vector<float> iterations;    // search-loop iterations per pixel
  std::vector<float> fetches;       // height and cone texture reads per pixel
  double gpu_milliseconds = 0.0;    // the draw, from GPU timestamps (0 when the device has none)
};

struct DeviceInfo {
  int index = 0;
  std::string name;
  std::string type;  // "discrete-gpu", "integrated-gpu", "virtual-gpu", "cpu", "other"
};

struct RendererOptions {
  // Empty: the best device (a discrete GPU, else an integrated one, else any, else the CPU driver).
  // Otherwise a device index or a case-insensitive part of its name.
  std::string device;
  bool validate = false;  // Khronos validation layer; every message is printed and counted
};

// Devices the Vulkan loader sees. Throws RenderError (saying what to install) when there is none.
std::vector<DeviceInfo> list_devices();

// The baked maps a method needs, made from the heights with the foundation's bakers.
struct HeightField {
  int width = 0;
  int height = 0;
  std::vector<float> heights;  // [0, 1], row-major, bake conventions
};

// An RGBA8 image, row-major, row 0 at v = 0 (like the heights).
struct Albedo {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> rgba;
};

class Renderer {
 public:
  // Creates the instance, device, descriptor layouts and render targets' layouts once.
  explicit Renderer(const RendererOptions& options = {});
  ~Renderer();
  Renderer(Renderer&&) noexcept;
  Renderer& operator=(Renderer&&) noexcept;

  const DeviceInfo& device() const;

  // Sets the heights (validated like the bakers do). Maps are baked the first time a method needs
  // them - cone maps for the bilinear surface (bake::BilinearBaker within `cone_budget`; relaxed
  // adds bake::bake_relaxed's 1-sector ratios to them), the dual max pyramid, bake_distance_map's
  // distance map - and kept until the heights change. The cone maps are conservative at any
  // budget, so a starved bake (0 ms) costs cone steps, never a wrong hit; unlimited by default.
  void set_height_field(const HeightField& field, const bake::Budget& cone_budget = {});

  // The albedo the hit is shaded with, sampled at the hit's texture coordinates (bilinear, the
  // view's address mode, repeated with the tile); its 8-bit values are used as they are (no sRGB
  // decoding). Until one is set, and after clear_albedo, a procedural grid shows the errors.
  void set_albedo(const Albedo& albedo);
  void clear_albedo();

  // The base mesh for Surface::mesh (render/mesh.h): its tangent frames and curvature are computed
  // here; throws RenderError when the mesh cannot carry a relief (see mesh_vertices).
  void set_mesh(const Mesh& mesh);

  // Renders one frame; pipelines are made once per method and kept.
  Frame render(const View& view, const MethodSettings& method);

  // Validation messages seen so far (only counted with options.validate).
  long long validation_messages() const;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

// Image error of a frame against a reference frame, over the pixels the reference hit, in 8-bit
// output units (each channel of RGB counted; a pixel where only one frame hit counts its full
// difference against the background).
struct ImageError {
  double rmse = 0.0;
  double max_error = 0.0;
  double fraction_over_10 = 0.0;  // pixels with any channel off by more than 10
  long long pixels = 0;
};
ImageError compare(const Frame& frame, const Frame& reference);

// The exact ray-height-field intersection on the CPU (a cell-by-cell walk of the bilinear surface,
// solving the quadratic in each cell) for the plane, for tests: the texture coordinates (u, v, h) of the first hit of the ray
// through pixel (px, py), or hit = false when the ray misses the relief of the [0, tile]^2 patch.
struct CpuHit {
  bool hit = false;
  glm::dvec3 texture;  // u, v, h
  double distance = 0.0;
};
CpuHit cpu_trace(const HeightField& field, const View& view, double px, double py);
// The same exact intersection on a quadric surface (View::surface other than plane): march the
// bilinear surface from where the ray enters the outer surface in steps of at most 1/32 of a
// texel of (u, v) travel, then bisect; the texture point is (u, v, h), distance the world distance.
CpuHit cpu_trace_quadric(const HeightField& field, const View& view, double px, double py);
// The bilinear height the renderer samples at texture coordinates (u, v) (texel centres at
// (j + 0.5) / W), with the address mode.
double bilinear_height(const HeightField& field, bake::Address address, double u, double v);
// The smallest s in [0, 1] where the ray p(s) = origin + s * descent (texture space, descent.z = -1,
// origin inside the [0, tile]^2 patch) is at or below the bilinear surface; where the ray leaves the
// patch first, an s whose point lies outside the patch. Exact up to double rounding.
double first_crossing(const HeightField& field, bake::Address address, double tile, const glm::dvec3& origin,
                      const glm::dvec3& descent);

}  // namespace displace::render
