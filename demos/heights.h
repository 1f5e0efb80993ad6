// demos/heights.h - a scene's heights for the one-off commands (sim, bake, sweep, report, demo)
// through the one source switch (pipeline::HeightSource), with what files and output lines say of
// them; and the application's readers of the files a scene names: height images (OpenImageIO, with
// the scene's channel, invert and range), albedo images and meshes.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "demos/image_io.h"
#include "pipeline/frame_pipeline.h"
#include "pipeline/maps.h"
#include "pipeline/scene.h"
#include "sim/sim.h"

namespace displace::app {

// The heights of a scene at one time: raw (metres; a height image's [0, 1] values as read) and in
// [0, 1] for the baker and the renderer.
struct SceneHeights {
  int width = 0, height = 0;
  std::vector<float> raw;
  std::vector<float> heights;  // [0, 1]
  sim::HeightMapping mapping;
  std::size_t clamped = 0;
  std::string description;  // one phrase for an output line: where they came from
  Metadata metadata;        // the source's attributes (sim's EXR; passed on to cone maps)
  double milliseconds = 0.0;
  double loop_error = 0.0;  // an ocean loop's largest relative change to a wave frequency (0: none)
};
// `time` in seconds; the effects the scene consumes (pipeline::scene_effects: choppy crests are
// resampled onto the grid, as the renderer draws them). Throws AppError.
// With a renderer, a moving source (ocean, sinusoids) is simulated on its device and read back.
SceneHeights scene_heights(const pipeline::Scene& scene, double time, render::Renderer* device = nullptr);
// Whether the scene's [backend] sim puts its heights on a device (pipeline::runs_on_default_device);
// static sources never.
bool sim_wants_device(const pipeline::Scene& scene);

// Raw metres to channel `height` with the source's attributes (what `displace sim` writes).
void write_height_exr(const std::filesystem::path& file, const SceneHeights& heights);
// The attributes of the heights, renamed for a cone map whose own `height` channel is in [0, 1].
Metadata source_attributes_for_cones(const Metadata& metadata);

// The application's readers for pipeline::FramePipeline and the one-off commands.
HeightLoadSettings load_settings(const pipeline::ImageRead& read);
pipeline::HeightLoader height_loader(const pipeline::ImageRead& read);
pipeline::AlbedoLoader albedo_loader();
// The scene's mesh (surface = mesh) onto `renderer`; load_scene_files also its albedo image (none:
// the grid), which a FramePipeline sets itself (albedo_loader).
void load_scene_mesh(render::Renderer& renderer, const pipeline::Scene& scene);
void load_scene_files(render::Renderer& renderer, const pipeline::Scene& scene);

// The view of a scene at its start time: what the one-off commands render.
render::View start_view(const pipeline::Scene& scene);
// A scene's heights at its start time into `maps`, its mesh and albedo onto `renderer` (the commands
// that render many methods over one scene's maps: sweep, report).
void load_scene(render::Renderer& renderer, pipeline::MapMaker& maps, const pipeline::Scene& scene);

// Output phrases shared by the commands.
std::string source_name(pipeline::SourceKind kind);
std::string mapping_phrase(const sim::HeightMapping& mapping);
std::string clamped_phrase(std::size_t clamped);
std::string budget_phrase(double milliseconds);
std::string baked_within(double milliseconds);  // "within a 2 ms budget", "with an unlimited budget"
std::string stats_phrase(const bake::BakeStats& stats);
void make_output_directory(const std::filesystem::path& directory);

}  // namespace displace::app
