// pipeline/stages.cpp - the stages' CPU and device backends (stages.h) and where they run.
#include "pipeline/stages.h"

#include <cmath>
#include <optional>

namespace displace::pipeline {
namespace {

bool static_source(const Scene& scene) {
  return scene.source == SourceKind::bricks || scene.source == SourceKind::cliff ||
         (scene.source == SourceKind::image && !is_image_sequence(scene.image));
}

// What the host makes of `needs` where the placement puts the rest on the device: the levels follow a
// device sim's heights (a static map's with its cones on the device get none: the host's chain would
// need the host's cones).
render::MapNeeds host_needs(render::MapNeeds needs, const Placement& placement) {
  if (placement.sim_on_device || placement.cones_on_device) needs.levels = false;
  if (placement.cones_on_device) {
    needs.cone_sectors = 0;
    needs.relaxed = false;
  }
  return needs;
}

}  // namespace

Placement place_stages(const Scene& scene, const render::DeviceInfo& device) {
  const render::MapNeeds needs = render::map_needs(scene.method, scene_view(scene, scene.start));
  Placement placement;
  placement.sim_on_device = simulates_on_device(scene.source) && runs_on_device(scene.sim_backend, device);
  if (needs.cone_sectors > 0 && !needs.relaxed && runs_on_device(scene.bake_backend, device)) {
    if (placement.sim_on_device || static_source(scene)) {
      placement.cones_on_device = true;
    } else if (scene.bake_backend == Backend::device) {
      throw SceneError(
          "backend.bake = \"device\" bakes heights on the device or a static map's: moving heights made on "
          "the CPU need backend.sim = \"device\" (or \"auto\") too");
    }
  }
  placement.levels_on_device = placement.sim_on_device && needs.levels && needs.cone_sectors > 0;
  // the heights go to the CPU where the host makes a map of them
  const render::MapNeeds host = host_needs(needs, placement);
  placement.heights_to_cpu =
      host.cone_sectors > 0 || host.relaxed || host.levels || host.max_pyramid || host.distance;
  return placement;
}

namespace {

// ---- heights

class CpuHeights final : public HeightStage {
 public:
  CpuHeights(const Scene& scene, HeightLoader loader)
      : source_(source_settings(scene), scene_effects(scene), std::move(loader)) {}

  void make(double time, HeightFrame& out, FrameRecord& record) override {
    record.time = time;
    record.effects = source_.effects();
    source_.make(time, record.index, out);
    record.ffts = out.ffts;
    record.choppy_residual = out.choppy_residual;
  }
  unsigned effects() const override { return source_.effects(); }
  bool is_static() const override { return source_.is_static(); }
  double loop_error() const override { return source_.loop_error(); }
  void hand_over(render::MapSet&) const override {}
  void finished(FrameRecord&) const override {}

 private:
  HeightSource source_;
};

// The source simulated on the renderer's device; its heights read back only where the host's maps
// read them.
class DeviceHeights final : public HeightStage {
 public:
  DeviceHeights(const Scene& scene, const Placement& placement, render::Renderer& renderer,
                double ahead_seconds)
      : settings_(source_settings(scene)),
        sim_(make_device_sim(renderer, settings_, scene_effects(scene), &info_)),
        effects_(source_effects(scene.source, scene_effects(scene))),
        to_cpu_(placement.heights_to_cpu),
        ahead_(ahead_seconds) {}

  void make(double time, HeightFrame& out, FrameRecord& record) override {
    record.time = time;
    record.effects = effects_;
    record.sim_on_device = true;
    record.sim_device_ms = sim_->device_milliseconds();
    record.choppy_residual = 0.0;
    const long long ffts = sim_->fft_count();
    simulate(time + ahead_);
    record.ffts = sim_->fft_count() - ffts;
    out.field.width = out.field.height = sim_->size();
    out.version = next_map_version();
    if (to_cpu_) {
      sim_->read_back(&out.field.heights, nullptr, nullptr);
    } else {
      out.field.heights.clear();
    }
    out.foam.clear();
  }
  // The heights at `time` again (a map stage that baked the frame ahead's map first).
  void simulate(double time) { sim_->simulate(source_time(settings_, time)); }
  long long fft_count() const { return sim_->fft_count(); }
  std::shared_ptr<const render::DeviceHeightImages> maps() const { return sim_->maps(); }

  unsigned effects() const override { return effects_; }
  bool is_static() const override { return false; }
  double loop_error() const override { return info_.loop_error; }
  void hand_over(render::MapSet& maps) const override {
    maps.width = maps.height = sim_->size();
    maps.heights = {};
    maps.device_heights = sim_->maps();
  }
  void finished(FrameRecord& record) const override { record.sim_device_ms = sim_->device_milliseconds(); }

 private:
  SourceSettings settings_;
  DeviceSimInfo info_;
  std::unique_ptr<sim::DeviceSim> sim_;
  unsigned effects_;
  bool to_cpu_;
  double ahead_;
};

// ---- maps

MapHeights frame_heights(const HeightFrame& frame) {
  MapHeights heights = map_heights(frame.field, frame.version);
  heights.dirty_since = frame.dirty_since;
  heights.dirty = frame.dirty;
  heights.foam = frame.foam;
  heights.foam_version = frame.foam_version;
  return heights;
}

// The host's maps (pipeline/maps.h's MapMaker) of what `needs` lists.
class HostMaps {
 public:
  HostMaps(const Scene& scene, const render::MapNeeds& needs, render::Renderer& renderer)
      : needs_(needs), maker_(renderer.device().max_image_dimension_3d, 2) {
    if (scene.source != SourceKind::image) maker_.reserve(needs, scene.map_size, scene.map_size);
  }
  void make(int slot, const HeightFrame& frame, const ConeSchedule& schedule, FrameRecord& record) {
    MapStats stats;
    maker_.make(slot, frame_heights(frame), needs_, schedule, stats);
    if (needs_.cone_sectors > 0) {
      record.cones = stats.cones;
      record.pending = stats.pending;
      record.cone_lag = stats.cone_lag;
      record.cone_lift = stats.cone_lift;
      record.cones_updated = stats.cones_updated;
    }
  }
  const render::MapSet& made(int slot) const { return maker_.made(slot); }

 private:
  render::MapNeeds needs_;
  MapMaker maker_;
};

class CpuMaps final : public MapStage {
 public:
  CpuMaps(const Scene& scene, const Placement& placement, const render::MapNeeds& needs,
          render::Renderer& renderer)
      : host_(scene, host_needs(needs, placement), renderer) {}
  void make(int slot, const HeightFrame& heights, const ConeSchedule& schedule,
            FrameRecord& record) override {
    host_.make(slot, heights, schedule, record);
  }
  render::MapSet hand_over(int slot) const override { return host_.made(slot); }
  const render::MapSet& made(int slot) const override { return host_.made(slot); }
  void finished(FrameRecord&) const override {}

 private:
  HostMaps host_;
};

// What the placement puts on the device (the cone maps, the levels of detail), the rest on the host.
class DeviceMaps final : public MapStage {
 public:
  DeviceMaps(const Scene& scene, const Placement& placement, const render::MapNeeds& needs,
             render::Renderer& renderer, HeightStage& heights, int lag_frames, bool ahead)
      : renderer_(renderer),
        sim_(dynamic_cast<DeviceHeights*>(&heights)),
        needs_(needs),
        host_(scene, host_needs(needs, placement), renderer),
        first_pass_(scene.device_first_pass),
        cones_on_device_(placement.cones_on_device),
        lag_frames_(lag_frames),
        ahead_(ahead) {
    if (cones_on_device_ && sim_)
      cones_ = std::make_unique<bake::DeviceCones>(renderer.frames(), sim_->maps(), needs.cone_sectors,
                                                   needs.cone_address);
    if (placement.levels_on_device)
      levels_ = std::make_unique<bake::DeviceLevels>(renderer.frames(), sim_->maps(), needs.cone_sectors,
                                                     needs.cone_address);
  }

  void make(int slot, const HeightFrame& frame, const ConeSchedule& schedule, FrameRecord& record) override {
    if (cones_on_device_) bake_cones(frame, schedule.budget, record);
    if (levels_) levels_->make(schedule.budget, first_pass_);  // of the frame's own heights (after ahead's)
    host_.make(slot, frame, schedule, record);
  }

  render::MapSet hand_over(int slot) const override {
    render::MapSet maps = host_.made(slot);
    if (levels_) {
      maps.device_levels = levels_->maps();
      maps.level_count = levels_->level_count();
      maps.level_sectors = levels_->sector_count();
      maps.level_address = levels_->address();
      maps.levels = {};
    }
    if (cones_on_device_) {
      render::ConeMapView& cones = maps.cones[std::size_t(render::cone_slot(needs_.cone_sectors))];
      cones = render::ConeMapView{};
      cones.sector_count = needs_.cone_sectors;
      cones.address = needs_.cone_address;
      cones.device = cones_->map();
    }
    return maps;
  }
  const render::MapSet& made(int slot) const override { return host_.made(slot); }

  void finished(FrameRecord& record) const override {
    if (cones_) {
      record.bake_device_ms = cones_->device_milliseconds();
      if (lag_frames_ > 0) record.cone_lift = cones_->lift();
    }
    if (levels_) {
      record.levels_device_ms = levels_->device_milliseconds();
      record.bake_device_ms = (cones_ ? record.bake_device_ms : 0.0) + record.levels_device_ms;
    }
  }

 private:
  // The cone bake, recorded into the renderer's next frame after the sim: a device sim's heights every
  // frame (lagged: a share of the next map, the last one served raised; bake/device/device_cones.h), a static
  // map's once per version of its heights.
  void bake_cones(const HeightFrame& frame, const bake::Budget& budget, FrameRecord& record) {
    if (!cones_) {
      const bake::HeightView heights{frame.field.heights.data(), frame.field.width, frame.field.height};
      cones_ = std::make_unique<bake::DeviceCones>(renderer_.frames(), heights, needs_.cone_sectors,
                                                   needs_.cone_address);
    }
    if (sim_ || baked_from_ != frame.version) {
      if (ahead_) {  // the next frame's map from the next frame's heights, then this frame's heights
        cones_->advance_lagged(budget, 1, first_pass_);
        const long long ffts = sim_->fft_count();
        sim_->simulate(record.time);
        record.ffts += sim_->fft_count() - ffts;
        record.cone_lag = cones_->compose_lagged();
      } else {
        record.cone_lag = cones_->bake_lagged(budget, lag_frames_, first_pass_);
      }
      baked_from_ = frame.version;
    }
    record.bake_on_device = true;
    record.bake_device_ms = cones_->device_milliseconds();
    record.cones.sector_count = needs_.cone_sectors;
  }

  render::Renderer& renderer_;
  DeviceHeights* sim_;  // null: the heights are the host's (a static map)
  render::MapNeeds needs_;
  HostMaps host_;
  bake::DeviceFirstPass first_pass_;
  bool cones_on_device_;
  int lag_frames_;
  bool ahead_;
  std::unique_ptr<bake::DeviceCones> cones_;
  std::unique_ptr<bake::DeviceLevels> levels_;
  std::uint64_t baked_from_ = 0;  // the heights the cones were last baked from
};

}  // namespace

std::unique_ptr<HeightStage> make_height_stage(const Scene& scene, const Placement& placement,
                                               render::Renderer& renderer, HeightLoader loader,
                                               double ahead_seconds) {
  if (placement.sim_on_device)
    return std::make_unique<DeviceHeights>(scene, placement, renderer, ahead_seconds);
  return std::make_unique<CpuHeights>(scene, std::move(loader));
}

std::unique_ptr<MapStage> make_map_stage(const Scene& scene, const Placement& placement,
                                         const render::MapNeeds& needs, render::Renderer& renderer,
                                         HeightStage& heights, int lag_frames, bool ahead) {
  if (placement.cones_on_device || placement.levels_on_device)
    return std::make_unique<DeviceMaps>(scene, placement, needs, renderer, heights, lag_frames, ahead);
  return std::make_unique<CpuMaps>(scene, placement, needs, renderer);
}

}  // namespace displace::pipeline
