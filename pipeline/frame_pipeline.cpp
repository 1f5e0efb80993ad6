// pipeline/frame_pipeline.cpp - the per-frame service (frame_pipeline.h).
#include "pipeline/frame_pipeline.h"

#include <tbb/parallel_pipeline.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>

namespace displace::pipeline {
namespace {

double steady_milliseconds() {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

}  // namespace

struct FramePipeline::State {
  State(const Scene& s, render::Renderer& r, std::function<double()> c, HeightLoader loader)
      : scene(s),
        renderer(r),
        clock(c ? std::move(c) : std::function<double()>(steady_milliseconds)),
        loader_for_queries(std::move(loader)),
        maker(r.device().max_image_dimension_3d, int(heights.size())) {}

  Scene scene;
  render::Renderer& renderer;
  std::function<double()> clock;
  HeightLoader loader_for_queries;
  std::unique_ptr<HeightQuery> queries;  // made at the first query
  render::MapNeeds needs;
  bool deterministic = true;  // a work budget or none: a frame depends on its index only
  int cone_lag_frames = 0;    // lagged cone maps: the scene's lag where it applies, else 0
  bool cone_ahead = false;    // Scene::cone_ahead where it applies (a lag of 1 on the device path)

  // kept for the whole run
  std::array<HeightFrame, 2> heights;      // frames in flight (run_frames overlaps two; run uses the first)
  std::optional<HeightSource> source;      // the CPU's sim; none when the sim runs on the device
  unsigned effects = effect_heights;       // what the sim computes (HeightSource::effects)
  bool static_source = false;              // the same heights at every time (the device's sims move)
  double loop_error = 0.0;                 // sim::Ocean::loop_error of the ocean's loop
  MapMaker maker;                          // a slot per frame in flight
  int current = 0;                         // the frame in flight the stage functions work on
  std::atomic<double> last_other_ms{0.0};  // sim + upload + render of the last frame

  // the device path: the source simulated on the renderer's device, its heights read back only for a
  // bake on the CPU
  std::unique_ptr<render::DeviceSim> device_source;
  bool heights_to_cpu = true;
  bool sim_on_device() const { return device_source != nullptr; }
  // the cone maps baked on the device (from the device sim's heights, or a static source's uploaded
  // once at the first bake); the CPU's map maker then makes only the other maps
  bool bake_on_device = false;
  std::unique_ptr<render::DeviceCones> device_cones;
  std::uint64_t device_cones_version = 0;  // the heights the device cones were last baked from
  // the levels of detail of a device sim's heights, made on the device (whichever bakes level 0)
  std::unique_ptr<render::DeviceLevels> device_levels;
  render::MapNeeds cpu_needs;  // what the map maker makes
  render::DeviceConeBudget device_budget;
};

FramePipeline::FramePipeline(const Scene& scene, render::Renderer& renderer, std::function<double()> clock,
                             HeightLoader loader, AlbedoLoader albedo_loader) {
  if (!scene.albedo.empty()) {
    if (!albedo_loader)
      throw SceneError("an albedo material needs an albedo loader (the application's image reader)");
    renderer.set_albedo(albedo_loader(scene.albedo));
  } else {
    renderer.clear_albedo();
  }
  state_ = std::make_unique<State>(scene, renderer, std::move(clock), std::move(loader));
  State& s = *state_;
  if (!(scene.fps > 0.0)) throw SceneError("time.fps must be above 0");
  const render::DeviceFirstPass& first_pass = scene.device_first_pass;
  if (first_pass.ring_radius < 0 || first_pass.ring_radius > render::max_first_pass_rings ||
      first_pass.window_radius < 1 || first_pass.window_radius > render::max_first_pass_window) {
    throw SceneError("backend.device_rings must be in [0, " + std::to_string(render::max_first_pass_rings) +
                     "] and backend.device_window in [1, " + std::to_string(render::max_first_pass_window) +
                     "]");
  }
  if (first_pass.group && first_pass.ring_radius > 0)
    throw SceneError(
        "backend.device_group takes backend.device_rings = 0 (a first pass by groups or by rings)");
  s.needs = render::map_needs(scene.method, scene_view(scene, scene.start));
  s.deterministic = !std::isfinite(scene.frame_ms);
  // the sim: on the device, or the CPU's (made only then: an ocean's FFT plans and arrays are
  // hundreds of MB at 2048)
  if (simulates_on_device(scene.source) && runs_on_device(scene.sim_backend, renderer.device())) {
    DeviceSimInfo info;
    s.device_source = make_device_sim(renderer, source_settings(scene), scene_effects(scene), &info);
    s.effects = source_effects(scene.source, scene_effects(scene));
    s.loop_error = info.loop_error;
  } else {
    s.source.emplace(source_settings(scene), scene_effects(scene), s.loader_for_queries);
    s.effects = s.source->effects();
    s.static_source = s.source->is_static();
    s.loop_error = s.source->loop_error();
  }
  const bool lagged = !s.deterministic && !s.static_source && !s.needs.relaxed;
  s.cone_lag_frames = lagged ? scene.cone_lag_frames : 0;
  // the cone bake on the device: the bilinear cones (a relaxed layer is the CPU's), from heights that
  // are on the device already or never change
  if (s.needs.cone_sectors > 0 && !s.needs.relaxed && runs_on_device(scene.bake_backend, renderer.device())) {
    if (s.sim_on_device() || s.static_source) {
      s.bake_on_device = true;
    } else if (scene.bake_backend == Backend::device) {
      throw SceneError(
          "backend.bake = \"device\" bakes heights on the device or a static map's: moving heights made on "
          "the "
          "CPU need backend.sim = \"device\" (or \"auto\") too");
    }
  }
  s.cpu_needs = s.needs;
  // the levels follow the heights: a device sim's are made on the device (whichever bakes level 0);
  // a static map's with its cones on the device get none (the CPU's chain would need the CPU's cones)
  if (s.sim_on_device() || s.bake_on_device) s.cpu_needs.levels = false;
  s.device_budget.first_pass = scene.device_first_pass;
  s.device_budget.texels = scene.bake_work >= 0            ? scene.bake_work
                           : std::isfinite(scene.frame_ms) ? 0
                                                           : render::unlimited_texels;
  if (s.bake_on_device) {
    s.cpu_needs.cone_sectors = 0;
    s.cpu_needs.relaxed = false;
    if (s.sim_on_device())
      s.device_cones =
          std::make_unique<render::DeviceCones>(renderer, s.needs.cone_sectors, s.needs.cone_address);
  }
  if (s.sim_on_device() && s.needs.levels && s.needs.cone_sectors > 0)
    s.device_levels =
        std::make_unique<render::DeviceLevels>(renderer, s.needs.cone_sectors, s.needs.cone_address);
  if (scene.source != SourceKind::image) s.maker.reserve(s.cpu_needs, scene.map_size, scene.map_size);
  s.heights_to_cpu = s.cpu_needs.cone_sectors > 0 || s.cpu_needs.max_pyramid || s.cpu_needs.distance;
  if (scene.cone_ahead &&
      (scene.cone_lag_frames != 1 || !s.sim_on_device() || !s.bake_on_device || s.heights_to_cpu))
    throw SceneError(
        "budget.cone_ahead needs budget.cone_lag_frames = 1 with the sim and the cone bake on the device "
        "(a moving source, a cone method that reads no map the CPU makes, backend.sim and backend.bake "
        "device or auto on a GPU)");
  s.cone_ahead = scene.cone_ahead && s.cone_lag_frames == 1;  // where lagged maps apply (real time)
}

FramePipeline::~FramePipeline() = default;
FramePipeline::FramePipeline(FramePipeline&&) noexcept = default;
FramePipeline& FramePipeline::operator=(FramePipeline&&) noexcept = default;

const Scene& FramePipeline::scene() const { return state_->scene; }
double FramePipeline::loop_error() const { return state_->loop_error; }

void FramePipeline::query(std::span<const QueryPoint> points, double time, QueryResult& out) {
  State& s = *state_;
  if (!s.queries) s.queries = std::make_unique<HeightQuery>(s.scene, s.loader_for_queries);
  s.queries->query(points, time, out);
}
const render::HeightField& FramePipeline::heights() const {
  return state_->heights[std::size_t(state_->current)].field;
}
const render::MapSet& FramePipeline::maps() const { return state_->maker.made(state_->current); }

namespace {

// The device path's sim: recorded into the renderer's next frame; the heights come back to the CPU
// only for a bake there.
void simulate_on_device(FramePipeline::State& s, int slot, double time, FrameRecord& record) {
  HeightFrame& heights = s.heights[std::size_t(slot)];
  record.time = time;
  record.effects = s.effects;
  record.sim_on_device = true;
  record.sim_device_ms = s.device_source->device_milliseconds();
  const long long ffts = s.device_source->fft_count();
  // ahead: the next frame's heights first, for the map begun in the bake (which simulates this frame's after)
  const double sim_time = s.cone_ahead ? time + 1.0 / s.scene.fps : time;
  s.device_source->simulate(source_time(source_settings(s.scene), sim_time));
  record.ffts = s.device_source->fft_count() - ffts;
  record.choppy_residual = 0.0;
  heights.field.width = heights.field.height = s.device_source->size();
  heights.version = next_map_version();
  if (s.heights_to_cpu) {
    s.device_source->read_back(&heights.field.heights, nullptr, nullptr);
  } else {
    heights.field.heights.clear();
  }
  heights.foam.clear();
}

// The bake's share of the frame budget: what the last frame's other stages left of it (unlimited
// without a frame budget).
double bake_budget(const FramePipeline::State& s) {
  return std::isfinite(s.scene.frame_ms) ? std::max(0.0, s.scene.frame_ms - s.last_other_ms.load())
                                         : std::numeric_limits<double>::infinity();
}

// A frame's last accounting once its render ended at `drawn` (the frame began at `start`): its time,
// whether it overran the budget, and so what the next frame's bake may take.
void close_record(FramePipeline::State& s, FrameRecord& record, double start, double drawn) {
  record.frame_ms = drawn - start;
  record.overrun = std::isfinite(s.scene.frame_ms) && record.frame_ms > s.scene.frame_ms;
  s.last_other_ms = record.sim_ms + record.upload_ms + record.render_ms;
}

void simulate_into(FramePipeline::State& s, int slot, double time, FrameRecord& record) {
  if (s.sim_on_device()) {
    simulate_on_device(s, slot, time, record);
    return;
  }
  HeightFrame& heights = s.heights[std::size_t(slot)];
  record.time = time;
  record.effects = s.effects;
  s.source->make(time, record.index, heights);
  record.ffts = heights.ffts;
  record.choppy_residual = heights.choppy_residual;
}

// The maps of the frame in `slot` within the bake's share of the budget (MapMaker::make): refinement
// carried over on a static source in real time, lagged cone maps on moving ones where the scene asks.
// The device's cone bake: recorded into the renderer's next frame after the sim (a static map's
// cones once per version of its heights).
void bake_on_device(FramePipeline::State& s, const HeightFrame& frame, FrameRecord& record) {
  if (!s.device_cones) {
    const bake::HeightView heights{frame.field.heights.data(), frame.field.width, frame.field.height};
    s.device_cones = std::make_unique<render::DeviceCones>(s.renderer, heights, s.needs.cone_sectors,
                                                           s.needs.cone_address);
  }
  if (s.sim_on_device() || s.device_cones_version != frame.version) {
    // lagged: a share of the next map, and the last one served raised (render/device.h)
    if (s.cone_ahead) {  // the next frame's map from the next frame's heights, then this frame's heights
      s.device_cones->advance_lagged(s.device_budget, 1);
      const long long ffts = s.device_source->fft_count();
      s.device_source->simulate(source_time(source_settings(s.scene), record.time));
      record.ffts += s.device_source->fft_count() - ffts;
      record.cone_lag = s.device_cones->compose_lagged();
    } else {
      record.cone_lag = s.device_cones->bake_lagged(s.device_budget, s.cone_lag_frames);
    }
    s.device_cones_version = frame.version;
  }
  record.bake_on_device = true;
  record.bake_device_ms = s.device_cones->device_milliseconds();
  record.cones.sector_count = s.needs.cone_sectors;
}

void bake_into(FramePipeline::State& s, int slot, double budget_ms, FrameRecord& record) {
  record.bake_budget_ms = budget_ms;
  const HeightFrame& frame = s.heights[std::size_t(slot)];
  if (s.bake_on_device) bake_on_device(s, frame, record);
  if (s.device_levels) s.device_levels->make(s.device_budget);  // of the frame's own heights (after ahead's)
  MapHeights heights;
  heights.heights = frame.field.heights;
  heights.width = frame.field.width;
  heights.height = frame.field.height;
  heights.version = frame.version;
  heights.foam = frame.foam;
  heights.foam_version = frame.foam_version;
  ConeSchedule schedule;
  schedule.budget.milliseconds = budget_ms;
  schedule.budget.clock = s.clock;
  schedule.budget.max_work = s.scene.bake_work;
  schedule.budget.tolerance = s.scene.tolerance;
  schedule.refine = !s.deterministic;
  schedule.lag_frames = s.cone_lag_frames;
  schedule.frame_index = record.index;
  MapStats stats;
  s.maker.make(slot, heights, s.cpu_needs, schedule, stats);
  if (s.cpu_needs.cone_sectors > 0) {
    record.cones = stats.cones;
    record.pending = stats.pending;
    record.cone_lag = stats.cone_lag;
    record.cone_lift = stats.cone_lift;
  }
}

void upload_from(FramePipeline::State& s, int slot) {
  if (!s.sim_on_device() && !s.bake_on_device) {
    s.renderer.set_maps(s.maker.made(slot));
    return;
  }
  render::MapSet maps = s.maker.made(slot);
  if (s.sim_on_device()) {
    maps.width = maps.height = s.device_source->size();
    maps.heights = {};
    maps.heights_on_device = true;
    maps.foam_on_device = (s.device_source->effects() & render::device_foam) != 0;
    if (s.device_levels) {
      maps.levels_on_device = true;
      maps.level_count = s.device_levels->level_count();
      maps.level_sectors = s.device_levels->sector_count();
      maps.level_address = s.device_levels->address();
      maps.levels = {};
    }
  }
  if (s.bake_on_device) {
    render::ConeMapView& cones = maps.cones[std::size_t(render::cone_slot(s.needs.cone_sectors))];
    cones = render::ConeMapView{};
    cones.sector_count = s.needs.cone_sectors;
    cones.address = s.needs.cone_address;
    cones.on_device = true;
  }
  s.renderer.set_maps(maps);
}

}  // namespace

void FramePipeline::simulate(double time, FrameRecord& record) {
  simulate_into(*state_, state_->current, time, record);
}
void FramePipeline::bake(double budget_ms, FrameRecord& record) {
  bake_into(*state_, state_->current, budget_ms, record);
}
void FramePipeline::upload(FrameRecord&) { upload_from(*state_, state_->current); }

void FramePipeline::draw(const render::View& view, render::Frame& frame, unsigned outputs,
                         FrameRecord& record) {
  const Scene& scene = state_->scene;
  state_->renderer.render(view, {scene.method, scene.steps, scene.refine}, frame, outputs);
  record.render_device_ms = outputs != render::output_none ? frame.gpu_milliseconds : 0.0;
  // the device stages of this frame, when it has finished (its outputs read back)
  if (state_->sim_on_device()) record.sim_device_ms = state_->device_source->device_milliseconds();
  if (state_->device_cones) {
    record.bake_device_ms = state_->device_cones->device_milliseconds();
    if (state_->cone_lag_frames > 0) record.cone_lift = state_->device_cones->lift();
  }
  if (state_->device_levels) {
    record.levels_device_ms = state_->device_levels->device_milliseconds();
    record.bake_device_ms = (state_->device_cones ? record.bake_device_ms : 0.0) + record.levels_device_ms;
  }
}

FrameRecord FramePipeline::run(long long index, render::Frame& frame, unsigned outputs) {
  return run(index, scene_view(state_->scene, frame_time(state_->scene, index)), frame, outputs);
}

FrameRecord FramePipeline::run(long long index, const render::View& view, render::Frame& frame,
                               unsigned outputs) {
  State& s = *state_;
  FrameRecord record;
  record.index = index;
  const double time = frame_time(s.scene, index);
  const double start = s.clock();
  simulate(time, record);
  const double simulated = s.clock();
  bake(bake_budget(s), record);
  const double baked = s.clock();
  upload(record);
  const double uploaded = s.clock();
  draw(view, frame, outputs, record);
  const double drawn = s.clock();
  record.sim_ms = simulated - start;
  record.bake_ms = baked - simulated;
  record.upload_ms = uploaded - baked;
  record.render_ms = drawn - uploaded;
  close_record(s, record, start, drawn);
  return record;
}

void FramePipeline::run_frames(long long first, long long count, unsigned outputs,
                               const std::function<void(const FrameRecord&, const render::Frame&)>& consume) {
  State& s = *state_;
  if (s.sim_on_device() || s.bake_on_device) {  // (frame_pipeline.h: run() frame after frame)
    render::Frame frame;
    for (long long n = 0; n < count; ++n) consume(run(first + n, frame, outputs), frame);
    return;
  }
  struct Token {
    FrameRecord record;
    int slot = 0;
    double start = 0.0;
  };
  std::array<Token, 2> tokens;
  render::Frame frame;
  long long next = 0;
  tbb::parallel_pipeline(
      tokens.size(),
      tbb::make_filter<void, Token*>(tbb::filter_mode::serial_in_order,
                                     [&](tbb::flow_control& control) -> Token* {
                                       if (next >= count) {
                                         control.stop();
                                         return nullptr;
                                       }
                                       const long long index = first + next;
                                       Token& token = tokens[std::size_t(next % 2)];
                                       token.slot = int(next % 2);
                                       ++next;
                                       token.record = FrameRecord{};
                                       token.record.index = index;
                                       token.start = s.clock();
                                       simulate_into(s, token.slot, frame_time(s.scene, index), token.record);
                                       token.record.sim_ms = s.clock() - token.start;
                                       return &token;
                                     }) &
          tbb::make_filter<Token*, Token*>(tbb::filter_mode::serial_in_order,
                                           [&](Token* token) {
                                             const double start = s.clock();
                                             bake_into(s, token->slot, bake_budget(s), token->record);
                                             token->record.bake_ms = s.clock() - start;
                                             return token;
                                           }) &
          tbb::make_filter<Token*, void>(tbb::filter_mode::serial_in_order, [&](Token* token) {
            FrameRecord& record = token->record;
            const double start = s.clock();
            upload_from(s, token->slot);
            const double uploaded = s.clock();
            draw(scene_view(s.scene, record.time), frame, outputs, record);
            const double drawn = s.clock();
            record.upload_ms = uploaded - start;
            record.render_ms = drawn - uploaded;
            close_record(s, record, token->start, drawn);
            consume(record, frame);
          }));
}

}  // namespace displace::pipeline
