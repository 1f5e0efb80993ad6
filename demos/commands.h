// demos/commands.h - the `displace` subcommands as named stages that take typed settings.
//
// Each stage is callable alone (the tests do): synthesize a height field, map it to [0, 1], bake
// cones, export. The run_* functions chain them for one subcommand and print what they did.
// Failures throw AppError (std::invalid_argument from sim and bake::BakeError pass through to the
// CLI boundary in displace_main.cpp).
#pragma once

#include <iosfwd>
#include <string>
#include <vector>

#include "bake/bake.h"
#include "demos/cone_export.h"
#include "demos/image_io.h"
#include "demos/options.h"
#include "pipeline/maps.h"
#include "sim/sim.h"

namespace displace::app {

// Raw heights in metres from a source, with the source's fixed mapping to [0, 1] and the
// attributes that describe it (source, time, seed, patch size, spectrum, scale, bias).
struct SynthesizedHeights {
  int width = 0;
  int height = 0;
  std::vector<float> raw;  // metres
  sim::HeightMapping mapping;
  Metadata metadata;
  double milliseconds = 0.0;
};
SynthesizedHeights synthesize(const SourceSettings& source);

// Writes raw metres to channel `height` with the synthesis attributes.
void write_height_exr(const std::filesystem::path& file, const SynthesizedHeights& heights);

// Heights in [0, 1] ready to bake, whatever they came from.
struct BakeInput {
  int width = 0;
  int height = 0;
  std::vector<float> heights;
  std::string description;  // one phrase for the human line: where the heights came from
  Metadata metadata;        // passed on to the exported cone map
};
BakeInput prepare_bake_input(const std::variant<FileInput, SourceSettings>& input);

struct BakedCones {
  std::vector<float> ratios;  // interleaved, width * height * sector_count
  std::vector<float> apex;    // bilinear cones: width * height apex heights; center cones: empty
  bake::BakeStats stats;
};
// Center cones (between texel centres) with one of the center bakers. `progress` hears from the
// slow ones (exact, original, relaxed).
BakedCones bake_cones(std::span<const float> heights, int width, int height, int sector_count, Baker baker,
                      bake::Address address, double budget_milliseconds, float tolerance = 0.25f,
                      const bake::Progress& progress = {});
// Bilinear cones (bake::bake_bilinear_cones' contract) with their apex heights: Baker::full bakes
// them whole, Baker::budgeted with bake::BilinearBaker within the budget (0 allowed); `progress`
// goes to either.
BakedCones bake_bilinear(std::span<const float> heights, int width, int height, int sector_count, Baker baker,
                         bake::Address address, double budget_milliseconds, float tolerance = 0.25f,
                         const bake::Progress& progress = {});

// The --stats JSON line (no trailing newline).
std::string stats_json(const bake::BakeStats& stats, Baker baker, bake::Address address,
                       ConeKind kind = ConeKind::center);

// A rendered frame's colour to .png (8-bit) or .exr (float RGBA), and one AOV (AovOutput's formats).
void write_frame_image(const std::filesystem::path& file, const render::Frame& frame,
                       const Metadata& metadata);
void write_aov(const AovOutput& aov, const render::Frame& frame, const Metadata& metadata);

// The error target of `sweep` and `report`: rmse against the reference, 8-bit units.
inline constexpr double sweep_target_rmse = 3.0;

// Per-pixel statistics of a frame (read back with output_all) over the pixels that hit the relief.
struct FrameSummary {
  double mean_iterations = 0.0, mean_fetches = 0.0, p99_fetches = 0.0, max_iterations = 0.0;
  long long hit_pixels = 0;
};
FrameSummary summarize(const render::Frame& frame);

// A sweep scene's heights into `maps`, and its mesh and albedo onto `renderer`.
void load_scene(render::Renderer& renderer, pipeline::MapMaker& maps, const SceneSettings& scene);

// One method at one step count against a reference frame: its error and what it cost.
struct MethodRun {
  render::ImageError error;
  FrameSummary summary;
  double median_ms = 0.0;  // the median device time of the renders
};
// Renders `method` `repeat` times from the maps `maps` makes for it; `frame` keeps the last one.
MethodRun measure_method(render::Renderer& renderer, pipeline::MapMaker& maps, const render::View& view,
                         const render::MethodSettings& method, int repeat, const render::Frame& reference,
                         render::Frame& frame);

void run_sim(const SimSettings& settings, std::ostream& out);
void run_bake(const BakeSettings& settings, std::ostream& out);
void run_render(const RenderSettings& settings, std::ostream& out);
void run_sweep(const SweepSettings& settings, std::ostream& out);
void run_demo(const DemoSettings& settings, std::ostream& out);
// Writes the built-in scene as a TOML scene file (pipeline::scene_toml).
void run_print_scene(const PrintSceneSettings& settings, std::ostream& out);
// demos/frames.cpp: the frame pipeline's users.
void run_sequence(const SequenceSettings& settings, std::ostream& out);
void run_bench_frame(const BenchFrameSettings& settings, std::ostream& out);
// demos/report.cpp: what accuracy costs in time, as CSVs, figures and a README.
void run_report(const ReportSettings& settings, std::ostream& out);

// The overview `displace --help` prints; `displace COMMAND --help` lists one command's flags.
std::string usage_text();

// Runs one parsed command; returns the exit status.
int run_command(const CommandSettings& settings, std::ostream& out);

}  // namespace displace::app
