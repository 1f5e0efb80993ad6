// demos/commands/settings.h - the typed settings each command's flags become, and the commands
// that run them (demos/commands/<name>.cpp). A command's settings carry one pipeline::Scene (or
// several): the built-in or file its --scene names with its flags over it.
#pragma once

#include <filesystem>
#include <iosfwd>
#include <limits>
#include <string>
#include <vector>

#include "bake/bake.h"
#include "demos/cone_export.h"
#include "demos/frame_output.h"
#include "pipeline/scene.h"
#include "render/render.h"

namespace displace::app {

enum class ImageFormat { exr, png };

struct SimSettings {
  pipeline::Scene scene;                     // the heights at scene.start
  std::filesystem::path output;              // .exr
  std::filesystem::path frequency_spectrum;  // .csv: the ocean's synthesized S(f) beside the analytic one
};

struct QuerySettings {
  pipeline::Scene scene;  // the surface at scene.start
  std::string points;     // CSV x,y in metres, or "-" for standard input
  std::string output;     // CSV (or JSON with `json`), or "-" for standard output
  bool json = false;
};

struct BakeSettings {
  pipeline::Scene scene;  // the heights at scene.start (an image: --input)
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

// A one-off render's (and sweep's) cone bake when neither the scene ([budget] frame_ms) nor
// --bake-budget-ms sets one: milliseconds after the first stage began, which always completes (a
// 2048 x 2048 map's first picture in about 3 s here; maps up to about 512 x 512 finish within it).
inline constexpr double first_picture_budget_ms = 1000.0;

struct RenderSettings {
  pipeline::Scene scene;         // frame 0 at scene.start, as `displace sequence` draws it
  std::filesystem::path output;  // .png or .exr
  std::vector<AovOutput> aovs;
  bool compare_reference = false;
  render::RendererOptions renderer;
};

struct SweepSettings {
  std::vector<pipeline::Scene> scenes;  // each seen from its camera at its start time
  std::vector<render::Method> methods;
  std::vector<int> steps;
  int refine = 8;
  int repeat = 3;                // renders per row; the row reports the median device time
  std::filesystem::path output;  // .csv
  render::RendererOptions renderer;
};

struct ReportSettings {
  std::vector<pipeline::Scene> scenes;  // default: the sweep's three built-in scenes
  bool quick = false;
  int image_side = 0;  // --size N: square images of the render figures; 0: the mode's
  std::filesystem::path output = "docs/report";
  bool plots = true;  // --no-plots: the data only (CSV and JSON), no python
  render::RendererOptions renderer;
};

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

struct BenchFrameSettings {
  pipeline::Scene scene;
  int frames = 120;
  int warm_up = 5;
  bool serial = false;         // the stages one after another (FramePipeline::run), none overlapped
  bool pin_threads = false;    // the loop's threads one per CPU (pipeline::ThreadPinning)
  std::filesystem::path json;  // empty: none
  render::RendererOptions renderer;
};

// `displace play`'s budget when nothing sets one: real time (demos/commands/play.cpp).
inline constexpr double interactive_budget_ms = 33.0;

struct PlaySettings {
  pipeline::Scene scene;
  long long frames = -1;             // exactly N fixed-step frames (0 .. N-1), then exit; -1: until closed
  std::filesystem::path screenshot;  // with frames: the last frame
  bool vsync = false;                // present with FIFO (the display's rate)
  bool pin_threads = false;
  bool overlay = true;                // the overlay shown from the start (H toggles it)
  std::filesystem::path window_shot;  // with frames: the last frame as the window shows it (overlay included)
  render::RendererOptions renderer;
};
// The scene play runs: interactive play without a frame budget or work limit (from the scene or the
// command line) starts at interactive_budget_ms; with --frames the scene's budget stays (the frames
// `displace sequence` renders).
pipeline::Scene play_scene(const PlaySettings& settings);

struct DemoSettings {
  int map_size = 512;  // ocean samples along u and v
  std::filesystem::path output_directory = "out";
};

void run_sim(const SimSettings& settings, std::ostream& out);
void run_query(const QuerySettings& settings, std::ostream& out);
void run_bake(const BakeSettings& settings, std::ostream& out);
void run_render(const RenderSettings& settings, std::ostream& out);
void run_sweep(const SweepSettings& settings, std::ostream& out);
void run_report(const ReportSettings& settings, std::ostream& out);
void run_sequence(const SequenceSettings& settings, std::ostream& out);
void run_bench_frame(const BenchFrameSettings& settings, std::ostream& out);
void run_play(const PlaySettings& settings, std::ostream& out);
void run_demo(const DemoSettings& settings, std::ostream& out);

}  // namespace displace::app
