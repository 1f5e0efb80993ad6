// pipeline/frame_pipeline.cpp - the per-frame service (frame_pipeline.h).
#include "pipeline/frame_pipeline.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_pipeline.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>
#include <span>
#include <vector>

#include "pipeline/maps.h"

namespace displace::pipeline {
namespace {

// resample_displaced's Newton steps: at most 8, a block of texels stopping once every residual is
// within 3e-4 texel (0.003 leaves heights 2.5e-4 of their range off where J is small; this, 2.5e-5).
// On the water scene's ocean (choppiness 1.5) a block measures its residual 2.5 times on average.
constexpr int choppy_iterations = 8;
constexpr float choppy_settle = 3e-4f;  // texels

double steady_milliseconds() {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

constexpr std::size_t lift_grain = 1 << 15;  // texels per task of the lift's passes

}  // namespace

// The lift and the raise. Conservative: the bilinear surface rose by at most lift = max over texels
// of (h - h_made) anywhere (it interpolates the texels' differences), so s(x) <= s_made(x) + lift <=
// (H_c + lift) + |x - p| / r_k for every p in Q_c and x in sector k - the same ratios hold from the
// raised apex. apex + lift is rounded up past both roundings by taking the next float above the
// rounded sum (both positive, so its bits plus one); 1 is above every height. The largest rise is
// taken in eight independent maxima per task (a vector's worth).
float raise_apexes(std::span<const float> made_from, std::span<const float> now, std::span<const float> apex,
                   std::span<float> raised) {
  const float lift = tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, now.size(), lift_grain), 0.0f,
      [&](const tbb::blocked_range<std::size_t>& range, float largest) {
        float rise[8] = {};
        const std::size_t first = range.begin(), whole = first + (range.size() / 8) * 8;
        for (std::size_t t = first; t < whole; t += 8) {
          for (int k = 0; k < 8; ++k) {
            const float d = now[t + k] - made_from[t + k];
            rise[k] = d > rise[k] ? d : rise[k];
          }
        }
        for (std::size_t t = whole; t < range.end(); ++t) rise[0] = std::max(rise[0], now[t] - made_from[t]);
        return std::max(largest, *std::max_element(std::begin(rise), std::end(rise)));
      },
      [](float a, float b) { return std::max(a, b); });
  if (!(lift > 0.0f)) {
    std::copy(apex.begin(), apex.end(), raised.begin());
    return 0.0f;
  }
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, apex.size(), lift_grain),
                    [&](const tbb::blocked_range<std::size_t>& range) {
                      for (std::size_t t = range.begin(); t < range.end(); ++t) {
                        raised[t] = std::min(
                            1.0f, std::bit_cast<float>(std::bit_cast<std::uint32_t>(apex[t] + lift) + 1u));
                      }
                    });
  return lift;
}

unsigned scene_effects(const Scene& scene) {
  unsigned effects = effect_heights;
  if (scene.source == SourceKind::ocean && scene.ocean.choppiness > 0.0f) effects |= effect_choppy;
  if (scene.source == SourceKind::ocean && scene.foam && scene.material == render::Material::water) {
    effects |= effect_foam;
  }
  return effects;
}

// What one frame in flight owns: its heights and maps, and what the renderer is handed.
struct FrameBuffers {
  sim::OceanFrame ocean_frame;
  std::vector<float> raw;
  std::vector<float> jacobian, foam;  // the foam effect: the Jacobian on the grid, then coverage
  std::uint64_t foam_version = 0;
  render::HeightField field;
  std::uint64_t heights_version = 0;
  bool heights_changed = false;
  bool maps_made = false;  // for the current heights
  std::vector<float> ratios, apex, relaxed;
  std::span<const float> cone_ratios;  // what upload hands over: `ratios`, or a lagged map's
  std::uint64_t cones_version = 0;
  bake::DualMaxPyramid pyramid;
  std::uint64_t pyramid_version = 0;
  DistanceMap distance;
  std::uint64_t distance_version = 0;
  bake::BakeStats cone_stats;
  render::MapSet set;

  bake::HeightView heights_view() const { return {field.heights.data(), field.width, field.height}; }
};

// The lagged cone maps of a real-time scene whose heights change: the map made last is served with
// its apexes raised by the most any texel rose since its heights, while the baker makes the next one
// over as many frames as the budget needs (frame_pipeline.h). Two slots, the one served and the one
// the baker emits into, so that a frame still uploading a map never sees it change.
struct LaggedCones {
  std::vector<float> ratios, apex;  // as emitted (apexes not raised)
  std::vector<float> heights;       // the heights they were made from
  bake::BakeStats stats;
  long long frame = 0;  // whose heights
};

struct FramePipeline::State {
  State(const Scene& s, render::Renderer& r, std::function<double()> c, HeightLoader l)
      : scene(s),
        renderer(r),
        clock(c ? std::move(c) : std::function<double()>(steady_milliseconds)),
        loader(std::move(l)) {}

  Scene scene;
  render::Renderer& renderer;
  std::function<double()> clock;
  HeightLoader loader;
  unsigned effects = effect_heights;
  render::MapNeeds needs;
  bool deterministic = true;  // a work budget or none: a frame depends on its index only
  bool static_source = false;

  // kept for the whole run
  std::optional<sim::Ocean> ocean;
  std::vector<sim::Wave> waves;
  sim::HeightMapping mapping;
  std::optional<bake::BilinearBaker> baker;
  int baker_width = 0, baker_height = 0;
  std::array<LaggedCones, 2> lagged;
  int served = -1, building = 0;  // lagged slots: served (-1: none yet) and the one being made
  int build_frames = 0;           // frames the map being made has had so far

  // frames in flight (run_frames overlaps two; run uses the first)
  std::array<FrameBuffers, 2> buffers;
  int current = 0;      // the buffers the stage functions work on
  int last_baked = -1;  // the buffers the baker emitted into last (refine continues from them)
  std::atomic<double> last_other_ms{0.0};  // sim + upload + render of the last frame

  FrameBuffers& frame() { return buffers[std::size_t(current)]; }
};

FramePipeline::FramePipeline(const Scene& scene, render::Renderer& renderer, std::function<double()> clock,
                             HeightLoader loader, AlbedoLoader albedo_loader)
    : state_(std::make_unique<State>(scene, renderer, std::move(clock), std::move(loader))) {
  State& s = *state_;
  if (!scene.albedo.empty()) {
    if (!albedo_loader)
      throw SceneError("an albedo material needs an albedo loader (the application's image reader)");
    renderer.set_albedo(albedo_loader(scene.albedo));
  } else {
    renderer.clear_albedo();
  }
  const int n = scene.source == SourceKind::image ? 0 : scene.map_size;
  if (scene.source != SourceKind::image && (n < 2 || n > 8192)) {
    throw SceneError("source.map_size must be between 2 and 8192");
  }
  if (!(scene.fps > 0.0)) throw SceneError("time.fps must be above 0");
  s.effects = scene_effects(scene);
  s.needs = render::map_needs(scene.method, scene_view(scene, scene.start));
  s.deterministic = !std::isfinite(scene.frame_ms);
  for (FrameBuffers& b : s.buffers) {
    b.field = {n, n, std::vector<float>(std::size_t(n) * n)};
    b.raw.resize(b.field.heights.size());
  }
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
        for (FrameBuffers& b : s.buffers) {
          (scene.source == SourceKind::bricks ? sim::brick_heights : sim::cliff_heights)(n, n, scene.seed,
                                                                                         b.raw);
        }
        s.mapping = sim::HeightMapping{1.0f, 0.0f};
        break;
      case SourceKind::image:
        if (!s.loader)
          throw SceneError("an image scene needs a height loader (the application's image reader)");
        s.static_source = !is_image_sequence(scene.image);
        s.mapping = sim::HeightMapping{1.0f, 0.0f};
        break;
    }
  } catch (const std::invalid_argument& error) {
    throw SceneError(std::string("the scene's source: ") + error.what());
  }
  if (s.needs.cone_sectors > 0 && scene.source != SourceKind::image) {
    s.baker.emplace(n, n, s.needs.cone_sectors, s.needs.cone_address);
    s.baker_width = s.baker_height = n;
  }
}

FramePipeline::~FramePipeline() = default;
FramePipeline::FramePipeline(FramePipeline&&) noexcept = default;
FramePipeline& FramePipeline::operator=(FramePipeline&&) noexcept = default;

const Scene& FramePipeline::scene() const { return state_->scene; }
const render::HeightField& FramePipeline::heights() const { return state_->frame().field; }
const render::MapSet& FramePipeline::maps() const { return state_->frame().set; }

namespace {

void simulate_into(FramePipeline::State& s, FrameBuffers& b, double time, FrameRecord& record) {
  record.time = time;
  record.effects = s.effects;
  if (s.scene.source == SourceKind::image) {
    if (s.static_source && b.heights_version != 0) {
      b.heights_changed = false;
      return;
    }
    render::HeightField loaded =
        s.loader(s.static_source ? s.scene.image : image_for_frame(s.scene.image, record.index));
    if (loaded.width != b.field.width || loaded.height != b.field.height) {
      b.maps_made = false;
      if (s.needs.cone_sectors > 0 &&
          (!s.baker || s.baker_width != loaded.width || s.baker_height != loaded.height)) {
        s.baker.emplace(loaded.width, loaded.height, s.needs.cone_sectors, s.needs.cone_address);
        s.baker_width = loaded.width;
        s.baker_height = loaded.height;
        s.last_baked = -1;
      }
    }
    b.field = std::move(loaded);
    b.heights_changed = true;
    b.heights_version = next_map_version();
    return;
  }
  const int n = b.field.width;
  if (s.static_source) {
    b.heights_changed = b.heights_version == 0;
    if (b.heights_changed) {
      sim::apply_mapping(s.mapping, b.raw, b.field.heights);
      b.heights_version = next_map_version();
    }
    return;
  }
  if (s.ocean) {
    const long long ffts = s.ocean->fft_count();
    const bool choppy = (s.effects & effect_choppy) != 0;
    const bool foam = (s.effects & effect_foam) != 0;
    s.ocean->evaluate(
        time, sim::ocean_heights | (choppy ? sim::ocean_displacement : 0u) | (foam ? sim::ocean_foam : 0u),
        b.ocean_frame);
    record.ffts = s.ocean->fft_count() - ffts;
    if (foam) b.jacobian.resize(b.field.heights.size());
    if (choppy) {
      record.choppy_residual = sim::resample_displaced(
          n, s.ocean->patch_size(), b.ocean_frame.height, b.ocean_frame.displacement_x,
          b.ocean_frame.displacement_y, choppy_iterations, b.raw,
          foam ? std::span<const float>(b.ocean_frame.jacobian) : std::span<const float>{},
          foam ? std::span<float>(b.jacobian) : std::span<float>{}, choppy_settle);
      sim::apply_mapping(s.mapping, b.raw, b.field.heights);
    } else {
      if (foam) b.jacobian = b.ocean_frame.jacobian;
      sim::apply_mapping(s.mapping, b.ocean_frame.height, b.field.heights);
    }
    if (foam) {
      b.foam.resize(b.jacobian.size());
      for (std::size_t t = 0; t < b.foam.size(); ++t) {
        b.foam[t] = std::clamp((foam_start - b.jacobian[t]) / (foam_start - foam_full), 0.0f, 1.0f);
      }
      b.foam_version = next_map_version();
    }
  } else {
    sim::sinusoid_heights(s.waves, s.scene.sinusoids.patch_size, time, n, n, b.raw);
    sim::apply_mapping(s.mapping, b.raw, b.field.heights);
  }
  b.heights_changed = true;
  b.heights_version = next_map_version();
}

// A lagged frame (see LaggedCones): the stage under way advances within the budget (a new one starts
// on this frame's heights when none is), and the map made last is served, raised (raise_apexes).
void bake_lagged(FramePipeline::State& s, FrameBuffers& b, const bake::Budget& budget, FrameRecord& record) {
  const int width = b.field.width, height = b.field.height;
  const std::size_t texels = b.field.heights.size();
  const int sectors = s.needs.cone_sectors;
  if (s.served >= 0 && s.lagged[std::size_t(s.served)].heights.size() != texels) s.served = -1;  // a new size
  if (!s.baker->in_progress()) {
    s.building = s.served < 0 ? 0 : 1 - s.served;
    LaggedCones& next = s.lagged[std::size_t(s.building)];
    next.heights.assign(b.field.heights.begin(), b.field.heights.end());
    next.frame = record.index;
    next.ratios.resize(texels * std::size_t(sectors));
    next.apex.resize(texels);
    s.baker->begin(b.heights_view());
    s.build_frames = 0;
  }
  LaggedCones& next = s.lagged[std::size_t(s.building)];
  const bake::ConeView cones{next.ratios.data(), width, height, sectors};
  // an even share of the stage a frame (made by its begin frame + lag frames), more while the budget
  // lasts; with no map to serve yet the first is made whole
  const double due = s.served < 0 ? 1.0 : double(s.build_frames + 1) / double(s.scene.cone_lag_frames + 1);
  const bool made = s.baker->advance(budget, cones, next.apex, next.stats, std::min(due, 1.0));
  ++s.build_frames;
  if (made) s.served = s.building;
  const LaggedCones& served = s.lagged[std::size_t(s.served)];
  b.apex.resize(texels);
  const float lift = raise_apexes(served.heights, b.field.heights, served.apex, b.apex);
  b.cone_ratios = served.ratios;
  b.cone_stats = served.stats;
  b.cones_version = next_map_version();
  record.cone_lag = record.index - served.frame;
  record.cone_lift = lift;
}

void bake_into(FramePipeline::State& s, FrameBuffers& b, double budget_ms, FrameRecord& record) {
  record.bake_budget_ms = budget_ms;
  bool remake = b.heights_changed || !b.maps_made;
  FrameBuffers& last = s.buffers[std::size_t(std::max(s.last_baked, 0))];
  if (remake && s.static_source && s.last_baked >= 0 && &last != &b && last.maps_made) {
    // the same heights in the other frame's buffers: take their maps (and the baker's progress)
    b.ratios = last.ratios;
    b.apex = last.apex;
    b.relaxed = last.relaxed;
    b.cones_version = last.cones_version;
    b.pyramid = last.pyramid;
    b.pyramid_version = last.pyramid_version;
    b.distance = last.distance;
    b.distance_version = last.distance_version;
    b.cone_stats = last.cone_stats;
    b.maps_made = true;
    b.heights_changed = false;
    remake = false;
  }
  const int width = b.field.width, height = b.field.height;
  const std::size_t texels = b.field.heights.size();
  if (s.needs.cone_sectors > 0) {
    bake::Budget budget;
    budget.milliseconds = budget_ms;
    budget.clock = s.clock;
    budget.max_work = s.scene.bake_work;
    budget.tolerance = s.scene.tolerance;
    const bool lagged =
        !s.deterministic && !s.static_source && !s.needs.relaxed && s.scene.cone_lag_frames > 0;
    if (!lagged) {
      b.ratios.resize(texels * std::size_t(s.needs.cone_sectors));
      b.apex.resize(texels);
      b.cone_ratios = b.ratios;
    }
    const bake::ConeView cones{b.ratios.data(), width, height, s.needs.cone_sectors};  // not lagged only
    if (lagged) {
      bake_lagged(s, b, budget, record);
    } else if (remake) {
      b.cone_stats = s.baker->bake(b.heights_view(), budget, cones, b.apex);
      b.cones_version = next_map_version();
    } else if (!s.deterministic && s.baker->pending() > 0) {
      // a static source in real time: refinement goes on where the last frame stopped, from the
      // ratios the baker emitted last
      if (&last != &b) {
        std::copy(last.ratios.begin(), last.ratios.end(), b.ratios.begin());
        std::copy(last.apex.begin(), last.apex.end(), b.apex.begin());
      }
      b.cone_stats = s.baker->refine(budget, cones, b.apex);
      b.cones_version = next_map_version();
    }
    s.last_baked = int(&b - s.buffers.data());
    if (s.needs.relaxed && remake) {
      b.relaxed.resize(texels);
      bake::bake_relaxed(b.heights_view(), s.needs.cone_address, {b.relaxed.data(), width, height, 1});
    }
    record.cones = b.cone_stats;
    record.pending = s.baker->pending();
  }
  if (s.needs.max_pyramid && remake) {
    b.pyramid = bake::build_dual_max_pyramid(b.heights_view(), s.needs.address);
    b.pyramid_version = next_map_version();
  }
  if (s.needs.distance && remake) {
    bake_distance(b.heights_view(), s.needs.address, s.renderer.device().max_image_dimension_3d, b.distance);
    b.distance_version = next_map_version();
  }
  b.maps_made = true;
  b.heights_changed = false;
}

void upload_from(FramePipeline::State& s, FrameBuffers& b) {
  render::MapSet& set = b.set;
  set = render::MapSet{};
  set.width = b.field.width;
  set.height = b.field.height;
  set.heights = b.field.heights;
  set.heights_version = b.heights_version;
  if (s.needs.cone_sectors > 0) {
    render::ConeMapView& cones = set.cones[std::size_t(render::cone_slot(s.needs.cone_sectors))];
    cones.sector_count = s.needs.cone_sectors;
    cones.address = s.needs.cone_address;
    cones.ratios = b.cone_ratios;
    cones.apex = b.apex;
    if (s.needs.relaxed) cones.relaxed = b.relaxed;
    cones.version = b.cones_version;
  }
  if (s.needs.max_pyramid) set.max_pyramid = {&b.pyramid, s.needs.address, b.pyramid_version};
  if (!b.foam.empty()) {
    set.foam = b.foam;
    set.foam_version = b.foam_version;
  }
  if (s.needs.distance) {
    set.distance = {b.distance.width, b.distance.height, b.distance.depth,
                    s.needs.address,  b.distance.values, b.distance_version};
  }
  s.renderer.set_maps(set);
}

}  // namespace

void FramePipeline::simulate(double time, FrameRecord& record) {
  simulate_into(*state_, state_->frame(), time, record);
}
void FramePipeline::bake(double budget_ms, FrameRecord& record) {
  bake_into(*state_, state_->frame(), budget_ms, record);
}
void FramePipeline::upload(FrameRecord&) { upload_from(*state_, state_->frame()); }

void FramePipeline::draw(const render::View& view, render::Frame& frame, unsigned outputs, FrameRecord&) {
  const Scene& scene = state_->scene;
  state_->renderer.render(view, {scene.method, scene.steps, scene.refine}, frame, outputs);
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
  const double budget = std::isfinite(s.scene.frame_ms) ? std::max(0.0, s.scene.frame_ms - s.last_other_ms)
                                                        : std::numeric_limits<double>::infinity();
  bake(budget, record);
  const double baked = s.clock();
  upload(record);
  const double uploaded = s.clock();
  draw(view, frame, outputs, record);
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

void FramePipeline::run_frames(long long first, long long count, unsigned outputs,
                               const std::function<void(const FrameRecord&, const render::Frame&)>& consume) {
  State& s = *state_;
  struct Token {
    FrameRecord record;
    FrameBuffers* buffers = nullptr;
    double start = 0.0;
  };
  std::array<Token, 2> tokens;
  render::Frame frame;
  long long next = 0;
  auto budget_now = [&] {
    return std::isfinite(s.scene.frame_ms) ? std::max(0.0, s.scene.frame_ms - s.last_other_ms.load())
                                           : std::numeric_limits<double>::infinity();
  };
  tbb::parallel_pipeline(
      tokens.size(),
      tbb::make_filter<void,
                       Token*>(tbb::filter_mode::serial_in_order, [&](tbb::flow_control& control) -> Token* {
        if (next >= count) {
          control.stop();
          return nullptr;
        }
        const long long index = first + next;
        Token& token = tokens[std::size_t(next % 2)];
        token.buffers = &s.buffers[std::size_t(next % 2)];
        ++next;
        token.record = FrameRecord{};
        token.record.index = index;
        token.start = s.clock();
        simulate_into(s, *token.buffers, frame_time(s.scene, index), token.record);
        token.record.sim_ms = s.clock() - token.start;
        return &token;
      }) & tbb::make_filter<Token*, Token*>(tbb::filter_mode::serial_in_order, [&](Token* token) {
        const double start = s.clock();
        bake_into(s, *token->buffers, budget_now(), token->record);
        token->record.bake_ms = s.clock() - start;
        return token;
      }) & tbb::make_filter<Token*, void>(tbb::filter_mode::serial_in_order, [&](Token* token) {
        FrameRecord& record = token->record;
        const double start = s.clock();
        upload_from(s, *token->buffers);
        const double uploaded = s.clock();
        const render::View view = scene_view(s.scene, record.time);
        s.renderer.render(view, {s.scene.method, s.scene.steps, s.scene.refine}, frame, outputs);
        const double drawn = s.clock();
        record.upload_ms = uploaded - start;
        record.render_ms = drawn - uploaded;
        record.frame_ms = drawn - token->start;
        record.overrun = std::isfinite(s.scene.frame_ms) && record.frame_ms > s.scene.frame_ms;
        s.last_other_ms = record.sim_ms + record.upload_ms + record.render_ms;
        consume(record, frame);
      }));
}

}  // namespace displace::pipeline
