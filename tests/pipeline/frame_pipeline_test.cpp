// tests/pipeline/frame_pipeline_test.cpp - the per-frame service (pipeline/frame_pipeline.cpp): effects on
// demand, the frame budget through an injected clock, conservative maps when the bake is starved,
// reproducible frames.
#include "pipeline/frame_pipeline.h"

#include <gtest/gtest.h>
#include <sched.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <set>
#include <string>
#include <string_view>
#include <thread>

#include "pipeline/scene.h"
#include "pipeline/thread_pinning.h"
#include "render/render.h"
#include "tests/pipeline/pipeline_checks.h"
#include "tests/render_fixtures.h"

namespace {

using namespace displace;
using displace::testing::shared_renderer;
using pipeline::FramePipeline;
using pipeline::FrameRecord;
using pipeline::Scene;
using pipeline::SceneError;

// A clock that moves only when asked: each call advances it by `tick` milliseconds (atomic: the
// overlapped stages read it from two threads).
struct FakeClock {
  std::atomic<double> now{0.0};
  double tick = 0.01;
  double operator()() { return now.fetch_add(tick) + tick; }
};

// Only what the scene consumes runs: the calm ocean costs exactly one FFT a frame (heights); choppy
// crests add the two displacement FFTs and resample the displaced surface onto the grid; foam (the
// water material) adds the three Jacobian FFTs, and nothing asks for spectral slopes (normals come
// from the heights).
TEST(Pipeline, SimulatesOnlyTheEffectsTheSceneNeeds) {
  Scene calm = small_scene("calm", 32, 16);
  calm.method = render::Method::relief;
  EXPECT_EQ(pipeline::scene_effects(calm), unsigned(pipeline::effect_heights));
  FramePipeline calm_pipeline(calm, shared_renderer());
  render::Frame frame;
  for (int n = 0; n < 3; ++n) {
    const FrameRecord record = calm_pipeline.run(n, frame);
    EXPECT_EQ(record.ffts, 1);
    EXPECT_EQ(record.effects, unsigned(pipeline::effect_heights));
    EXPECT_TRUE(calm_pipeline.maps().foam.empty());
  }
  Scene choppy = calm;
  choppy.ocean.choppiness = 1.0f;
  EXPECT_EQ(pipeline::scene_effects(choppy), unsigned(pipeline::effect_heights | pipeline::effect_choppy));
  FramePipeline choppy_pipeline(choppy, shared_renderer());
  FrameRecord record = choppy_pipeline.run(0, frame);
  EXPECT_EQ(record.ffts, 3);
  EXPECT_LT(record.choppy_residual, 1e-3 * calm.ocean.patch_size / 32);  // a thousandth of a texel
  // the choppy heights differ from the calm ones (crests move), and stay in [0, 1]
  FrameRecord calm_record;
  calm_pipeline.simulate(0.0, calm_record);
  EXPECT_NE(choppy_pipeline.heights().heights, calm_pipeline.heights().heights);
  for (float h : choppy_pipeline.heights().heights) EXPECT_TRUE(h >= 0.0f && h <= 1.0f);

  Scene water = small_scene("water", 32, 16);
  water.method = render::Method::relief;
  water.ocean.choppiness = 2.5f;  // folds somewhere: foam to show
  EXPECT_EQ(pipeline::scene_effects(water),
            unsigned(pipeline::effect_heights | pipeline::effect_choppy | pipeline::effect_foam));
  FramePipeline water_pipeline(water, shared_renderer());
  record = water_pipeline.run(0, frame);
  EXPECT_EQ(record.ffts, 6);
  const std::span<const float> foam = water_pipeline.maps().foam;
  ASSERT_EQ(foam.size(), std::size_t(32 * 32));
  EXPECT_GT(*std::max_element(foam.begin(), foam.end()), 0.5f);
  EXPECT_EQ(*std::min_element(foam.begin(), foam.end()), 0.0f);
  water.foam = false;
  EXPECT_EQ(pipeline::scene_effects(water), unsigned(pipeline::effect_heights | pipeline::effect_choppy));
}

// The water material on a flat sea: looking straight down shows the dark water body (2% sky);
// at a grazing angle Fresnel's law turns it into a mirror of the bright horizon; foam is white.
TEST(Pipeline, WaterReflectsTheSkyByFresnelAndFoamIsWhite) {
  const int size = 16;
  const std::vector<float> flat(std::size_t(size) * size, 0.5f);
  render::MapSet maps;
  maps.width = maps.height = size;
  maps.heights = flat;
  maps.heights_version = std::uint64_t(1) << 61;
  render::Renderer& renderer = shared_renderer();
  renderer.set_maps(maps);
  auto mean_colour = [&](glm::vec3 eye, bool with_foam) {
    render::View view;
    view.material = render::Material::water;
    view.camera.eye = eye;
    view.camera.look_at = {0.5f, 0.5f, 0.0f};
    view.camera.up = std::abs(eye.z) > 1.0f ? glm::vec3(0, 1, 0) : glm::vec3(0, 0, 1);
    view.camera.width = view.camera.height = 64;
    view.camera.fov_y_degrees = 5.0f;
    std::vector<float> coverage(flat.size(), 1.0f);
    if (with_foam) {
      maps.foam = coverage;
      maps.foam_version = (std::uint64_t(1) << 61) + 1;
    } else {
      maps.foam = {};
    }
    renderer.set_maps(maps);
    const render::Frame frame = renderer.render(view, {render::Method::relief, 8, 2});
    glm::dvec3 sum(0.0);
    long long hit = 0;
    for (std::size_t p = 0; p < frame.uv.size() / 3; ++p) {
      if (frame.uv[p * 3 + 2] < 0.5f) continue;
      sum += glm::dvec3(frame.color[p * 4], frame.color[p * 4 + 1], frame.color[p * 4 + 2]);
      ++hit;
    }
    EXPECT_GT(hit, 100);
    return glm::vec3(sum / double(std::max<long long>(hit, 1)));
  };
  const glm::vec3 down = mean_colour({0.5f, 0.5f, 3.0f}, false);
  const glm::vec3 grazing = mean_colour({0.5f, -2.0f, 0.2f}, false);  // 4.6 degrees above the sea
  const glm::vec3 foam = mean_colour({0.5f, 0.5f, 3.0f}, true);
  EXPECT_LT(down.r + down.g + down.b, 3 * 40.0f) << down.r << " " << down.g << " " << down.b;
  // at 4.6 degrees Fresnel reflects about 2/3 of the near-horizon sky: measured (96, 120, 143)
  EXPECT_GT(grazing.r + grazing.g + grazing.b, 3 * 100.0f)
      << grazing.r << " " << grazing.g << " " << grazing.b;
  EXPECT_GT(grazing.r + grazing.g + grazing.b, 3.0f * (down.r + down.g + down.b));
  EXPECT_GT(grazing.b, grazing.r);  // the sky is blue
  EXPECT_GT(foam.r + foam.g + foam.b, 3 * 180.0f);
  EXPECT_EQ(renderer.validation_messages(), 0);
}

// The bake gets what the frame budget leaves (measured on the scene's clock) and never runs past
// it by more than a refinement chunk; a frame over its budget is reported as one, and the loop
// goes on with conservative maps.
TEST(Pipeline, TheBakeKeepsToItsShareOfTheFrameBudget) {
  FakeClock clock;
  Scene scene = small_scene("calm", 64, 16);
  scene.method = render::Method::acm4;
  scene.tolerance = 0.0f;  // refinement always has work
  // the first stage alone, at budget 0
  scene.frame_ms = 0.0;
  FramePipeline starved(scene, shared_renderer(), std::ref(clock));
  render::Frame frame;
  FrameRecord record = starved.run(0, frame);
  EXPECT_EQ(record.bake_budget_ms, 0.0);
  EXPECT_TRUE(record.overrun);
  const double first_stage_ms = record.bake_ms;
  EXPECT_GT(record.pending, 0);
  // a budget that leaves the bake room for refinement
  scene.frame_ms = 50.0;
  FramePipeline budgeted(scene, shared_renderer(), std::ref(clock));
  for (int n = 0; n < 4; ++n) {
    record = budgeted.run(n, frame);
    const double share = record.bake_budget_ms;
    EXPECT_LE(share, scene.frame_ms);
    EXPECT_LE(record.bake_ms, std::max(share, first_stage_ms) + 2.0) << "frame " << n;  // ~a chunk of ticks
    EXPECT_GT(record.cones.texels_refined, 0) << "frame " << n;
  }
}

// Every cone ray of `pipeline`'s frames ends at or before its exact first crossing (render::cpu_trace
// on the frame's heights).
void expect_no_ray_past_the_first_crossing(const Scene& scene, int frames, pipeline::HeightLoader loader = {},
                                           std::vector<pipeline::FrameRecord>* records = nullptr) {
  FramePipeline pipeline(scene, shared_renderer(), {}, std::move(loader));
  render::Frame frame;
  long long compared = 0, beyond = 0;
  for (int n = 0; n < frames; ++n) {
    const pipeline::FrameRecord record = pipeline.run(n, frame, render::output_uv | render::output_depth);
    if (records != nullptr) records->push_back(record);
    const render::View view = pipeline::scene_view(scene, pipeline::frame_time(scene, n));
    for (int py = 0; py < frame.height; ++py) {
      for (int px = 0; px < frame.width; ++px) {
        const std::size_t p = std::size_t(py) * frame.width + px;
        const render::CpuHit truth = render::cpu_trace(pipeline.heights(), view, px + 0.5, py + 0.5);
        if (!truth.hit || frame.uv[p * 3 + 2] < 0.5f) continue;
        ++compared;
        beyond += frame.depth[p] - truth.distance > 1e-4;
      }
    }
  }
  EXPECT_GT(compared, frames * frame.width * frame.height / 4) << scene.name;
  EXPECT_EQ(beyond, 0) << scene.name << " / " << render::method_info(scene.method).name;
}

// An animated sequence whose bake budget is 0 (every frame over budget: static maps from the first
// stage only, moving ones lagged by up to 4 frames - the last map served with raised apexes, over
// enough frames that lagged maps are made and served): no ray of any cone method ends
// past its exact first crossing, on every frame, on the cliff's spikes and ledges, the bricks, the
// ripples, the ocean and animated checkers and terraces.
TEST(Pipeline, StarvedBakesStayConservativeOnEveryFrame) {
  for (const char* name : {"cliff", "bricks", "ripples", "calm"}) {
    const bool moving = std::string_view(name) == "ripples" || std::string_view(name) == "calm";
    for (const render::Method method : {render::Method::csm, render::Method::acm4, render::Method::acm8}) {
      Scene scene = small_scene(name, 32, 40);
      scene.method = method;
      scene.steps = 8;
      scene.frame_ms = 0.0;
      scene.cone_lag_frames = 4;
      expect_no_ray_past_the_first_crossing(scene, moving ? 9 : 3);
    }
  }
  // animated checkers and terraces (an image sequence whose frames shift the pattern)
  const pipeline::HeightLoader loader = [](const std::filesystem::path& file) {
    const int frame = std::stoi(file.stem().string().substr(2));
    if (file.string().find("checkers") != std::string::npos) {
      return displace::testing::field_of(
          32, 32, [&](int i, int j) { return ((i + frame) / 4 + j / 4) % 2 ? 0.9 : 0.1; });
    }
    return displace::testing::field_of(
        32, 32, [&](int i, int j) { return 0.1 + 0.2 * (((i + 2 * j + frame) / 5) % 5); });
  };
  for (const char* pattern : {"checkers/c_##.png", "terraces/t_##.png"}) {
    for (const render::Method method : {render::Method::csm, render::Method::acm4, render::Method::acm8}) {
      Scene scene = small_scene("bricks", 32, 40);
      scene.name = pattern;
      scene.source = pipeline::SourceKind::image;
      scene.image = pattern;
      scene.method = method;
      scene.steps = 8;
      scene.frame_ms = 0.0;
      scene.cone_lag_frames = 4;
      expect_no_ray_past_the_first_crossing(scene, 9, loader);
    }
  }
}

// An image sequence that changes in places (a terrain being edited: a bump added each frame, one
// frame repeated): each changed frame's cone map is updated where the heights changed, with a
// fraction of a whole bake's searches, the repeated frame bakes nothing, and no ray of a cone method
// ends past its exact first crossing on any frame.
TEST(Pipeline, ImageSequencesChangedInPlacesUpdateTheirCones) {
  auto heights_of = [](int frame) {
    return displace::testing::field_of(128, 128, [&](int i, int j) {
      double h = 0.3 + 0.1 * std::sin(0.2 * i) * std::cos(0.15 * j);
      for (int bump = 1; bump <= frame; ++bump) {
        if (bump == 3) continue;  // frame 3 repeats frame 2
        const double di = i - (24 + 18 * bump), dj = j - (40 + 10 * bump);
        h += 0.15 * std::max(0.0, 1.0 - (di * di + dj * dj) / 9.0);
      }
      return std::min(h, 1.0);
    });
  };
  const pipeline::HeightLoader loader = [&](const std::filesystem::path& file) {
    return heights_of(std::stoi(file.stem().string().substr(2)));
  };
  for (const render::Method method : {render::Method::csm, render::Method::acm4}) {
    Scene scene = small_scene("bricks", 128, 40);
    scene.source = pipeline::SourceKind::image;
    scene.image = "e_##.png";
    scene.method = method;
    scene.steps = 8;
    std::vector<pipeline::FrameRecord> records;
    expect_no_ray_past_the_first_crossing(scene, 6, loader, &records);
    const std::string name = render::method_info(method).name;
    ASSERT_EQ(records.size(), 6u);
    EXPECT_FALSE(records[0].cones_updated) << name;
    for (const int frame : {1, 2, 4, 5}) {
      EXPECT_TRUE(records[std::size_t(frame)].cones_updated) << name << " frame " << frame;
      EXPECT_LT(records[std::size_t(frame)].cones.texels_refined, records[0].cones.texels_refined / 2)
          << name << " frame " << frame;
    }
    EXPECT_FALSE(records[3].cones_updated) << name;  // frame 2's map, handed over again
    EXPECT_EQ(records[3].cones.work, records[2].cones.work) << name;
    EXPECT_EQ(records[3].cones.texels_refined, records[2].cones.texels_refined) << name;
  }
}

// Lagged cone maps (frame_pipeline.h): with the bake's share at 0 and a lag of N frames, every
// frame runs an even share of the first stage, so a map begun on frame b (frame 0's made whole)
// is made by frame b + N and served until the next one is: never more than 2N frames old, a new map
// at least every N + 1 frames. Each frame hands the renderer exactly the map of the frame its age
// says - the ratios a whole bake of that frame's heights gives, bit for bit - with every apex raised
// by the most any texel rose since (the record's lift), rounded up. A lag of 1 makes each map in two
// frames; a share that fits the whole stage serves each frame its own map, and so does a lag of 0.
TEST(Pipeline, LaggedConesServeTheLastMapRaisedWhileTheNextIsMade) {
  const int lag = 4;
  auto bake_alone = [](const render::HeightField& field, std::vector<float>& ratios,
                       std::vector<float>& apex) {
    bake::BilinearBaker baker(field.width, field.height, 4, bake::Address::wrap);
    ratios.resize(field.heights.size() * 4);
    apex.resize(field.heights.size());
    bake::Budget none;
    none.milliseconds = 0.0;
    baker.bake({field.heights.data(), field.width, field.height}, none,
               {ratios.data(), field.width, field.height, 4}, apex);
  };
  FakeClock clock;
  Scene scene = small_scene("calm", 128, 16);  // 128 rows: every step has work
  scene.method = render::Method::acm4;
  scene.frame_ms = 0.0;
  scene.cone_lag_frames = lag;
  FramePipeline pipeline(scene, shared_renderer(), std::ref(clock));
  std::vector<render::HeightField> heights;
  render::Frame frame;
  std::vector<float> ratios, apex;
  int served_maps = 0;
  long long served_from = 0, served_since = 0;
  for (int n = 0; n < 3 * (lag + 1) + 1; ++n) {
    const FrameRecord record = pipeline.run(n, frame, render::output_color);
    heights.push_back(pipeline.heights());
    ASSERT_GE(record.cone_lag, 0) << "frame " << n;
    ASSERT_LE(record.cone_lag, n == 0 ? 0 : std::min<long long>(n, 2 * lag)) << "frame " << n;
    const long long from = n - record.cone_lag;  // the frame whose map is served
    ASSERT_GE(from, served_from) << "frame " << n;
    if (from != served_from) {  // a new map: begun the frame after the last one was first served
      EXPECT_EQ(from, served_since + 1) << "frame " << n;
      EXPECT_LE(n - from, lag) << "frame " << n;
      ++served_maps;
      served_since = n;
    }
    served_from = from;
    float lift = 0.0f;
    for (std::size_t t = 0; t < heights[std::size_t(n)].heights.size(); ++t) {
      lift = std::max(lift, heights[std::size_t(n)].heights[t] - heights[std::size_t(from)].heights[t]);
    }
    EXPECT_EQ(record.cone_lift, lift) << "frame " << n;
    if (n > from) {
      EXPECT_GT(lift, 0.0f) << "frame " << n;  // the ocean rises somewhere
    }
    bake_alone(heights[std::size_t(from)], ratios, apex);
    const render::ConeMapView& cones = pipeline.maps().cones[std::size_t(render::cone_slot(4))];
    ASSERT_EQ(cones.ratios.size(), ratios.size());
    EXPECT_TRUE(std::equal(ratios.begin(), ratios.end(), cones.ratios.begin())) << "frame " << n;
    for (std::size_t t = 0; t < apex.size(); ++t) {
      const float raised = lift > 0.0f ? std::min(1.0f, std::nextafter(apex[t] + lift, 2.0f)) : apex[t];
      ASSERT_EQ(cones.apex[t], raised) << "frame " << n << " texel " << t;
      ASSERT_TRUE(cones.apex[t] == 1.0f ||
                  double(cones.apex[t]) >= double(apex[t]) + double(lift))  // 1: above all
          << "frame " << n << " texel " << t;
    }
  }
  EXPECT_GE(served_maps, 3);

  scene.cone_lag_frames = 1;  // maps begun on frames 1, 3, 5, ... and served from the frame after
  FramePipeline two_frames(scene, shared_renderer(), std::ref(clock));
  for (int n = 0; n < 7; ++n) {
    EXPECT_EQ(two_frames.run(n, frame, render::output_color).cone_lag, n < 2 ? n : 1 + n % 2)
        << "frame " << n;
  }
  for (const auto& [frame_ms, frames_of_lag] : {std::pair{1e9, 4}, std::pair{0.0, 0}}) {
    scene.frame_ms = frame_ms;  // the whole stage fits, or no lag: every frame its own map
    scene.cone_lag_frames = frames_of_lag;
    FramePipeline own(scene, shared_renderer(), std::ref(clock));
    for (int n = 0; n < 3; ++n) {
      const FrameRecord record = own.run(n, frame, render::output_color);
      EXPECT_EQ(record.cone_lag, 0);
      EXPECT_EQ(record.cone_lift, 0.0f);
      bake_alone(own.heights(), ratios, apex);
      const render::ConeMapView& cones = own.maps().cones[std::size_t(render::cone_slot(4))];
      EXPECT_TRUE(std::equal(apex.begin(), apex.end(), cones.apex.begin())) << "frame " << n;
    }
  }
}

// Frames depend on the scene and the frame index only (no wall-clock budget): two pipelines that
// render the ocean's frames in different orders agree bit for bit, and a static scene renders the
// same picture on every frame.
TEST(Pipeline, FramesAreReproducibleFromTheirIndex) {
  Scene scene = small_scene("water", 32, 24);
  scene.method = render::Method::acm4;
  scene.bake_work = 2000;
  FramePipeline forward(scene, shared_renderer()), backward(scene, shared_renderer());
  std::vector<render::Frame> ahead(4), behind(4);
  for (int n = 0; n < 4; ++n) forward.run(n, ahead[std::size_t(n)], render::output_all);
  for (int n = 3; n >= 0; --n) backward.run(n, behind[std::size_t(n)], render::output_all);
  for (int n = 0; n < 4; ++n) {
    EXPECT_EQ(ahead[std::size_t(n)].color, behind[std::size_t(n)].color) << n;
    EXPECT_EQ(ahead[std::size_t(n)].depth, behind[std::size_t(n)].depth) << n;
  }
  EXPECT_NE(ahead[0].color, ahead[1].color);  // the ocean moves

  Scene bricks = small_scene("bricks", 32, 24);
  bricks.method = render::Method::relief;
  FramePipeline still(bricks, shared_renderer());
  render::Frame first, later;
  still.run(0, first, render::output_all);
  still.run(7, later, render::output_all);
  EXPECT_EQ(first.color, later.color);
  EXPECT_EQ(first.uv, later.uv);
}

// A static scene in real time (a wall-clock budget): refinement carries on from frame to frame and
// the picture converges - with enough steps an exact-class method's pixels move by at most 1 (8-bit)
// while the fallback ratios are refined.
TEST(Pipeline, RefiningAStaticSceneMovesExactPixelsByAtMostOne) {
  FakeClock clock;
  clock.tick = 0.25;  // a refinement chunk costs a tick: a few chunks a frame
  Scene scene = small_scene("cliff", 64, 32);
  scene.method = render::Method::acm4;
  scene.steps = 256;
  scene.tolerance = 0.0f;
  scene.frame_ms = 4.0;
  FramePipeline pipeline(scene, shared_renderer(), std::ref(clock));
  render::Frame previous, frame;
  FrameRecord record = pipeline.run(0, previous, render::output_color);
  const long long pending_at_start = record.pending;
  ASSERT_GT(pending_at_start, 0);
  for (int n = 1; n < 6; ++n) {
    record = pipeline.run(n, frame, render::output_color);
    int worst = 0;
    for (std::size_t i = 0; i < frame.color.size(); ++i)
      worst = std::max(worst, std::abs(int(frame.color[i]) - int(previous.color[i])));
    EXPECT_LE(worst, 1) << "frame " << n;
    previous = frame;
  }
  EXPECT_LT(record.pending, pending_at_start);
  EXPECT_EQ(shared_renderer().validation_messages(), 0);
}

// Temporal stability on the animated ocean. Metric: the mean absolute temporal difference (MATD)
// of consecutive frames, over RGB of every pixel (8-bit units). The reference's MATD is the true
// motion of the water; a method whose stepping error changes from frame to frame (flicker, popping
// at silhouettes) adds to it. Each method's MATD may exceed the reference's by at most 10% plus
// 0.25 (8-bit): the mean of the per-frame image error's change is bounded by the image error itself,
// which the exact-class methods at these steps keep small; measured margins are in the output.
TEST(Pipeline, AnimatedOceanFlickersNoMoreThanTheReference) {
  auto matd = [](const render::Frame& a, const render::Frame& b) {
    double sum = 0.0;
    for (std::size_t i = 0; i < a.color.size(); ++i) {
      if (i % 4 == 3) continue;
      sum += std::abs(int(a.color[i]) - int(b.color[i]));
    }
    return sum / double(a.color.size() / 4 * 3);
  };
  auto sequence_matd = [&](render::Method method, int steps) {
    Scene scene = small_scene("calm", 64, 64);
    scene.unbounded = false;  // the patch, which the reference tessellates
    scene.method = method;
    scene.steps = steps;
    scene.fps = 10.0;  // frames far enough apart that the water visibly moves
    FramePipeline frames(scene, shared_renderer());
    render::Frame previous, frame;
    frames.run(0, previous);
    double total = 0.0;
    for (int n = 1; n < 6; ++n) {
      frames.run(n, frame);
      total += matd(previous, frame);
      std::swap(previous, frame);
    }
    return total / 5.0;
  };
  const double reference = sequence_matd(render::Method::reference, 1);
  EXPECT_GT(reference, 0.5);  // the water moves
  for (const auto& [method, steps] :
       {std::pair{render::Method::acm4, 8}, std::pair{render::Method::relief, 16},
        std::pair{render::Method::qdm, 16}, std::pair{render::Method::csm, 8},
        std::pair{render::Method::pom, 16}}) {
    const double value = sequence_matd(method, steps);
    std::printf("MATD %-8s %2d steps %.3f (reference %.3f, ratio %.3f)\n", render::method_info(method).name,
                steps, value, reference, value / reference);
    EXPECT_LE(value, 1.1 * reference + 0.25) << render::method_info(method).name;
  }
}

// Overlapped frames (the next frame's sim and bake while this one renders) are the frames run()
// makes, in order; a static scene in real time keeps refining across the two frame buffers.
TEST(Pipeline, OverlappedFramesMatchTheSequentialOnes) {
  Scene scene = small_scene("water", 32, 24);
  scene.method = render::Method::acm4;
  scene.bake_work = 1500;
  FramePipeline sequential(scene, shared_renderer()), overlapped(scene, shared_renderer());
  std::vector<render::Frame> expected(5);
  for (int n = 0; n < 5; ++n) sequential.run(10 + n, expected[std::size_t(n)], render::output_all);
  long long seen = 0;
  overlapped.run_frames(10, 5, render::output_all,
                        [&](const FrameRecord& record, const render::Frame& frame) {
                          EXPECT_EQ(record.index, 10 + seen);
                          EXPECT_EQ(frame.color, expected[std::size_t(seen)].color) << record.index;
                          EXPECT_EQ(frame.depth, expected[std::size_t(seen)].depth) << record.index;
                          ++seen;
                        });
  EXPECT_EQ(seen, 5);

  // lagged cone maps at budget 0 (each frame its even share of a map): the same maps frame by frame,
  // however the frames overlap (the map being made and the one served are never the same buffers)
  Scene lagged = small_scene("water", 64, 24);
  lagged.method = render::Method::acm4;
  lagged.frame_ms = 0.0;
  lagged.cone_lag_frames = 2;
  FramePipeline in_series(lagged, shared_renderer()), in_flight(lagged, shared_renderer());
  std::vector<render::Frame> series(8);
  std::vector<long long> ages;
  for (int n = 0; n < 8; ++n)
    ages.push_back(in_series.run(n, series[std::size_t(n)], render::output_all).cone_lag);
  seen = 0;
  in_flight.run_frames(0, 8, render::output_all, [&](const FrameRecord& record, const render::Frame& frame) {
    EXPECT_EQ(record.cone_lag, ages[std::size_t(seen)]) << record.index;
    EXPECT_EQ(frame.color, series[std::size_t(seen)].color) << record.index;
    EXPECT_EQ(frame.depth, series[std::size_t(seen)].depth) << record.index;
    ++seen;
  });
  EXPECT_EQ(seen, 8);
  EXPECT_GT(*std::max_element(ages.begin(), ages.end()), 1);

  FakeClock clock;
  clock.tick = 0.25;
  Scene cliff = small_scene("cliff", 64, 16);
  cliff.method = render::Method::acm4;
  cliff.tolerance = 0.0f;
  cliff.frame_ms = 4.0;
  FramePipeline real_time(cliff, shared_renderer(), std::ref(clock));
  std::vector<long long> pending;
  real_time.run_frames(0, 6, render::output_color, [&](const FrameRecord& record, const render::Frame&) {
    pending.push_back(record.pending);
  });
  ASSERT_EQ(pending.size(), 6u);
  for (std::size_t n = 1; n < pending.size(); ++n) EXPECT_LE(pending[n], pending[n - 1]) << n;
  EXPECT_LT(pending.back(), pending.front());
}

// An image scene reads frame n's file of a numbered sequence through the application's loader
// (here one that makes the heights from the name), its map size the image's; a single file is
// read once.
TEST(Pipeline, ImageSequencesReadTheFileOfEachFrame) {
  EXPECT_EQ(pipeline::image_for_frame("maps/h_####.exr", 7), std::filesystem::path("maps/h_0007.exr"));
  EXPECT_EQ(pipeline::image_for_frame("h_#_#.png", 12), std::filesystem::path("h_12_12.png"));
  EXPECT_FALSE(pipeline::is_image_sequence("maps/h.exr"));
  const Scene parsed =
      pipeline::parse_scene("[source]\nkind = \"image\"\npath = \"h_##.png\"\n", "dir/scene.toml");
  EXPECT_EQ(parsed.image, std::filesystem::path("dir/h_##.png"));
  EXPECT_NE(error_of("[source]\nkind = \"image\"\n").find("source.path"), std::string::npos);
  EXPECT_NE(error_of("[source]\npath = \"a.png\"\n").find("source.path"), std::string::npos);

  std::vector<std::string> read;
  pipeline::HeightLoader loader = [&](const std::filesystem::path& file) {
    read.push_back(file.string());
    const int frame = std::stoi(file.stem().string().substr(2));
    return displace::testing::field_of(
        24, 16, [&](int i, int j) { return 0.5 + 0.4 * std::sin(0.3 * (i + j + frame)); });
  };
  Scene scene = small_scene("bricks", 32, 16);
  scene.source = pipeline::SourceKind::image;
  scene.image = "h_##.png";
  scene.method = render::Method::acm4;
  FramePipeline frames(scene, shared_renderer(), {}, loader);
  render::Frame frame;
  for (int n : {3, 4}) frames.run(n, frame);
  EXPECT_EQ(read, (std::vector<std::string>{"h_03.png", "h_04.png"}));
  EXPECT_EQ(frames.heights().width, 24);
  EXPECT_EQ(frames.heights().height, 16);
  scene.image = "h_05.png";
  FramePipeline still(scene, shared_renderer(), {}, loader);
  for (int n : {0, 1, 2}) still.run(n, frame);
  EXPECT_EQ(read.size(), 3u);                                         // one more read for all three frames
  EXPECT_THROW(FramePipeline(scene, shared_renderer()), SceneError);  // no loader
}

}  // namespace
