// pipeline/scene.h - what a frame pipeline renders, as typed settings: the source of the heights,
// the camera (with optional keyframes), the method, time and the frame budget. Scene files are TOML
// (read with toml++); every key has a default, and unknown keys or bad values are refused with the
// file, line and key. Parsing lives here; the pipeline only takes the typed Scene.
#pragma once

#include <array>
#include <filesystem>
#include <glm/glm.hpp>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "bake/device/first_pass.h"
#include "render/view.h"
#include "sim/sim.h"
#include "vulkan/device_info.h"

namespace displace::pipeline {

// A scene the user got wrong: a missing or malformed file, an unknown key, a bad value.
struct SceneError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

enum class SourceKind { ocean, sinusoids, bricks, cliff, image };

// Limits of the scene's keys (the scene reader's and the command line's; the sources' own limits
// are sim.h's, the view's render.h's).
inline constexpr int min_map_size = 2;                    // [source] map_size, texels a side
inline constexpr int max_map_size = sim::max_ocean_size;  // (even for the ocean)
inline constexpr double max_abs_time = 1e12;              // seconds: [time] start, keyframe times
inline constexpr double max_fps = 10000.0;                // [time] fps, from 1e-3
inline constexpr double max_direction_degrees = 360.0;    // wind_direction, either way
inline constexpr float min_steepness = 1e-3f;             // [sinusoids] steepness, to sim::max_steepness
inline constexpr double max_frame_ms = 1e9;               // [budget] frame_ms, about 11 days
inline constexpr long long max_bake_work = 1ll << 40;     // [budget] bake_work, texels a frame
inline constexpr int max_cone_lag_frames = 64;            // [budget] cone_lag_frames
inline constexpr double max_foam_coverage = 2.0;          // [material] foam_coverage, a Jacobian, from 0

// How a height image is read ([source] channel, invert, height_range; kind = "image").
struct ImageRead {
  std::string channel;  // a name or an index; empty: `height`, or the only grey one
  bool invert = false;  // the image stores depth (1 = deepest)
  std::optional<std::array<float, 2>> height_range;  // float images: the raw values that map to 0 and 1
};

// The camera at scene time `time` (seconds): eye and look-at point, world units.
struct CameraKey {
  double time = 0.0;
  glm::vec3 eye{0.0f};
  glm::vec3 look_at{0.0f};
};

inline sim::OceanParams calm_ocean() {
  sim::OceanParams params;
  params.choppiness = 0.0f;
  return params;
}

// Where a stage runs ([backend] sim and bake): `automatic` is the device on a GPU and the CPU on the
// CPU driver (lavapipe), where the device path only moves the CPU's work into the driver.
enum class Backend { automatic, cpu, device };
const char* backend_word(Backend backend);  // "auto", "cpu", "device"
// The scene file's words for the ocean's spectra and spreading models ([ocean] spectrum and
// spreading_model: "pierson-moskowitz", "donelan-banner", ...), in the order the docs list them.
std::vector<sim::Spectrum> ocean_spectra();
std::vector<sim::Spreading> spreading_models();
std::string_view spectrum_word(sim::Spectrum spectrum);
std::string_view spreading_word(sim::Spreading model);
// Whether a stage set to `backend` runs on the device of `device`.
bool runs_on_device(Backend backend, const vulkan::DeviceInfo& device);
// runs_on_device for the device a default Renderer picks (render::default_device), for a program
// that has made no renderer yet: "auto" runs on it where it is not a CPU driver; with no device at
// all, false (the renderer that cannot be made says why, where one is needed). Vulkan is asked once
// a process.
bool runs_on_default_device(Backend backend);

struct Scene {
  std::string name = "scene";

  // [source]
  SourceKind source = SourceKind::ocean;
  int map_size = 256;      // height map texels a side
  std::uint64_t seed = 1;  // bricks and cliff roughness
  // kind = "image": a height image, or a numbered sequence where each run of '#' in the file name
  // is frame n zero-padded to that many digits (heights_####.exr: frame 7 reads heights_0007.exr);
  // relative to the scene file. The map size is the image's. Read by the application's loader.
  std::filesystem::path image;
  ImageRead image_read;
  // [ocean]; size is map_size. Choppy crests (and foam) only where a scene asks: choppiness 0 by default
  sim::OceanParams ocean = calm_ocean();
  sim::SinusoidParams sinusoids;  // [sinusoids]

  // [camera]: eye, look_at, up, fov_y; keyframes override eye and look_at over time
  render::Camera camera;
  std::vector<CameraKey> keyframes;  // sorted by time

  // [material]: kind = "grid" | "albedo" | "water"; foam (water only) shows where the choppy
  // surface folds; albedo = an image the hit is shaded with (kind = "albedo"; relative to the file)
  render::Material material = render::Material::grid;
  bool foam = false;
  // foam where the choppy surface's Jacobian falls below foam_coverage (full foam 0.4 below it: a
  // higher value covers more of the sea), drawn in foam_color (linear RGB) times foam_intensity
  float foam_coverage = 0.85f;
  glm::vec3 foam_color{0.92f, 0.95f, 0.96f};
  float foam_intensity = 1.0f;
  std::filesystem::path albedo;

  // [render]
  render::Method method = render::Method::acm4;
  int steps = 32;
  int refine = 8;
  render::Surface surface = render::Surface::plane;
  std::filesystem::path mesh;                   // surface = mesh: an OBJ file (relative to the file)
  float radius = 0.25f;                         // the quadric's outer radius, world units
  bake::Address address = bake::Address::wrap;  // how the map continues past its edges
  bool shadows = false;
  glm::vec3 light{0.35f, 0.25f, 1.0f};  // towards the light (the sun); normalized when used
  float depth_scale = 0.1f;
  int tile = 1;
  // extent = "unbounded": the plane tiled to the horizon under the sky (render::View::unbounded; the
  // water scenes), or "patch": the one patch (every other scene, and every accuracy comparison)
  bool unbounded = false;

  // [time]: frame n is shown at start + n / fps
  double start = 0.0;  // seconds
  double fps = 60.0;

  // [budget]: the frame budget the bake's share is taken from (milliseconds; infinity: unlimited),
  // and a work budget for the bake (texels searched per frame; -1: none) that keeps frames
  // reproducible where a wall-clock budget cannot.
  double frame_ms = std::numeric_limits<double>::infinity();
  long long bake_work = -1;
  float tolerance = 0.25f;  // the bake's refinement tolerance
  // With a frame budget (real time) and heights that change: frames a cone map's first stage may
  // spread over after the one it begins on, while the last map is served with raised apexes
  // (FramePipeline's lagged maps); 0: every frame makes its own.
  int cone_lag_frames = 0;  // 0 .. max_cone_lag_frames
  // With cone_lag_frames = 1 and the sim and the bake on the device: each frame begins the next
  // frame's map from heights simulated at the next frame's time (start + 1 / fps on), baked beside
  // its draw, so that every frame samples a map of its own heights, raised by a lift of about 0.
  bool cone_ahead = false;

  // [backend]: where the sim and the cone bake run. The sim's backend applies to the moving sources
  // (ocean, sinusoids); static ones (bricks, cliff, images) are made or read once on the CPU.
  Backend sim_backend = Backend::automatic;
  Backend bake_backend = Backend::automatic;
  // How the device's cone bake makes its first pass (bake::DeviceFirstPass): ring_radius 0
  // searches the pyramid, r > 0 bounds rings of nodes (2 by default), group by 8 x 8 texel groups
  // (with ring_radius 0); window_radius cells around each texel are bounded by the slope window.
  // [backend] device_rings, device_window and device_group.
  bake::DeviceFirstPass device_first_pass{};
};

// Where a scene's stages run on `device`, decided once for a pipeline or a command (the one place
// `auto` is resolved): the sim on the device for the ocean and sinusoids; the bilinear cone bake there
// (not a relaxed layer) from a device sim's heights or a static map's; the levels of detail with a
// device sim's heights, whichever bakes level 0. Throws SceneError for a device bake of moving heights
// made on the CPU.
struct Placement {
  bool sim_on_device = false;
  bool cones_on_device = false;
  bool levels_on_device = false;
  bool heights_to_cpu = true;  // the host's maps read the heights (a device sim then reads them back)
  // A stage on the device records into the renderer's next frame: its frames run on the render thread.
  bool records_into_frame() const { return sim_on_device || cones_on_device; }
};
Placement place_stages(const Scene& scene, const vulkan::DeviceInfo& device);

// The image file of frame n (SourceKind::image): each run of '#' replaced by n, zero-padded.
std::filesystem::path image_for_frame(const std::filesystem::path& pattern, long long frame_index);
bool is_image_sequence(const std::filesystem::path& pattern);

// Frame n's scene time, in double: start + n / fps; with an ocean loop of T seconds that holds a whole
// number N = T fps of frames (loop_frames), start + (n mod N) / fps, so that frames n and n + N are
// the same frame (the sea and the camera alike).
double frame_time(const Scene& scene, long long frame_index);
long long loop_frames(const Scene& scene);  // N, or 0: no loop (or T fps not a whole number)
// The view of frame time `time` (the keyframes interpolated with a cubic Hermite spline through
// every key, tangents from the neighbouring keys; held before the first and after the last).
render::View scene_view(const Scene& scene, double time);

// Built-in scenes: "water" (a fully developed sea in an 11 m/s wind, Pierson-Moskowitz, with choppy
// crests resampled onto the grid, foam, the water material), "calm" (the same sea with choppiness 0 and
// no foam), "storm" (Beaufort 9, fully developed, deep), "harbour" (6 m deep: a short-fetch TMA sea and a
// swell), "ripples" (sinusoids, water material), "ocean" (the default Phillips ocean on the grid),
// "bricks", "cliff" (static maps, the grid).
std::vector<std::string> builtin_scene_names();
Scene builtin_scene(std::string_view name);  // throws SceneError naming the built-ins

// Reads a scene file (named after the file when it has no name key); throws SceneError
// "FILE:LINE: KEY: what is wrong".
Scene read_scene_file(const std::filesystem::path& file);
Scene parse_scene(std::string_view toml_text, const std::string& source_name);
// The keys of `toml_text` over `base` (a built-in scene or a file's): what a command line's flags
// do to a scene. The same checks as a file's; `source_name` names the text in errors.
Scene apply_scene(const Scene& base, std::string_view toml_text, const std::string& source_name);
// The scene as a TOML file that read_scene_file reads back to the same Scene.
std::string scene_toml(const Scene& scene);

}  // namespace displace::pipeline
