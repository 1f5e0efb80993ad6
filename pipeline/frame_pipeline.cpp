// pipeline/frame_pipeline.cpp - the per-frame service (frame_pipeline.h).
#include "pipeline/frame_pipeline.h"

#include <tbb/parallel_pipeline.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>

#include "pipeline/stages.h"

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
        loader_for_queries(std::move(loader)) {}

  Scene scene;
  render::Renderer& renderer;
  std::function<double()> clock;
  HeightLoader loader_for_queries;
  std::unique_ptr<HeightQuery> queries;  // made at the first query
  render::MapNeeds needs;
  Placement placement;        // where the stages run, decided once
  bool deterministic = true;  // a work budget or none: a frame depends on its index only
  int cone_lag_frames = 0;    // lagged cone maps: the scene's lag where it applies, else 0

  // kept for the whole run
  std::array<HeightFrame, 2> heights;      // frames in flight (run_frames overlaps two; run uses the first)
  std::unique_ptr<HeightStage> source;     // the sim (stages.h)
  std::unique_ptr<MapStage> maps;          // the bake, a slot per frame in flight
  int current = 0;                         // the frame in flight the stage functions work on
  std::atomic<double> last_other_ms{0.0};  // sim + upload + render of the last frame
};

namespace {

void check_first_pass(const bake::DeviceFirstPass& first_pass) {
  if (first_pass.ring_radius < 0 || first_pass.ring_radius > bake::max_first_pass_rings ||
      first_pass.window_radius < 1 || first_pass.window_radius > bake::max_first_pass_window) {
    throw SceneError("backend.device_rings must be in [0, " + std::to_string(bake::max_first_pass_rings) +
                     "] and backend.device_window in [1, " + std::to_string(bake::max_first_pass_window) +
                     "]");
  }
  if (first_pass.group && first_pass.ring_radius > 0)
    throw SceneError(
        "backend.device_group takes backend.device_rings = 0 (a first pass by groups or by rings)");
}

}  // namespace

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
  check_first_pass(scene.device_first_pass);
  s.needs = render::map_needs(scene.method, scene_view(scene, scene.start));
  s.deterministic = !std::isfinite(scene.frame_ms);
  s.placement = place_stages(scene, renderer.device());
  const Placement& placed = s.placement;
  if (scene.cone_ahead && (scene.cone_lag_frames != 1 || !placed.sim_on_device || !placed.cones_on_device ||
                           placed.heights_to_cpu))
    throw SceneError(
        "budget.cone_ahead needs budget.cone_lag_frames = 1 with the sim and the cone bake on the device "
        "(a moving source, a cone method that reads no map the CPU makes, backend.sim and backend.bake "
        "device or auto on a GPU)");
  // the sim: on the device, or the CPU's (made only then: an ocean's FFT plans and arrays are
  // hundreds of MB at 2048)
  const bool lag_possible = !s.deterministic && !s.needs.relaxed;
  const bool ahead = scene.cone_ahead && lag_possible && scene.cone_lag_frames == 1;  // real time only
  s.source = make_height_stage(scene, placed, renderer, s.loader_for_queries, ahead ? 1.0 / scene.fps : 0.0);
  s.cone_lag_frames = lag_possible && !s.source->is_static() ? scene.cone_lag_frames : 0;
  s.maps = make_map_stage(scene, placed, s.needs, renderer, *s.source, s.cone_lag_frames, ahead);
}

FramePipeline::~FramePipeline() = default;
FramePipeline::FramePipeline(FramePipeline&&) noexcept = default;
FramePipeline& FramePipeline::operator=(FramePipeline&&) noexcept = default;

const Scene& FramePipeline::scene() const { return state_->scene; }
double FramePipeline::loop_error() const { return state_->source->loop_error(); }
const Placement& FramePipeline::placement() const { return state_->placement; }

void FramePipeline::query(std::span<const QueryPoint> points, double time, QueryResult& out) {
  State& s = *state_;
  if (!s.queries) s.queries = std::make_unique<HeightQuery>(s.scene, s.loader_for_queries);
  s.queries->query(points, time, out);
}
const render::HeightField& FramePipeline::heights() const {
  return state_->heights[std::size_t(state_->current)].field;
}
const render::MapSet& FramePipeline::maps() const { return state_->maps->made(state_->current); }

namespace {

// The bake's share of the frame budget: what the last frame's other stages left of it (unlimited
// without a frame budget).
double bake_budget(const FramePipeline::State& s) {
  return std::isfinite(s.scene.frame_ms) ? std::max(0.0, s.scene.frame_ms - s.last_other_ms.load())
                                         : std::numeric_limits<double>::infinity();
}

void simulate_into(FramePipeline::State& s, int slot, double time, FrameRecord& record) {
  s.source->make(time, s.heights[std::size_t(slot)], record);
}

// The maps of the frame in `slot` within the bake's share of the budget: refinement carried over on a
// static source in real time, lagged cone maps on moving ones where the scene asks.
void bake_into(FramePipeline::State& s, int slot, double budget_ms, FrameRecord& record) {
  record.bake_budget_ms = budget_ms;
  ConeSchedule schedule;
  schedule.budget.milliseconds = budget_ms;
  schedule.budget.clock = s.clock;
  schedule.budget.max_work = s.scene.bake_work;
  schedule.budget.tolerance = s.scene.tolerance;
  schedule.refine = !s.deterministic;
  schedule.lag_frames = s.cone_lag_frames;
  schedule.frame_index = record.index;
  s.maps->make(slot, s.heights[std::size_t(slot)], schedule, record);
}

void upload_from(FramePipeline::State& s, int slot) {
  render::MapSet maps = s.maps->hand_over(slot);
  s.source->hand_over(maps);
  s.renderer.set_maps(maps);
}

// A frame's first two stages, each timed: its sim (the frame begins at `start`) and its bake.
void simulate_frame(FramePipeline::State& s, int slot, double start, FrameRecord& record) {
  simulate_into(s, slot, frame_time(s.scene, record.index), record);
  record.sim_ms = s.clock() - start;
}
void bake_frame(FramePipeline::State& s, int slot, FrameRecord& record) {
  const double start = s.clock();
  bake_into(s, slot, bake_budget(s), record);
  record.bake_ms = s.clock() - start;
}

void draw_frame(FramePipeline::State& s, const render::View& view, render::Frame& frame, unsigned outputs,
                FrameRecord& record) {
  s.renderer.render(view, {s.scene.method, s.scene.steps, s.scene.refine}, frame, outputs);
  record.render_device_ms = outputs != render::output_none ? frame.gpu_milliseconds : 0.0;
  // the device stages of this frame, when it has finished (its outputs read back)
  s.source->finished(record);
  s.maps->finished(record);
}

// A frame's last stages: its upload and draw; then its accounting (the frame began at `start`): its
// time, whether it overran the budget, and so what the next frame's bake may take.
void show_frame(FramePipeline::State& s, int slot, const render::View& view, double start,
                render::Frame& frame, unsigned outputs, FrameRecord& record) {
  const double begun = s.clock();
  upload_from(s, slot);
  const double uploaded = s.clock();
  draw_frame(s, view, frame, outputs, record);
  const double drawn = s.clock();
  record.upload_ms = uploaded - begun;
  record.render_ms = drawn - uploaded;
  record.frame_ms = drawn - start;
  record.overrun = std::isfinite(s.scene.frame_ms) && record.frame_ms > s.scene.frame_ms;
  s.last_other_ms = record.sim_ms + record.upload_ms + record.render_ms;
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
  draw_frame(*state_, view, frame, outputs, record);
}

FrameRecord FramePipeline::run(long long index, render::Frame& frame, unsigned outputs) {
  return run(index, scene_view(state_->scene, frame_time(state_->scene, index)), frame, outputs);
}

FrameRecord FramePipeline::run(long long index, const render::View& view, render::Frame& frame,
                               unsigned outputs) {
  State& s = *state_;
  FrameRecord record;
  record.index = index;
  const double start = s.clock();
  simulate_frame(s, s.current, start, record);
  bake_frame(s, s.current, record);
  show_frame(s, s.current, view, start, frame, outputs, record);
  return record;
}

void FramePipeline::run_frames(long long first, long long count, unsigned outputs,
                               const std::function<void(const FrameRecord&, const render::Frame&)>& consume) {
  State& s = *state_;
  struct Token {
    FrameRecord record;
    int slot = 0;
    double start = 0.0;
  };
  std::array<Token, 2> tokens;
  render::Frame frame;
  if (s.placement.records_into_frame()) {  // (frame_pipeline.h: run() frame after frame)
    for (long long n = 0; n < count; ++n) consume(run(first + n, frame, outputs), frame);
    return;
  }
  long long next = 0;
  tbb::parallel_pipeline(
      tokens.size(),
      tbb::make_filter<void,
                       Token*>(tbb::filter_mode::serial_in_order, [&](tbb::flow_control& control) -> Token* {
        if (next >= count) {
          control.stop();
          return nullptr;
        }
        Token& token = tokens[std::size_t(next % 2)];
        token.slot = int(next % 2);
        token.record = FrameRecord{};
        token.record.index = first + next;
        ++next;
        token.start = s.clock();
        simulate_frame(s, token.slot, token.start, token.record);
        return &token;
      }) & tbb::make_filter<Token*, Token*>(tbb::filter_mode::serial_in_order, [&](Token* token) {
        bake_frame(s, token->slot, token->record);
        return token;
      }) & tbb::make_filter<Token*, void>(tbb::filter_mode::serial_in_order, [&](Token* token) {
        FrameRecord& record = token->record;
        show_frame(s, token->slot, scene_view(s.scene, record.time), token->start, frame, outputs, record);
        consume(record, frame);
      }));
}

}  // namespace displace::pipeline
