// demos/commands/bench_frame.cpp - `displace bench-frame`: the frame pipeline's loop for F frames after
// a warm-up, timed stage by stage (p50, p95, p99), with the frames within budget, FFTs per frame, the
// effects, Vulkan allocations and resident memory (the soak reads its JSON).
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "demos/cli/command.h"
#include "demos/cli/flags.h"
#include "demos/cli/scene_flags.h"
#include "demos/commands/settings.h"
#include "demos/error.h"
#include "demos/frame_output.h"
#include "demos/heights.h"
#include "demos/image_io.h"
#include "demos/memory.h"
#include "demos/progress.h"
#include "pipeline/frame_pipeline.h"
#include "pipeline/thread_pinning.h"

namespace displace::app {
namespace {

// The resident memory of this process (VmRSS of /proc/self/status), kilobytes; -1 where there is none.
long long resident_kilobytes() {
  std::FILE* status = std::fopen("/proc/self/status", "r");
  if (!status) return -1;
  char line[256];
  long long kilobytes = -1;
  while (std::fgets(line, sizeof line, status)) {
    if (std::sscanf(line, "VmRSS: %lld kB", &kilobytes) == 1) break;
  }
  std::fclose(status);
  return kilobytes;
}

double percentile(std::vector<double> values, double fraction) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  const std::size_t rank =
      std::min(values.size() - 1, std::size_t(std::ceil(fraction * double(values.size())) - 1));
  return values[rank];
}

}  // namespace

namespace {

// What bench-frame measures over the timed frames (those after the warm-up).
struct BenchSamples {
  std::vector<double> sim, bake, upload, draw, frame_ms, interval, lag, lift;
  // the device's own times (GPU timestamps; 0 where none) of the stages that ran there
  std::vector<double> sim_device, bake_device, draw_device;
  bool sim_on_device = false, bake_on_device = false;
  long long ffts = 0, within = 0;
  unsigned effects = 0;
  bool cones = false;  // a cone map was baked (the records' cone stats)
  long long allocations_after_warm_up = 0;
  // resident memory: after the warm-up, the most seen after it, at the end (a soak's growth)
  long long rss_after_warm_up = -1, rss_max = -1, rss_end = -1;
  long long allocations = 0;  // Vulkan allocations after the warm-up
  int pinned_threads = 0, pinned_cpus = 0;
};

// Runs the warm-up and the timed frames, collecting every frame's record as it comes back.
BenchSamples run_bench_frames(const BenchFrameSettings& settings, render::Renderer& renderer,
                              pipeline::FramePipeline& pipeline) {
  const pipeline::Scene& scene = settings.scene;
  BenchSamples samples;
  for (std::vector<double>* times : {&samples.sim, &samples.bake, &samples.upload, &samples.draw,
                                     &samples.frame_ms, &samples.interval, &samples.lag, &samples.lift}) {
    times->reserve(std::size_t(settings.frames));  // made before the loop: not counted as growth
  }
  double last_done = 0.0;
  long long seen = 0;
  auto take = [&](const pipeline::FrameRecord& record) {
    const double now = steady_seconds() * 1e3;
    if (seen == settings.warm_up) {
      samples.allocations_after_warm_up = renderer.memory_allocations();
      samples.rss_after_warm_up = resident_kilobytes();
    }
    if (seen >= settings.warm_up) {
      samples.rss_max = std::max(samples.rss_max, resident_kilobytes());
      samples.sim.push_back(record.sim_ms);
      samples.sim_device.push_back(record.sim_device_ms);
      samples.bake_device.push_back(record.bake_device_ms);
      samples.draw_device.push_back(record.render_device_ms);
      samples.sim_on_device |= record.sim_on_device;
      samples.bake_on_device |= record.bake_on_device;
      samples.bake.push_back(record.bake_ms);
      samples.upload.push_back(record.upload_ms);
      samples.draw.push_back(record.render_ms);
      samples.frame_ms.push_back(record.frame_ms);
      samples.cones |= record.cones.sector_count > 0;
      samples.lag.push_back(double(record.cone_lag));
      samples.lift.push_back(double(record.cone_lift));
      if (seen > settings.warm_up) samples.interval.push_back(now - last_done);
      samples.ffts += record.ffts;
      samples.effects |= record.effects;
      samples.within += std::isfinite(scene.frame_ms) ? (now - last_done <= scene.frame_ms) : 1;
    }
    last_done = now;
    ++seen;
  };
  // colour read back: a frame's render stage then ends when the device has drawn it (with no
  // readback the submission returns at once and the wait shows up in the next upload instead)
  const long long total = settings.warm_up + settings.frames;
  // after the renderer: its rasterizer threads exist now
  std::optional<pipeline::ThreadPinning> pinning;
  if (settings.pin_threads) pinning.emplace();
  if (settings.serial) {
    render::Frame frame;
    for (long long index = 0; index < total; ++index) take(pipeline.run(index, frame, render::output_color));
  } else {
    pipeline.run_frames(0, total, render::output_color,
                        [&](const pipeline::FrameRecord& record, const render::Frame&) { take(record); });
  }
  renderer.wait_idle();
  samples.pinned_threads = pinning ? pinning->pinned_threads() : 0;
  samples.pinned_cpus = pinning ? pinning->cpu_count() : 0;
  pinning.reset();
  samples.allocations = renderer.memory_allocations() - samples.allocations_after_warm_up;
  samples.rss_end = resident_kilobytes();
  samples.rss_max = std::max(samples.rss_max, samples.rss_end);
  if (samples.interval.empty()) samples.interval = samples.frame_ms;
  return samples;
}

double largest(const std::vector<double>& values) {
  return values.empty() ? 0.0 : *std::max_element(values.begin(), values.end());
}

// The human table; returns the stages' percentiles as JSON for --json.
nlohmann::ordered_json print_bench_table(const BenchFrameSettings& settings, const BenchSamples& samples,
                                         const std::string& device, std::ostream& out) {
  const pipeline::Scene& scene = settings.scene;
  struct Row {
    const char* name;
    const std::vector<double>* values;
    const std::vector<double>* device;  // the device's own times, where the stage has them
  };
  const Row rows[] = {
      {"sim", &samples.sim, &samples.sim_device}, {"bake", &samples.bake, &samples.bake_device},
      {"upload", &samples.upload, nullptr},       {"render", &samples.draw, &samples.draw_device},
      {"frame", &samples.interval, nullptr},      {"latency", &samples.frame_ms, nullptr}};
  out << fmt::format(
      "displace bench-frame: {} ({} {}x{} map, {}x{} pixels, {} {} steps), {} frames after {} warm-up, "
      "budget {}, {}, sim on the {}, bake on the {}, on {}\n",
      scene.name, scene.source == pipeline::SourceKind::image ? "image" : "a", scene.map_size, scene.map_size,
      scene.camera.width, scene.camera.height, render::method_info(scene.method).name, scene.steps,
      settings.frames, settings.warm_up,
      std::isfinite(scene.frame_ms) ? fmt::format("{:g} ms", scene.frame_ms) : std::string("unlimited"),
      settings.serial ? "stages in series" : "stages overlapped", samples.sim_on_device ? "device" : "CPU",
      samples.bake_on_device ? "device" : "CPU", device);
  if (settings.pin_threads) {
    out << (samples.pinned_cpus > 0
                ? fmt::format("  {} threads pinned one per CPU over {} CPUs\n", samples.pinned_threads,
                              samples.pinned_cpus)
                : std::string("  --pin-threads: nothing pinned (fewer than two CPUs, or no affinity "
                              "here)\n"));
  }
  out << "  stage     p50 ms   p95 ms   p99 ms   device p50 ms\n";
  nlohmann::ordered_json stages = nlohmann::ordered_json::object();
  for (const Row& row : rows) {
    const double p50 = percentile(*row.values, 0.50), p95 = percentile(*row.values, 0.95),
                 p99 = percentile(*row.values, 0.99);
    const double device_p50 = row.device ? percentile(*row.device, 0.50) : 0.0;
    out << fmt::format("  {:<8} {:8.2f} {:8.2f} {:8.2f}   {}\n", row.name, p50, p95, p99,
                       device_p50 > 0.0 ? fmt::format("{:8.3f}", device_p50) : std::string("       -"));
    stages[row.name] = {{"p50_ms", p50}, {"p95_ms", p95}, {"p99_ms", p99}};
    if (row.device)
      stages[row.name]["device_p50_ms"] = device_p50 > 0.0 ? nlohmann::ordered_json(device_p50) : nullptr;
  }
  out << "  device = the device's own time (GPU timestamps) of the stages that ran there\n";
  if (settings.serial) {
    out << fmt::format(
        "  frame = the time between finished frames (the stages one after another, each with the\n"
        "  whole machine); latency = from a frame's sim to its render's end\n");
  } else {
    out << fmt::format(
        "  frame = the time between finished frames (stages overlap: the next frame's sim and bake run\n"
        "  while this one renders); latency = from a frame's sim to its render's end\n");
  }
  out << fmt::format(
      "  within budget: {:.1f}% of frames; FFTs per frame: {:.2f}; effects: {}; Vulkan allocations "
      "after warm-up: {}\n",
      100.0 * double(samples.within) / double(settings.frames),
      double(samples.ffts) / double(settings.frames), fmt::join(effect_names(samples.effects), ", "),
      samples.allocations);
  if (samples.cones) {
    out << fmt::format(
        "  cone maps: made from the heights of {:g} frames before (p50; at most {:g}), apexes raised by "
        "{:.4f} (p50; at most {:.4f}) of the height range\n",
        percentile(samples.lag, 0.50), largest(samples.lag), percentile(samples.lift, 0.50),
        largest(samples.lift));
  }
  if (samples.rss_end >= 0) {
    out << fmt::format(
        "  {} of {} frames rendered; resident memory {} kB after warm-up, {} kB at the end ({:+} kB), "
        "at most {} kB\n",
        samples.frame_ms.size(), settings.frames, samples.rss_after_warm_up, samples.rss_end,
        samples.rss_end - samples.rss_after_warm_up, samples.rss_max);
  }
  return stages;
}

// The --json document: the table's figures under snake_case keys.
nlohmann::ordered_json bench_json(const BenchFrameSettings& settings, const BenchSamples& samples,
                                  nlohmann::ordered_json stages, const std::string& device) {
  const pipeline::Scene& scene = settings.scene;
  using json = nlohmann::ordered_json;
  const auto p50_and_max = [&](const std::vector<double>& values) {
    return samples.cones ? json{{"p50", percentile(values, 0.50)}, {"max", largest(values)}} : json(nullptr);
  };
  return {{"frames", settings.frames},
          {"backend",
           {{"sim", samples.sim_on_device ? "device" : "cpu"},
            {"bake", samples.bake_on_device ? "device" : "cpu"}}},
          {"budget_ms", std::isfinite(scene.frame_ms) ? json(scene.frame_ms) : json(nullptr)},
          {"stages", std::move(stages)},
          {"within_budget", double(samples.within) / double(settings.frames)},
          {"ffts_per_frame", double(samples.ffts) / double(settings.frames)},
          {"effects", effect_names(samples.effects)},
          {"vulkan_allocations_after_warmup", samples.allocations},
          {"frames_rendered", (long long)samples.frame_ms.size()},
          {"cone_lag_frames", p50_and_max(samples.lag)},
          {"cone_lift", p50_and_max(samples.lift)},
          {"overlapped", !settings.serial},
          {"pinned_threads", samples.pinned_threads},
          {"rss_kb", samples.rss_end < 0 ? json(nullptr)
                                         : json{{"after_warmup", samples.rss_after_warm_up},
                                                {"end", samples.rss_end},
                                                {"growth", samples.rss_end - samples.rss_after_warm_up},
                                                {"max", samples.rss_max}}},
          {"scene", scene.name},
          {"device", device}};
}

}  // namespace

void run_bench_frame(const BenchFrameSettings& settings, std::ostream& out) {
  render::Renderer renderer(settings.renderer);
  require_memory(pipeline_memory(settings.scene), renderer.memory_limits());
  load_scene_mesh(renderer, settings.scene);
  pipeline::FramePipeline pipeline(settings.scene, renderer, {}, height_loader(settings.scene.image_read),
                                   albedo_loader());
  const BenchSamples samples = run_bench_frames(settings, renderer, pipeline);
  const std::string device = renderer.device().name;
  nlohmann::ordered_json stages = print_bench_table(settings, samples, device, out);
  if (!settings.json.empty()) {
    const nlohmann::ordered_json json = bench_json(settings, samples, std::move(stages), device);
    files::write_file(settings.json, json.dump(2) + '\n');
    out << "  wrote " << settings.json.string() << '\n';
  }
  require_no_validation_messages(settings.renderer.validate, renderer.validation_messages());
}

Finish add_bench_frame_command(CLI::App& command) {
  command.description(
      "Run the frame pipeline for F frames after a warm-up and print, per stage, the p50, p95 and p99 "
      "milliseconds, the frames within budget, FFTs per frame, the effects, and Vulkan allocations.");
  command.footer(
      "--json writes the table as one JSON object (snake_case keys, units in the names): frames,\n"
      "backend.sim and backend.bake (cpu, device), budget_ms (null: unlimited), stages.STAGE.p50_ms, "
      "p95_ms,\n"
      "p99_ms and device_p50_ms (STAGE: sim, bake, upload, render, frame, latency; device_p50_ms null where\n"
      "the stage has no device time), within_budget (fraction of frames), ffts_per_frame, effects,\n"
      "vulkan_allocations_after_warmup, frames_rendered, cone_lag_frames.p50 and max, cone_lift.p50 and max\n"
      "(fraction of the height range; null without cone maps), overlapped, pinned_threads,\n"
      "rss_kb.after_warmup, end, growth and max (null where unknown), scene, device.");
  struct Draft {
    cli::SceneFlags scene;
    BenchFrameSettings settings;
    std::string json;
  };
  auto draft = std::make_shared<Draft>();
  cli::add_scene_flags(command, draft->scene, cli::scene_all, "water");
  cli::add_renderer_flags(command, draft->settings.renderer);
  command.option_defaults()->group("Benchmark");
  cli::add_value(command, "--frames", draft->settings.frames, "frames timed (default 120)", "F",
                 cli::integer_in(1, 1000000));
  cli::add_value(command, "--warm-up", draft->settings.warm_up, "frames run first, not timed (default 5)",
                 "N", cli::integer_in(2, 10000));
  cli::add_switch(
      command, "--serial", draft->settings.serial,
      "run the stages one after another, none overlapped: what each costs with the whole machine");
  cli::add_switch(
      command, "--pin-threads", draft->settings.pin_threads,
      "run TBB's threads and lavapipe's rasterizer threads one per CPU (Linux): frame times without "
      "the stalls of a woken thread queued on a busy CPU");
  cli::add_value(command, "--json", draft->json, "also write the table as JSON", "FILE.json",
                 cli::output_file({".json"}));
  return [&command, draft] {
    BenchFrameSettings settings = draft->settings;
    settings.scene = cli::finish_scene(command, draft->scene);
    cli::check_cone_lag(command, settings.scene);
    settings.json = draft->json;
    cli::finish_renderer(settings.renderer);
    return ParsedCommand{"bench-frame", settings,
                         [settings](std::ostream& out) { run_bench_frame(settings, out); }};
  };
}
}  // namespace displace::app
