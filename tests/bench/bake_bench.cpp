// tests/bench/bake_bench.cpp - milliseconds per bake next to how tight the map is.
//
// tightness = mean emitted ratio / mean exact ratio (1 = exact; above 1 means the baker claims more
// empty space than there is, and violations counts the ratios above exact). Maps: a 512-style FFT
// ocean frame, sinusoid water and a brick-like map, at 128..1024. `bilinear` (bake_bilinear_cones)
// bakes another map - cones for the bilinear surface from a texel's whole square, with apex
// heights - so its tightness is only a comparison of means and it counts no violations. Maps have
// 4 sectors; BM_Bake8 is the budgeted baker with 8 (octant sweeps). BM_Update times one update()
// after a local change, with the repair the baker picks and with the incremental one forced;
// BM_UpdateBilinear the bilinear baker's update() (the frame pipeline's, for an image sequence's
// frame that changed in places) against a whole bake of the same heights.
// BM_BakeNonSquare/<map>/<W>x<H> (4 sectors) and BM_BakeNonSquare8 (8): the budgeted baker, no
// limit, on non-square maps next to the square map of about as many texels (2048x1024, 1024x2048
// and 1448x1448; 1024x512, 512x1024 and 724x724; 4096x256, 256x4096 and 1024x1024); the ocean is
// the FFT ocean of the longer side sampled along the shorter (test::make_ocean); refined_frac is
// the share of texels the refinement stages took after stage L.
// BM_BakeRelaxed/<map>/<baker>/<size>: bake_relaxed (relaxed) and the search it replaced,
// bake_relaxed_reference (relaxed-reference, up to 512: minutes above), 1 sector, clamp, on the
// built-in bricks and cliff (sim::brick_heights, sim::cliff_heights) and test::make_pockets;
// vs_conservative = mean ratio / the exact conservative map's; where the reference row of the same
// map and size ran before in the process, vs_reference = mean ratio / the reference's and wider =
// ratios above the reference's, bit for bit (-1: not compared). BM_BakeRelaxedBudgeted/ocean/<ms>/<size>:
// RelaxedBaker, one bake() a frame of the 256 ocean at a budget of 0, 16 or 50 ms (4 sectors, wrap).
//   build/displace_bench --benchmark_filter=Bake --benchmark_repetitions=5
//   (add --benchmark_report_aggregates_only=true for medians only)
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <mutex>
#include <span>
#include <string>
#include <tuple>
#include <vector>

#include "bake/bake.h"
#include "bake/work_span.h"
#include "sim/sim.h"
#include "tests/test_maps.h"

namespace {

using namespace displace;

enum class MapKind { ocean, sinusoids, bricks };
constexpr MapKind map_kinds[] = {MapKind::ocean, MapKind::sinusoids, MapKind::bricks};

const char* kind_name(MapKind kind) {
  switch (kind) {
    case MapKind::ocean: return "ocean";
    case MapKind::sinusoids: return "sinusoids";
    case MapKind::bricks: return "bricks";
  }
  return "?";
}

std::vector<float> make_heights(MapKind kind, int width, int height) {
  std::vector<float> heights(std::size_t(width) * height);
  if (kind == MapKind::ocean) {
    heights = test::make_ocean(width, height).values;
  } else if (kind == MapKind::sinusoids) {
    sim::SinusoidParams params;
    const std::vector<sim::Wave> waves = sim::make_sinusoid_waves(params);
    std::vector<float> raw(heights.size());
    sim::sinusoid_heights(waves, params.patch_size, 0.0f, width, height, raw);
    sim::apply_mapping(sim::sinusoid_mapping(waves), raw, heights);
  } else {
    heights = test::make_bricks(width, height).values;
  }
  return heights;
}

struct Reference {
  std::vector<float> heights;
  std::vector<float> exact;
  double exact_mean = 0.0;
};

// Heights and exact cones, made once per map, size and sector count.
const Reference& reference(MapKind kind, int width, int height, int sector_count) {
  static std::mutex mutex;
  static std::map<std::tuple<int, int, int, int>, Reference> cache;
  std::lock_guard<std::mutex> lock(mutex);
  Reference& entry = cache[{int(kind), width, height, sector_count}];
  if (entry.heights.empty()) {
    entry.heights = make_heights(kind, width, height);
    entry.exact.resize(entry.heights.size() * sector_count);
    const bake::BakeStats stats = bake::bake_exact({entry.heights.data(), width, height}, bake::Address::wrap,
                                                   {entry.exact.data(), width, height, sector_count});
    entry.exact_mean = stats.mean_ratio;
  }
  return entry;
}
const Reference& reference(MapKind kind, int size, int sector_count) {
  return reference(kind, size, size, sector_count);
}

enum class Baker {
  exact,
  original,
  paper_adaptive,
  budgeted,
  budgeted_zero,
  budgeted_frame,
  budgeted_long,
  bilinear
};
constexpr double frame_budget_ms = 16.0;  // one 60 Hz frame
constexpr double long_budget_ms = 50.0;   // a 20 Hz update

void run_map(benchmark::State& state, MapKind kind, Baker baker, int width, int height, int sector_count) {
  const Reference& ref = reference(kind, width, height, sector_count);
  std::vector<float> cones(ref.exact.size()), apex(ref.heights.size());
  const bake::HeightView heights{ref.heights.data(), width, height};
  const bake::ConeView out{cones.data(), width, height, sector_count};
  bake::BakeStats stats;
  // a frame pipeline keeps its baker (and its buffers) from frame to frame
  bake::BudgetedBaker budgeted(width, height, sector_count, bake::Address::wrap);
  for (auto _ : state) {
    switch (baker) {
      case Baker::exact: stats = bake::bake_exact(heights, bake::Address::wrap, out); break;
      case Baker::original: stats = bake::bake_original(heights, bake::Address::wrap, out); break;
      case Baker::bilinear: stats = bake::bake_bilinear_cones(heights, bake::Address::wrap, out, apex); break;
      case Baker::paper_adaptive:
        stats = bake::bake_paper_adaptive(heights, bake::Address::wrap, {}, out);
        break;
      case Baker::budgeted:
      case Baker::budgeted_zero:
      case Baker::budgeted_frame:
      case Baker::budgeted_long: {
        bake::Budget budget;
        if (baker == Baker::budgeted_zero) budget.milliseconds = 0.0;
        if (baker == Baker::budgeted_frame) budget.milliseconds = frame_budget_ms;
        if (baker == Baker::budgeted_long) budget.milliseconds = long_budget_ms;
        stats = budgeted.bake(heights, budget, out);  // a new frame: nothing carried over
        break;
      }
    }
    benchmark::DoNotOptimize(cones.data());
  }
  state.counters["tightness"] = stats.mean_ratio / ref.exact_mean;
  if (baker != Baker::bilinear) {
    long long violations = 0;
    for (std::size_t n = 0; n < cones.size(); ++n) violations += cones[n] > ref.exact[n];
    state.counters["violations"] = double(violations);
  }
  const double texels = double(width) * double(height);
  state.counters["fallback_frac"] = double(stats.texels_fallback) / texels;
  state.counters["refined_frac"] = double(stats.texels_refined) / texels;
  state.counters["work_per_texel"] = double(stats.work) / texels;
}

void run(benchmark::State& state, MapKind kind, Baker baker, int sector_count = 4) {
  const int size = int(state.range(0));
  run_map(state, kind, baker, size, size, sector_count);
}

// Frame `frame`'s local change, outside the timing: a rect x rect patch raised and lowered in a
// checkerboard by 0.05 (the other way round every other frame), at a place that moves from frame to
// frame.
bake::Rect change_patch(benchmark::State& state, std::vector<float>& heights, int size, int rect, int frame) {
  state.PauseTiming();
  const int x0 = (37 * frame) % (size - rect), y0 = (53 * frame) % (size - rect);
  const float sign = frame % 2 == 0 ? 1.0f : -1.0f;
  for (int i = y0; i < y0 + rect; ++i)
    for (int j = x0; j < x0 + rect; ++j) {
      float& h = heights[std::size_t(i) * size + j];
      h = std::clamp(h + sign * ((i + j) % 2 == 0 ? 0.05f : -0.05f), 0.0f, 1.0f);
    }
  state.ResumeTiming();
  return {x0, y0, x0 + rect, y0 + rect};
}

// One frame of update() after a local change: a rect x rect patch raised and lowered in a
// checkerboard, moved every iteration; the baker picks its repair (cheaper) or is told to repair
// incrementally (with no limit, so it also refines what the change left loose).
void run_update(benchmark::State& state, MapKind kind, bake::BudgetedBaker::UpdatePolicy policy) {
  const int size = int(state.range(0)), rect = int(state.range(1));
  const Reference& ref = reference(kind, size, 4);
  std::vector<float> heights = ref.heights, cones(ref.exact.size());
  bake::BudgetedBaker baker(size, size, 4, bake::Address::wrap);
  baker.bake({heights.data(), size, size}, {}, {cones.data(), size, size, 4});
  bake::BakeStats stats;
  int frame = 0;
  for (auto _ : state) {
    const bake::Rect dirty = change_patch(state, heights, size, rect, frame);
    stats = baker.update({heights.data(), size, size}, std::span<const bake::Rect>(&dirty, 1), {},
                         {cones.data(), size, size, 4}, policy);
    ++frame;
  }
  state.counters["pending"] = double(stats.texels_fallback);
}

// ---- the render-safe (bilinear-surface) cone maps: BM_BakeBilinear/ocean/{budgeted,full}/N

// Ocean frames 1/60 s apart and, where affordable, bake_bilinear_cones' maps of them.
struct OceanFrames {
  std::vector<std::vector<float>> heights;
  std::vector<double> full_mean;  // per frame; NaN where the full bake was not run
};

const OceanFrames& ocean_frames(int size, MapKind kind = MapKind::ocean) {
  static std::mutex mutex;
  static std::map<std::pair<int, int>, OceanFrames> cache;
  std::lock_guard<std::mutex> lock(mutex);
  OceanFrames& entry = cache[{size, int(kind)}];
  if (entry.heights.empty()) {
    const int count = size <= 512 ? 4 : 2;
    sim::OceanParams params;
    params.size = size;
    sim::Ocean ocean(params);
    sim::OceanFrame frame;
    sim::SinusoidParams sinusoid_params;
    const std::vector<sim::Wave> waves = sim::make_sinusoid_waves(sinusoid_params);
    for (int n = 0; n < count; ++n) {
      std::vector<float> heights(std::size_t(size) * size);
      if (kind == MapKind::ocean) {
        ocean.evaluate(float(n) / 60.0f, sim::ocean_heights, frame);
        sim::apply_mapping(ocean.mapping(), frame.height, heights);
      } else if (kind == MapKind::sinusoids) {
        std::vector<float> raw(heights.size());
        sim::sinusoid_heights(waves, sinusoid_params.patch_size, float(n) / 60.0f, size, size, raw);
        sim::apply_mapping(sim::sinusoid_mapping(waves), raw, heights);
      } else {
        heights = test::make_bricks(size, size).values;
      }
      entry.heights.push_back(std::move(heights));
      double mean = std::numeric_limits<double>::quiet_NaN();
      if (size <= 1024) {  // the full bake takes about 7 s at 1024 and minutes above
        std::vector<float> cones(std::size_t(size) * size * 4), apex(std::size_t(size) * size);
        mean = bake::bake_bilinear_cones({entry.heights.back().data(), size, size}, bake::Address::wrap,
                                         {cones.data(), size, size, 4}, apex)
                   .mean_ratio;
      }
      entry.full_mean.push_back(mean);
    }
  }
  return entry;
}

// Sampled check of the contract: for every 97th texel c, points p of Q_c (corners, edge midpoints,
// centre) and surface points x on the half-texel grid within 12 texels, s(x) <= H_c + |x - p| / r_k
// for each quadrant k holding x - p (both on a boundary). Returns the pairs that fail by over 1e-6.
long long sampled_violations(const std::vector<float>& heights, int size, const std::vector<float>& cones,
                             const std::vector<float>& apex) {
  auto h = [&](int i, int j) {
    return double(heights[std::size_t((i % size + size) % size) * size + (j % size + size) % size]);
  };
  auto s = [&](int y, int x) {  // at half-texel coordinates (x / 2, y / 2) from texel centres
    const int i0 = y >= 0 ? y / 2 : -((1 - y) / 2), j0 = x >= 0 ? x / 2 : -((1 - x) / 2);
    const double fy = (y - 2 * i0) * 0.5, fx = (x - 2 * j0) * 0.5;
    return (h(i0, j0) * (1 - fx) + h(i0, j0 + 1) * fx) * (1 - fy) +
           (h(i0 + 1, j0) * (1 - fx) + h(i0 + 1, j0 + 1) * fx) * fy;
  };
  constexpr int reach = 24;  // half texels
  long long violations = 0;
  for (std::size_t t = 0; t < heights.size(); t += 97) {
    const int i = int(t / size), j = int(t % size);
    const double hc = apex[t];
    for (int py = 2 * i - 1; py <= 2 * i + 1; ++py)
      for (int px = 2 * j - 1; px <= 2 * j + 1; ++px)
        for (int y = py - reach; y <= py + reach; ++y)
          for (int x = px - reach; x <= px + reach; ++x) {
            const double above = s(y, x) - hc;
            if (!(above > 1e-6)) continue;
            const int dx = x - px, dy = y - py;
            const double distance = std::hypot(dx * 0.5 / size, dy * 0.5 / size);
            for (int k = 0; k < 4; ++k) {
              const bool in = (k == 0 || k == 3 ? dx >= 0 : dx <= 0) && (k <= 1 ? dy >= 0 : dy <= 0);
              if (in && above > distance / cones[t * 4 + k] + 1e-6) ++violations;
            }
          }
  }
  return violations;
}

// Stage L's scaling, from one more bake of each frame with its work and span recorded
// (bake/work_span.h): ws_work_ms, what one thread takes; ws_bound2_ms and ws_bound16_ms, at least
// what 2 and 16 threads take (serial + the regions' max(work / T, span)); ws_bound16_vs_time, the
// 16-thread bound over this run's milliseconds per bake (the predicted ratio when this run has 2
// cores: taskset -c 0,1).
void add_work_span_counters(benchmark::State& state, bake::BilinearBaker& baker, const OceanFrames& frames,
                            double ms_per_bake) {
  const int size = int(state.range(0));
  std::vector<float> cones(std::size_t(size) * size * 4), apex(std::size_t(size) * size);
  bake::detail::WorkSpan record;
  bake::Budget budget;
  budget.milliseconds = 0.0;
  for (const std::vector<float>& heights : frames.heights) {
    const bake::detail::WorkSpanRecording recording(record);
    baker.bake({heights.data(), size, size}, budget, {cones.data(), size, size, 4}, apex);
  }
  const double bakes = double(frames.heights.size());
  state.counters["ws_work_ms"] = 1e3 * bake::detail::work_span_total(record) / bakes;
  state.counters["ws_bound2_ms"] = 1e3 * bake::detail::work_span_bound(record, 2) / bakes;
  state.counters["ws_bound16_ms"] = 1e3 * bake::detail::work_span_bound(record, 16) / bakes;
  state.counters["ws_bound16_vs_time"] =
      1e3 * bake::detail::work_span_bound(record, 16) / bakes / ms_per_bake;
}

void run_bilinear(benchmark::State& state, bool budgeted,
                  double budget_ms = std::numeric_limits<double>::infinity(), MapKind kind = MapKind::ocean) {
  const int size = int(state.range(0));
  const OceanFrames& frames = ocean_frames(size, kind);
  std::vector<float> cones(std::size_t(size) * size * 4), apex(std::size_t(size) * size);
  const bake::ConeView out{cones.data(), size, size, 4};
  bake::BilinearBaker baker(size, size, 4, bake::Address::wrap);  // kept from frame to frame
  bake::BakeStats stats;
  if (budgeted) {  // a kept baker: its buffers exist from the first frame on, which is not timed
    bake::Budget budget;
    budget.milliseconds = 0.0;
    baker.bake({frames.heights[0].data(), size, size}, budget, out, apex);
  }
  std::size_t frame = 0, last = 0;
  const auto start = std::chrono::steady_clock::now();
  for (auto _ : state) {
    last = frame % frames.heights.size();
    const bake::HeightView heights{frames.heights[last].data(), size, size};
    bake::Budget budget;
    budget.milliseconds = budget_ms;
    stats = budgeted ? baker.bake(heights, budget, out, apex)
                     : bake::bake_bilinear_cones(heights, bake::Address::wrap, out, apex);
    benchmark::DoNotOptimize(cones.data());
    ++frame;
  }
  const double elapsed_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  if (budgeted && budget_ms == 0.0) add_work_span_counters(state, baker, frames, elapsed_ms / double(frame));
  if (!std::isnan(frames.full_mean[last]))
    state.counters["mean_ratio_vs_full"] = stats.mean_ratio / frames.full_mean[last];
  state.counters["mean_ratio"] = stats.mean_ratio;
  state.counters["violations"] = double(sampled_violations(frames.heights[last], size, cones, apex));
  state.counters["searched_frac"] = double(stats.texels_refined) / double(size * size);
}

// Stage L of the bilinear baker (0 ms) on a non-square map, its baker kept and warmed up.
void run_bilinear_map(benchmark::State& state, MapKind kind, int width, int height) {
  static std::mutex mutex;
  static std::map<std::tuple<int, int, int>, std::vector<float>> cache;
  std::vector<float>* heights;
  {
    std::lock_guard<std::mutex> lock(mutex);
    heights = &cache[{int(kind), width, height}];
    if (heights->empty()) *heights = make_heights(kind, width, height);
  }
  std::vector<float> cones(heights->size() * 4), apex(heights->size());
  bake::BilinearBaker baker(width, height, 4, bake::Address::wrap);
  bake::Budget budget;
  budget.milliseconds = 0.0;
  bake::BakeStats stats =
      baker.bake({heights->data(), width, height}, budget, {cones.data(), width, height, 4}, apex);
  for (auto _ : state) {
    stats = baker.bake({heights->data(), width, height}, budget, {cones.data(), width, height, 4}, apex);
    benchmark::DoNotOptimize(cones.data());
  }
  state.counters["mean_ratio"] = stats.mean_ratio;
}

// One frame of BilinearBaker::update after a local change (what the frame pipeline runs for an image
// sequence's frame that changed in places), no limit: the same moving checkerboard patch as
// run_update, repaired by update() or baked whole (`whole`) by the same kept baker.
void run_bilinear_update(benchmark::State& state, MapKind kind, bool whole) {
  const int size = int(state.range(0)), rect = int(state.range(1));
  std::vector<float> heights = make_heights(kind, size, size);
  std::vector<float> cones(std::size_t(size) * size * 4), apex(std::size_t(size) * size);
  const bake::ConeView out{cones.data(), size, size, 4};
  bake::BilinearBaker baker(size, size, 4, bake::Address::wrap);
  baker.bake({heights.data(), size, size}, {}, out, apex);
  bake::BakeStats stats;
  int frame = 0;
  for (auto _ : state) {
    const bake::Rect dirty = change_patch(state, heights, size, rect, frame);
    const bake::HeightView view{heights.data(), size, size};
    stats = whole ? baker.bake(view, {}, out, apex)
                  : baker.update(view, std::span<const bake::Rect>(&dirty, 1), {}, out, apex);
    benchmark::DoNotOptimize(cones.data());
    ++frame;
  }
  state.counters["mean_ratio"] = stats.mean_ratio;
  state.counters["searched_frac"] = double(stats.texels_refined) / double(size * size);
  state.counters["violations"] = double(sampled_violations(heights, size, cones, apex));
}

// ---- relaxed cone maps: BM_BakeRelaxed/<map>/<baker>/<size>

enum class ReliefKind { built_in_bricks, built_in_cliff, pockets };

const char* relief_name(ReliefKind kind) {
  switch (kind) {
    case ReliefKind::built_in_bricks: return "bricks";
    case ReliefKind::built_in_cliff: return "cliff";
    case ReliefKind::pockets: return "pockets";
  }
  return "?";
}

// Heights, the exact conservative map's mean and (once its row has run) the reference relaxed map.
struct RelaxedReference {
  std::vector<float> heights;
  double conservative_mean = 0.0;
  std::vector<float> relaxed;
};

RelaxedReference& relaxed_reference(ReliefKind kind, int size) {
  static std::mutex mutex;
  static std::map<std::pair<int, int>, RelaxedReference> cache;
  std::lock_guard<std::mutex> lock(mutex);
  RelaxedReference& entry = cache[{int(kind), size}];
  if (entry.heights.empty()) {
    entry.heights.resize(std::size_t(size) * size);
    if (kind == ReliefKind::built_in_bricks) sim::brick_heights(size, size, 1, entry.heights);
    if (kind == ReliefKind::built_in_cliff) sim::cliff_heights(size, size, 1, entry.heights);
    if (kind == ReliefKind::pockets) entry.heights = test::make_pockets(size, size).values;
    std::vector<float> exact(entry.heights.size());
    entry.conservative_mean = bake::bake_exact({entry.heights.data(), size, size}, bake::Address::clamp,
                                               {exact.data(), size, size, 1})
                                  .mean_ratio;
  }
  return entry;
}

void run_relaxed(benchmark::State& state, ReliefKind kind, bool reference) {
  const int size = int(state.range(0));
  RelaxedReference& ref = relaxed_reference(kind, size);
  std::vector<float> cones(ref.heights.size());
  const bake::HeightView heights{ref.heights.data(), size, size};
  const bake::ConeView out{cones.data(), size, size, 1};
  bake::BakeStats stats;
  for (auto _ : state) {
    stats = reference ? bake::bake_relaxed_reference(heights, bake::Address::clamp, out)
                      : bake::bake_relaxed(heights, bake::Address::clamp, out);
    benchmark::DoNotOptimize(cones.data());
  }
  if (reference) ref.relaxed = cones;
  state.counters["mean_ratio"] = stats.mean_ratio;
  state.counters["vs_conservative"] = stats.mean_ratio / ref.conservative_mean;
  state.counters["work_per_texel"] = double(stats.work) / double(cones.size());
  double wider = -1.0, vs_reference = -1.0;
  if (!ref.relaxed.empty()) {
    wider = 0.0;
    double sum = 0.0;
    for (std::size_t n = 0; n < cones.size(); ++n) {
      wider += cones[n] > ref.relaxed[n];
      sum += ref.relaxed[n];
    }
    vs_reference = stats.mean_ratio / (sum / double(cones.size()));
  }
  state.counters["wider"] = wider;
  state.counters["vs_reference"] = vs_reference;
}

// RelaxedBaker on frames of the ocean (4 sectors, wrap), one bake() a frame at a budget:
// pending_frac = texels still at stage L's ratio after the call, vs_relaxed = mean ratio / the full
// relaxed map's (bake_relaxed, once per frame at set-up).
void run_relaxed_budgeted(benchmark::State& state, double budget_ms) {
  const int size = int(state.range(0));
  const OceanFrames& frames = ocean_frames(size);
  static std::mutex mutex;
  static std::map<int, std::vector<double>> full_means;
  std::vector<double> full;
  {
    std::lock_guard<std::mutex> lock(mutex);
    std::vector<double>& means = full_means[size];
    if (means.empty())
      for (const std::vector<float>& heights : frames.heights) {
        std::vector<float> cones(heights.size() * 4);
        means.push_back(bake::bake_relaxed({heights.data(), size, size}, bake::Address::wrap,
                                           {cones.data(), size, size, 4})
                            .mean_ratio);
      }
    full = means;
  }
  std::vector<float> cones(std::size_t(size) * size * 4);
  bake::RelaxedBaker baker(size, size, 4, bake::Address::wrap);  // kept from frame to frame
  bake::BakeStats stats;
  std::size_t frame = 0, last = 0;
  for (auto _ : state) {
    last = frame % frames.heights.size();
    bake::Budget budget;
    budget.milliseconds = budget_ms;
    stats = baker.bake({frames.heights[last].data(), size, size}, budget, {cones.data(), size, size, 4});
    benchmark::DoNotOptimize(cones.data());
    ++frame;
  }
  state.counters["pending_frac"] = double(stats.texels_fallback) / double(size * size);
  state.counters["mean_ratio"] = stats.mean_ratio;
  state.counters["vs_relaxed"] = stats.mean_ratio / full[last];
}

struct Registration {
  Registration() {
    // BM_BakeRelaxedBudgeted/ocean/<budget>/<size>: a frame of relaxed cones within a budget
    for (double ms : {0.0, 16.0, 50.0}) {
      auto* b = benchmark::RegisterBenchmark(
          (std::string("BM_BakeRelaxedBudgeted/ocean/") + std::to_string(int(ms)) + "ms").c_str(),
          [ms](benchmark::State& state) { run_relaxed_budgeted(state, ms); });
      b->Arg(256)
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime();  // the full bake: seconds at 256, a minute at 512
    }
    // the reference first, so that the relaxed row of the same map and size compares with it
    for (ReliefKind kind : {ReliefKind::built_in_bricks, ReliefKind::built_in_cliff, ReliefKind::pockets})
      for (int size : {256, 512, 1024})
        for (bool reference : {true, false}) {
          if (reference && size > 512) continue;  // minutes above 512
          auto* b = benchmark::RegisterBenchmark(
              (std::string("BM_BakeRelaxed/") + relief_name(kind) +
               (reference ? "/relaxed-reference" : "/relaxed"))
                  .c_str(),
              [kind, reference](benchmark::State& state) { run_relaxed(state, kind, reference); });
          b->Arg(size)->Unit(benchmark::kMillisecond)->UseRealTime();
          if (reference) b->Iterations(1);
        }
    // BM_BakeBilinearNonSquare/<map>/<W>x<H>: stage L on non-square maps next to the square one
    for (MapKind kind : {MapKind::ocean, MapKind::bricks})
      for (const auto& [width, height] : {std::pair{2048, 1024}, std::pair{1024, 2048}, std::pair{1448, 1448},
                                          std::pair{4096, 256}, std::pair{1024, 1024}}) {
        auto* b =
            benchmark::RegisterBenchmark((std::string("BM_BakeBilinearNonSquare/") + kind_name(kind) + "/" +
                                          std::to_string(width) + "x" + std::to_string(height))
                                             .c_str(),
                                         [kind, width = width, height = height](benchmark::State& state) {
                                           run_bilinear_map(state, kind, width, height);
                                         });
        b->Unit(benchmark::kMillisecond)->UseRealTime();
      }
    for (bool budgeted : {true, false})
      for (int size : {256, 512, 1024, 2048}) {
        if (!budgeted && size > 512) continue;  // the full bake: 7 s at 1024, minutes above
        auto* b = benchmark::RegisterBenchmark(
            (std::string("BM_BakeBilinear/ocean/") + (budgeted ? "budgeted" : "full")).c_str(),
            [budgeted](benchmark::State& state) { run_bilinear(state, budgeted); });
        b->Arg(size)->Unit(benchmark::kMillisecond)->UseRealTime();
        if (!budgeted || size >= 2048) b->Iterations(2);
      }
    // stage L alone (0 ms) and a 60 Hz frame's worth of refinement
    for (double ms : {0.0, 16.0}) {
      auto* b = benchmark::RegisterBenchmark(
          (std::string("BM_BakeBilinear/ocean/budgeted-") + (ms == 0.0 ? "0ms" : "16ms")).c_str(),
          [ms](benchmark::State& state) { run_bilinear(state, true, ms); });
      b->Arg(256)->Arg(512)->Arg(1024)->Arg(2048)->Unit(benchmark::kMillisecond)->UseRealTime();
    }
    // the other benchmark maps: stage L alone against the full bake
    for (MapKind kind : {MapKind::sinusoids, MapKind::bricks})
      for (bool budgeted : {true, false}) {
        auto* b = benchmark::RegisterBenchmark(
            (std::string("BM_BakeBilinear/") + kind_name(kind) + "/" + (budgeted ? "budgeted-0ms" : "full"))
                .c_str(),
            [kind, budgeted](benchmark::State& state) { run_bilinear(state, budgeted, 0.0, kind); });
        b->Arg(256)->Arg(512)->Unit(benchmark::kMillisecond)->UseRealTime();
        if (!budgeted) b->Iterations(2);
      }
    const std::pair<Baker, const char*> bakers[] = {{Baker::budgeted, "budgeted"},
                                                    {Baker::budgeted_zero, "budgeted-0ms"},
                                                    {Baker::budgeted_frame, "budgeted-16ms"},
                                                    {Baker::budgeted_long, "budgeted-50ms"},
                                                    {Baker::paper_adaptive, "paper-adaptive"},
                                                    {Baker::exact, "exact"},
                                                    {Baker::bilinear, "bilinear"},
                                                    {Baker::original, "original"}};
    for (MapKind kind : map_kinds)
      for (const auto& [baker, name] : bakers)
        for (int size : {128, 256, 512, 1024}) {
          // the published per-texel search takes minutes above 512: measure it up to 512, once
          if (baker == Baker::original && size > 512) continue;
          auto* b = benchmark::RegisterBenchmark(
              (std::string("BM_Bake/") + kind_name(kind) + "/" + name).c_str(),
              [kind, baker](benchmark::State& state) { run(state, kind, baker); });
          b->Arg(size)->Unit(benchmark::kMillisecond)->UseRealTime();
          if (baker == Baker::original || baker == Baker::exact) b->Iterations(1);
        }
    // BM_Update/<map>/<policy>/<size>/<rect>
    using Policy = bake::BudgetedBaker::UpdatePolicy;
    for (MapKind kind : {MapKind::ocean, MapKind::bricks})
      for (const auto& [policy, name] :
           {std::pair{Policy::cheaper, "cheaper"}, std::pair{Policy::incremental, "incremental"}}) {
        auto* b = benchmark::RegisterBenchmark(
            (std::string("BM_Update/") + kind_name(kind) + "/" + name).c_str(),
            [kind, policy = policy](benchmark::State& state) { run_update(state, kind, policy); });
        b->Args({512, 4})->Args({512, 16})->Args({512, 64})->Unit(benchmark::kMillisecond)->UseRealTime();
      }
    // BM_UpdateBilinear/<map>/<update|whole>/<size>/<rect>: the bilinear baker's update() against a
    // whole bake of the same heights
    for (MapKind kind : {MapKind::ocean, MapKind::bricks})
      for (bool whole : {false, true}) {
        auto* b = benchmark::RegisterBenchmark(
            (std::string("BM_UpdateBilinear/") + kind_name(kind) + "/" + (whole ? "whole" : "update"))
                .c_str(),
            [kind, whole](benchmark::State& state) { run_bilinear_update(state, kind, whole); });
        b->Args({256, 16})->Args({512, 4})->Args({512, 16})->Args({512, 64});
        b->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(whole ? 2 : 6);
      }
    // 8 sectors (octant sweeps): BM_Bake8/<map>/budgeted/<size>
    for (MapKind kind : map_kinds) {
      auto* b = benchmark::RegisterBenchmark(
          (std::string("BM_Bake8/") + kind_name(kind) + "/budgeted").c_str(),
          [kind](benchmark::State& state) { run(state, kind, Baker::budgeted, 8); });
      b->Arg(256)->Arg(512)->Unit(benchmark::kMillisecond)->UseRealTime();
    }
    // non-square maps next to the square map of about as many texels, 4 and 8 sectors, no limit:
    // BM_BakeNonSquare/<map>/<W>x<H>, BM_BakeNonSquare8/<map>/<W>x<H>
    const std::pair<int, int> sizes[] = {{2048, 1024}, {1024, 2048}, {1448, 1448}, {1024, 512}, {512, 1024},
                                         {724, 724},   {4096, 256},  {256, 4096},  {1024, 1024}};
    for (int sectors : {4, 8})
      for (MapKind kind : {MapKind::ocean, MapKind::bricks})
        for (const auto& [width, height] : sizes) {
          auto* b = benchmark::RegisterBenchmark(
              (std::string(sectors == 8 ? "BM_BakeNonSquare8/" : "BM_BakeNonSquare/") + kind_name(kind) +
               "/" + std::to_string(width) + "x" + std::to_string(height))
                  .c_str(),
              [kind, sectors, width = width, height = height](benchmark::State& state) {
                run_map(state, kind, Baker::budgeted, width, height, sectors);
              });
          b->Unit(benchmark::kMillisecond)->UseRealTime();
        }
  }
} registration;

}  // namespace
