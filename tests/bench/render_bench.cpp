// tests/bench/render_bench.cpp - what handing a frame's maps to the renderer costs: the upload of a
// changed 512 x 512 height map with its 4-sector bilinear cone map and apex heights (6.3 MB of
// floats), whole and as one dirty rectangle, through Renderer::set_maps and what the device does
// with them (wait_idle), next to a plain memcpy of the same bytes: on a device that shares the
// host's memory written straight into the images, and (`staged`) through the staging ring and a
// device copy as on a discrete GPU. Counters: MB/s of the caller's bytes, and Vulkan allocations per
// frame (must be 0 after the first).
//
// BM_DeviceBake/ocean/<N>: bake::DeviceCones' bake of a device ocean's N x N heights (4 sectors,
// wrap; the ocean simulated once), unlimited and (/first-pass) budget 0, each bake waited for. Counters:
// mean_ratio_vs_full, the mean ratio read back over bake::bake_bilinear_cones' on the same heights
// (not computed at 2048: minutes of CPU), and texels_refined.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <memory>
#include <vector>

#include "bake/bake.h"
#include "bake/device/device_cones.h"
#include "pipeline/height_source.h"
#include "render/render.h"
#include "sim/device/device_sim.h"

namespace {

using namespace displace;

constexpr int map_side = 512;
constexpr int sectors = 4;

struct Maps {
  std::vector<float> heights, ratios, apex;
  Maps() : heights(std::size_t(map_side) * map_side), ratios(heights.size() * sectors), apex(heights.size()) {
    for (std::size_t t = 0; t < heights.size(); ++t) {
      heights[t] = float(t % 97) / 97.0f;
      apex[t] = std::min(1.0f, heights[t] + 0.01f);
      for (int k = 0; k < sectors; ++k) ratios[t * sectors + k] = float((t + k) % 13) / 13.0f;
    }
  }
  std::size_t bytes() const { return (heights.size() + ratios.size() + apex.size()) * sizeof(float); }
};

render::MapSet map_set(const Maps& maps, std::uint64_t version, std::uint64_t since,
                       std::span<const bake::Rect> dirty) {
  render::MapSet set;
  set.width = set.height = map_side;
  set.heights = maps.heights;
  set.heights_version = version;
  set.heights_dirty_since = since;
  set.heights_dirty = dirty;
  set.cones[std::size_t(render::cone_slot(sectors))] = {
      sectors, bake::Address::wrap, maps.ratios, maps.apex, {}, version, since, dirty};
  return set;
}

render::Renderer& renderer_of(bool host_written) {
  auto options_of = [](bool host_written_maps) {
    render::RendererOptions options;
    options.pipeline_cache = "off";
    options.host_written_maps = host_written_maps;
    return options;
  };
  static render::Renderer host(options_of(true)), staged(options_of(false));
  return host_written ? host : staged;
}

// rect_side 0: the whole maps change every frame; otherwise one rect_side^2 rectangle does.
void run_upload(benchmark::State& state, int rect_side, bool host_written) {
  render::Renderer& renderer = renderer_of(host_written);
  Maps maps;
  std::uint64_t version = std::uint64_t(1) << 40;
  renderer.set_maps(map_set(maps, version, 0, {}));
  renderer.wait_idle();
  const bake::Rect rect{100, 200, 100 + rect_side, 200 + rect_side};
  const std::span<const bake::Rect> dirty =
      rect_side > 0 ? std::span<const bake::Rect>(&rect, 1) : std::span<const bake::Rect>{};
  const long long allocations = renderer.memory_allocations();
  double host_seconds = 0.0;
  for (auto _ : state) {
    ++version;
    const auto start = std::chrono::steady_clock::now();
    renderer.set_maps(map_set(maps, version, version - 1, dirty));
    host_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    renderer.wait_idle();
  }
  state.counters["set_maps_ms"] = 1e3 * host_seconds / double(state.iterations());
  const double bytes = rect_side > 0 ? double(rect_side) * rect_side * (1 + sectors + 1) * sizeof(float)
                                     : double(maps.bytes());
  state.counters["MB/s"] = benchmark::Counter(bytes / 1e6, benchmark::Counter::kIsIterationInvariantRate);
  state.counters["allocations"] = double(renderer.memory_allocations() - allocations);
  state.SetLabel(renderer.device().name + (renderer.host_written_maps() ? ", host-written" : ", staged"));
}

void run_memcpy(benchmark::State& state) {
  Maps maps;
  std::vector<std::byte> destination(maps.bytes());
  for (auto _ : state) {
    std::byte* out = destination.data();
    for (const std::vector<float>* source : {&maps.heights, &maps.ratios, &maps.apex}) {
      std::memcpy(out, source->data(), source->size() * sizeof(float));
      out += source->size() * sizeof(float);
    }
    benchmark::DoNotOptimize(destination.data());
    benchmark::ClobberMemory();
  }
  state.counters["MB/s"] =
      benchmark::Counter(double(maps.bytes()) / 1e6, benchmark::Counter::kIsIterationInvariantRate);
}

BENCHMARK_CAPTURE(run_upload, whole, 0, true)
    ->Name("BM_UploadMaps/512/whole")
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(run_upload, rect64, 64, true)
    ->Name("BM_UploadMaps/512/rect64")
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(run_upload, whole_staged, 0, false)
    ->Name("BM_UploadMaps/512/whole-staged")
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(run_upload, rect64_staged, 64, false)
    ->Name("BM_UploadMaps/512/rect64-staged")
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(run_memcpy)->Name("BM_UploadMaps/512/memcpy")->Unit(benchmark::kMillisecond)->UseRealTime();

// ---- BM_DeviceBake

constexpr int device_bake_sectors = 4;
constexpr int full_reference_limit = 1024;  // texels a side: above, no CPU reference bake

void run_device_bake(benchmark::State& state, long long texels, bake::DeviceFirstPass first_pass) {
  const int side = int(state.range(0));
  static render::Renderer renderer([] {
    render::RendererOptions options;
    options.pipeline_cache = "off";
    return options;
  }());
  pipeline::SourceSettings settings;
  settings.kind = pipeline::SourceKind::ocean;
  settings.map_size = side;
  const std::unique_ptr<sim::DeviceSim> made =
      pipeline::make_device_sim(renderer, settings, pipeline::effect_heights);
  sim::DeviceSim& ocean = *made;
  ocean.simulate(3.0);
  bake::DeviceCones cones(renderer.frames(), ocean.maps(), device_bake_sectors, bake::Address::wrap);
  bake::BakeStats stats;
  for (auto _ : state) {
    cones.bake(bake::work_budget(texels), first_pass);
    stats = cones.read_back(nullptr, nullptr);
  }
  std::vector<float> ratios, heights;
  cones.read_back(&ratios, nullptr);
  state.counters["texels_refined"] = double(stats.texels_refined);
  state.counters["texels_cut"] = double(stats.texels_fallback + stats.texels_refined);
  if (side <= full_reference_limit) {
    ocean.read_back(&heights, nullptr, nullptr);
    std::vector<float> full(ratios.size()), apex(heights.size());
    bake::bake_bilinear_cones({heights.data(), side, side}, bake::Address::wrap,
                              {full.data(), side, side, device_bake_sectors}, apex);
    double device_sum = 0.0, full_sum = 0.0;
    for (std::size_t v = 0; v < ratios.size(); ++v) {
      device_sum += ratios[v];
      full_sum += full[v];
    }
    state.counters["mean_ratio_vs_full"] = device_sum / full_sum;
  }
  state.SetLabel(renderer.device().name);
}

BENCHMARK_CAPTURE(run_device_bake, unlimited, bake::unlimited_texels, bake::DeviceFirstPass{})
    ->Name("BM_DeviceBake/ocean")
    ->Arg(256)
    ->Arg(512)
    ->Arg(1024)
    ->Arg(2048)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
// the default first pass (rings of radius 2, the full window)
BENCHMARK_CAPTURE(run_device_bake, first_pass, 0, bake::DeviceFirstPass{})
    ->Name("BM_DeviceBake/ocean/first-pass")
    ->Arg(256)
    ->Arg(512)
    ->Arg(1024)
    ->Arg(2048)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
// the first pass as a search of the pyramid (ring_radius 0)
BENCHMARK_CAPTURE(run_device_bake, search, 0, bake::DeviceFirstPass{4, 0})
    ->Name("BM_DeviceBake/ocean/first-pass-search")
    ->Arg(256)
    ->Arg(512)
    ->Arg(1024)
    ->Arg(2048)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
// the first pass as rings (bake::DeviceFirstPass) of radius 1 with the full window, of radius 2 with
// a window of 2 cells
BENCHMARK_CAPTURE(run_device_bake, rings_1, 0, bake::DeviceFirstPass{4, 1})
    ->Name("BM_DeviceBake/ocean/first-pass-rings-1")
    ->Arg(256)
    ->Arg(512)
    ->Arg(1024)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(run_device_bake, rings_2_window_2, 0, bake::DeviceFirstPass{2, 2})
    ->Name("BM_DeviceBake/ocean/first-pass-rings-2-window-2")
    ->Arg(256)
    ->Arg(512)
    ->Arg(1024)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
// the group's first pass (bake::DeviceFirstPass::group), the full window and a window of 2 cells
BENCHMARK_CAPTURE(run_device_bake, group_4, 0, bake::DeviceFirstPass{4, 0, true})
    ->Name("BM_DeviceBake/ocean/first-pass-group")
    ->Arg(256)
    ->Arg(512)
    ->Arg(1024)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(run_device_bake, group_2, 0, bake::DeviceFirstPass{2, 0, true})
    ->Name("BM_DeviceBake/ocean/first-pass-group-window-2")
    ->Arg(256)
    ->Arg(512)
    ->Arg(1024)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
