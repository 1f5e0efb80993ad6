// pipeline/stages.h - a frame's two stages, each one interface with a CPU and a device backend:
// HeightStage makes a frame's heights, MapStage the maps its method reads from them (cone maps, the
// levels of detail, the pyramid and the distance map). FramePipeline places the stages once
// (place_stages, scene.h), makes one of each here, and then runs them without asking where they run.
//
// Both backends take the same budget (ConeSchedule: a bake::Budget, refinement, a lag) and fill the
// same record (FrameRecord); a device backend turns the budget into work by bake::device_refine_limit.
// A device backend records its work into the renderer's next frame, so its frames run on the thread
// that renders (Placement::records_into_frame). Internal to pipeline/: not installed.
#pragma once

#include <memory>

#include "bake/device/device_cones.h"
#include "pipeline/frame_pipeline.h"
#include "sim/device/device_sim.h"

namespace displace::pipeline {

class HeightStage {
 public:
  virtual ~HeightStage() = default;
  // The heights at `time` for frame record.index into `out`, reusing its memory; sets record.time,
  // effects, ffts and choppy_residual. Heights the device keeps for maps made there leave
  // out.field.heights empty (the size and version are set).
  virtual void make(double time, HeightFrame& out, FrameRecord& record) = 0;
  virtual unsigned effects() const = 0;  // Effect bits make() computes
  virtual bool is_static() const = 0;    // the same heights at every time
  virtual double loop_error() const = 0;
  // Names in `maps` what the renderer samples of the heights where the device holds them (the CPU's
  // are the map stage's set already).
  virtual void hand_over(render::MapSet& maps) const = 0;
  // After the frame's draw: the device's milliseconds of the last finished frame (0 on the CPU).
  virtual void finished(FrameRecord& record) const = 0;
};

class MapStage {
 public:
  virtual ~MapStage() = default;
  // The maps of the frame in `slot` (0 or 1) from its heights within `schedule`; fills record.cones,
  // pending, cone_lag and cone_lift for the cone map the frame samples.
  virtual void make(int slot, const HeightFrame& heights, const ConeSchedule& schedule,
                    FrameRecord& record) = 0;
  // What the renderer samples for the frame in `slot`.
  virtual render::MapSet hand_over(int slot) const = 0;
  virtual const render::MapSet& made(int slot) const = 0;  // the host's maps of the slot
  // After the frame's draw: the device's milliseconds and the lift of the last finished frame.
  virtual void finished(FrameRecord& record) const = 0;
};

// The scene's heights where `placement` puts them. ahead_seconds > 0 (the device's cone_ahead): each
// make() simulates that much later, for a map stage that bakes a frame ahead (and simulates again).
std::unique_ptr<HeightStage> make_height_stage(const Scene& scene, const Placement& placement,
                                               render::Renderer& renderer, HeightLoader loader,
                                               double ahead_seconds);
// The maps `needs` lists where `placement` puts them, for two frames in flight. `heights` is the
// stage that made the frame's heights (alive while this is used).
std::unique_ptr<MapStage> make_map_stage(const Scene& scene, const Placement& placement,
                                         const render::MapNeeds& needs, render::Renderer& renderer,
                                         HeightStage& heights, int lag_frames, bool ahead);

}  // namespace displace::pipeline
