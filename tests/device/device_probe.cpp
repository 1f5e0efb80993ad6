// tests/device/device_probe.cpp - what the renderer costs and how close it comes, on whatever device
// render::Renderer picks (a GPU when there is one), without the application layer: it links only
// pipeline/, render/, bake/ and sim/, so that it runs on a machine that has a Vulkan driver but not
// this project's packages (tests/device/pack.sh carries it there with displace_device_tests).
//
//   displace_device_probe [OUTPUT_DIR]
//
// 1. Every method at 8, 16, 32 and 64 steps on the built-in water (512 map), bricks and cliff scenes
//    at 1920 x 1080: the median GPU milliseconds of 9 draws (timestamps), rmse and the share of
//    pixels off by more than 10 against the reference, and mean fetches per pixel. The reference of
//    each scene and acm4 at 32 steps on water are written to OUTPUT_DIR as binary PPM.
// 2. The frame loop of `displace bench-frame`: water, acm4 at 32 steps, bake budget 0 ms, map and
//    image sizes 256, 512 and 1024, 150 frames after 10 of warm-up, in series and overlapped, each
//    with every frame's own cone map and with maps lagged by up to 3 frames (`--cone-lag 3`): p50 of
//    each stage and the frame's p50 and p95 in milliseconds, the maps' p50 age in frames, and Vulkan
//    allocations after warm-up. Each with the sim and bake on the CPU, the sim on the device, and both
//    on the device (lagged by 0, 1, 3 and 7 frames: bake::DeviceCones::bake_lagged; 1 also with the
//    maps made ahead, Scene::cone_ahead), with
//    the device's own milliseconds per stage (GPU timestamps) where the stage ran there; 2048 too, with
//    fewer frames.
// 3. Stage L of the renderer's cone maps (bake::BilinearBaker, budget 0) on the CPU with 1, 2, 4, 8 and
//    16 threads (TBB arenas, up to the CPUs this process may use) on the water ocean's 256, 512 and 1024
//    heights: the median of 5 bakes, to tell whether the bake scales past two cores on that machine,
//    next to the bound that a recorded bake's work and span give (bake/work_span.h).
// 4. The device's cone maps alone (bake::DeviceCones of a device ocean, 512, 1024 and 2048),
//    unlimited and budget 0 (each first pass shape): median wall and device milliseconds, texels
//    refined, mean ratio.
// DISPLACE_PROBE_QUICK=1 makes it small (one scene at 64 x 36 pixels, a 64 map, 5 frames): the
// test suite runs it that way so that it keeps working. DISPLACE_PROBE_PART=frames runs part 2 only,
// =threads part 3 only, =cones part 4 only; DISPLACE_PROBE_DEVICE_BAKE=1 keeps part 2's frame loops
// with the bake on the device alone; DISPLACE_PROBE_DEVICE_RINGS=R gives the device bake's first
// pass rings of radius R there (bake::DeviceFirstPass; 0: the search; default 2), and
// DISPLACE_PROBE_DEVICE_GROUP=1 the group's first pass; DISPLACE_PROBE_CONE_MAPS=256,512 sets part 4's
// map sides, DISPLACE_PROBE_FRAME_MAPS part 2's; DISPLACE_PROBE_ASYNC=0 keeps lagged maps' bands on
// the frame's queue (RendererOptions::async_compute) where the device has a compute queue apart.
// Part 2 with the bake on the device also runs the frames in flight: nothing read back, the mean
// period.
#include <sched.h>
#include <tbb/info.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "bake/work_span.h"
#include "pipeline/frame_pipeline.h"
#include "pipeline/height_source.h"
#include "pipeline/maps.h"
#include "pipeline/scene.h"

namespace {

using namespace displace;

double percentile(std::vector<double> values, double p) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  return values[std::min(values.size() - 1, std::size_t(p * double(values.size())))];
}

void write_ppm(const render::Frame& frame, const std::string& path) {
  std::ofstream out(path, std::ios::binary);
  out << "P6\n" << frame.width << " " << frame.height << "\n255\n";
  for (std::size_t p = 0; p < std::size_t(frame.width) * frame.height; ++p) {
    out.write(reinterpret_cast<const char*>(&frame.color[4 * p]), 3);
  }
}

double mean_positive(const std::vector<float>& values) {
  double sum = 0.0;
  long long count = 0;
  for (float v : values) {
    if (v > 0.0f) {
      sum += v;
      ++count;
    }
  }
  return count ? sum / double(count) : 0.0;
}

struct Plan {
  std::vector<const char*> scenes{"water", "bricks", "cliff"};
  int width = 1920, height = 1080, water_map = 512, repeats = 9;
  std::vector<int> steps{8, 16, 32, 64};
  std::vector<int> frame_sizes{256, 512, 1024, 2048};
  std::vector<int> cone_lags{0, 3};
  int warm_up = 10, frames = 150, large_frames = 40;  // large: maps of 2048 and more
  std::vector<int> thread_maps{256, 512, 1024};
  int thread_repeats = 5;
  std::vector<int> cone_maps{512, 1024, 2048};
  int cone_repeats = 5;
};

Plan quick_plan() {
  Plan plan;
  plan.scenes = {"water"};
  plan.width = 64;
  plan.height = 36;
  plan.water_map = 64;
  plan.repeats = 1;
  plan.steps = {8};
  plan.frame_sizes = {64};
  plan.cone_maps = {64};
  plan.cone_repeats = 1;
  plan.warm_up = 2;
  plan.frames = 5;
  plan.thread_maps = {64};
  plan.thread_repeats = 1;
  return plan;
}

void method_table(render::Renderer& renderer, const Plan& plan, const std::string& directory) {
  for (const char* name : plan.scenes) {
    pipeline::Scene scene = pipeline::builtin_scene(name);
    scene.unbounded = false;  // the patch, which the reference tessellates
    if (std::string(name) == "water") scene.map_size = plan.water_map;
    scene.camera.width = plan.width;
    scene.camera.height = plan.height;
    pipeline::FramePipeline frames(scene, renderer);
    pipeline::FrameRecord record;
    frames.simulate(0.0, record);
    pipeline::MapMaker maps(renderer.device().max_image_dimension_3d);
    maps.set_heights(frames.heights());
    const render::View view = pipeline::scene_view(scene, 0.0);
    const render::Frame reference =
        pipeline::render_with_maps(renderer, maps, view, {render::Method::reference, 1, 0});
    write_ppm(reference, directory + "/" + name + "_reference.ppm");
    std::printf("scene %s, map %d x %d, %d x %d pixels; reference %.3f ms\n", name, frames.heights().width,
                frames.heights().height, plan.width, plan.height, reference.gpu_milliseconds);
    std::printf("%-16s %5s %9s %9s %8s %8s\n", "method", "steps", "median_ms", "rmse", "over10%", "fetches");
    render::Frame frame;
    for (const render::MethodInfo& info : render::method_table()) {
      if (info.method == render::Method::reference || !render::supports_surface(info.method, view.surface))
        continue;
      for (int steps : plan.steps) {
        const render::MethodSettings settings{info.method, steps, 8};
        frame = pipeline::render_with_maps(renderer, maps, view, settings);
        const render::ImageError error = render::compare(frame, reference);
        const double fetches = mean_positive(frame.fetches);
        std::vector<double> times;
        for (int r = 0; r < plan.repeats; ++r) {
          renderer.render(view, settings, frame, render::output_color);
          times.push_back(frame.gpu_milliseconds);
        }
        std::printf("%-16s %5d %9.4f %9.3f %8.3f %8.2f\n", info.name, steps, percentile(times, 0.5),
                    error.rmse, 100.0 * error.fraction_over_10, fetches);
        if (std::string(name) == "water" && info.method == render::Method::acm4 && steps == 32) {
          write_ppm(frame, directory + "/water_acm4.ppm");
        }
        if (info.family == render::MethodFamily::surface) break;  // no steps to give
      }
    }
    std::fflush(stdout);
  }
}

void frame_loop(render::Renderer& renderer, const Plan& plan) {
  for (int size : plan.frame_sizes) {
    // sim and bake on the CPU; the sim on the device; both on the device (its cone maps are each
    // frame's own: no lag)
    using pipeline::Backend;
    const std::pair<Backend, Backend> backends[] = {
        {Backend::cpu, Backend::cpu}, {Backend::device, Backend::cpu}, {Backend::device, Backend::device}};
    const char* only_device_bake =
        std::getenv("DISPLACE_PROBE_DEVICE_BAKE");                   // 1: those configurations alone
    const char* rings = std::getenv("DISPLACE_PROBE_DEVICE_RINGS");  // the device bake's first pass
    const char* group = std::getenv("DISPLACE_PROBE_DEVICE_GROUP");  // 1: the group's first pass
    const bool group_first_pass = group && std::string(group) == "1";
    const int ring_radius =
        rings && *rings ? std::atoi(rings) : (group_first_pass ? 0 : bake::default_first_pass_rings);
    for (const auto& [sim_backend, bake_backend] : backends) {
      if (only_device_bake && std::string(only_device_bake) == "1" && bake_backend != Backend::device)
        continue;
      std::vector<int> lags = plan.cone_lags;
      if (bake_backend == Backend::device && plan.frames > 20)
        lags = {0, 1, 3, 7};                       // 1: a whole map a frame late
      std::vector<std::pair<int, bool>> lag_rows;  // (lag, maps made ahead)
      for (int lag : lags) {
        lag_rows.emplace_back(lag, false);
        if (lag == 1 && sim_backend == Backend::device && bake_backend == Backend::device)
          lag_rows.emplace_back(1, true);  // Scene::cone_ahead
      }
      for (const auto& [lag, ahead] : lag_rows) {
        // in series, overlapped and, with the bake on the device, in flight: nothing read back (as a
        // window shows its frames), two frames in flight, the mean period over the frames
        const int modes = bake_backend == Backend::device ? 3 : 2;
        for (int mode = 0; mode < modes; ++mode) {
          const bool overlapped = mode == 1;
          const int frame_count = size >= 2048 ? plan.large_frames : plan.frames;
          pipeline::Scene scene = pipeline::builtin_scene("water");
          scene.sim_backend = sim_backend;
          scene.bake_backend = bake_backend;
          scene.map_size = size;
          scene.camera.width = scene.camera.height = size;
          scene.method = render::Method::acm4;
          scene.steps = 32;
          scene.frame_ms = 0.0;
          scene.cone_lag_frames = lag;
          scene.cone_ahead = ahead;
          scene.device_first_pass.ring_radius = ring_radius;
          scene.device_first_pass.group = group_first_pass;
          pipeline::FramePipeline frames(scene, renderer);
          render::Frame frame;
          for (int n = 0; n < plan.warm_up; ++n) frames.run(n, frame);
          const long long allocations = renderer.memory_allocations();
          if (mode == 2) {
            std::vector<double> sim_device, bake_device;
            const auto start = std::chrono::steady_clock::now();
            for (int n = 0; n < frame_count; ++n) {
              const pipeline::FrameRecord r = frames.run(plan.warm_up + n, frame, render::output_none);
              sim_device.push_back(r.sim_device_ms);  // an earlier frame's: the last one finished
              bake_device.push_back(r.bake_device_ms);
            }
            renderer.wait_idle();
            const double period =
                std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count() /
                frame_count;
            std::printf(
                "frame in flight: water, map %d, %d x %d pixels, cone lag %d%s, sim on the %s, bake on the "
                "%s "
                "(first pass: rings %d%s), bands on %s: mean period %.3f ms over %d frames (nothing read "
                "back), device p50 sim %.3f bake %.3f ms, %lld allocations after warm-up\n",
                size, size, size, lag, ahead ? " ahead" : "", pipeline::backend_word(scene.sim_backend),
                pipeline::backend_word(scene.bake_backend), ring_radius, group_first_pass ? ", group" : "",
                renderer.device().compute_queue_apart ? "a compute queue apart" : "the frame's queue", period,
                frame_count, percentile(sim_device, 0.5), percentile(bake_device, 0.5),
                renderer.memory_allocations() - allocations);
            std::fflush(stdout);
            continue;
          }
          std::vector<double> sim, bake, upload, draw, total, age, lift, sim_device, bake_device, draw_device;
          std::vector<double> levels_device;
          auto keep = [&](const pipeline::FrameRecord& r, const render::Frame&) {
            levels_device.push_back(r.levels_device_ms);
            age.push_back(double(r.cone_lag));
            lift.push_back(double(r.cone_lift));
            sim_device.push_back(r.sim_device_ms);
            bake_device.push_back(r.bake_device_ms);
            draw_device.push_back(r.render_device_ms);
            sim.push_back(r.sim_ms);
            bake.push_back(r.bake_ms);
            upload.push_back(r.upload_ms);
            draw.push_back(r.render_ms);
            total.push_back(r.frame_ms);
          };
          if (overlapped) {
            frames.run_frames(plan.warm_up, frame_count, render::output_color, keep);
          } else {
            for (int n = 0; n < frame_count; ++n) keep(frames.run(plan.warm_up + n, frame), frame);
          }
          std::printf(
              "frame: water, map %d, %d x %d pixels, %s, cone lag %d%s, sim on the %s, bake on the %s (first "
              "pass: rings %d%s): p50 sim %.3f "
              "bake %.3f upload %.3f render %.3f frame %.3f ms, frame p95 %.3f ms, device p50 sim %.3f bake "
              "%.3f (of it the levels of detail %.3f) "
              "render %.3f ms, maps %.0f frames old (p50) raised by %.4f (p50), %lld allocations after "
              "warm-up\n",
              size, size, size, overlapped ? "overlapped" : "in series", lag, ahead ? " ahead" : "",
              pipeline::backend_word(scene.sim_backend), pipeline::backend_word(scene.bake_backend),
              ring_radius, group_first_pass ? ", group" : "", percentile(sim, 0.5), percentile(bake, 0.5),
              percentile(upload, 0.5), percentile(draw, 0.5), percentile(total, 0.5), percentile(total, 0.95),
              percentile(sim_device, 0.5), percentile(bake_device, 0.5), percentile(levels_device, 0.5),
              percentile(draw_device, 0.5), percentile(age, 0.5), percentile(lift, 0.5),
              renderer.memory_allocations() - allocations);
          std::fflush(stdout);
        }
      }
    }
  }
}

// Stage L on 1, 2, 4, ... threads: does the CPU bake scale on this machine?
void stage_l_threads(render::Renderer& renderer, const Plan& plan) {
  cpu_set_t allowed;
  const int affinity = sched_getaffinity(0, sizeof allowed, &allowed) == 0 ? CPU_COUNT(&allowed) : -1;
  std::printf("threads: TBB's default concurrency %d, CPUs this process may use %d\n",
              tbb::info::default_concurrency(), affinity);
  for (int size : plan.thread_maps) {
    pipeline::Scene scene = pipeline::builtin_scene("water");
    scene.map_size = size;
    scene.sim_backend = pipeline::Backend::cpu;
    pipeline::FramePipeline frames(scene, renderer);
    pipeline::FrameRecord record;
    frames.simulate(0.0, record);
    const render::HeightField& field = frames.heights();
    const bake::HeightView heights{field.heights.data(), field.width, field.height};
    std::vector<float> ratios(std::size_t(size) * size * 4), apex(std::size_t(size) * size);
    const bake::ConeView cones{ratios.data(), size, size, 4};
    bake::Budget budget;
    budget.milliseconds = 0.0;
    double one_thread = 0.0;
    for (int threads = 1; threads <= std::max(1, tbb::info::default_concurrency()) && threads <= 16;
         threads *= 2) {
      tbb::task_arena arena(threads);
      std::vector<double> times;
      arena.execute([&] {
        bake::BilinearBaker baker(size, size, 4, bake::Address::wrap);
        baker.bake(heights, budget, cones, apex);  // warm
        for (int r = 0; r < plan.thread_repeats; ++r) {
          const auto start = std::chrono::steady_clock::now();
          baker.bake(heights, budget, cones, apex);
          times.push_back(
              std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
        }
      });
      // and the bound that its work and span give for this many threads (bake/work_span.h)
      bake::detail::WorkSpan work_span;
      arena.execute([&] {
        bake::BilinearBaker baker(size, size, 4, bake::Address::wrap);
        baker.bake(heights, budget, cones, apex);
        const bake::detail::WorkSpanRecording recording(work_span);
        baker.bake(heights, budget, cones, apex);
      });
      const double median = percentile(times, 0.5);
      if (threads == 1) one_thread = median;
      std::printf(
          "stage L: water %d x %d, 4 sectors, %2d threads: median %.3f ms (%.2fx one thread's); work %.3f "
          "ms, "
          "at least %.3f ms on %d threads\n",
          size, size, threads, median, one_thread / median, 1e3 * bake::detail::work_span_total(work_span),
          1e3 * bake::detail::work_span_bound(work_span, threads), threads);
      if (threads == 16 || threads == std::max(1, tbb::info::default_concurrency())) {
        std::printf("  serial %.3f ms", 1e3 * work_span.serial);
        for (const bake::detail::WorkSpanRegion& region : work_span.regions)
          std::printf("; %s work %.3f span %.3f ms (%lld tasks)", region.name.c_str(), 1e3 * region.work,
                      1e3 * region.span, region.tasks);
        std::printf("\n");
      }
      std::fflush(stdout);
    }
  }
}

// The device's cone maps alone (bake::DeviceCones, 4 sectors, wrap) of a device ocean's heights,
// unlimited and budget 0 (the first pass, in each of its shapes: the search, and rings of radius 1, 2
// and 3 with the full window, 2 with a window of 2 cells, 1 with windows of 2 and 1, 2 with a window
// of 1, the group's with windows of 4 and 2): each
// bake submitted and waited for (wall) and its GPU timestamps (device), medians; the texels refined
// and the mean ratio read back.
void device_cones(render::Renderer& renderer, const Plan& plan) {
  struct Shape {
    long long texels;
    bake::DeviceFirstPass first_pass;
  };
  const Shape shapes[] = {{bake::unlimited_texels, {}},
                          {0, {4, 0}},
                          {0, {4, 1}},
                          {0, {4, 2}},
                          {0, {4, 3}},
                          {0, {2, 2}},
                          {0, {2, 1}},
                          {0, {1, 1}},
                          {0, {1, 2}},
                          {0, {4, 0, true}},
                          {0, {2, 0, true}}};
  for (int size : plan.cone_maps) {
    pipeline::SourceSettings settings;
    settings.kind = pipeline::SourceKind::ocean;
    settings.map_size = size;
    const std::unique_ptr<sim::DeviceSim> ocean =
        pipeline::make_device_sim(renderer, settings, pipeline::effect_heights);
    ocean->simulate(3.0);
    bake::DeviceCones cones(renderer.frames(), ocean->maps(), 4, bake::Address::wrap);
    for (const Shape& shape : shapes) {
      const long long texels = shape.texels;
      std::vector<double> wall, device;
      bake::BakeStats stats;
      for (int r = 0; r <= plan.cone_repeats; ++r) {  // the first one warms up
        const auto start = std::chrono::steady_clock::now();
        cones.bake(bake::work_budget(texels), shape.first_pass);
        stats = cones.read_back(nullptr, nullptr);
        if (r == 0) continue;
        wall.push_back(
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
        device.push_back(cones.device_milliseconds());
      }
      std::vector<float> ratios;
      cones.read_back(&ratios, nullptr);
      double sum = 0.0;
      for (float ratio : ratios) sum += double(ratio);
      const bake::DeviceFirstPass& pass = shape.first_pass;
      const std::string form = pass.ring_radius > 0 ? "rings " + std::to_string(pass.ring_radius)
                                                    : (pass.group ? "group" : "search");
      char first_pass[96];
      std::snprintf(first_pass, sizeof first_pass, "first pass (budget 0), window %d, %s", pass.window_radius,
                    form.c_str());
      std::printf(
          "device cones: water %d x %d, 4 sectors, %s: median %.3f ms wall, %.3f ms device; %lld texels "
          "refined, mean ratio %.4f\n",
          size, size, texels == 0 ? first_pass : "unlimited", percentile(wall, 0.5), percentile(device, 0.5),
          stats.texels_refined, ratios.empty() ? 0.0 : sum / double(ratios.size()));
      std::fflush(stdout);
    }
  }
}

// The map sides that the variable NAME lists ("256,512"), when it is set, in place of SIDES.
void map_sides(const char* name, std::vector<int>& sides) {
  const char* list = std::getenv(name);
  if (!list || !*list) return;
  sides.clear();
  for (const char* at = list; *at;) {
    char* end = nullptr;
    const long side = std::strtol(at, &end, 10);
    if (end == at || side < 1 || side > render::max_map_side)
      throw std::runtime_error(std::string(name) + ": not a list of map sides: " + list);
    sides.push_back(int(side));
    at = *end == ',' ? end + 1 : end;
  }
}

}  // namespace

int main(int argc, char** argv) {
  try {
    const std::string directory = argc > 1 ? argv[1] : ".";
    const char* quick = std::getenv("DISPLACE_PROBE_QUICK");
    Plan plan = quick && *quick && std::string(quick) != "0" ? quick_plan() : Plan{};
    map_sides("DISPLACE_PROBE_CONE_MAPS", plan.cone_maps);
    map_sides("DISPLACE_PROBE_FRAME_MAPS", plan.frame_sizes);
    render::RendererOptions options;
    options.pipeline_cache = "off";
    const char* async = std::getenv("DISPLACE_PROBE_ASYNC");  // 0: lagged bands on the frame's queue
    options.async_compute = !(async && std::string(async) == "0");
    render::Renderer renderer(options);
    std::printf("device: %s (%s), %d sub-texel bits, lagged bands on %s\n", renderer.device().name.c_str(),
                renderer.device().type.c_str(), renderer.device().sub_texel_precision_bits,
                renderer.device().compute_queue_apart ? "a compute queue apart" : "the frame's queue");
    const char* part = std::getenv("DISPLACE_PROBE_PART");
    const std::string only = part ? part : "";
    if (only.empty()) method_table(renderer, plan, directory);
    if (only.empty() || only == "frames") frame_loop(renderer, plan);
    if (only.empty() || only == "threads") stage_l_threads(renderer, plan);
    if (only.empty() || only == "cones") device_cones(renderer, plan);
    return 0;
  } catch (const std::exception& error) {
    std::fprintf(stderr, "displace_device_probe: error: %s\n", error.what());
    return 1;
  }
}
