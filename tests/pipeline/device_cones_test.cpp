// tests/pipeline/device_cones_test.cpp - the cone maps made on the device (bake/device/device_cones.h,
// DeviceCones) against bake.h's contract for the bilinear surface, checked by brute force
// (tests/bake/bake_checks.h's check_bilinear) on what the renderer samples: hard, random, spike and
// non-square maps, 1, 4 and 8 sectors, wrap and clamp, every budget; against the full CPU bake's mean
// ratio; with a DeviceSim's heights and in a rendered frame.
#include "bake/device/device_cones.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iterator>
#include <limits>
#include <map>
#include <memory>
#include <numeric>
#include <string>
#include <vector>

#include "bake/lagged.h"
#include "pipeline/height_source.h"
#include "render/render.h"
#include "render/testing.h"
#include "sim/device/device_sim.h"
#include "tests/bake/bake_checks.h"
#include "tests/test_maps.h"

namespace {

using namespace displace;
using bake::Address;
using test::Map;

render::Renderer& cones_renderer() {
  static render::Renderer renderer = [] {
    render::RendererOptions options;
    options.validate = true;
    render::Renderer made(options);
    render::testing::hold_async_work(made);  // lagged bands run as late as a GPU's other queue may run them
    return made;
  }();
  return renderer;
}

struct DeviceBake {
  bake::ConeMap cones;
  std::vector<float> apex;
  bake::BakeStats stats;
};

DeviceBake read(bake::DeviceCones& device, int width, int height) {
  DeviceBake b;
  b.cones = {width, height, device.sector_count(), {}};
  b.stats = device.read_back(&b.cones.ratios, &b.apex);
  return b;
}

DeviceBake bake_on_device(bake::DeviceCones& device, long long budget,
                          bake::DeviceFirstPass first_pass = {}) {
  device.bake(bake::work_budget(budget), first_pass);
  return read(device, device.width(), device.height());
}

// The first passes tested: the default (rings of radius 2, the full window), the search, rings of
// radius 1 with the full window (whose levels stop at 1), of radius 2 with a window of 2 cells (down to
// the cells), of 3 with one cell; the group's first pass with the full window and with a window of 2.
const bake::DeviceFirstPass search{4, 0}, rings_1{4, 1}, rings_2{2, 2}, rings_3{1, 3};
const bake::DeviceFirstPass group_4{4, 0, true}, group_2{2, 0, true};

// The budgets every claim is tested at: the first pass alone, a few cut texels, unlimited; each
// first pass alone, and a few cut texels after the one with the smallest window.
struct Budget {
  long long texels;
  bake::DeviceFirstPass first_pass;
};
const Budget budgets[] = {{0, {}},      {0, search},  {0, rings_1},
                          {0, rings_2}, {0, group_4}, {7, search},
                          {7, rings_3}, {7, group_2}, {bake::unlimited_texels, {}}};

// Texels checked: all of a small map, every stride-th of a larger one (the check is O(texels x map)),
// a third of those for the rings' first passes, and an eighth for a budget between the first pass and
// unlimited (its texels hold the first pass's ratios or the full search's, both checked whole;
// TheBudgetBoundsTheTexelsRefined has the rest).
int stride_for(const Map& map, const Budget& budget) {
  const int texels = map.width * map.height;
  const int stride = texels <= 100 ? 1 : (texels <= 250 ? 3 : 11);
  if (budget.texels != 0 && budget.texels != bake::unlimited_texels) return 8 * stride + 1;
  return budget.first_pass.ring_radius > 0 || budget.first_pass.group ? 3 * stride + 1 : stride;
}

std::string where(const Map& map, int sectors, Address address, const Budget& budget) {
  return map.name + " " + std::to_string(map.width) + "x" + std::to_string(map.height) + " sectors " +
         std::to_string(sectors) + " " + bake::address_name(address) + " budget " +
         std::to_string(budget.texels) + " window " + std::to_string(budget.first_pass.window_radius) +
         " rings " + std::to_string(budget.first_pass.ring_radius) +
         (budget.first_pass.group ? " group" : "");
}

// Every ratio and apex the device stores meets the contract, at every budget; the apex is never below
// the CPU bake's (bake_bilinear_cones: the largest of s over Q_c, rounded up).
void expect_contract(const std::vector<Map>& maps, long long& pairs) {
  render::Renderer& renderer = cones_renderer();
  for (const Map& map : maps)
    for (int sectors : {1, 4, 8})
      for (Address address : {Address::wrap, Address::clamp}) {
        bake::DeviceCones device(renderer.frames(), bake::view_of(map), sectors, address);
        const bake::BilinearCones full = bake::bake_bilinear(map, sectors, address);
        for (const Budget& budget : budgets) {
          const DeviceBake b = bake_on_device(device, budget.texels, budget.first_pass);
          const std::string at = where(map, sectors, address, budget);
          for (std::size_t t = 0; t < b.apex.size(); ++t) ASSERT_GE(b.apex[t], full.apex[t]) << at;
          for (float r : b.cones.ratios) ASSERT_TRUE(r >= 0.0f && r <= 1.0f) << at << " " << r;
          if (budget.texels == 0) {
            EXPECT_EQ(b.stats.texels_refined, 0) << at;
          }
          if (budget.texels > 0) {
            EXPECT_LE(b.stats.texels_refined, budget.texels) << at;
          }
          const bake::BilinearCheck check =
              bake::check_bilinear(map, address, b.cones, b.apex, stride_for(map, budget));
          pairs += check.pairs;
          ASSERT_EQ(check.violations, 0) << at << " worst " << check.worst;
        }
      }
}

TEST(DeviceCones, HardMapsMeetTheContractAtEveryBudget) {
  std::vector<Map> maps = bake::bilinear_maps();
  for (const Map& map : bake::hard_maps())
    if (map.width * map.height <= 600) maps.push_back(map);
  long long pairs = 0;
  expect_contract(maps, pairs);
  std::printf("device cones, hard maps: %lld (p, x) pairs checked\n", pairs);
  EXPECT_GT(pairs, 1000000);
  EXPECT_EQ(cones_renderer().validation_messages(), 0);
}

TEST(DeviceCones, RandomSpikeAndNonSquareMapsMeetTheContract) {
  std::vector<Map> maps;
  for (int n = 0; n < 4; ++n) {
    const int w = 1 + int(test::hash01(71, n, 1) * 12), h = 1 + int(test::hash01(71, n, 2) * 12);
    Map random = bake::make_noise(w, h);
    random.name = "random-" + std::to_string(n);
    maps.push_back(random);
  }
  maps.push_back(bake::make_single_spike(13, 6));
  maps.push_back(test::make_spikes(5, 17, 11));
  maps.push_back(test::make_fractal_cliff(24, 8, 5));
  maps.push_back(test::make_bricks(8, 20));
  long long pairs = 0;
  expect_contract(maps, pairs);
  std::printf("device cones, random maps: %lld (p, x) pairs checked\n", pairs);
  EXPECT_GT(pairs, 100000);
  EXPECT_EQ(cones_renderer().validation_messages(), 0);
}

// The group's first pass on maps larger than a group's near cells (24 a side), where the group's far
// ratios - from the group's square at a few apexes - bound most cells: the contract at budget 0 (the
// full window and 2 cells) and 7, every 41st texel checked (each group at a place or two in it).
TEST(DeviceCones, GroupFirstPassMeetsTheContractWhereItsFarRatiosCount) {
  render::Renderer& renderer = cones_renderer();
  struct Case {
    Map map;
    std::vector<int> sectors;
  };
  const Case cases[] = {{test::make_ocean(48, 48), {4, 8}},
                        {test::make_fractal_cliff(40, 32), {1, 4}},
                        {test::make_spikes(36, 28), {4}},
                        {test::make_terraces(34, 30), {8}},
                        {bake::make_single_spike(40, 36), {4}}};
  long long pairs = 0;
  for (const Case& c : cases)
    for (int sectors : c.sectors)
      for (Address address : {Address::wrap, Address::clamp}) {
        bake::DeviceCones device(renderer.frames(), bake::view_of(c.map), sectors, address);
        for (const Budget& budget : {Budget{0, group_4}, Budget{0, group_2}, Budget{7, group_2}}) {
          const DeviceBake b = bake_on_device(device, budget.texels, budget.first_pass);
          const std::string at = where(c.map, sectors, address, budget);
          const bake::BilinearCheck check = bake::check_bilinear(c.map, address, b.cones, b.apex, 41);
          pairs += check.pairs;
          ASSERT_EQ(check.violations, 0) << at << " worst " << check.worst;
        }
      }
  std::printf("device cones, the group's first pass: %lld (p, x) pairs checked\n", pairs);
  EXPECT_GT(pairs, 1000000);
  EXPECT_EQ(renderer.validation_messages(), 0);
}

// Unlimited keeps at least 0.9 of the full CPU bake's mean ratio (both lower bounds of the same
// contract; the device's are rounded down to 11 bits and its apexes raised to 16, as stored).
TEST(DeviceCones, UnlimitedKeepsNineTenthsOfTheFullBakesMeanRatio) {
  render::Renderer& renderer = cones_renderer();
  for (const Map& map :
       {test::make_ocean(64, 64), test::make_fractal_cliff(48, 40), test::make_bricks(40, 40)})
    for (int sectors : {1, 4, 8}) {
      const Address address = Address::wrap;
      bake::DeviceCones device(renderer.frames(), bake::view_of(map), sectors, address);
      const bake::BilinearCones full = bake::bake_bilinear(map, sectors, address);
      const double full_mean = bake::mean_ratio(full.cones);
      const DeviceBake unlimited = bake_on_device(device, bake::unlimited_texels);
      const DeviceBake first = bake_on_device(device, 0, search);
      const DeviceBake ring_1 = bake_on_device(device, 0, {4, 1});
      const DeviceBake ring_2 = bake_on_device(device, 0, {4, 2});
      const DeviceBake group = bake_on_device(device, 0, group_4);
      const double kept = bake::mean_ratio(unlimited.cones) / full_mean;
      std::printf(
          "%s sectors %d: device mean ratio / full bake's: unlimited %.4f, search %.4f (%lld of %d "
          "texels cut), rings 1 %.4f, rings 2 (the default) %.4f, group %.4f\n",
          map.name.c_str(), sectors, kept, bake::mean_ratio(first.cones) / full_mean,
          first.stats.texels_fallback, map.width * map.height, bake::mean_ratio(ring_1.cones) / full_mean,
          bake::mean_ratio(ring_2.cones) / full_mean, bake::mean_ratio(group.cones) / full_mean);
      EXPECT_GE(kept, 0.9) << map.name << " sectors " << sectors;
      EXPECT_EQ(unlimited.stats.texels_refined, map.width * map.height);
      // a first pass with the full window never claims more than the full search: each node it bounds
      // whole bounds its cells, and every ratio is the least bound
      for (const DeviceBake* pass : {&first, &ring_1, &ring_2, &group})
        EXPECT_LE(bake::mean_ratio(pass->cones), bake::mean_ratio(unlimited.cones) + 1e-9) << map.name;
      // each shape runs its own form of the kernel (a pipeline per form): on the ocean, where the
      // first pass cuts most texels, the rings' and the group's maps are not the search's, nor each
      // other's
      if (map.name == "ocean") {
        EXPECT_NE(ring_1.cones.ratios, first.cones.ratios) << "sectors " << sectors;
        EXPECT_NE(ring_2.cones.ratios, ring_1.cones.ratios) << "sectors " << sectors;
        EXPECT_NE(group.cones.ratios, first.cones.ratios) << "sectors " << sectors;
        EXPECT_NE(group.cones.ratios, ring_1.cones.ratios) << "sectors " << sectors;
      }
    }
  EXPECT_EQ(renderer.validation_messages(), 0);
}

// The check has teeth on the device's maps: ratios 10% too large are caught.
TEST(DeviceCones, CheckCatchesRatiosTenPercentTooLarge) {
  render::Renderer& renderer = cones_renderer();
  int caught = 0, tried = 0;
  for (const Map& map : {bake::make_ramp(8, 6), bake::make_noise(6, 6), test::make_fractal_cliff(10, 8),
                         test::make_bricks(12, 8), bake::make_single_spike(7, 5)})
    for (Address address : {Address::wrap, Address::clamp})
      for (const Budget& budget : {Budget{0, {}}, Budget{0, search}, Budget{0, rings_1}, Budget{0, group_4},
                                   Budget{bake::unlimited_texels, {}}}) {
        bake::DeviceCones device(renderer.frames(), bake::view_of(map), 4, address);
        DeviceBake b = bake_on_device(device, budget.texels, budget.first_pass);
        ASSERT_EQ(bake::check_bilinear(map, address, b.cones, b.apex).violations, 0) << map.name;
        for (float& r : b.cones.ratios) r = std::min(1.0f, r * 1.1f);
        ++tried;
        if (bake::check_bilinear(map, address, b.cones, b.apex).violations > 0) ++caught;
      }
  std::printf("device ratios x1.1 caught on %d of %d maps\n", caught, tried);
  EXPECT_GE(caught, tried * 3 / 4);
}

// The budget bounds the refinement: at most `texels` cut texels are searched again, and every one
// of them only raises ratios; the cut count does not depend on the budget.
// The one rule from the Budget every baker takes to a device bake's work: a work budget is that many
// cut texels searched again (whatever the clock says), a wall-clock budget the first pass alone,
// neither every texel to the cells.
TEST(DeviceCones, OneRuleTurnsABudgetIntoWork) {
  EXPECT_EQ(bake::device_refine_limit(bake::Budget{}), bake::unlimited_texels);
  bake::Budget timed;
  timed.milliseconds = 5.0;
  EXPECT_EQ(bake::device_refine_limit(timed), 0);
  timed.milliseconds = 0.0;
  EXPECT_EQ(bake::device_refine_limit(timed), 0);
  bake::Budget work = timed;
  work.max_work = 42;
  EXPECT_EQ(bake::device_refine_limit(work), 42);
  EXPECT_EQ(bake::device_refine_limit(bake::work_budget(0)), 0);
  EXPECT_EQ(bake::device_refine_limit(bake::work_budget(bake::unlimited_texels)), bake::unlimited_texels);
}

TEST(DeviceCones, TheBudgetBoundsTheTexelsRefined) {
  render::Renderer& renderer = cones_renderer();
  const Map map = test::make_fractal_cliff(40, 24);
  bake::DeviceCones device(renderer.frames(), bake::view_of(map), 4, Address::clamp);
  const DeviceBake unlimited = bake_on_device(device, bake::unlimited_texels);
  for (const bake::DeviceFirstPass first_pass : {bake::DeviceFirstPass{}, search, rings_1, group_4}) {
    const std::string at =
        "rings " + std::to_string(first_pass.ring_radius) + (first_pass.group ? " group" : "");
    const DeviceBake first = bake_on_device(device, 0, first_pass);
    const long long cut = first.stats.texels_fallback;  // the first pass alone: every cut texel left
    ASSERT_GT(cut, 10) << at;
    EXPECT_EQ(first.stats.texels_refined, 0) << at;
    double previous = bake::mean_ratio(first.cones);
    for (long long budget : {5ll, 50ll, 1000000ll}) {
      const DeviceBake b = bake_on_device(device, budget, first_pass);
      EXPECT_EQ(b.stats.texels_fallback + b.stats.texels_refined, cut) << at;  // the cut texels
      EXPECT_EQ(b.stats.texels_refined, std::min(budget, cut)) << at;
      for (std::size_t v = 0; v < b.cones.ratios.size(); ++v)
        ASSERT_GE(b.cones.ratios[v], first.cones.ratios[v]) << at;
      EXPECT_EQ(b.apex, first.apex) << at;
      const double mean = bake::mean_ratio(b.cones);
      EXPECT_GE(mean, previous - 1e-3) << at;  // which texels get the tickets is the device's order
      previous = mean;
    }
    // all cut texels refined from the full window: the unlimited map
    EXPECT_NEAR(previous, bake::mean_ratio(unlimited.cones), 1e-6) << at;
  }
}

// A 32 x 32 device ocean (a 200 m patch, 12 m/s wind), heights only.
std::unique_ptr<sim::DeviceSim> small_ocean(render::Renderer& renderer, std::uint64_t seed) {
  pipeline::SourceSettings settings;
  settings.kind = pipeline::SourceKind::ocean;
  settings.map_size = 32;
  settings.ocean.patch_size = 200.0f;
  settings.ocean.wind_speed = 12.0f;
  settings.ocean.seed = seed;
  return pipeline::make_device_sim(renderer, settings, pipeline::effect_heights);
}

// The cones of a DeviceSim's heights, sampled by the renderer with no upload: the contract on the
// heights read back, the frame drawn from both device maps, and nothing allocated per frame.
TEST(DeviceCones, OceanConesAreSampledAndAllocateNothingPerFrame) {
  render::Renderer& renderer = cones_renderer();
  const std::unique_ptr<sim::DeviceSim> made = small_ocean(renderer, 7);
  sim::DeviceSim& ocean = *made;
  bake::DeviceCones cones(renderer.frames(), ocean.maps(), 4, Address::wrap);
  ASSERT_EQ(cones.width(), 32);
  render::MapSet maps;
  maps.width = maps.height = 32;
  maps.device_heights = ocean.maps();
  maps.cones[std::size_t(render::cone_slot(4))].sector_count = 4;
  maps.cones[std::size_t(render::cone_slot(4))].device = cones.map();
  render::View view;
  view.camera.width = view.camera.height = 24;
  const render::MethodSettings method{render::Method::acm4, 32, 4};
  render::Frame frame;
  long long allocations = 0;
  for (int step = 0; step < 4; ++step) {
    ocean.simulate(2.0 + step / 30.0);
    cones.bake(bake::work_budget(step % 2 == 0 ? 0 : bake::unlimited_texels));
    renderer.set_maps(maps);
    renderer.render(view, method, frame, render::output_uv);
    if (step == 1) allocations = renderer.memory_allocations();
  }
  EXPECT_EQ(renderer.memory_allocations(), allocations);
  long long hits = 0;
  for (std::size_t p = 0; p < frame.uv.size(); p += 3) hits += frame.uv[p + 2] > 0.0f ? 1 : 0;
  EXPECT_GT(hits, 0);
  std::vector<float> heights;
  ocean.read_back(&heights, nullptr, nullptr);
  const DeviceBake b = read(cones, 32, 32);
  const Map map{"device-ocean", 32, 32, heights};
  EXPECT_EQ(bake::check_bilinear(map, Address::wrap, b.cones, b.apex, 5).violations, 0);
  EXPECT_EQ(renderer.validation_messages(), 0);
}

// Lagged maps (bake_lagged): each frame samples the map of the heights of the frame it began on, bit
// for bit the ratios that a whole bake of those heights gives, with every apex raised by the most a
// texel rose since (within the two units of rounding up); every frame's map holds for that frame's own
// heights (brute force on every 17th texel: the check is most of the test's time under TSan), and the
// same maps served unraised do not (the lift is what keeps them conservative). A new map begins every
// N frames and is served from its N-th on, at most 2N - 1 frames old; nothing is allocated after the
// first.
TEST(DeviceCones, LaggedMapsAreOldMapsRaisedAndHoldForEachFramesHeights) {
  render::Renderer& renderer = cones_renderer();
  const std::unique_ptr<sim::DeviceSim> made = small_ocean(renderer, 11);
  sim::DeviceSim& ocean = *made;
  for (int lag : {1, 3}) {
    bake::DeviceCones cones(renderer.frames(), ocean.maps(), 4, Address::wrap);
    struct Served {
      std::vector<float> heights;
      DeviceBake bake;
      long long age = 0;
      float lift = 0.0f;
    };
    std::vector<Served> frames;
    long long allocations = 0;
    for (int f = 0; f < 2 * lag + 3; ++f) {  // two maps after the whole one: ages 0 to 2N - 1
      ocean.simulate(1.0 + 0.4 * f);         // a fast sea: the heights rise by up to a tenth of their range
      Served served;
      served.age = cones.bake_lagged(bake::work_budget(0), lag);
      // the frame submitted first, as a frame loop submits it. Nothing here waits for a band in
      // flight (read_back neither), and the renderer holds the bands back until something waits for
      // them (render::testing::hold_async_work): a wait that the serving frame lacks shows in its map.
      ocean.finish();
      served.bake = read(cones, 32, 32);
      served.lift = cones.lift();
      ocean.read_back(&served.heights, nullptr, nullptr);
      frames.push_back(std::move(served));
      if (f == 0) allocations = renderer.memory_allocations();
    }
    EXPECT_EQ(renderer.memory_allocations(), allocations) << "lag " << lag;
    int unraised_fail = 0;
    std::map<long long, DeviceBake> references;  // a whole bake of each map's heights, by its frame
    for (int f = 0; f < int(frames.size()); ++f) {
      const Served& served = frames[std::size_t(f)];
      const std::string at = "lag " + std::to_string(lag) + " frame " + std::to_string(f);
      // frame 0 makes a whole map; then one begins on frame 1, N + 1, 2N + 1, ... and is served from
      // its N-th frame on
      const long long begun = f < 1 + lag ? 0 : 1 + lag * ((f - 1 - lag) / lag);
      ASSERT_EQ(served.age, f - begun) << at;
      ASSERT_LE(served.age, 2 * lag - 1) << at;
      const std::vector<float>& then = frames[std::size_t(begun)].heights;
      float rise = 0.0f;
      for (std::size_t t = 0; t < then.size(); ++t) rise = std::max(rise, served.heights[t] - then[t]);
      EXPECT_EQ(served.lift, rise) << at;
      // the map of the heights it began on, raised
      if (references.count(begun) == 0) {
        const Map old_map{"ocean-then", 32, 32, then};
        bake::DeviceCones whole(renderer.frames(), bake::view_of(old_map), 4, Address::wrap);
        references[begun] = bake_on_device(whole, 0);
      }
      const DeviceBake& reference = references[begun];
      ASSERT_EQ(served.bake.cones.ratios, reference.cones.ratios) << at;
      for (std::size_t t = 0; t < then.size(); ++t) {
        ASSERT_GE(served.bake.apex[t], std::min(1.0f, reference.apex[t] + rise)) << at;
        ASSERT_LE(served.bake.apex[t], reference.apex[t] + rise + 2.5f / 65535.0f) << at;
      }
      // conservative for this frame's heights; unraised, not always
      const Map now_map{"ocean-now", 32, 32, served.heights};
      EXPECT_EQ(
          bake::check_bilinear(now_map, Address::wrap, served.bake.cones, served.bake.apex, 17).violations, 0)
          << at;
      if (unraised_fail == 0 && served.lift > 0.0f &&
          bake::check_bilinear(now_map, Address::wrap, reference.cones, reference.apex, 9).violations > 0)
        ++unraised_fail;
    }
    EXPECT_GT(unraised_fail, 0) << "lag " << lag;
  }
  EXPECT_EQ(renderer.validation_messages(), 0);
}

// The group's first pass in lagged maps: each band of group rows makes its groups' far ratios before
// its texels, so every frame's map is bit for bit the whole first pass of the heights it began on
// (the brute-force checks of those whole bakes are GroupFirstPassMeetsTheContract's).
TEST(DeviceCones, LaggedGroupMapsAreWholeBakesOfTheirHeights) {
  render::Renderer& renderer = cones_renderer();
  const std::unique_ptr<sim::DeviceSim> made = small_ocean(renderer, 12);
  sim::DeviceSim& ocean = *made;
  const int lag = 3;
  bake::DeviceCones cones(renderer.frames(), ocean.maps(), 4, Address::wrap);
  std::vector<std::vector<float>> heights;
  for (int f = 0; f < 2 * lag + 3; ++f) {
    ocean.simulate(1.0 + 0.4 * f);
    heights.emplace_back();
    ocean.read_back(&heights.back(), nullptr, nullptr);
    const long long age = cones.bake_lagged(bake::work_budget(0), lag, group_4);
    const DeviceBake served = read(cones, 32, 32);
    const Map then{"ocean-then", 32, 32, heights[std::size_t(f - age)]};
    bake::DeviceCones whole(renderer.frames(), bake::view_of(then), 4, Address::wrap);
    const DeviceBake reference = bake_on_device(whole, 0, group_4);
    ASSERT_EQ(served.cones.ratios, reference.cones.ratios) << "frame " << f << " age " << age;
  }
  EXPECT_EQ(renderer.validation_messages(), 0);
}

// A lag that changes while a map is under way (play's L key): the map keeps its rows done and its
// last share runs what is left, so every frame's map is still bit for bit the whole bake of the heights
// it began on, and served on the frame its schedule (bake::LagSchedule) says.
TEST(DeviceCones, ALagChangedMidMapKeepsEveryMapWhole) {
  render::Renderer& renderer = cones_renderer();
  const std::unique_ptr<sim::DeviceSim> made = small_ocean(renderer, 13);
  sim::DeviceSim& ocean = *made;
  bake::DeviceCones cones(renderer.frames(), ocean.maps(), 4, Address::wrap);
  bake::LagSchedule schedule(bake::LagSchedule::Lands::after_draw);
  const int lags[] = {3, 3, 3, 1, 1, 4, 4, 2, 2, 2, 5, 1, 1, 1};
  std::vector<std::vector<float>> heights;
  std::map<long long, DeviceBake> references;
  for (int f = 0; f < int(std::size(lags)); ++f) {
    ocean.simulate(1.0 + 0.4 * f);
    heights.emplace_back();
    ocean.read_back(&heights.back(), nullptr, nullptr);
    const long long age = cones.bake_lagged(bake::work_budget(0), lags[f]);
    schedule.finished(schedule.next(f, lags[f]).last());
    ASSERT_EQ(age, f - schedule.served_frame()) << "frame " << f;
    const DeviceBake served = read(cones, 32, 32);
    const long long begun = f - age;
    if (references.count(begun) == 0) {
      const Map then{"ocean-then", 32, 32, heights[std::size_t(begun)]};
      bake::DeviceCones whole(renderer.frames(), bake::view_of(then), 4, Address::wrap);
      references[begun] = bake_on_device(whole, 0);
    }
    ASSERT_EQ(served.cones.ratios, references[begun].cones.ratios) << "frame " << f << " age " << age;
  }
  EXPECT_GE(references.size(), 4u);
  EXPECT_EQ(renderer.validation_messages(), 0);
}

TEST(DeviceCones, RefusesWhatItCannotBake) {
  render::Renderer& renderer = cones_renderer();
  std::vector<float> heights(16, 0.5f);
  auto message_of = [](auto&& make) -> std::string {
    try {
      make();
    } catch (const render::RenderError& error) {
      return error.what();
    }
    return "";
  };
  EXPECT_NE(message_of([&] {
              bake::DeviceCones(renderer.frames(), bake::HeightView{heights.data(), 0, 0}, 4, Address::wrap);
            }).find("between 1 and"),
            std::string::npos);
  heights[5] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_NE(message_of([&] {
              bake::DeviceCones(renderer.frames(), bake::HeightView{heights.data(), 4, 4}, 4, Address::wrap);
            }).find("row 1, column 1"),
            std::string::npos);
  heights[5] = 1.5f;
  EXPECT_THROW(bake::DeviceCones(renderer.frames(), bake::HeightView{heights.data(), 4, 4}, 4, Address::wrap),
               render::RenderError);
  heights[5] = 0.5f;
  EXPECT_NE(message_of([&] {
              bake::DeviceCones(renderer.frames(), bake::HeightView{heights.data(), 4, 4}, 3, Address::wrap);
            }).find("1, 4 or 8 sectors"),
            std::string::npos);
  EXPECT_NE(
      message_of([&] { bake::DeviceCones(renderer.frames(), nullptr, 4, Address::wrap); }).find("alive"),
      std::string::npos);
  {  // the heights of a DeviceSim that is gone: refused by a bake and by a frame that would read them
    std::unique_ptr<sim::DeviceSim> ocean = small_ocean(renderer, 3);
    const std::shared_ptr<const render::DeviceHeightImages> handle = ocean->maps();
    ocean->simulate(1.0);
    ocean->finish();  // nothing recorded is left to run when it goes
    bake::DeviceCones cones(renderer.frames(), handle, 4, Address::wrap);
    render::MapSet maps;
    maps.width = maps.height = ocean->size();
    maps.device_heights = handle;
    renderer.set_maps(maps);
    ocean.reset();
    EXPECT_NE(message_of([&] { cones.bake(bake::work_budget(0)); }).find("is gone"), std::string::npos);
    render::View view;
    view.camera.width = view.camera.height = 8;
    EXPECT_NE(message_of([&] {
                renderer.render(view, {render::Method::pom, 8, 0});
              }).find("is gone"),
              std::string::npos);
    EXPECT_NE(
        message_of([&] { bake::DeviceCones(renderer.frames(), handle, 4, Address::wrap); }).find("alive"),
        std::string::npos);
    EXPECT_NE(message_of([&] { renderer.set_maps(maps); }).find("DeviceSim of this renderer, alive"),
              std::string::npos);
  }
  std::shared_ptr<const render::DeviceConeImage> gone;
  {
    bake::DeviceCones cones(renderer.frames(), bake::HeightView{heights.data(), 4, 4}, 4, Address::wrap);
    gone = cones.map();
    EXPECT_THROW(cones.read_back(nullptr, nullptr), render::RenderError);  // nothing baked yet
    EXPECT_THROW(cones.bake_lagged(bake::work_budget(0), -1), render::RenderError);
    for (const bake::DeviceFirstPass first_pass :
         {bake::DeviceFirstPass{0, 0}, bake::DeviceFirstPass{5, 0}, bake::DeviceFirstPass{4, -1},
          bake::DeviceFirstPass{4, 9}}) {
      const std::string message = message_of([&] { cones.bake(bake::work_budget(0), first_pass); });
      EXPECT_NE(message.find("radius"), std::string::npos) << message;
      EXPECT_THROW(cones.bake_lagged(bake::work_budget(0), 2, first_pass), render::RenderError);
    }
    const std::string both = message_of([&] {
      cones.bake(bake::work_budget(0), bake::DeviceFirstPass{4, 1, true});
    });
    EXPECT_NE(both.find("by rings or by its group"), std::string::npos) << both;
  }
  // a MapSet naming the cones of a DeviceCones that is gone
  render::MapSet maps;
  maps.width = maps.height = 4;
  maps.heights = heights;
  maps.cones[std::size_t(render::cone_slot(4))].sector_count = 4;
  maps.cones[std::size_t(render::cone_slot(4))].device = gone;
  EXPECT_NE(message_of([&] { renderer.set_maps(maps); }).find("4-sector DeviceCones of this renderer, alive"),
            std::string::npos);
  EXPECT_EQ(renderer.validation_messages(), 0);
}

}  // namespace
