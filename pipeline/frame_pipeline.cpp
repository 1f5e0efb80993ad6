// pipeline/frame_pipeline.cpp - the per-frame service (frame_pipeline.h).
#include "pipeline/frame_pipeline.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>
#include <vector>

#include "pipeline/maps.h"

namespace displace::pipeline {
namespace {

constexpr int choppy_iterations = 6;  // fixed-point steps of resample_displaced (residual ~1e-4 texel on the ocean)

double steady_milliseconds() {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace

unsigned scene_effects(const Scene& scene) {
  unsigned effects = effect_heights;
  if (scene.source == SourceKind::ocean && scene.ocean.choppiness > 0.0f) effects |= effect_choppy;
  if (scene.source == SourceKind::ocean && scene.foam && scene.material == render::Material::water) {
    effects |= effect_foam;
  }
  return effects;
}

struct FramePipeline::State {
  State(const Scene& s, render::Renderer& r, std::function<double()> c)
      : scene(s), renderer(r), clock(c ? std::move(c) : std::function<double()>(steady_milliseconds)) {}

  Scene scene;
  render::Renderer& renderer;
  std::function<double()> clock;
  unsigned effects = effect_heights;
  render::MapNeeds needs;
  bool deterministic = true;  // a work budget or none: a frame depends on its index only
  bool static_source = false;

  // sim
  std::optional<sim::Ocean> ocean;
  sim::OceanFrame ocean_frame;
  std::vector<sim::Wave> waves;
  sim::HeightMapping mapping;
  std::vector<float> raw;
  std::vector<float> jacobian, foam;  // the foam effect: the Jacobian on the grid, then coverage
  std::uint64_t foam_version = 0;
  render::HeightField field;
  std::uint64_t heights_version = 0;
  bool heights_changed = false;
  bool maps_made = false;  // for the current heights

  // bake
  std::optional<bake::BilinearBaker> baker;
  std::vector<float> ratios, apex, relaxed;
  std::uint64_t cones_version = 0;
  bake::DualMaxPyramid pyramid;
  std::uint64_t pyramid_version = 0;
  std::vector<float> distance;
  int distance_width = 0, distance_height = 0, distance_depth = 0;
  std::uint64_t distance_version = 0;
  bake::BakeStats cone_stats;

  render::MapSet set;
  double last_other_ms = 0.0;  // sim + upload + render of the last frame

  bake::HeightView heights_view() const { return {field.heights.data(), field.width, field.height}; }
};

FramePipeline::FramePipeline(const Scene& scene, render::Renderer& renderer, std::function<double()> clock)
    : state_(std::make_unique<State>(scene, renderer, std::move(clock))) {
  State& s = *state_;
  const int n = scene.map_size;
  if (n < 2 || n > 8192) throw SceneError("source.map_size must be between 2 and 8192");
  if (!(scene.fps > 0.0)) throw SceneError("time.fps must be above 0");
  s.effects = scene_effects(scene);
  s.needs = render::map_needs(scene.method, scene_view(scene, scene.start));
  s.deterministic = !std::isfinite(scene.frame_ms);
  s.field = {n, n, std::vector<float>(std::size_t(n) * n)};
  s.raw.resize(s.field.heights.size());
  try {
    switch (scene.source) {
      case SourceKind::ocean: {
        sim::OceanParams params = scene.ocean;
        params.size = n;
        s.ocean.emplace(params);
        s.mapping = s.ocean->mapping();
        break;
      }
      case SourceKind::sinusoids:
        s.waves = sim::make_sinusoid_waves(scene.sinusoids);
        s.mapping = sim::sinusoid_mapping(s.waves);
        break;
      case SourceKind::bricks:
      case SourceKind::cliff:
        s.static_source = true;
        (scene.source == SourceKind::bricks ? sim::brick_heights : sim::cliff_heights)(n, n, scene.seed, s.raw);
        s.mapping = sim::HeightMapping{1.0f, 0.0f};
        break;
    }
  } catch (const std::invalid_argument& error) {
    throw SceneError(std::string("the scene's source: ") + error.what());
  }
  if (s.needs.cone_sectors > 0) s.baker.emplace(n, n, s.needs.cone_sectors, s.needs.cone_address);
}

FramePipeline::~FramePipeline() = default;
FramePipeline::FramePipeline(FramePipeline&&) noexcept = default;
FramePipeline& FramePipeline::operator=(FramePipeline&&) noexcept = default;

const Scene& FramePipeline::scene() const { return state_->scene; }
const render::HeightField& FramePipeline::heights() const { return state_->field; }
const render::MapSet& FramePipeline::maps() const { return state_->set; }

void FramePipeline::simulate(double time, FrameRecord& record) {
  State& s = *state_;
  record.time = time;
  record.effects = s.effects;
  const int n = s.field.width;
  if (s.static_source) {
    s.heights_changed = s.heights_version == 0;
    if (s.heights_changed) {
      sim::apply_mapping(s.mapping, s.raw, s.field.heights);
      s.heights_version = next_map_version();
    }
    return;
  }
  if (s.ocean) {
    const long long ffts = s.ocean->fft_count();
    const bool choppy = (s.effects & effect_choppy) != 0;
    const bool foam = (s.effects & effect_foam) != 0;
    s.ocean->evaluate(time,
                      sim::ocean_heights | (choppy ? sim::ocean_displacement : 0u) | (foam ? sim::ocean_foam : 0u),
                      s.ocean_frame);
    record.ffts = s.ocean->fft_count() - ffts;
    if (foam) s.jacobian.resize(s.field.heights.size());
    if (choppy) {
      record.choppy_residual = sim::resample_displaced(
          n, s.ocean->patch_size(), s.ocean_frame.height, s.ocean_frame.displacement_x, s.ocean_frame.displacement_y,
          choppy_iterations, s.raw, foam ? std::span<const float>(s.ocean_frame.jacobian) : std::span<const float>{},
          foam ? std::span<float>(s.jacobian) : std::span<float>{});
      sim::apply_mapping(s.mapping, s.raw, s.field.heights);
    } else {
      if (foam) s.jacobian = s.ocean_frame.jacobian;
      sim::apply_mapping(s.mapping, s.ocean_frame.height, s.field.heights);
    }
    if (foam) {
      s.foam.resize(s.jacobian.size());
      for (std::size_t t = 0; t < s.foam.size(); ++t) {
        s.foam[t] = std::clamp((foam_start - s.jacobian[t]) / (foam_start - foam_full), 0.0f, 1.0f);
      }
      s.foam_version = next_map_version();
    }
  } else {
    sim::sinusoid_heights(s.waves, s.scene.sinusoids.patch_size, time, n, n, s.raw);
    sim::apply_mapping(s.mapping, s.raw, s.field.heights);
  }
  s.heights_changed = true;
  s.heights_version = next_map_version();
}

void FramePipeline::bake(double budget_ms, FrameRecord& record) {
  State& s = *state_;
  record.bake_budget_ms = budget_ms;
  const bool remake = s.heights_changed || !s.maps_made;
  const int n = s.field.width;
  const std::size_t texels = s.field.heights.size();
  if (s.needs.cone_sectors > 0) {
    bake::Budget budget;
    budget.milliseconds = budget_ms;
    budget.clock = s.clock;
    budget.max_work = s.scene.bake_work;
    budget.tolerance = s.scene.tolerance;
    s.ratios.resize(texels * std::size_t(s.needs.cone_sectors));
    s.apex.resize(texels);
    const bake::ConeView cones{s.ratios.data(), n, n, s.needs.cone_sectors};
    if (remake) {
      s.cone_stats = s.baker->bake(s.heights_view(), budget, cones, s.apex);
      s.cones_version = next_map_version();
    } else if (!s.deterministic && s.baker->pending() > 0) {
      // a static source in real time: refinement goes on where the last frame stopped
      s.cone_stats = s.baker->refine(budget, cones, s.apex);
      s.cones_version = next_map_version();
    }
    if (s.needs.relaxed && remake) {
      s.relaxed.resize(texels);
      bake::bake_relaxed(s.heights_view(), s.needs.cone_address, {s.relaxed.data(), n, n, 1});
    }
    record.cones = s.cone_stats;
    record.pending = s.baker->pending();
  }
  if (s.needs.max_pyramid && remake) {
    s.pyramid = bake::build_dual_max_pyramid(s.heights_view(), s.needs.address);
    s.pyramid_version = next_map_version();
  }
  if (s.needs.distance && remake) {
    const int side = std::min(distance_max_side, s.renderer.device().max_image_dimension_3d);
    s.distance_width = std::min(n, side);
    s.distance_height = std::min(n, side);
    s.distance_depth = std::min(distance_slices, s.renderer.device().max_image_dimension_3d);
    s.distance.resize(std::size_t(s.distance_width) * s.distance_height * s.distance_depth);
    bake::bake_distance_map(s.heights_view(), s.needs.address,
                            {s.distance.data(), s.distance_width, s.distance_height, s.distance_depth});
    s.distance_version = next_map_version();
  }
  s.maps_made = true;
  s.heights_changed = false;
}

void FramePipeline::upload(FrameRecord&) {
  State& s = *state_;
  render::MapSet& set = s.set;
  set = render::MapSet{};
  set.width = s.field.width;
  set.height = s.field.height;
  set.heights = s.field.heights;
  set.heights_version = s.heights_version;
  if (s.needs.cone_sectors > 0) {
    render::ConeMapView& cones = set.cones[std::size_t(render::cone_slot(s.needs.cone_sectors))];
    cones.sector_count = s.needs.cone_sectors;
    cones.address = s.needs.cone_address;
    cones.ratios = s.ratios;
    cones.apex = s.apex;
    if (s.needs.relaxed) cones.relaxed = s.relaxed;
    cones.version = s.cones_version;
  }
  if (s.needs.max_pyramid) set.max_pyramid = {&s.pyramid, s.needs.address, s.pyramid_version};
  if (!s.foam.empty()) {
    set.foam = s.foam;
    set.foam_version = s.foam_version;
  }
  if (s.needs.distance) {
    set.distance = {s.distance_width, s.distance_height, s.distance_depth, s.needs.address, s.distance,
                    s.distance_version};
  }
  s.renderer.set_maps(set);
}

void FramePipeline::draw(const render::View& view, render::Frame& frame, unsigned outputs, FrameRecord&) {
  const Scene& scene = state_->scene;
  state_->renderer.render(view, {scene.method, scene.steps, scene.refine}, frame, outputs);
}

FrameRecord FramePipeline::run(long long index, render::Frame& frame, unsigned outputs) {
  State& s = *state_;
  FrameRecord record;
  record.index = index;
  const double time = frame_time(s.scene, index);
  const double start = s.clock();
  simulate(time, record);
  const double simulated = s.clock();
  const double budget = std::isfinite(s.scene.frame_ms) ? std::max(0.0, s.scene.frame_ms - s.last_other_ms)
                                                        : std::numeric_limits<double>::infinity();
  bake(budget, record);
  const double baked = s.clock();
  upload(record);
  const double uploaded = s.clock();
  draw(scene_view(s.scene, time), frame, outputs, record);
  const double drawn = s.clock();
  record.sim_ms = simulated - start;
  record.bake_ms = baked - simulated;
  record.upload_ms = uploaded - baked;
  record.render_ms = drawn - uploaded;
  record.frame_ms = drawn - start;
  record.overrun = std::isfinite(s.scene.frame_ms) && record.frame_ms > s.scene.frame_ms;
  s.last_other_ms = record.sim_ms + record.upload_ms + record.render_ms;
  return record;
}

}  // namespace displace::pipeline
