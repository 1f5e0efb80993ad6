// tests/bench/sim_bench.cpp - time per frame of the sim stage next to its accuracy: the FFT ocean's
// Parseval error (mean h^2 over the grid against sum |h~|^2) and the sinusoid grid's largest deviation
// from the closed form.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <vector>

#include "sim/sim.h"

namespace {

using namespace displace::sim;

constexpr float frame_step = 1.0f / 60.0f;  // seconds between benchmark frames

double parseval_relative_error(const Ocean& ocean, const OceanFrame& frame, float time) {
  double mean_square = 0.0;
  for (float h : frame.height) mean_square += static_cast<double>(h) * h;
  mean_square /= static_cast<double>(frame.height.size());
  double spectral = 0.0;
  for (const auto& value : ocean.height_spectrum(time)) spectral += std::norm(std::complex<double>(value));
  return std::abs(mean_square - spectral) / spectral;
}

void run_ocean(benchmark::State& state, unsigned outputs) {
  OceanParams params;
  params.size = static_cast<int>(state.range(0));
  Ocean ocean(params);
  OceanFrame frame;
  float time = 0.0f;
  ocean.evaluate(time, outputs, frame);  // first touch of the buffers
  const long long ffts_before = ocean.fft_count();
  for (auto _ : state) {
    time += frame_step;
    ocean.evaluate(time, outputs, frame);
    benchmark::DoNotOptimize(frame.height.data());
    benchmark::ClobberMemory();
  }
  state.counters["ffts_per_frame"] =
      static_cast<double>(ocean.fft_count() - ffts_before) / static_cast<double>(state.iterations());
  state.counters["modes"] = static_cast<double>(params.size) * params.size;
  if ((outputs & ocean_heights) != 0)
    state.counters["parseval_rel_error"] = parseval_relative_error(ocean, frame, time);
}

void BM_OceanHeights(benchmark::State& state) { run_ocean(state, ocean_heights); }
void BM_OceanAllOutputs(benchmark::State& state) {
  run_ocean(state, ocean_heights | ocean_slopes | ocean_displacement | ocean_foam);
}
BENCHMARK(BM_OceanHeights)
    ->RangeMultiplier(2)
    ->Range(128, 1024)
    ->Unit(benchmark::kMicrosecond)
    ->UseRealTime();
BENCHMARK(BM_OceanAllOutputs)
    ->RangeMultiplier(2)
    ->Range(128, 1024)
    ->Unit(benchmark::kMicrosecond)
    ->UseRealTime();

// The choppy ocean back on the grid (the water scene's sim after the FFTs): heights and the foam's
// Jacobian resampled through the fixed-point steps; accuracy = the largest residual |p + D(p) - x|
// in texels.
void run_choppy_resample(benchmark::State& state, int iterations, float settle) {
  OceanParams params;
  params.size = static_cast<int>(state.range(0));
  params.choppiness = 1.5f;  // the water scene's
  Ocean ocean(params);
  OceanFrame frame;
  ocean.evaluate(1.0, ocean_heights | ocean_displacement | ocean_foam, frame);
  std::vector<float> heights(frame.height.size()), jacobian(frame.height.size());
  double residual = 0.0;
  for (auto _ : state) {
    residual =
        resample_displaced(params.size, params.patch_size, frame.height, frame.displacement_x,
                           frame.displacement_y, iterations, heights, frame.jacobian, jacobian, settle);
    benchmark::DoNotOptimize(heights.data());
    benchmark::ClobberMemory();
  }
  state.counters["residual_texels"] = residual * params.size / params.patch_size;
}
// six fixed steps (the frame pipeline's before), and the pipeline's: up to 8, settling at 0.003 texel
void BM_ChoppyResample(benchmark::State& state) { run_choppy_resample(state, 6, 0.0f); }
void BM_ChoppySettled(benchmark::State& state) { run_choppy_resample(state, 8, 3e-4f); }  // the pipeline's
BENCHMARK(BM_ChoppyResample)
    ->RangeMultiplier(2)
    ->Range(256, 1024)
    ->Unit(benchmark::kMicrosecond)
    ->UseRealTime();
BENCHMARK(BM_ChoppySettled)
    ->RangeMultiplier(2)
    ->Range(256, 1024)
    ->Unit(benchmark::kMicrosecond)
    ->UseRealTime();

void BM_SinusoidHeights(benchmark::State& state) {
  const int size = static_cast<int>(state.range(0));
  SinusoidParams params;
  const std::vector<Wave> waves = make_sinusoid_waves(params);
  std::vector<float> heights(static_cast<std::size_t>(size) * size);
  float time = 0.0f;
  for (auto _ : state) {
    time += frame_step;
    sinusoid_heights(waves, params.patch_size, time, size, size, heights);
    benchmark::DoNotOptimize(heights.data());
    benchmark::ClobberMemory();
  }
  // largest deviation from the closed form over a sparse set of samples, relative to sum of amplitudes
  double error = 0.0;
  const int stride = std::max(1, size / 32);
  for (int row = 0; row < size; row += stride) {
    for (int column = 0; column < size; column += stride) {
      const float x = (static_cast<float>(column) + 0.5f) / static_cast<float>(size) * params.patch_size;
      const float y = (static_cast<float>(row) + 0.5f) / static_cast<float>(size) * params.patch_size;
      error = std::max(error, static_cast<double>(std::abs(heights[row * size + column] -
                                                           sinusoid_height_at(waves, x, y, time))));
    }
  }
  state.counters["max_rel_error"] = error * 2.0 * sinusoid_mapping(waves).scale;
  state.counters["waves"] = static_cast<double>(waves.size());
}
BENCHMARK(BM_SinusoidHeights)->Arg(512)->Unit(benchmark::kMicrosecond)->UseRealTime();

}  // namespace
