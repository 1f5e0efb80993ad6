// pipeline/height_source.h - the one source switch: a scene's source settings (ocean, sinusoids,
// bricks, cliff or height images) -> heights in [0, 1] for a time, with only the effects asked for
// (choppy crests, foam). "Who makes the heights" is this one choice; pipeline/maps.h's MapMaker is
// "who makes the maps" from them. The frame pipeline and one-off commands both use it.
//
// State made once (sim::Ocean with its FFT plans, the waves, the mapping) and kept; make() writes
// into a HeightFrame the caller keeps (one per frame in flight), reusing its memory. Moving heights
// draw a new version per make(); a static source keeps one, and make() into a frame that holds it
// does nothing. An image sequence's frame equal to the one before keeps its version, and one that
// changed in places says where (HeightFrame::dirty), so that its maps are updated there. Allocation and
// versions: docs/design/pipeline.md#pipelineheight_sourceh-the-source-switch
//
//   pipeline::HeightSource source(pipeline::source_settings(scene), pipeline::scene_effects(scene));
//   pipeline::HeightFrame heights;
//   source.make(/*time*/ 2.5, /*frame_index*/ 0, heights);  // heights.field in [0, 1], heights.raw metres
//   maps.set_heights(heights.field);                         // a pipeline::MapMaker
//   renderer.set_maps(maps.maps_for(method, view));
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <span>
#include <vector>

#include "bake/device/device_cones.h"
#include "pipeline/scene.h"
#include "render/render.h"
#include "sim/device/device_sim.h"
#include "sim/sim.h"

namespace displace::pipeline {

// The effects a source computes: only what something consumes.
enum Effect : unsigned {
  effect_heights = 1u << 0,  // always
  effect_choppy = 1u << 1,   // the ocean's horizontal displacement, resampled onto the grid (choppiness > 0)
  effect_foam = 1u << 2,     // the Jacobian of the displacement, as foam coverage (water material with foam)
};
// Foam coverage from the Jacobian J of the choppy map: none at J >= foam_start (Scene::foam_coverage),
// full at J <= foam_start - foam_width, linear between (J = 1 on a flat sea, < 0 where the surface
// folds over). Measured on the default ocean (256 texels, 200 m, 12 m/s): J spans [0.70, 1.34] at
// choppiness 1 and [0.35, 1.94] at 2.5, so the default 0.85 starts foam on the most compressed crests.
inline constexpr float foam_width = 0.4f;
// What a scene consumes: choppy crests for an ocean with choppiness, foam for the water material.
unsigned scene_effects(const Scene& scene);
// What a source of `kind` computes of `effects`: the heights, and choppy and foam for an ocean only.
unsigned source_effects(SourceKind kind, unsigned effects);

// Reads a height image (SourceKind::image) into heights in [0, 1]: the application's reader
// (demos/ uses OpenImageIO); it throws for a file it cannot read.
using HeightLoader = std::function<render::HeightField(const std::filesystem::path& file)>;

// A source's settings: Scene's [source], [ocean] and [sinusoids] (source_settings(scene)).
struct SourceSettings {
  SourceKind kind = SourceKind::ocean;
  int map_size = 256;           // texels a side (image: the image's)
  std::uint64_t seed = 1;       // bricks and cliff roughness
  std::filesystem::path image;  // image: one file, or a numbered sequence (image_for_frame)
  sim::OceanParams ocean;       // its size is map_size
  sim::SinusoidParams sinusoids;
  float foam_start = 0.85f;  // the Jacobian where foam begins (Scene::foam_coverage)
};
SourceSettings source_settings(const Scene& scene);

// One frame's heights and what came with them. The caller keeps it; make() reuses its memory.
struct HeightFrame {
  render::HeightField field;  // [0, 1], the source's fixed mapping applied
  std::uint64_t version = 0;  // names the content (0: nothing made yet)
  // an image sequence's frame that changed only in places since the one before it (version
  // dirty_since): the rectangles that hold every change (empty: all of it, or not known)
  std::uint64_t dirty_since = 0;
  std::vector<bake::Rect> dirty;
  std::span<const float> raw;  // before the mapping (metres; images: `field`), views this frame's memory
  std::size_t clamped = 0;     // texels the mapping clamped into [0, 1]
  std::vector<float> foam;     // effect_foam: coverage in [0, 1] per texel, else empty
  std::uint64_t foam_version = 0;
  long long ffts = 0;            // inverse FFTs the last make() took
  double choppy_residual = 0.0;  // effect_choppy, metres: the resampling's largest |p + D(p) - x|

  // working memory
  sim::OceanFrame ocean;
  std::vector<float> raw_values, jacobian;
};

class HeightSource {
 public:
  // effects: Effect bits (effect_heights is implied; choppy and foam only for an ocean). loader: needed
  // by image sources. Throws SceneError for settings that cannot make heights.
  explicit HeightSource(const SourceSettings& settings, unsigned effects = effect_heights,
                        HeightLoader loader = {});
  ~HeightSource();
  HeightSource(HeightSource&&) noexcept;
  HeightSource& operator=(HeightSource&&) noexcept;

  // The heights at `time` (seconds) into `out`; `frame_index` picks an image sequence's file.
  void make(double time, long long frame_index, HeightFrame& out);

  bool is_static() const;              // the same heights at every time (bricks, cliff, one image)
  unsigned effects() const;            // what make() computes
  sim::HeightMapping mapping() const;  // raw -> [0, 1] (images: the identity)
  double loop_error() const;           // sim::Ocean::loop_error (0: no ocean, or no loop)

  struct State;

 private:
  std::unique_ptr<State> state_;
};

// The source of `settings` on `renderer`'s device (sim/device/device_sim.h): the ocean's spectrum as
// sim::Ocean draws it, or the sinusoids' waves, with the same mapping, the foam thresholds above and
// the effects asked for. Throws SceneError unless the source is the ocean or sinusoids.
bool simulates_on_device(SourceKind kind);
struct DeviceSimInfo {
  sim::HeightMapping mapping;  // raw -> [0, 1]
  double loop_error = 0.0;     // sim::Ocean::loop_error of the ocean's loop (0: none)
};
std::unique_ptr<sim::DeviceSim> make_device_sim(render::Renderer& renderer, const SourceSettings& settings,
                                                unsigned effects, DeviceSimInfo* info = nullptr);
// The time a source's heights are made for: `time` modulo the ocean's loop_seconds (the CPU's
// sim::Ocean takes it so itself; the device is given it), else `time`.
double source_time(const SourceSettings& settings, double time);

}  // namespace displace::pipeline
