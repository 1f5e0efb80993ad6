// pipeline/frame_pipeline.h - the per-frame service: scene -> only the effects it needs (sim) ->
// budgeted rebake of the maps its method reads (bake) -> upload -> render. The one place that
// knows sim, bake and render together; demos/ and the benchmarks are its clients.
//
// Stages, each a function a test can call alone: simulate(time) -> bake(budget) -> upload() ->
// draw(view). run(index) chains them for frame `index` at scene time start + index / fps (double).
// State made once and kept for the whole run: where the stages run (place_stages), the height stage
// and the map stage of that placement (pipeline/stages.h: a CPU or a device backend each), the
// heights of two frames.
//
// Budget: the bake gets what the frame budget leaves after the other stages of the previous frame. A
// work budget (scene.bake_work) or none makes every frame reproducible from its index alone; a
// wall-clock budget is real-time use (refinement carried over on a static source; with
// scene.cone_lag_frames = N > 0 lagged cone maps, every cone conservative, a map at most 2N frames old).
//
// In full: docs/design/pipeline.md#pipelineframe_pipelineh-the-frame-budget
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <span>

#include "bake/bake.h"
#include "pipeline/height_source.h"
#include "pipeline/maps.h"
#include "pipeline/query.h"
#include "pipeline/scene.h"
#include "render/render.h"

namespace displace::pipeline {

struct FrameRecord {
  long long index = 0;
  double time = 0.0;     // scene seconds
  unsigned effects = 0;  // Effect bits that ran
  long long ffts = 0;    // inverse FFTs the sim took
  double sim_ms = 0.0, bake_ms = 0.0, upload_ms = 0.0, render_ms = 0.0, frame_ms = 0.0;  // the scene's clock
  double bake_budget_ms = 0.0;   // the bake's share of the frame budget (infinity: unlimited)
  bool overrun = false;          // the frame took longer than the scene's frame budget
  bake::BakeStats cones;         // the cone bake (sector_count 0 when the method reads no cone map)
  long long pending = 0;         // texels the cone baker would still refine
  long long cone_lag = 0;        // frames since the heights the cone map was made from (lagged maps)
  float cone_lift = 0.0f;        // how far its apexes were raised for this frame's heights
  bool cones_updated = false;    // the cone map was updated where the heights changed (an image
                                 // sequence's frame changed in places: HeightFrame::dirty), not baked whole
  double choppy_residual = 0.0;  // metres: the resampling's largest |p + D(p) - x|
  // The device path: where the sim and the bake ran, and the device's own milliseconds from GPU
  // timestamps (0 where none): this frame's when its outputs were read back (the frame finished),
  // else the last finished frame's (with output_none, an earlier frame's; the draw's then 0). The
  // bake's counts the levels of detail made on the device (a device sim's on the unbounded sea), and
  // levels_device_ms is their share of it.
  bool sim_on_device = false, bake_on_device = false;
  double sim_device_ms = 0.0, bake_device_ms = 0.0, render_device_ms = 0.0, levels_device_ms = 0.0;
};

// Reads an albedo image (Scene::albedo) as RGBA8: the application's reader.
using AlbedoLoader = std::function<render::Albedo(const std::filesystem::path& file)>;

class FramePipeline {
 public:
  // clock: milliseconds (any origin); by default std::chrono::steady_clock. loader: needed by image
  // scenes; albedo_loader by albedo materials (the albedo is set on the renderer here, once).
  // Throws SceneError or render::RenderError for a scene that cannot run.
  FramePipeline(const Scene& scene, render::Renderer& renderer, std::function<double()> clock = {},
                HeightLoader loader = {}, AlbedoLoader albedo_loader = {});
  ~FramePipeline();
  FramePipeline(FramePipeline&&) noexcept;
  FramePipeline& operator=(FramePipeline&&) noexcept;

  // Frame `index`: every stage, the picture read back into `frame` (`outputs`, render::Output).
  FrameRecord run(long long index, render::Frame& frame, unsigned outputs = render::output_color);
  // The same frame seen through `view` instead of the scene's camera (an interactive camera).
  FrameRecord run(long long index, const render::View& view, render::Frame& frame,
                  unsigned outputs = render::output_color);

  // Frames first .. first + count - 1 with the stages overlapped (tbb::parallel_pipeline, two frames
  // in flight): frame n + 1's sim and bake run while frame n uploads and renders. `consume` gets
  // every frame, in order, with its record (the frame is reused: copy what is kept). The pictures
  // are the same as run()'s, frame by frame, and so are the budget and the records' accounting. With
  // the sim or the bake on the device these are run()'s frames one after another: the device
  // records its stages into the renderer's frame, which only the thread that renders may do, and
  // runs them while the host records the next frame.
  void run_frames(long long first, long long count, unsigned outputs,
                  const std::function<void(const FrameRecord&, const render::Frame&)>& consume);

  // The stages alone.
  void simulate(double time, FrameRecord& record);
  void bake(double budget_ms, FrameRecord& record);
  void upload(FrameRecord& record);
  void draw(const render::View& view, render::Frame& frame, unsigned outputs, FrameRecord& record);

  // Height queries (pipeline/query.h) of the surface this pipeline's scene draws, at any time and
  // camera-independent: the heights for `time` are made for the queries (and kept for the next ones
  // at that time), apart from the frames'.
  void query(std::span<const QueryPoint> points, double time, QueryResult& out);

  const Scene& scene() const;
  const Placement& placement() const;  // where the stages run (decided once, here)
  // An ocean loop's largest relative change to a wave frequency ([ocean] loop_seconds; 0: none).
  double loop_error() const;
  const render::HeightField& heights() const;  // [0, 1], the source's fixed mapping applied
  const render::MapSet& maps() const;          // what upload() hands over

  struct State;

 private:
  std::unique_ptr<State> state_;
};

}  // namespace displace::pipeline
