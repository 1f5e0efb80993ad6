// render/render.h - the Vulkan renderer. The whole public API of the render stage.
//
// Every per-pixel displacement method of render/shaders/methods.inc.glsl, side by side with a
// true-displacement reference, on the same camera and the same shading, so that differences in the
// pictures come only from the hit points.
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

#include <vulkan/vulkan_core.h>

#include <array>
#include <cstdint>
#include <functional>
#include <glm/glm.hpp>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

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

struct DeviceInfo {
  int index = 0;
  std::string name;
  std::string type;                // "discrete-gpu", "integrated-gpu", "virtual-gpu", "cpu", "other"
  int max_image_dimension_3d = 0;  // texels a side of a 3D image (the distance map)
  std::uint64_t max_storage_buffer_range = 0;  // bytes of one storage buffer (the max pyramid)
  // Linear filtering's weights are fixed point with this many fraction bits (subTexelPrecisionBits;
  // Vulkan asks for 4 at least, NVIDIA has 8): where a filtered read may be off (the distance map's
  // trilinear reads), the shaders allow for it.
  int sub_texel_precision_bits = 4;
  // The device path's lagged cone bands run on a queue of a compute-only family, beside the frame's
  // draw (RendererOptions::async_compute, and the device has such a family with timestamps)
  bool compute_queue_apart = false;
};

struct RendererOptions {
  // Empty: the best device (a discrete GPU, else an integrated one, else any, else the CPU driver).
  // Otherwise a device index or a case-insensitive part of its name.
  std::string device;
  bool validate = false;  // Khronos validation layer; every message is printed and counted
  // Where the VkPipelineCache is kept between runs: a directory; empty for the default
  // (default_pipeline_cache_dir()); "off" for none.
  std::string pipeline_cache;
  // Instance extensions a window system needs to make a surface (glfwGetRequiredInstanceExtensions).
  // Non-empty: the renderer can present (Swapchain): the device also gets VK_KHR_swapchain, and only
  // devices that have it are chosen.
  std::vector<std::string> instance_extensions;
  // With instance_extensions: whether a device's queue family can present to the caller's window
  // system (glfwGetPhysicalDevicePresentationSupport), asked before any surface exists, so that a
  // device that cannot show the window (a GPU under Xvfb) is passed over. Empty: not asked.
  std::function<bool(VkInstance, VkPhysicalDevice, std::uint32_t queue_family)> can_present;
  // Bytes of memory the guards may count on, host and device alike, when below what the machine has
  // (memory_limits()); 0: what the machine has. `memory_limit_source` names where it came from in
  // the guards' messages ("DISPLACE_MEMORY_LIMIT_MB").
  std::uint64_t memory_limit = 0;
  std::string memory_limit_source;
  // On the CPU driver (lavapipe), whose device memory is the host's: heights, foam and cone maps
  // are written by the host straight into linear images, with no staging copy (the renderer then
  // waits for frames in flight before it writes a map). Off: every map goes through the staging ring
  // and a device copy, as on a discrete GPU (the tests compare the two).
  bool host_written_maps = true;
  // The device path's lagged cone bands (DeviceCones::bake_lagged) on a queue of a compute-only
  // family where the device has one, so that a GPU runs them beside the frame's draw; off, or where
  // there is none (lavapipe), they go to the frame's own queue. The same submissions and waits either way.
  bool async_compute = true;
  // For tests, where the async queue is the frame's own: hold each async submission on the host until
  // a submission or a host wait needs it, so that it runs as late as a GPU's other queue may (on
  // lavapipe, which runs one queue in order, a wait left out then changes what a frame computes).
  bool hold_async_work = false;
};

// $DISPLACE_PIPELINE_CACHE when set ("off" turns the cache off), else $XDG_CACHE_HOME/displace,
// else $HOME/.cache/displace; "off" when none of them is set.
std::string default_pipeline_cache_dir();

// Devices the Vulkan loader sees. Throws RenderError (saying what to install) when there is none.
std::vector<DeviceInfo> list_devices();

// A height field on the CPU (the reference tracers' input and what map makers read).
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

// ---- Maps: made by the caller (bake/), handed to the renderer, which uploads them and never bakes.
//
// Every map is a view of memory the caller owns, valid for the call that hands it over (set_maps
// copies what changed). Versions: a map's `version` changes whenever its content does, and names
// that content for every map handed to this renderer (pipeline::MapMaker draws them from one
// process-wide counter); `dirty` lists the texel rectangles ([x0, x1) x [y0, y1)) that changed since
// version `dirty_since` (empty: all of it). The renderer copies only those rectangles when it holds
// version `dirty_since` of that map at the same size, and the whole map otherwise; a map whose
// version it already holds is not copied at all.

// The bilinear-surface cone map of bake::BilinearBaker / bake_bilinear_cones (apex heights with
// ratios for 1, 4 or 8 sectors), plus bake::bake_relaxed's 1-sector relaxed ratios for relaxed
// cone stepping (1 sector only).
struct ConeMapView {
  int sector_count = 0;  // 0: not given
  bake::Address address = bake::Address::wrap;
  std::span<const float> ratios;   // W x H x sector_count, interleaved (bake::ConeView)
  std::span<const float> apex;     // W x H
  std::span<const float> relaxed;  // W x H, or empty
  std::uint64_t version = 0;
  std::uint64_t dirty_since = 0;
  std::span<const bake::Rect> dirty;
  // The device path (render/device.h): the cones this renderer's DeviceCones of this sector count made
  // on the device (ratios, apex and relaxed then stay empty; address is the DeviceCones').
  bool on_device = false;
};

// bake::build_dual_max_pyramid's pyramid of the heights (maxmip, qdm).
struct MaxPyramidView {
  const bake::DualMaxPyramid* pyramid = nullptr;  // nullptr: not given
  bake::Address address = bake::Address::wrap;
  std::uint64_t version = 0;
};

// bake::bake_distance_map's distance map (sphere tracing); its size need not be the height map's.
struct DistanceMapView {
  int width = 0, height = 0, depth = 0;  // 0: not given
  bake::Address address = bake::Address::wrap;
  std::span<const float> values;  // W x H x D, bake::DistanceView's layout
  std::uint64_t version = 0;
};

inline constexpr int max_map_side = 16384;  // texels, MapSet::width and height (and Albedo's pixels)

struct MapSet {
  int width = 0, height = 0;       // of the height map and of every cone map
  std::span<const float> heights;  // W x H in [0, 1], bake conventions; every method reads them
  std::uint64_t heights_version = 0;
  std::uint64_t heights_dirty_since = 0;
  std::span<const bake::Rect> heights_dirty;
  std::array<ConeMapView, 3> cones;  // by cone_slot(sector_count): 1, 4 and 8 sectors
  MaxPyramidView max_pyramid;
  DistanceMapView distance;
  // foam coverage in [0, 1] per texel, for the water material (empty: none), with its version
  std::span<const float> foam;
  std::uint64_t foam_version = 0;
  // The device path (render/device.h): the heights, and the foam, a DeviceSim of this renderer made
  // on the device (`heights` and `foam` then stay empty; width and height are the ocean's).
  bool heights_on_device = false;
  bool foam_on_device = false;
  // Levels of detail (bake::downsample_heights; optional: without them every view traces level 0):
  // levels[l - 1] is level l = 1 .. level_count, (width >> l) x (height >> l) texels, its heights and
  // the bilinear cone map of `level_sectors` sectors baked for them with `level_address`. The chain
  // changes as a whole: a new `levels_version` copies every level.
  int level_count = 0;  // 0 .. bake::max_detail_levels
  int level_sectors = 0;
  bake::Address level_address = bake::Address::wrap;
  // The levels a DeviceLevels of this renderer makes (render/device.h; with heights_on_device): the
  // count, sectors and address must be its own, and `levels` stays empty.
  bool levels_on_device = false;
  struct Level {
    std::span<const float> heights;  // (W >> l) x (H >> l)
    std::span<const float> ratios;   // (W >> l) x (H >> l) x level_sectors, interleaved
    std::span<const float> apex;     // (W >> l) x (H >> l)
    // (W >> l) x (H >> l) x 3 (optional, water's shading): bake::downsample_moments' means of level
    // 0's gradient moments over each texel's footprint; empty: the level is shaded as if smooth
    std::span<const float> slopes;
  };
  std::array<Level, bake::max_detail_levels> levels{};
  std::uint64_t levels_version = 0;
};
int cone_slot(int sector_count);  // 0, 1, 2 for 1, 4, 8 sectors

// What a method reads for a view, from the method table: the renderer refuses a frame whose maps
// are missing (naming the map), and map makers (pipeline/maps.h) bake exactly this.
struct MapNeeds {
  int cone_sectors = 0;                              // 0: no cone map
  bool relaxed = false;                              // the cone map's relaxed layer
  bake::Address cone_address = bake::Address::wrap;  // wrap on quadrics (u closes around the axis)
  bool max_pyramid = false;
  bool distance = false;
  bake::Address address = bake::Address::wrap;  // of the pyramid and the distance map: the view's
  // the levels of detail with their cone maps of cone_sectors (MapSet::levels): an unbounded view of
  // csm, acm4, acm8 or acm4-interval whose View::level is not level_off
  bool levels = false;
};
MapNeeds map_needs(Method method, const View& view);
// Whether a method traces levels of detail on a view (map_needs' `levels`).
bool traces_levels(Method method, const View& view);

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

// ---- Memory guards (render/memory.cpp): what the renderer will allocate, estimated before it does,
// against what the machine has, so that work that cannot fit is refused with one line (what needs
// how much, what there is, what to lower) instead of running out of memory mid-way.
//
// The renderer checks itself: set_maps before it makes device maps and staging, render before it
// makes targets, readback buffers, the reference's tessellation or grows the caller's Frame. A
// caller can ask the same estimates up front (map_memory, frame_memory) and add its own (a bake's
// working memory) to refuse before any work starts.

enum class MemoryKind {
  device_local,  // device images and buffers (Vulkan, one allocation each)
  host_visible,  // staging, readback and vertex buffers the CPU writes or reads (Vulkan, one allocation each)
  host,          // ordinary process memory: vectors, bakes
};

struct Allocation {
  std::string what;  // the item, with its size: "the hit target of a 16384 x 16384 frame"
  std::uint64_t bytes = 0;
  MemoryKind kind = MemoryKind::host;
  std::string lower;  // what to lower when it does not fit: one of the lower_* names below
};

// Allocation::lower as render/ writes it: the fields of its own types, never a front end's flags (a
// CLI that shows the message maps each name to its flag: lower_frame_size to its image size flag).
inline constexpr const char* lower_frame_size = "Camera::width x Camera::height";
inline constexpr const char* lower_map_size = "MapSet::width x MapSet::height";
inline constexpr const char* lower_tile_or_map_size = "View::tile or MapSet::width x MapSet::height";

// What the machine offers. A CPU device (lavapipe) allocates from the process's own memory and
// reports a nominal heap (2 GiB on Mesa 22.3, whatever the machine has): there every byte counts
// against `host` and the heap sizes are not used.
struct MemoryLimits {
  std::string device;                // the device's name, for the messages; empty: no device (host work only)
  std::uint64_t host = 0;            // bytes of host memory available now
  std::uint64_t device_local = 0;    // bytes of the heap device-local memory comes from
  std::uint64_t host_visible = 0;    // bytes of the heap host-visible memory comes from
  bool shared_heap = false;          // both come from one heap
  bool device_is_host = false;       // a CPU device: device memory is host memory
  std::uint64_t max_allocation = 0;  // bytes of one Vulkan allocation at most (maxMemoryAllocationSize)
  std::string limited_by;            // non-empty: the limit was lowered by this (named in the messages)
};

// Host memory available now (MemAvailable of /proc/meminfo, else the free physical pages), lowered
// to `limit` bytes when that is not 0 (`source` names the limit in the messages); no device.
MemoryLimits host_memory_limits(std::uint64_t limit = 0, const std::string& source = {});

// Throws RenderError when `allocations` do not fit `limits`: one Vulkan allocation above the
// device's largest, or a sum above the memory it comes from. The message names the largest item of
// what does not fit, the bytes needed and available, and what to lower.
void check_memory(std::span<const Allocation> allocations, const MemoryLimits& limits);

// The shape of the maps handed to set_maps (MapSet's sizes; 0 sectors or depth: not given).
struct MapShape {
  int width = 0, height = 0;
  int cone_sectors = 0;
  bool relaxed = false;
  int level_count = 0;  // levels of detail (MapSet::level_count), with cone maps of level_sectors
  int level_sectors = 0;
  std::uint64_t max_pyramid_values = 0;  // floats of bake::DualMaxPyramid::values; 0: none
  int distance_width = 0, distance_height = 0, distance_depth = 0;
  bool foam = false;
};
// What set_maps allocates for maps of this shape given for the first time: device images and
// buffers, and the staging that carries them.
std::vector<Allocation> map_memory(const MapShape& shape);

// What render() allocates for its first frame of this view and method on a map_width x map_height
// map: the render targets, a readback buffer per output read back, the caller's Frame vectors, and
// for the reference its tessellation (on the CPU, then in buffers). `with_reference`: a frame of the
// reference follows (a comparison with the reference), in the other frame slot: its readback, Frame and
// tessellation too. Throws RenderError when the reference's tessellation would have more vertices
// than 32-bit indices address.
std::vector<Allocation> frame_memory(const View& view, const MethodSettings& method, int map_width,
                                     int map_height, unsigned outputs = output_all,
                                     bool with_reference = false);

// Bytes as text: "812 MB", "4.3 GB" (decimal units).
std::string memory_text(std::uint64_t bytes);

class Renderer {
 public:
  // Creates the instance, device, layouts, render pass and the per-frame resources once, and loads
  // the pipeline cache (RendererOptions::pipeline_cache).
  explicit Renderer(const RendererOptions& options = {});
  ~Renderer();  // waits for the frames in flight; saves the pipeline cache
  Renderer(Renderer&&) noexcept;
  Renderer& operator=(Renderer&&) noexcept;

  const DeviceInfo& device() const;

  // Hands over the maps (validated: sizes, finite heights in [0, 1]) and records the copies of what
  // changed into the next frame (MapSet's versions and dirty rectangles). Device images and buffers
  // are kept per map and made again only when a size changes; the staging memory is a ring, one
  // part per frame in flight. Throws RenderError for a map it cannot take.
  void set_maps(const MapSet& maps);

  // The albedo the hit is shaded with, sampled at the hit's texture coordinates (bilinear, the
  // view's address mode, repeated with the tile); its 8-bit values are used as they are (no sRGB
  // decoding). Until one is set, and after clear_albedo, a procedural grid shows the errors.
  void set_albedo(const Albedo& albedo);
  void clear_albedo();

  // The base mesh for Surface::mesh (render/mesh.h): its tangent frames and curvature are computed
  // here; throws RenderError when the mesh cannot carry a relief (see mesh_vertices).
  void set_mesh(const Mesh& mesh);

  // Renders one frame from the maps last set; a method whose maps were not given is refused with a
  // RenderError naming the map. Pipelines are made once per method and surface (through the
  // pipeline cache). `frame`'s vectors are reused (resized, not reallocated once large enough);
  // only `outputs` are read back, and with output_none the frame is not waited for.
  void render(const View& view, const MethodSettings& method, Frame& frame, unsigned outputs = output_all);
  Frame render(const View& view, const MethodSettings& method, unsigned outputs = output_all);

  // Waits until every submitted frame has finished.
  void wait_idle();

  // Validation messages seen so far (only counted with options.validate).
  long long validation_messages() const;
  // vkAllocateMemory calls so far: after warm-up frames of the same sizes, a frame allocates none.
  long long memory_allocations() const;
  // Graphics pipelines created so far (each method and surface once per renderer).
  long long pipelines_created() const;
  // Whether the height map given last is written by the host into device memory (no staging copy).
  bool host_written_maps() const;
  // The memory this renderer's device and the host offer now (RendererOptions::memory_limit applied).
  MemoryLimits memory_limits() const;

  struct Impl;

 private:
  friend class Swapchain;
  friend class DeviceSim;
  friend class DeviceCones;
  friend class DeviceLevels;
  std::unique_ptr<Impl> impl_;
};

// ---- Presenting: a window's swapchain, fed on the device from the renderer's colour target.
//
// render/ knows no window system: the caller makes the surface for the renderer's instance (the
// callback, e.g. glfwCreateWindowSurface) and the Swapchain owns it from then on. present() blits the
// colour target of the renderer's last frame (rendered with output_none: nothing is read back) into
// the next swapchain image on the same queue, after that frame. Out-of-date or suboptimal swapchains
// and size changes are handled by making the swapchain again; after the first frames of a size,
// present() allocates nothing.
using SurfaceFactory = std::function<VkSurfaceKHR(VkInstance instance)>;

class Swapchain {
 public:
  // `renderer` (made with RendererOptions::instance_extensions) must outlive the swapchain. Throws
  // RenderError when the device cannot present to the surface. vsync: FIFO; otherwise MAILBOX or
  // IMMEDIATE when offered (FIFO when not).
  Swapchain(Renderer& renderer, const SurfaceFactory& make_surface, int width, int height,
            bool vsync = false);
  ~Swapchain();  // waits for the presents in flight
  Swapchain(Swapchain&&) noexcept;
  Swapchain& operator=(Swapchain&&) noexcept;

  // Presents the renderer's last frame in a window of `width` x `height` pixels (the framebuffer
  // size now; the picture is scaled when its size differs). Returns false when nothing was shown:
  // a zero-sized (minimized) window, or a swapchain that went out of date (made again for the next
  // call).
  // With `shown`, the window's picture as presented (overlay included) is also copied back into its
  // width, height and color (RGBA8, top row first) when present() returns true, waited for; the
  // copy's buffer is allocated for the first such call of a swapchain size.
  bool present(int width, int height, Frame* shown = nullptr);
  int width() const;  // of the swapchain images
  int height() const;

  // An overlay drawn over the picture in the window by the caller's own Vulkan code (a GUI). After
  // the blit, present() records `prepare` outside any render pass (the overlay's uploads), then
  // begins overlay_render_pass over the swapchain image (the blitted picture loaded, colour
  // attachment optimal), records `draw` inside it and ends it. Both record into present()'s command
  // buffer on its thread; what they use must live until that present has finished (at most
  // frames_in_flight are in flight). An empty `draw` (the default) records no overlay pass. The
  // callbacks are only called inside present(): replacing them waits for nothing.
  struct Overlay {
    std::function<void(VkCommandBuffer commands)> prepare;
    std::function<void(VkCommandBuffer commands)> draw;
  };
  void set_overlay(Overlay overlay) noexcept;
  // What the overlay's code needs to make its own objects (Dear ImGui's ImGui_ImplVulkan_InitInfo).
  // render/ does not count those objects' memory; the queue is the renderer's: submit nothing to it
  // while a frame is being rendered or presented on another thread.
  struct Handles {
    VkInstance instance = VK_NULL_HANDLE;
    VkPhysicalDevice physical_device = VK_NULL_HANDLE;
    VkDevice device = VK_NULL_HANDLE;
    std::uint32_t queue_family = 0;
    VkQueue queue = VK_NULL_HANDLE;
    VkRenderPass overlay_render_pass = VK_NULL_HANDLE;  // one colour attachment of the swapchain's format
    std::uint32_t present_slots = frames_in_flight;     // presents in flight: buffers the overlay rotates
  };
  Handles handles() const;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

// Image error of a frame against a reference frame, over the pixels where either frame hit the
// relief, in 8-bit output units (each channel of RGB counted; a pixel where only one frame hit
// counts its full difference against the background). Both frames need their colour and uv read
// back (throws RenderError otherwise).
struct ImageError {
  double rmse = 0.0;
  double max_error = 0.0;
  double fraction_over_10 = 0.0;  // pixels with any channel off by more than 10
  long long pixels = 0;
};
ImageError compare(const Frame& frame, const Frame& reference);

// The exact ray-height-field intersection on the CPU (a cell-by-cell walk of the bilinear surface,
// solving the quadratic in each cell) for the plane, for tests: the texture coordinates (u, v, h) of the
// first hit of the ray through pixel (px, py), or hit = false when the ray misses the relief of the [0,
// tile]^2 patch.
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
