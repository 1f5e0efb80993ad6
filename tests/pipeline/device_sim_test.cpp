// tests/pipeline/device_sim_test.cpp - the ocean on the device (sim/device/device_sim.h) against the CPU
// ocean of pipeline::HeightSource: heights for every effect set, at t = 0, 1.5 s and 1e9 s, foam, FFT
// counts, and nothing allocated per frame.
#include "sim/device/device_sim.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "bake/device/device_cones.h"
#include "pipeline/height_source.h"
#include "render/render.h"

namespace {

using namespace displace;

render::Renderer& device_renderer() {
  static render::Renderer renderer([] {
    render::RendererOptions options;
    options.validate = true;
    return options;
  }());
  return renderer;
}

pipeline::SourceSettings ocean_settings(int size, float choppiness) {
  pipeline::SourceSettings settings;
  settings.kind = pipeline::SourceKind::ocean;
  settings.map_size = size;
  settings.ocean.patch_size = 200.0f;
  settings.ocean.wind_speed = 12.0f;
  settings.ocean.choppiness = choppiness;
  settings.ocean.seed = 7;
  return settings;
}

struct Difference {
  double worst = 0.0;      // largest |device - cpu|, in units of the value range
  double far_share = 0.0;  // share of texels further apart than `far`
};
Difference compare(const std::vector<float>& device, const std::vector<float>& cpu, double range,
                   double far) {
  Difference d;
  long long beyond = 0;
  for (std::size_t t = 0; t < cpu.size(); ++t) {
    const double off = std::abs(double(device[t]) - double(cpu[t])) / range;
    d.worst = std::max(d.worst, off);
    if (off > far) ++beyond;
  }
  d.far_share = double(beyond) / double(cpu.size());
  return d;
}

struct EffectCase {
  const char* name;
  unsigned effects;
  float choppiness;
};

TEST(DeviceSim, HeightsEqualTheCpuOceansForEveryEffectSet) {
  render::Renderer& renderer = device_renderer();
  const EffectCase cases[] = {
      {"heights", pipeline::effect_heights, 0.0f},
      {"foam", pipeline::effect_heights | pipeline::effect_foam, 0.0f},
      {"choppy", pipeline::effect_heights | pipeline::effect_choppy, 1.5f},
      {"choppy+foam", pipeline::effect_heights | pipeline::effect_choppy | pipeline::effect_foam, 1.5f},
  };
  const int expected_ffts[] = {1, 4, 3, 6};
  for (int c = 0; c < 4; ++c) {
    const EffectCase& effect_case = cases[c];
    SCOPED_TRACE(effect_case.name);
    const pipeline::SourceSettings settings = ocean_settings(128, effect_case.choppiness);
    pipeline::HeightSource cpu(settings, effect_case.effects);
    const std::unique_ptr<sim::DeviceSim> made =
        pipeline::make_device_sim(renderer, settings, effect_case.effects);
    sim::DeviceSim& device = *made;
    const bool choppy = (effect_case.effects & pipeline::effect_choppy) != 0;
    for (double time : {0.0, 1.5, 1e9}) {
      SCOPED_TRACE("t = " + std::to_string(time));
      pipeline::HeightFrame expected;
      cpu.make(time, 0, expected);
      const long long ffts_before = device.fft_count();
      device.simulate(time);
      EXPECT_EQ(device.fft_count() - ffts_before, expected_ffts[c]);
      EXPECT_EQ(expected.ffts, expected_ffts[c]);
      std::vector<float> heights, metres, foam;
      device.read_back(&heights, &metres, &foam);
      ASSERT_EQ(heights.size(), expected.field.heights.size());
      // heights in [0, 1]: within 1e-5 of the range; choppy water may fold where the inverse of the
      // displacement is not unique: at most 0.1% of texels further off, none by more than 1e-3
      const Difference d = compare(heights, expected.field.heights, 1.0, 1e-5);
      if (choppy) {
        EXPECT_LE(d.far_share, 1e-3);
        EXPECT_LE(d.worst, 1e-3);
      } else {
        EXPECT_LE(d.worst, 1e-5);
      }
      // metres: the same, in units of the mapped range (1 / scale metres)
      const Difference m = compare(metres, std::vector<float>(expected.raw.begin(), expected.raw.end()),
                                   1.0 / double(cpu.mapping().scale), 1e-5);
      EXPECT_LE(m.far_share, choppy ? 1e-3 : 0.0);
      if (effect_case.effects & pipeline::effect_foam) {
        ASSERT_EQ(foam.size(), expected.foam.size());
        // coverage is 2.5 x the Jacobian resampled, which changes fast across a crest: choppy water's
        // points moved by its settle move it more
        const Difference f = compare(foam, expected.foam, 1.0, choppy ? 1e-2 : 1e-5);
        EXPECT_LE(f.far_share, choppy ? 1e-3 : 0.0);
      } else {
        EXPECT_TRUE(foam.empty());
      }
    }
  }
  EXPECT_EQ(renderer.validation_messages(), 0);
}

TEST(DeviceSim, MovesWithTimeAndAllocatesNothingPerFrame) {
  render::Renderer& renderer = device_renderer();
  const pipeline::SourceSettings settings = ocean_settings(32, 1.5f);
  const unsigned effects = pipeline::effect_heights | pipeline::effect_choppy | pipeline::effect_foam;
  const std::unique_ptr<sim::DeviceSim> made = pipeline::make_device_sim(renderer, settings, effects);
  sim::DeviceSim& device = *made;
  std::vector<float> first, second;
  device.simulate(10.0);
  device.read_back(&first, nullptr, nullptr);
  const long long allocations = renderer.memory_allocations();
  for (int frame = 1; frame <= 5; ++frame) device.simulate(10.0 + frame / 60.0);
  device.read_back(&second, nullptr, nullptr);
  EXPECT_EQ(renderer.memory_allocations(), allocations);
  EXPECT_NE(first, second);
  EXPECT_EQ(renderer.validation_messages(), 0);
}

TEST(DeviceSim, RefusesWhatItCannotSimulate) {
  render::Renderer& renderer = device_renderer();
  sim::OceanSpectrumView view;
  view.size = 3;
  EXPECT_THROW(sim::DeviceSim(renderer.frames(), view, 0), render::RenderError);
  view.size = 4;
  view.patch_size = 10.0f;  // no modes given
  EXPECT_THROW(sim::DeviceSim(renderer.frames(), view, 0), render::RenderError);
  pipeline::SourceSettings bricks;
  bricks.kind = pipeline::SourceKind::bricks;
  EXPECT_THROW(pipeline::make_device_sim(renderer, bricks, 0), pipeline::SceneError);
  sim::SinusoidWavesView waves;
  waves.size = 8;
  waves.patch_size = 4.0f;
  const float not_finite[] = {1.0f, 0.0f, std::nanf(""), 1.0f, 0.0f};
  waves.waves = not_finite;
  EXPECT_THROW(sim::DeviceSim(renderer.frames(), waves), render::RenderError);
}

TEST(DeviceSim, SinusoidsEqualTheCpusAtEveryTime) {
  render::Renderer& renderer = device_renderer();
  for (bool tileable : {true, false}) {
    SCOPED_TRACE(tileable ? "on the lattice" : "off the lattice");
    pipeline::SourceSettings settings;
    settings.kind = pipeline::SourceKind::sinusoids;
    settings.map_size = 96;
    settings.sinusoids.wave_count = 24;
    settings.sinusoids.tileable = tileable;
    pipeline::HeightSource cpu(settings);
    const std::unique_ptr<sim::DeviceSim> device = pipeline::make_device_sim(renderer, settings, 0);
    for (double time : {0.0, 1.5, 1e9}) {
      SCOPED_TRACE("t = " + std::to_string(time));
      pipeline::HeightFrame expected;
      cpu.make(time, 0, expected);
      device->simulate(time);
      std::vector<float> heights;
      device->read_back(&heights, nullptr, nullptr);
      EXPECT_LE(compare(heights, expected.field.heights, 1.0, 1e-5).worst, 1e-5);
      EXPECT_EQ(device->fft_count(), 0);
    }
  }
  EXPECT_EQ(renderer.validation_messages(), 0);
}

}  // namespace
