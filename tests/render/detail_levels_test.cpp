// tests/render/detail_levels_test.cpp - the levels of detail on the unbounded plane (MapSet::levels,
// surface.frag.glsl's choose_level): a ray on a level ends at that level's exact first crossing, a
// still scene renders identical frames, views without levels are untouched, the memory estimate
// counts the atlases; and the measure of issue 32: fetches per pixel by distance band and the far
// sea's frame-to-frame flicker against a supersampled reference.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <string>
#include <vector>

#include "bake/bake.h"
#include "pipeline/frame_pipeline.h"
#include "pipeline/maps.h"
#include "pipeline/scene.h"
#include "render/render.h"
#include "tests/render/level_checks.h"
#include "tests/render_fixtures.h"

namespace {

using namespace displace;
using namespace displace::testing;
using render::Frame;
using render::HeightField;
using render::Method;
using render::View;

// Every level l of the chain, pinned (View::level = l) for every pixel: the cone methods' rays, with
// enough steps to finish their march, end at level l's own exact first crossing - never past it, and
// all but the few that run out of steps on it - and not at level 0's (level 0 itself: the control).
TEST(DetailLevels, RaysOnALevelEndAtThatLevelsFirstCrossing) {
  constexpr double tolerance = 1e-4;  // world units (a level-0 texel here is 0.016)
  const HeightField field = field_of(64, 64, [](int i, int j) {
    return 0.5 + 0.25 * std::sin(0.39 * i + 0.2 * j) + 0.2 * std::sin(1.7 * j + 0.3 * i * i);
  });
  ASSERT_EQ(bake::detail_level_count(64, 64), 6);
  shared_maps().set_heights(field);
  View view = slanted_unbounded_view();
  for (int level = 0; level <= 6; ++level) {
    const HeightField coarse = level_of(field, level);
    std::vector<double> truth, level0;
    for (int py = 0; py < view.camera.height; ++py)
      for (int px = 0; px < view.camera.width; ++px) {
        truth.push_back(exact_distance(coarse, view, px, py));
        level0.push_back(exact_distance(field, view, px, py));
      }
    view.level = level;
    for (const Method method : {Method::csm, Method::acm4, Method::acm8, Method::acm4_interval}) {
      const Frame frame = draw(view, {method, 256, 8});
      long long compared = 0, beyond = 0, on = 0, off_level0 = 0;
      double worst = 0.0;
      for (std::size_t p = 0; p < truth.size(); ++p) {
        if (frame.uv[p * 3 + 2] < 0.5f) continue;
        ++compared;
        const double past = frame.depth[p] - truth[p];
        worst = std::max(worst, past);
        beyond += past > tolerance;
        on += std::abs(past) <= tolerance;
        off_level0 += std::abs(frame.depth[p] - level0[p]) > 10 * tolerance;
      }
      std::printf(
          "level %d %-13s %lld rays: %lld at its first crossing, %lld beyond (worst %.2g), %lld off level "
          "0's\n",
          level, render::method_info(method).name, compared, on, beyond, worst, off_level0);
      EXPECT_EQ(compared, (long long)truth.size());
      EXPECT_EQ(beyond, 0) << "level " << level << " " << render::method_info(method).name;
      EXPECT_GE(on, compared * 99 / 100) << "level " << level << " " << render::method_info(method).name;
      if (level > 0) {
        EXPECT_GT(off_level0, compared / 10) << "level " << level << ": the level's surface is not level 0's";
      }
    }
  }
  EXPECT_EQ(shared_renderer().validation_messages(), 0);
}

// Views that trace no level - the patch, level_off, the other methods - render what they render
// without levels given, bit for bit; the memory estimate counts the levels' atlases (about 1/3 more
// than the height and cone images).
TEST(DetailLevels, ViewsWithoutLevelsAreUntouchedAndTheMemoryEstimateCountsThem) {
  const HeightField field = waves_field(64);
  render::Renderer& renderer = shared_renderer();
  pipeline::MapMaker plain(renderer.device().max_image_dimension_3d);
  plain.set_heights(field);
  shared_maps().set_heights(field);
  View unbounded = slanted_unbounded_view();
  View patch = unbounded;
  patch.unbounded = false;
  View off = unbounded;
  off.level = View::level_off;
  for (const auto& [view, method] :
       {std::pair{patch, Method::acm4}, std::pair{off, Method::acm4}, std::pair{unbounded, Method::relief}}) {
    render::MapNeeds needs = render::map_needs(method, view);
    EXPECT_FALSE(needs.levels);
    needs.levels = false;
    renderer.set_maps(plain.maps(needs));
    const Frame without = renderer.render(view, {method, 32, 8});
    needs.levels = true;
    needs.cone_sectors = std::max(needs.cone_sectors, 4);
    const render::MapSet& with_levels = shared_maps().maps(needs);
    ASSERT_EQ(with_levels.level_count, 6);
    renderer.set_maps(with_levels);
    const Frame with = renderer.render(view, {method, 32, 8});
    EXPECT_EQ(with.color, without.color);
    EXPECT_EQ(with.uv, without.uv);
    EXPECT_EQ(with.fetches, without.fetches);
  }
  // and the unbounded acm4 view does trace them
  renderer.set_maps(shared_maps().maps_for(Method::acm4, unbounded));
  const Frame levels = renderer.render(unbounded, {Method::acm4, 32, 8});
  renderer.set_maps(plain.maps_for(Method::acm4, off));
  const Frame level0 = renderer.render(off, {Method::acm4, 32, 8});
  EXPECT_NE(levels.uv, level0.uv);

  render::MapShape shape{512, 512, 4};
  const auto bytes = [](const std::vector<render::Allocation>& list) {
    std::uint64_t device = 0;
    for (const render::Allocation& a : list)
      device += a.kind == render::MemoryKind::device_local ? a.bytes : 0;
    return device;
  };
  const std::uint64_t level0_bytes = bytes(render::map_memory(shape));
  shape.level_count = 6;
  shape.level_sectors = 4;
  const std::uint64_t chain_bytes = bytes(render::map_memory(shape)) - level0_bytes;
  // heights and slope moments 16 bytes and 5 cone layers of 4 bytes a texel, over the (256 + 128) x
  // 256 texels of the atlases that hold 256^2 + 128^2 + ... texels: 9/16 of level 0's images (its
  // heights 4 bytes, its cones 20)
  EXPECT_EQ(chain_bytes, std::uint64_t(256 + 128) * 256 * (16 + 5 * 4));
  EXPECT_DOUBLE_EQ(double(chain_bytes) / double(level0_bytes), 9.0 / 16.0);
  EXPECT_EQ(renderer.validation_messages(), 0);
}

// A level's slope moments must be finite and three a texel (or absent); its heights in [0, 1]: the
// renderer refuses anything else with a message naming the level, and takes the chain without slopes.
TEST(DetailLevels, RefusesLevelsWithBadSlopeMomentsOrHeights) {
  render::Renderer& renderer = shared_renderer();
  shared_maps().set_heights(waves_field(64));
  const View view = slanted_unbounded_view();
  render::MapNeeds needs = render::map_needs(Method::acm4, view);
  ASSERT_TRUE(needs.levels);
  const render::MapSet good = shared_maps().maps(needs);
  ASSERT_EQ(good.level_count, 6);
  auto refused = [&](const render::MapSet& maps, const std::string& words) {
    try {
      renderer.set_maps(maps);
      (void)renderer.render(view, {Method::acm4, 32, 8});
    } catch (const render::RenderError& e) {
      EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
      return true;
    }
    return false;
  };
  std::vector<float> slopes(good.levels[1].slopes.begin(), good.levels[1].slopes.end());
  slopes[7] = std::numeric_limits<float>::quiet_NaN();
  render::MapSet bad = good;
  bad.levels[1].slopes = slopes;
  bad.levels_version += 1000;
  EXPECT_TRUE(refused(bad, "level of detail 2"));
  bad.levels[1].slopes = std::span<const float>(slopes).first(10);
  bad.levels_version += 1;
  EXPECT_TRUE(refused(bad, "three slope moments"));
  std::vector<float> heights(good.levels[0].heights.begin(), good.levels[0].heights.end());
  heights[3] = 1.5f;
  bad = good;
  bad.levels[0].heights = heights;
  bad.levels_version += 2000;
  EXPECT_TRUE(refused(bad, "level of detail 1"));
  bad = good;  // no slopes: accepted (the levels shaded as smooth)
  for (int level = 0; level < bad.level_count; ++level) bad.levels[std::size_t(level)].slopes = {};
  bad.levels_version += 3000;
  EXPECT_FALSE(refused(bad, ""));
  renderer.set_maps(good);
  EXPECT_EQ(renderer.validation_messages(), 0);
}

// A still scene (the time fixed) renders the same frame twice, bit for bit, with its levels.
TEST(DetailLevels, AStillSceneRendersIdenticalFrames) {
  pipeline::Scene scene = pipeline::builtin_scene("calm");
  scene.sim_backend = scene.bake_backend =
      pipeline::Backend::cpu;  // levels are the CPU path's (on a GPU auto is the device)
  scene.map_size = 64;
  scene.camera.width = 80;
  scene.camera.height = 56;
  pipeline::FramePipeline frames(scene, shared_renderer());
  ASSERT_EQ(frames.maps().level_count, 0);  // nothing made yet
  const unsigned outputs = render::output_color | render::output_uv | render::output_fetches;
  Frame first, second, other;
  frames.run(3, first, outputs);
  EXPECT_EQ(frames.maps().level_count, 6);
  frames.run(4, other, outputs);
  frames.run(3, second, outputs);
  EXPECT_EQ(first.color, second.color);
  EXPECT_EQ(first.uv, second.uv);
  EXPECT_EQ(first.fetches, second.fetches);
  EXPECT_NE(first.color, other.color);  // the sea moves between frames 3 and 4
  EXPECT_EQ(shared_renderer().validation_messages(), 0);
}

// Issue 32's measure on the calm sea (a slow swell, choppiness 0) from its default camera: fetches
// per pixel by distance band, and the far sea's flicker - the mean absolute change of a pixel's
// colour (8-bit units, RGB averaged) between consecutive frames (60 fps), over the top band of water
// - with levels (View::level_auto), level 0 only, and a supersampled reference (level 0 only at 4 x 4
// the pixels, box-averaged). With levels the far sea must cost fewer fetches than level 0's and
// flicker no more than the reference. `backend`: where the sim and the bake run, and so where the
// levels are made (the CPU's map maker, or bake::DeviceLevels).
void far_sea_against_supersampled(pipeline::Backend backend) {
  constexpr int width = 128, height = 80, supersampling = 4, frames = 8;
  constexpr std::array<double, 3> band_ends = {0.5, 2.0, 6.0};  // world units (the patch: 200 m)
  const char* band_names[4] = {"near (< 100 m)", "mid (100-400 m)", "far (400 m-1.2 km)", "top (> 1.2 km)"};
  pipeline::Scene scene = pipeline::builtin_scene("calm");
  scene.sim_backend = scene.bake_backend = backend;
  scene.map_size = 128;
  scene.camera.width = width;
  scene.camera.height = height;
  pipeline::FramePipeline pipe(scene, shared_renderer());
  const View auto_view = pipeline::scene_view(scene, scene.start);
  ASSERT_EQ(auto_view.level, View::level_auto);
  View off_view = auto_view;
  off_view.level = View::level_off;
  View fine_view = off_view;
  fine_view.camera.width = width * supersampling;
  fine_view.camera.height = height * supersampling;
  // each pixel's band from where its ray meets the plane (-1: the sky)
  std::vector<int> band(std::size_t(width) * height, -1);
  for (int py = 0; py < height; ++py)
    for (int px = 0; px < width; ++px) {
      const render::Ray ray = auto_view.camera.pixel_ray(px + 0.5, py + 0.5);
      if (ray.direction.z >= -1e-4) continue;
      const double distance = ray.origin.z / -ray.direction.z;
      band[std::size_t(py) * width + px] =
          int(std::upper_bound(band_ends.begin(), band_ends.end(), distance) - band_ends.begin());
    }
  std::array<double, 4> fetches_levels{}, fetches_off{};
  std::array<long long, 4> pixels{};
  std::array<double, 3> flicker{};  // levels, level 0, supersampled
  // per band: the mean colour (levels, level 0, supersampled) and the mean absolute difference from
  // the supersampled colour (levels, level 0); 8-bit units, the mean of the three channels
  std::array<std::array<double, 3>, 4> mean_colour{};
  std::array<std::array<double, 2>, 4> colour_error{};
  std::array<std::vector<float>, 3> previous;
  long long flicker_samples = 0;
  Frame levels, off, fine;
  const unsigned outputs = render::output_color | render::output_fetches;
  for (int n = 0; n < frames; ++n) {
    pipeline::FrameRecord record;
    record.index = n;
    pipe.simulate(pipeline::frame_time(scene, n), record);
    pipe.bake(std::numeric_limits<double>::infinity(), record);
    pipe.upload(record);
    pipe.draw(auto_view, levels, outputs, record);
    pipe.draw(off_view, off, outputs, record);
    pipe.draw(fine_view, fine, render::output_color, record);
    std::array<std::vector<float>, 3> colour;
    for (auto& c : colour) c.assign(std::size_t(width) * height * 3, 0.0f);
    for (std::size_t p = 0; p < band.size(); ++p) {
      for (int k = 0; k < 3; ++k) {
        colour[0][p * 3 + k] = levels.color[p * 4 + k];
        colour[1][p * 3 + k] = off.color[p * 4 + k];
      }
      const int px = int(p % width), py = int(p / width);
      for (int y = 0; y < supersampling; ++y)
        for (int x = 0; x < supersampling; ++x) {
          const std::size_t q = std::size_t(py * supersampling + y) * std::size_t(width * supersampling) +
                                std::size_t(px * supersampling + x);
          for (int k = 0; k < 3; ++k)
            colour[2][p * 3 + k] += float(fine.color[q * 4 + k]) / float(supersampling * supersampling);
        }
      if (band[p] < 0) continue;
      for (std::size_t v = 0; v < 3; ++v)
        for (std::size_t k = 0; k < 3; ++k) {
          mean_colour[std::size_t(band[p])][v] += colour[v][p * 3 + k] / 3.0;
          if (v < 2)
            colour_error[std::size_t(band[p])][v] +=
                std::abs(colour[v][p * 3 + k] - colour[2][p * 3 + k]) / 3.0;
        }
      fetches_levels[std::size_t(band[p])] += levels.fetches[p];
      fetches_off[std::size_t(band[p])] += off.fetches[p];
      ++pixels[std::size_t(band[p])];
      if (n == 0 || band[p] != 3) continue;
      ++flicker_samples;
      for (int v = 0; v < 3; ++v)
        for (int k = 0; k < 3; ++k)
          flicker[std::size_t(v)] +=
              std::abs(colour[std::size_t(v)][p * 3 + k] - previous[std::size_t(v)][p * 3 + k]) / 3.0;
    }
    previous = colour;
  }
  std::printf(
      "calm on the %s, %dx%d, map %d, %d frames at %g fps; fetches per pixel (levels / level 0 only):\n",
      pipeline::backend_word(backend), width, height, scene.map_size, frames, scene.fps);
  for (std::size_t b = 0; b < 4; ++b) {
    ASSERT_GT(pixels[b], 0) << band_names[b];
    std::printf("  %-20s %6lld pixels  %6.2f / %6.2f\n", band_names[b], pixels[b] / frames,
                fetches_levels[b] / double(pixels[b]), fetches_off[b] / double(pixels[b]));
  }
  std::printf(
      "mean colour (levels / level 0 only / supersampled) and mean |difference| from the supersampled:\n");
  for (std::size_t b = 0; b < 4; ++b) {
    for (double& c : mean_colour[b]) c /= double(pixels[b]);
    for (double& e : colour_error[b]) e /= double(pixels[b]);
    std::printf("  %-20s %6.2f / %6.2f / %6.2f   %6.2f / %6.2f\n", band_names[b], mean_colour[b][0],
                mean_colour[b][1], mean_colour[b][2], colour_error[b][0], colour_error[b][1]);
  }
  for (double& f : flicker) f /= double(flicker_samples);
  std::printf(
      "flicker of the top band (mean |change| a frame, 8-bit): levels %.3f, level 0 only %.3f, "
      "supersampled %dx%d %.3f\n",
      flicker[0], flicker[1], supersampling, supersampling, flicker[2]);
  EXPECT_LT(fetches_levels[2], fetches_off[2]);
  EXPECT_LT(fetches_levels[3], fetches_off[3]);
  // the far sea costs no more than the near sea (fetches per pixel: a work count)
  for (std::size_t b = 2; b < 4; ++b)
    EXPECT_LE(fetches_levels[b] / double(pixels[b]), fetches_levels[0] / double(pixels[0])) << band_names[b];
  // and looks like the supersampled sea: its mean colour within 12 of 255 (shaded as smooth as the
  // levels' surfaces are, without their slope moments, it was 29 and 41 too bright), each pixel
  // closer than level 0's
  for (std::size_t b = 2; b < 4; ++b) {
    EXPECT_LT(std::abs(mean_colour[b][0] - mean_colour[b][2]), 12.0) << band_names[b];
    EXPECT_LT(colour_error[b][0], colour_error[b][1]) << band_names[b];
  }
  EXPECT_LT(flicker[0], flicker[1]);
  EXPECT_LE(flicker[0], flicker[2]);
  EXPECT_EQ(shared_renderer().validation_messages(), 0);
}

TEST(DetailLevels, FarSeaFetchesAndFlickerAgainstASupersampledReference) {
  far_sea_against_supersampled(pipeline::Backend::cpu);
}

// The same on the device path (the sim, the cones and the levels made on the device, as `auto` does
// on a GPU): the far sea as the CPU path's.
TEST(DetailLevels, FarSeaOnTheDevicePathAgainstASupersampledReference) {
  far_sea_against_supersampled(pipeline::Backend::device);
}

}  // namespace
