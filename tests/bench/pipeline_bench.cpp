// tests/bench/pipeline_bench.cpp - what a frame of the pipeline costs, stage by stage, next to what
// the bake achieved: BM_Frame/<scene>/<map size>/<frame budget> runs successive frames (1/60 s
// apart) of a built-in scene rendered with acm4 (32 steps) at 512 x 512, read back as colour.
// Counters: median milliseconds of sim, bake, upload and render per frame, the bake's budget share,
// its mean ratio and the texels still pending, and FFTs per frame.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "pipeline/frame_pipeline.h"

namespace {

using namespace displace;

double median(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  return values.empty() ? 0.0 : values[values.size() / 2];
}

void run_frames(benchmark::State& state, const char* scene_name, int map_size, double frame_ms) {
  static render::Renderer renderer{render::RendererOptions{}};
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

void register_frames() {
  for (const char* scene : {"calm", "water", "ripples"}) {
    for (int size : {256, 512}) {
      for (double budget : {16.0, 100.0}) {
        const std::string name = std::string("BM_Frame/") + scene + "/" + std::to_string(size) + "/" +
                                 std::to_string(int(budget)) + "ms";
        benchmark::RegisterBenchmark(name.c_str(), [=](benchmark::State& state) { run_frames(state, scene, size, budget); })
            ->Unit(benchmark::kMillisecond)
            ->UseRealTime()
            ->Iterations(12);
      }
    }
  }
}

const int registered = (register_frames(), 0);

}  // namespace
