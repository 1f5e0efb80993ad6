// tests/bench/pipeline_bench.cpp - what a frame of the pipeline costs, stage by stage, next to what
// the bake achieved: BM_Frame/<scene>/<map size>/<frame budget> runs successive frames (1/60 s
// apart) of a built-in scene rendered with acm4 (32 steps) at 512 x 512, read back as colour.
// Counters: median milliseconds of sim, bake, upload and render per frame, the bake's budget share,
// its mean ratio and the texels still pending, and FFTs per frame.
//
// What a lagged cone map costs the render (pipeline/frame_pipeline.h, scene.cone_lag_frames):
// BM_LaggedCones/water/<map size>/lag:<n> renders frame 120 of the water scene (acm4, 32 steps,
// <map size>^2 pixels) from the cone map of frame 120 - n's heights, its apexes raised as the
// pipeline raises them (by the most any texel rose since). Counters: fetches per pixel and search
// iterations (means over the hit pixels), the lift, the hit pixels, and those that ended more than
// 0.01 texel from where lag 0's did (rays whose 32 steps ran out elsewhere). Timed: the render alone.
//
// The sim on the device (sim/device/device_sim.h) next to the CPU's: BM_DeviceSim/ocean/<map size> and
// BM_CpuSim/ocean/<map size> make the water scene's heights (choppy crests resampled onto the grid,
// foam) for successive frames; the device's frame is recorded, submitted and waited for. Counters:
// the device's own milliseconds per frame (GPU timestamps), FFTs per frame, and (device) the largest
// difference from the CPU's heights of the last frame in [0, 1] units and the share of texels more than
// 1e-5 apart (choppy folds).
//
// Height queries (pipeline/query.h): BM_Query/<points> answers that many random points of the water
// scene (256 map, choppy) at one time, once its heights exist; items per second is points per second.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "bake/bake.h"
#include "bake/device/device_cones.h"
#include "bake/lagged.h"
#include "pipeline/frame_pipeline.h"
#include "pipeline/height_source.h"
#include "pipeline/query.h"
#include "sim/device/device_sim.h"

namespace {

using namespace displace;

double median(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  return values.empty() ? 0.0 : values[values.size() / 2];
}

render::Renderer& bench_renderer() {
  static render::Renderer renderer{render::RendererOptions{}};
  return renderer;
}

void run_frames(benchmark::State& state, const char* scene_name, int map_size, double frame_ms) {
  render::Renderer& renderer = bench_renderer();
  pipeline::Scene scene = pipeline::builtin_scene(scene_name);
  scene.map_size = map_size;
  scene.method = render::Method::acm4;
  scene.steps = 32;
  scene.frame_ms = frame_ms;
  pipeline::FramePipeline frames(scene, renderer);
  render::Frame frame;
  frames.run(0, frame);  // warm-up: pipelines, device maps, staging
  std::vector<double> sim, bake, upload, draw, share, ratio, pending, ffts;
  long long index = 1;
  for (auto _ : state) {
    const pipeline::FrameRecord record = frames.run(index++, frame);
    sim.push_back(record.sim_ms);
    bake.push_back(record.bake_ms);
    upload.push_back(record.upload_ms);
    draw.push_back(record.render_ms);
    share.push_back(std::isfinite(record.bake_budget_ms) ? record.bake_budget_ms : -1.0);
    ratio.push_back(record.cones.mean_ratio);
    pending.push_back(double(record.pending));
    ffts.push_back(double(record.ffts));
  }
  state.counters["sim_ms"] = median(sim);
  state.counters["bake_ms"] = median(bake);
  state.counters["upload_ms"] = median(upload);
  state.counters["render_ms"] = median(draw);
  state.counters["bake_share_ms"] = median(share);
  state.counters["mean_ratio"] = median(ratio);
  state.counters["pending"] = median(pending);
  state.counters["ffts"] = median(ffts);
  state.SetLabel(renderer.device().name);
}

render::HeightField heights_of_frame(const pipeline::Scene& scene, long long index) {
  pipeline::FramePipeline frames(scene, bench_renderer());
  pipeline::FrameRecord record;
  frames.simulate(pipeline::frame_time(scene, index), record);
  return frames.heights();
}

void run_lagged(benchmark::State& state, int map_size, int lag) {
  render::Renderer& renderer = bench_renderer();
  pipeline::Scene scene = pipeline::builtin_scene("water");
  scene.map_size = map_size;
  scene.camera.width = scene.camera.height = map_size;
  const long long frame_index = 120;
  const render::HeightField now = heights_of_frame(scene, frame_index);
  const render::View view = pipeline::scene_view(scene, pipeline::frame_time(scene, frame_index));
  const std::size_t texels = now.heights.size();
  // the map a lag of n serves: baked from frame 120 - n's heights (first stage only), raised
  auto served_map = [&](int frames_old, std::vector<float>& ratios, std::vector<float>& apex) {
    const render::HeightField then = heights_of_frame(scene, frame_index - frames_old);
    bake::BilinearBaker baker(map_size, map_size, 4, bake::Address::wrap);
    ratios.resize(texels * 4);
    apex.resize(texels);
    bake::Budget none;
    none.milliseconds = 0.0;
    std::vector<float> made(texels);
    baker.bake({then.heights.data(), map_size, map_size}, none, {ratios.data(), map_size, map_size, 4}, made);
    return bake::raise_apexes(then.heights, now.heights, made, apex);
  };
  auto render_with = [&](const std::vector<float>& ratios, const std::vector<float>& apex,
                         std::uint64_t version, render::Frame& frame) {
    render::MapSet maps;
    maps.width = maps.height = map_size;
    maps.heights = now.heights;
    maps.heights_version = 1;
    render::ConeMapView& cones = maps.cones[std::size_t(render::cone_slot(4))];
    cones.sector_count = 4;
    cones.ratios = ratios;
    cones.apex = apex;
    cones.version = version;
    renderer.set_maps(maps);
    renderer.render(view, {render::Method::acm4, 32, 8}, frame,
                    render::output_uv | render::output_fetches | render::output_iterations);
  };
  std::vector<float> ratios, apex;
  render::Frame fresh, frame;
  served_map(0, ratios, apex);
  render_with(ratios, apex, 1000, fresh);
  const float lift = served_map(lag, ratios, apex);
  render_with(ratios, apex, 1001 + std::uint64_t(lag), frame);
  for (auto _ : state) renderer.render(view, {render::Method::acm4, 32, 8}, frame, render::output_color);
  render_with(ratios, apex, 1001 + std::uint64_t(lag), frame);
  double fetches = 0.0, iterations = 0.0;
  long long hits = 0, moved = 0;
  for (std::size_t p = 0; p < frame.fetches.size(); ++p) {
    if (frame.uv[3 * p + 2] < 0.5f) continue;
    ++hits;
    fetches += frame.fetches[p];
    iterations += frame.iterations[p];
    const double du = double(frame.uv[3 * p] - fresh.uv[3 * p]),
                 dv = double(frame.uv[3 * p + 1] - fresh.uv[3 * p + 1]);
    moved += std::sqrt(du * du + dv * dv) * map_size > 0.01;
  }
  state.counters["fetches_per_pixel"] = fetches / double(std::max(hits, 1ll));
  state.counters["iterations"] = iterations / double(std::max(hits, 1ll));
  state.counters["lift"] = lift;
  state.counters["moved_pixels"] = double(moved);
  state.counters["hit_pixels"] = double(hits);
  state.SetLabel(renderer.device().name);
}

void register_frames() {
  for (int size : {256, 512}) {
    for (int lag : {0, 1, 2, 4, 8}) {
      const std::string name = "BM_LaggedCones/water/" + std::to_string(size) + "/lag:" + std::to_string(lag);
      benchmark::RegisterBenchmark(name.c_str(),
                                   [=](benchmark::State& state) { run_lagged(state, size, lag); })
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime();
    }
  }
  for (const char* scene : {"calm", "water", "ripples"}) {
    for (int size : {256, 512}) {
      for (double budget : {16.0, 100.0}) {
        const std::string name = std::string("BM_Frame/") + scene + "/" + std::to_string(size) + "/" +
                                 std::to_string(int(budget)) + "ms";
        benchmark::RegisterBenchmark(name.c_str(),
                                     [=](benchmark::State& state) { run_frames(state, scene, size, budget); })
            ->Unit(benchmark::kMillisecond)
            ->UseRealTime()
            ->Iterations(12);
      }
    }
  }
}

const int registered = (register_frames(), 0);

pipeline::SourceSettings water_source(int map_size, unsigned& effects) {
  pipeline::Scene scene = pipeline::builtin_scene("water");
  scene.map_size = map_size;
  effects = pipeline::scene_effects(scene);
  return pipeline::source_settings(scene);
}

void run_device_sim(benchmark::State& state) {
  render::Renderer& renderer = bench_renderer();
  unsigned effects = 0;
  const pipeline::SourceSettings settings = water_source(int(state.range(0)), effects);
  const std::unique_ptr<sim::DeviceSim> device = pipeline::make_device_sim(renderer, settings, effects);
  double time = 0.0;
  device->simulate(time);
  device->finish();
  const long long ffts = device->fft_count();
  std::vector<double> device_ms;
  for (auto _ : state) {
    time += 1.0 / 60.0;
    device->simulate(time);
    device->finish();
    device_ms.push_back(device->device_milliseconds());
  }
  // accuracy: the last frame against the CPU's
  std::vector<float> heights;
  device->read_back(&heights, nullptr, nullptr);
  pipeline::HeightSource cpu(settings, effects);
  pipeline::HeightFrame expected;
  cpu.make(time, 0, expected);
  double worst = 0.0;
  long long apart = 0;
  for (std::size_t t = 0; t < heights.size(); ++t) {
    const double off = std::abs(double(heights[t]) - double(expected.field.heights[t]));
    worst = std::max(worst, off);
    apart += off > 1e-5 ? 1 : 0;
  }
  state.counters["device_ms"] = median(device_ms);
  state.counters["ffts_per_frame"] = double(device->fft_count() - ffts) / double(state.iterations());
  state.counters["max_error_vs_cpu"] = worst;
  state.counters["share_apart"] = double(apart) / double(heights.size());
}

void run_cpu_sim(benchmark::State& state) {
  unsigned effects = 0;
  const pipeline::SourceSettings settings = water_source(int(state.range(0)), effects);
  pipeline::HeightSource source(settings, effects);
  pipeline::HeightFrame frame;
  double time = 0.0;
  source.make(time, 0, frame);
  long long ffts = 0;
  for (auto _ : state) {
    time += 1.0 / 60.0;
    source.make(time, 0, frame);
    ffts += frame.ffts;
    benchmark::DoNotOptimize(frame.field.heights.data());
  }
  state.counters["ffts_per_frame"] = double(ffts) / double(state.iterations());
}

BENCHMARK(run_device_sim)
    ->Name("BM_DeviceSim/ocean")
    ->Arg(256)
    ->Arg(512)
    ->Arg(1024)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(run_cpu_sim)
    ->Name("BM_CpuSim/ocean")
    ->Arg(256)
    ->Arg(512)
    ->Arg(1024)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void run_query(benchmark::State& state) {
  pipeline::Scene scene = pipeline::builtin_scene("water");
  pipeline::HeightQuery query(scene);
  std::vector<pipeline::QueryPoint> points(std::size_t(state.range(0)));
  std::uint64_t seed = 12345;
  for (pipeline::QueryPoint& point : points) {
    seed = seed * 6364136223846793005ull + 1442695040888963407ull;
    point.x = double(seed >> 11) * 0x1.0p-53 * 1000.0 - 500.0;
    seed = seed * 6364136223846793005ull + 1442695040888963407ull;
    point.y = double(seed >> 11) * 0x1.0p-53 * 1000.0 - 500.0;
  }
  pipeline::QueryResult result;
  query.query(points, 1.0, result);  // the heights made, the vectors sized
  for (auto _ : state) {
    query.query(points, 1.0, result);
    benchmark::DoNotOptimize(result.height_m.data());
  }
  state.SetItemsProcessed(state.iterations() * state.range(0));
  state.counters["heights_made"] = double(query.heights_made());
}
BENCHMARK(run_query)
    ->Name("BM_Query")
    ->Arg(1000)
    ->Arg(100000)
    ->Arg(1000000)
    ->Unit(benchmark::kMicrosecond)
    ->UseRealTime();

}  // namespace
