// tests/pipeline/device_levels_test.cpp - the levels of detail made on the device
// (bake/device/device_cones.h, DeviceLevels) from a DeviceSim's heights: the chain is the CPU's chain of the
// same heights (heights bit for bit, slope moments within a rounding, each level's top its highest height),
// every level's cones keep the bilinear contract for that level's surface (brute force, 1, 4 and 8 sectors,
// the first pass and unlimited), rays on each pinned level end at that level's exact first crossing, and the
// frame pipeline's device path traces them on the unbounded sea with nothing allocated per frame.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "bake/bake.h"
#include "bake/device/device_cones.h"
#include "pipeline/frame_pipeline.h"
#include "pipeline/height_source.h"
#include "pipeline/scene.h"
#include "render/render.h"
#include "sim/device/device_sim.h"
#include "tests/bake/bake_checks.h"
#include "tests/render/level_checks.h"
#include "tests/test_maps.h"

namespace {

using namespace displace;
using bake::Address;

render::Renderer& levels_renderer() {
  static render::Renderer renderer([] {
    render::RendererOptions options;
    options.validate = true;
    return options;
  }());
  return renderer;
}

std::unique_ptr<sim::DeviceSim> device_ocean(render::Renderer& renderer, int size, std::uint64_t seed) {
  pipeline::SourceSettings settings;
  settings.kind = pipeline::SourceKind::ocean;
  settings.map_size = size;
  settings.ocean.patch_size = 200.0f;
  settings.ocean.wind_speed = 12.0f;
  settings.ocean.seed = seed;
  return pipeline::make_device_sim(renderer, settings, pipeline::effect_heights);
}

render::HeightField heights_of(sim::DeviceSim& sim) {
  render::HeightField field{sim.size(), sim.size(), {}};
  sim.read_back(&field.heights, nullptr, nullptr);
  return field;
}

// The slope moments of every level of `field`'s chain, as the map maker makes them ([l - 1]: level l).
std::vector<std::vector<float>> cpu_moments(const render::HeightField& field, int levels) {
  std::vector<std::vector<float>> moments(std::size_t(levels), std::vector<float>{});
  std::vector<float> below(field.heights.size() * 3);
  bake::gradient_moments({field.heights.data(), field.width, field.height}, below);
  for (int level = 1; level <= levels; ++level) {
    const int width = field.width >> (level - 1), height = field.height >> (level - 1);
    std::vector<float>& coarse = moments[std::size_t(level - 1)];
    coarse.resize(std::size_t(width / 2) * std::size_t(height / 2) * 3);
    bake::downsample_moments(level == 1 ? below : moments[std::size_t(level - 2)], width, height, coarse);
  }
  return moments;
}

// At two times of a 64 ocean: every level's heights are the CPU's chain of the heights read back, bit
// for bit; its moments within a float rounding of the largest (a GPU may fuse what the CPU rounds
// apart); its top, where its rays start, is its highest height.
TEST(DeviceLevels, TheChainIsTheCpusChainOfTheSameHeights) {
  render::Renderer& renderer = levels_renderer();
  const std::unique_ptr<sim::DeviceSim> sim = device_ocean(renderer, 64, 3);
  bake::DeviceLevels levels(renderer.frames(), sim->maps(), 4, Address::wrap);
  ASSERT_EQ(levels.level_count(), 6);
  for (const double time : {0.0, 1.5}) {
    sim->simulate(time);
    levels.make(bake::work_budget(0));
    const render::HeightField field = heights_of(*sim);
    const std::vector<std::vector<float>> moments = cpu_moments(field, 6);
    for (int level = 1; level <= 6; ++level) {
      const render::HeightField expected = displace::testing::level_of(field, level);
      std::vector<float> heights, slopes;
      float top = -1.0f;
      levels.read_back(level, &heights, &slopes, nullptr, nullptr, &top);
      ASSERT_EQ(heights.size(), expected.heights.size());
      long long different = 0;
      for (std::size_t t = 0; t < heights.size(); ++t) different += heights[t] != expected.heights[t];
      EXPECT_EQ(different, 0) << "level " << level << " at " << time << " s";
      const std::vector<float>& cpu = moments[std::size_t(level - 1)];
      ASSERT_EQ(slopes.size(), cpu.size());
      float largest = 0.0f, worst = 0.0f;
      for (std::size_t m = 0; m < cpu.size(); ++m) {
        largest = std::max(largest, std::abs(cpu[m]));
        worst = std::max(worst, std::abs(slopes[m] - cpu[m]));
      }
      EXPECT_GT(largest, 0.0f);
      EXPECT_LE(worst, 1e-6f * largest) << "level " << level << " at " << time << " s";
      EXPECT_EQ(top, *std::max_element(expected.heights.begin(), expected.heights.end()))
          << "level " << level;
    }
  }
  EXPECT_EQ(renderer.validation_messages(), 0);
}

// Every level's cones from the device (what the renderer samples: the atlas) against the contract for
// that level's surface, by brute force on every texel: 1, 4 and 8 sectors, the first pass (the
// default's rings) and unlimited.
TEST(DeviceLevels, EveryLevelsConesKeepTheBilinearContract) {
  render::Renderer& renderer = levels_renderer();
  const std::unique_ptr<sim::DeviceSim> sim = device_ocean(renderer, 32, 11);
  sim->simulate(2.0);
  const render::HeightField field = heights_of(*sim);
  for (const int sectors : {1, 4, 8}) {
    bake::DeviceLevels levels(renderer.frames(), sim->maps(), sectors, Address::wrap);
    ASSERT_EQ(levels.level_count(), 5);
    for (const long long budget : {0LL, bake::unlimited_texels}) {
      levels.make(bake::work_budget(budget));
      for (int level = 1; level <= levels.level_count(); ++level) {
        const render::HeightField coarse = displace::testing::level_of(field, level);
        bake::ConeMap cones{coarse.width, coarse.height, sectors, {}};
        std::vector<float> apex;
        levels.read_back(level, nullptr, nullptr, &cones.ratios, &apex);
        const test::Map map{"level " + std::to_string(level), coarse.width, coarse.height, coarse.heights};
        EXPECT_EQ(bake::check_bilinear(map, Address::wrap, cones, apex).violations, 0)
            << sectors << " sectors, budget " << budget << ", level " << level;
      }
    }
  }
  EXPECT_EQ(renderer.validation_messages(), 0);
}

// The renderer on device levels: each level pinned for every pixel (View::level), the cone methods'
// rays with steps enough to finish end at that level's exact first crossing of the chain made from
// the heights read back - never past it (a wrong top, atlas place or level would put them past or
// elsewhere) - with the level-0 maps on the device too: nothing of the frame comes from the host.
TEST(DeviceLevels, RaysOnEachLevelEndAtThatLevelsFirstCrossing) {
  constexpr double tolerance = 1e-4;  // world units (a level-0 texel here is 0.016)
  render::Renderer& renderer = levels_renderer();
  const std::unique_ptr<sim::DeviceSim> sim = device_ocean(renderer, 64, 5);
  bake::DeviceCones cones(renderer.frames(), sim->maps(), 4, Address::wrap);
  bake::DeviceLevels levels(renderer.frames(), sim->maps(), 4, Address::wrap);
  sim->simulate(3.0);
  cones.bake(bake::work_budget(0));
  levels.make(bake::work_budget(0));
  const render::HeightField field = heights_of(*sim);
  render::MapSet maps;
  maps.width = maps.height = 64;
  maps.device_heights = sim->maps();
  maps.cones[std::size_t(render::cone_slot(4))].sector_count = 4;
  maps.cones[std::size_t(render::cone_slot(4))].device = cones.map();
  maps.device_levels = levels.maps();
  maps.level_count = levels.level_count();
  maps.level_sectors = 4;
  maps.level_address = Address::wrap;
  renderer.set_maps(maps);
  render::View view = displace::testing::slanted_unbounded_view();
  for (int level = 1; level <= levels.level_count(); ++level) {
    const render::HeightField coarse = displace::testing::level_of(field, level);
    view.level = level;
    render::Frame frame;
    renderer.render(view, {render::Method::acm4, 256, 8}, frame, render::output_uv | render::output_depth);
    long long compared = 0, beyond = 0, on = 0;
    for (int py = 0; py < view.camera.height; ++py)
      for (int px = 0; px < view.camera.width; ++px) {
        const std::size_t p = std::size_t(py) * std::size_t(view.camera.width) + std::size_t(px);
        if (frame.uv[p * 3 + 2] < 0.5f) continue;
        ++compared;
        const double past = frame.depth[p] - displace::testing::exact_distance(coarse, view, px, py);
        beyond += past > tolerance;
        on += std::abs(past) <= tolerance;
      }
    std::printf("level %d: %lld rays, %lld at its first crossing, %lld beyond\n", level, compared, on,
                beyond);
    EXPECT_EQ(compared, (long long)view.camera.width * view.camera.height) << "level " << level;
    EXPECT_EQ(beyond, 0) << "level " << level;
    EXPECT_GE(on, compared * 99 / 100) << "level " << level;
  }
  // a MapSet whose levels are not this DeviceLevels' is refused
  maps.level_count = levels.level_count() - 1;
  EXPECT_THROW(renderer.set_maps(maps), render::RenderError);
  EXPECT_EQ(renderer.validation_messages(), 0);
}

// The frame pipeline on the unbounded sea with the sim and the bake on the device: the levels are the
// device's (the far sea traced on them, as the CPU path's is), their bakes count in the bake's device
// time, and frames allocate nothing once both frame slots ran one.
TEST(DeviceLevels, TheDevicePathTracesItsLevelsAndAllocatesNothingPerFrame) {
  render::Renderer& renderer = levels_renderer();
  pipeline::Scene scene = pipeline::builtin_scene("water");
  scene.map_size = 64;
  scene.camera.width = 64;
  scene.camera.height = 40;
  scene.sim_backend = pipeline::Backend::device;
  scene.bake_backend = pipeline::Backend::device;
  ASSERT_TRUE(scene.unbounded);
  pipeline::FramePipeline device(scene, renderer);
  render::Frame frame;
  for (long long index = 0; index < 2; ++index) device.run(index, frame, render::output_color);
  const long long allocations = renderer.memory_allocations();
  for (long long index = 2; index < 5; ++index) {
    const pipeline::FrameRecord record = device.run(index, frame, render::output_color);
    EXPECT_TRUE(record.bake_on_device);
    // the frame finished: its levels' time is a share of the bake's (both 0 without timestamps)
    EXPECT_EQ(record.levels_device_ms > 0.0, record.bake_device_ms > 0.0);
    EXPECT_GT(record.bake_device_ms, record.levels_device_ms);
  }
  EXPECT_EQ(renderer.memory_allocations(), allocations);
  EXPECT_EQ(device.maps().level_count, 0);  // the host's maps hold no levels: the device's are sampled

  // the same frame with the levels off (View::level_off) differs in the far sea only
  render::View far_view = pipeline::scene_view(scene, scene.start);
  render::Frame with_levels, without;
  renderer.render(far_view, {scene.method, scene.steps, scene.refine}, with_levels, render::output_color);
  far_view.level = render::View::level_off;
  renderer.render(far_view, {scene.method, scene.steps, scene.refine}, without, render::output_color);
  long long different = 0;
  for (std::size_t b = 0; b < with_levels.color.size(); ++b)
    different += with_levels.color[b] != without.color[b];
  EXPECT_GT(different, 0) << "the levels change nothing: they are not traced";
  EXPECT_EQ(renderer.validation_messages(), 0);
}

}  // namespace
