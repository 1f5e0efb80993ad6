// demos/options.h - the `displace` command line, parsed into typed settings.
//
// This is the only place that looks at argv strings: each command's flags are declared to CLI11
// with their limits (shown by `displace COMMAND --help`), checked there (unknown flags, missing
// values, bad or absurd numbers, flags that do not go together) and become typed values; the
// commands take these structs.
//
// Exit status, one rule for every command: 2 (AppError of kind usage) when the command line alone is
// wrong and changing it fixes it: an unknown flag, a missing or bad value, a value outside the
// flag's limits, flags that do not go together, or a flag that does not fit its input (--height-range
// on an integer image, --channel naming no channel of it, --map-size on an image scene); 1 (kind
// runtime) when the problem lies outside the command line: a file that is missing, unreadable,
// truncated or malformed (images, meshes, scene files of either kind: their content is a file's, not
// the command line's), an output that cannot be written, no Vulkan device, a bake or render that
// fails, or work that needs more memory than the machine has.
#pragma once

#include <cstdint>
#include <filesystem>
#include <limits>
#include <span>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "bake/bake.h"
#include "demos/cone_export.h"
#include "demos/image_io.h"
#include "pipeline/scene.h"
#include "render/render.h"
#include "sim/sim.h"

namespace displace::app {

enum class SourceKind { ocean, sinusoids, bricks, cliff };

// A synthesized height field: `size` x `size` samples at `time` (--map-size, --time).
struct SourceSettings {
  SourceKind kind = SourceKind::ocean;
  int size = 0;                   // samples along u and along v
  double time = 0.0;              // seconds
  sim::OceanParams ocean;         // kind == ocean; ocean.size == size
  sim::SinusoidParams sinusoids;  // kind == sinusoids
  std::uint64_t seed = 1;         // kind == bricks or cliff
};

// A height image on disk and how to read it.
struct FileInput {
  std::filesystem::path path;
  HeightLoadSettings load;
};

enum class ImageFormat { exr, png };

// `--help`: `text` is one command's help (its flags and their limits); empty: the overview
// (usage_text() in commands.h).
struct HelpSettings {
  std::string text;
};

struct SimSettings {
  SourceSettings source;
  std::filesystem::path output;  // .exr
};

struct BakeSettings {
  std::variant<FileInput, SourceSettings> input;
  int sector_count = 4;
  ConeKind cones = ConeKind::center;  // bilinear: Baker::budgeted or Baker::full
  Baker baker = Baker::budgeted;
  double budget_milliseconds = std::numeric_limits<double>::infinity();  // budgeted only (0 allowed)
  float tolerance = 0.25f;  // budgeted only: refine while a ratio may be more than this fraction below exact
  bake::Address address = bake::Address::wrap;
  std::filesystem::path output;
  ImageFormat output_format = ImageFormat::exr;
  bool stats = false;  // one JSON line on stdout instead of the human line
};

struct DemoSettings {
  int map_size = 512;  // ocean samples along u and v
  std::filesystem::path output_directory = "out";
};

// An arbitrary output variable written next to the picture: uv, depth, iterations or fetches.
enum class Aov { uv, depth, iterations, fetches };
struct AovOutput {
  Aov aov = Aov::uv;
  std::filesystem::path file;  // uv and depth: .exr; iterations and fetches: .exr (raw) or .png (heatmap)
};

struct RenderSettings {
  std::variant<FileInput, SourceSettings> input;
  render::View view;
  render::MethodSettings method;
  std::filesystem::path output;  // .png or .exr
  std::vector<AovOutput> aovs;
  std::filesystem::path albedo;  // empty: the procedural grid
  std::filesystem::path mesh;    // --surface mesh:FILE.obj
  bool compare_reference = false;
  // the milliseconds and tolerance of the cone maps' bake (bake::BilinearBaker; unlimited by
  // default), for the methods that read cone maps
  bake::Budget cone_budget;
  render::RendererOptions renderer;
};

// One scene of a sweep: the heights and the view (the render flags without method and outputs).
struct SceneSettings {
  std::string name;
  std::variant<FileInput, SourceSettings> input;
  render::View view;
  std::filesystem::path albedo;  // empty: the procedural grid
  std::filesystem::path mesh;    // --surface mesh:FILE.obj
};

struct SweepSettings {
  std::vector<SceneSettings> scenes;
  std::vector<render::Method> methods;
  std::vector<int> steps;
  int refine = 8;
  int repeat = 3;                // renders per row; the row reports the median device time
  std::filesystem::path output;  // .csv
  bake::Budget cone_budget;      // the cone methods' maps, as RenderSettings' cone_budget
  render::RendererOptions renderer;
};

// The built-in scenes of `displace sweep`: bricks, ocean and cliff.
SceneSettings builtin_scene(std::string_view name);
// A scene file: one render flag per line ("--source ocean", "--map-size 256", "--eye 0.5,-0.3,0.6"),
// '#' starts a comment. Throws AppError of kind runtime naming the file (and the line where it
// helps) when it cannot be read or describes no scene.
SceneSettings read_scene_file(const std::filesystem::path& file);

// `displace scene --print NAME`: a built-in scene of pipeline/scene.h (pipeline::builtin_scene_names()).
struct PrintSceneSettings {
  std::string name;
};

// `displace sequence`: frames A..B (every STEP-th) of a frame-pipeline scene, headless, each to
// a file named by a '#' pattern (one zero-padded digit per '#').
struct SequenceSettings {
  pipeline::Scene scene;
  long long first = 0, last = 0, step = 1;
  // --shard I/N: this run renders the frames whose position in A..B:STEP is I modulo N (round robin,
  // I from 1), so that shards finish together
  int shard_index = 1, shard_count = 1;
  std::filesystem::path output;   // pattern, .png (8-bit) or .exr (float colour)
  std::vector<AovOutput> aovs;    // file patterns
  bool resume = false;            // skip frames whose every output exists
  std::filesystem::path video;    // .mp4 or .webm through ffmpeg; empty: none
  std::filesystem::path preview;  // an animated .gif of the frames rendered; empty: none
  render::RendererOptions renderer;
};

// `displace bench-frame`: the frame-pipeline loop timed stage by stage.
struct BenchFrameSettings {
  pipeline::Scene scene;
  int frames = 120;
  int warm_up = 5;
  bool serial = false;         // --serial: the stages one after another (FramePipeline::run), none overlapped
  bool pin_threads = false;    // --pin-threads: the loop's threads one per CPU (pipeline::ThreadPinning)
  std::filesystem::path json;  // empty: none
  render::RendererOptions renderer;
};

// `displace play`: the frame pipeline's scene animated in a window (demos/play.cpp).
struct PlaySettings {
  std::string scene = "water";  // a built-in scene (pipeline::builtin_scene_names()) or a .toml scene file
  int width = 0, height = 0;    // --size WxH: the window and image in pixels; 0: the scene's
  int map_size = 0;             // --map-size N; 0: the scene's
  int cone_lag = -1;            // --cone-lag N (lagged cone maps in real time); -1: the scene's
  long long frames = -1;  // --frames N: exactly N fixed-step frames (0 .. N-1), then exit; -1: until closed
  std::filesystem::path screenshot;  // --screenshot F.png (with --frames): the last frame
  bool vsync = false;                // present with FIFO (the display's rate)
  bool pin_threads = false;  // --pin-threads: the loop's threads one per CPU (pipeline::ThreadPinning)
  render::RendererOptions renderer;
};

// `displace report`: what accuracy costs in time (demos/report.cpp). Full or quick (--quick: the
// same figures from fewer and smaller renders, for CI).
struct ReportSettings {
  std::vector<SceneSettings> scenes;  // default: the sweep's three built-in scenes
  bool quick = false;
  int image_side = 0;  // --size N: square images of the render figures; 0: the mode's
  std::filesystem::path output = "docs/report";
  bool plots = true;  // --no-plots: the data only (CSV and JSON), no python
  render::RendererOptions renderer;
};

using CommandSettings =
    std::variant<HelpSettings, SimSettings, BakeSettings, DemoSettings, RenderSettings, SweepSettings,
                 PrintSceneSettings, SequenceSettings, BenchFrameSettings, PlaySettings, ReportSettings>;

// The extension of a path, lower-cased (".png").
std::string lower_extension(const std::filesystem::path& path);

// Whether `word` names a command (sim, bake, render, sweep, demo, scene, play).
bool is_command(std::string_view word);

// `args` excludes the program name and must not be empty.
CommandSettings parse_command_line(std::span<const std::string_view> args);

}  // namespace displace::app
