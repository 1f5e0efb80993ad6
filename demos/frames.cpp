// demos/frames.cpp - the frame pipeline's headless users: `displace sequence` (frames to files,
// shardable, resumable) and `displace bench-frame` (the loop timed stage by stage).
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
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

#include "demos/commands.h"
#include "demos/error.h"
#include "demos/memory.h"
#include "demos/progress.h"
#include "pipeline/frame_pipeline.h"
#include "pipeline/thread_pinning.h"

namespace displace::app {
namespace {

double seconds_now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// The application's height-image reader for image scenes.
pipeline::HeightLoader image_loader() {
  return [](const std::filesystem::path& file) {
    LoadedHeights loaded = load_heights(file, {});
    return render::HeightField{loaded.width, loaded.height, std::move(loaded.heights)};
  };
}

// The application's colour-image reader for albedo materials.
pipeline::AlbedoLoader albedo_loader() {
  return [](const std::filesystem::path& file) {
    Rgba8Image image = read_color_image(file);
    return render::Albedo{image.width, image.height, std::move(image.pixels)};
  };
}

std::vector<std::string> effect_names(unsigned effects) {
  std::vector<std::string> names;
  if (effects & pipeline::effect_heights) names.emplace_back("heights");
  if (effects & pipeline::effect_choppy) names.emplace_back("choppy");
  if (effects & pipeline::effect_foam) names.emplace_back("foam");
  return names;
}

// Writes through a temporary name in the same directory and renames it into place, so that an
// interrupted run never leaves half a file under the real name.
template <typename Write>
void write_atomically(const std::filesystem::path& file, Write&& write) {
  const std::filesystem::path temporary =
      file.parent_path() /
      fmt::format(".{}.partial{}{}", file.stem().string(), ::getpid(), file.extension().string());
  write(temporary);
  std::error_code error;
  std::filesystem::rename(temporary, file, error);
  if (error) {
    std::filesystem::remove(temporary, error);
    throw runtime_error(fmt::format("cannot move the frame into place as '{}'", file.string()));
  }
}

bool on_path(const std::string& program) {
  const char* path = std::getenv("PATH");
  if (!path) return false;
  std::string directories = path;
  std::size_t start = 0;
  while (start <= directories.size()) {
    const std::size_t end = std::min(directories.find(':', start), directories.size());
    const std::filesystem::path candidate =
        std::filesystem::path(directories.substr(start, end - start)) / program;
    if (::access(candidate.c_str(), X_OK) == 0) return true;
    start = end + 1;
  }
  return false;
}

// The per-frame CSV of a sequence: next to the frames, named after the pattern without its '#'s.
std::filesystem::path csv_file(const SequenceSettings& settings) {
  std::string stem = settings.output.stem().string();
  stem.erase(std::remove(stem.begin(), stem.end(), '#'), stem.end());
  while (!stem.empty() && (stem.back() == '_' || stem.back() == '-' || stem.back() == '.')) stem.pop_back();
  if (stem.empty()) stem = "frames";
  if (settings.shard_count > 1)
    stem += fmt::format(".shard{}of{}", settings.shard_index, settings.shard_count);
  return settings.output.parent_path() / (stem + ".csv");
}

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

// The frames of this shard (round robin over A..B:STEP).
std::vector<long long> shard_frames(const SequenceSettings& settings) {
  std::vector<long long> frames;
  long long position = 0;
  for (long long n = settings.first; n <= settings.last; n += settings.step, ++position) {
    if (position % settings.shard_count == settings.shard_index - 1) frames.push_back(n);
  }
  return frames;
}

// The directories of the frame and AOV patterns, made before the first frame.
void make_output_directories(const SequenceSettings& settings) {
  std::vector<std::filesystem::path> patterns{settings.output};
  for (const AovOutput& aov : settings.aovs) patterns.push_back(aov.file);
  std::error_code error;
  for (const std::filesystem::path& pattern : patterns) {
    if (!pattern.parent_path().empty()) std::filesystem::create_directories(pattern.parent_path(), error);
    if (error)
      throw runtime_error(fmt::format("cannot create the directory '{}'", pattern.parent_path().string()));
  }
}

// The render outputs the frame and its AOVs read back.
unsigned sequence_outputs(const SequenceSettings& settings) {
  unsigned outputs = render::output_color;
  for (const AovOutput& aov : settings.aovs) {
    outputs |= aov.aov == Aov::uv           ? render::output_uv
               : aov.aov == Aov::depth      ? render::output_depth
               : aov.aov == Aov::iterations ? render::output_uv | render::output_iterations
                                            : render::output_uv | render::output_fetches;
  }
  return outputs;
}

// ffmpeg reading raw RGBA frames for --video; null without --video.
std::FILE* start_video(const SequenceSettings& settings) {
  if (settings.video.empty()) return nullptr;
  const pipeline::Scene& scene = settings.scene;
  const std::string command = fmt::format(
      "ffmpeg -loglevel error -y -f rawvideo -pix_fmt rgba -s {}x{} -r {} -i - -pix_fmt yuv420p '{}'",
      scene.camera.width, scene.camera.height, scene.fps, settings.video.string());
  std::FILE* video = ::popen(command.c_str(), "w");
  if (!video) throw runtime_error("cannot start ffmpeg for --video");
  return video;
}

constexpr const char* sequence_csv_header =
    "frame,time_s,sim_ms,bake_ms,upload_ms,render_ms,frame_ms,bake_budget_ms,overrun,ffts,effects,cone_"
    "mean_ratio,pending_texels,cone_lag_frames,cone_lift\n";

std::string sequence_csv_row(long long n, const pipeline::FrameRecord& record) {
  return fmt::format(
      "{},{:.17g},{:.3f},{:.3f},{:.3f},{:.3f},{:.3f},{},{},{},{},{:.6f},{},{},{:.6f}\n", n, record.time,
      record.sim_ms, record.bake_ms, record.upload_ms, record.render_ms, record.frame_ms,
      std::isfinite(record.bake_budget_ms) ? fmt::format("{:.3f}", record.bake_budget_ms) : "inf",
      record.overrun ? 1 : 0, record.ffts, fmt::join(effect_names(record.effects), "+"),
      record.cones.mean_ratio, record.pending, record.cone_lag, record.cone_lift);
}

// Frame n's picture and AOVs, each written atomically.
void write_sequence_frame(const SequenceSettings& settings, long long n, const pipeline::FrameRecord& record,
                          const render::Frame& frame, const std::filesystem::path& picture,
                          const std::vector<AovOutput>& aovs) {
  const pipeline::Scene& scene = settings.scene;
  Metadata metadata = {{"displace:scene", scene.name},
                       {"displace:frame", int(n)},
                       {"displace:time", fmt::format("{:.17g}", record.time)},
                       {"displace:method", std::string(render::method_info(scene.method).name)},
                       {"displace:steps", scene.steps}};
  write_atomically(picture,
                   [&](const std::filesystem::path& file) { write_frame_image(file, frame, metadata); });
  for (const AovOutput& aov : aovs) {
    write_atomically(aov.file, [&](const std::filesystem::path& file) {
      write_aov({aov.aov, file}, frame, metadata);
    });
  }
}

// Progress: a bar on a terminal, one line a frame otherwise.
void report_sequence_progress(std::ostream& out, bool terminal, long long n, long long finished,
                              std::size_t total, double rate, const pipeline::FrameRecord& record,
                              const std::filesystem::path& picture) {
  if (terminal) {
    const int width = 30;
    const int filled = int(width * double(finished) / double(total));
    const double left = double((long long)total - finished);
    std::fprintf(stderr, "\r[%s%s] frame %lld of %zu, %.2f frames/s, %.0f s left ",
                 std::string(filled, '#').c_str(), std::string(width - filled, '.').c_str(), finished, total,
                 rate, left / std::max(rate, 1e-9));
    std::fflush(stderr);
  } else {
    out << fmt::format(
        "frame {} ({} of {}): {:.1f} ms (sim {:.1f}, bake {:.1f}, upload {:.1f}, render {:.1f}) -> {}\n", n,
        finished, total, record.frame_ms, record.sim_ms, record.bake_ms, record.upload_ms, record.render_ms,
        picture.string());
  }
}

}  // namespace

void run_sequence(const SequenceSettings& settings, std::ostream& out) {
  const std::vector<long long> frames = shard_frames(settings);
  make_output_directories(settings);
  if (!settings.video.empty() && !on_path("ffmpeg")) {
    throw runtime_error(
        "--video needs ffmpeg on the PATH (apt-get install ffmpeg); the frames alone need no --video");
  }
  const unsigned outputs = sequence_outputs(settings);
  render::Renderer renderer(settings.renderer);
  require_memory(pipeline_memory(settings.scene), renderer.memory_limits());
  pipeline::FramePipeline pipeline(settings.scene, renderer, {}, image_loader(), albedo_loader());
  const pipeline::Scene& scene = settings.scene;
  std::FILE* video = start_video(settings);

  const std::filesystem::path csv_path = csv_file(settings);
  std::string csv = sequence_csv_header;
  const bool terminal = stderr_is_terminal();
  const double start = seconds_now();
  render::Frame frame;
  std::vector<std::vector<std::uint8_t>> preview;
  long long done = 0, skipped = 0;
  for (const long long n : frames) {
    const std::filesystem::path picture = pipeline::image_for_frame(settings.output, n);
    std::vector<AovOutput> aovs = settings.aovs;
    for (AovOutput& aov : aovs) aov.file = pipeline::image_for_frame(aov.file, n);
    const bool present = std::filesystem::exists(picture) &&
                         std::all_of(aovs.begin(), aovs.end(),
                                     [](const AovOutput& aov) { return std::filesystem::exists(aov.file); });
    if (settings.resume && present && !video && settings.preview.empty()) {
      ++skipped;
      continue;
    }
    const pipeline::FrameRecord record = pipeline.run(n, frame, outputs);
    write_sequence_frame(settings, n, record, frame, picture, aovs);
    if (!settings.preview.empty()) preview.push_back(frame.color);
    if (video && std::fwrite(frame.color.data(), 1, frame.color.size(), video) != frame.color.size()) {
      ::pclose(video);
      throw runtime_error("ffmpeg stopped taking frames for --video");
    }
    csv += sequence_csv_row(n, record);
    ++done;
    const double rate = double(done) / std::max(seconds_now() - start, 1e-9);
    report_sequence_progress(out, terminal, n, done + skipped, frames.size(), rate, record, picture);
  }
  if (terminal) std::fprintf(stderr, "\r%*s\r", 90, "");
  if (video && ::pclose(video) != 0) throw runtime_error("ffmpeg failed to encode --video");
  if (!preview.empty()) {
    write_atomically(settings.preview, [&](const std::filesystem::path& file) {
      write_animated_gif(file, scene.camera.width, scene.camera.height, preview, int(std::lround(scene.fps)));
    });
    out << "  animated preview: " << settings.preview.string() << '\n';
  }
  if (done > 0) {
    write_atomically(csv_path, [&](const std::filesystem::path& file) {
      std::ofstream stream(file);
      stream << csv;
      if (!stream) throw runtime_error(fmt::format("cannot write '{}'", file.string()));
    });
  }
  out << fmt::format(
      "displace sequence: {} {}, frames {}..{} step {}{}: rendered {}, skipped {} (present), "
      "{:.1f} s on {}\n",
      scene.name, render::method_info(scene.method).name, settings.first, settings.last, settings.step,
      settings.shard_count > 1 ? fmt::format(", shard {}/{}", settings.shard_index, settings.shard_count)
                               : std::string(),
      done, skipped, seconds_now() - start, renderer.device().name);
  if (done > 0) out << "  per-frame stage times: " << csv_path.string() << '\n';
  if (settings.renderer.validate && renderer.validation_messages() > 0) {
    throw runtime_error(
        fmt::format("{} Vulkan validation messages (printed above)", renderer.validation_messages()));
  }
}

namespace {

// What bench-frame measures over the timed frames (those after the warm-up).
struct BenchSamples {
  std::vector<double> sim, bake, upload, draw, frame_ms, interval, lag, lift;
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
    const double now = seconds_now() * 1e3;
    if (seen == settings.warm_up) {
      samples.allocations_after_warm_up = renderer.memory_allocations();
      samples.rss_after_warm_up = resident_kilobytes();
    }
    if (seen >= settings.warm_up) {
      samples.rss_max = std::max(samples.rss_max, resident_kilobytes());
      samples.sim.push_back(record.sim_ms);
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
  };
  const Row rows[] = {{"sim", &samples.sim},        {"bake", &samples.bake},
                      {"upload", &samples.upload},  {"render", &samples.draw},
                      {"frame", &samples.interval}, {"latency", &samples.frame_ms}};
  out << fmt::format(
      "displace bench-frame: {} ({} {}x{} map, {}x{} pixels, {} {} steps), {} frames after {} warm-up, "
      "budget {}, {}, on {}\n",
      scene.name, scene.source == pipeline::SourceKind::image ? "image" : "a", scene.map_size, scene.map_size,
      scene.camera.width, scene.camera.height, render::method_info(scene.method).name, scene.steps,
      settings.frames, settings.warm_up,
      std::isfinite(scene.frame_ms) ? fmt::format("{:g} ms", scene.frame_ms) : std::string("unlimited"),
      settings.serial ? "stages in series" : "stages overlapped", device);
  if (settings.pin_threads) {
    out << (samples.pinned_cpus > 0
                ? fmt::format("  {} threads pinned one per CPU over {} CPUs\n", samples.pinned_threads,
                              samples.pinned_cpus)
                : std::string("  --pin-threads: nothing pinned (fewer than two CPUs, or no affinity "
                              "here)\n"));
  }
  out << "  stage     p50 ms   p95 ms   p99 ms\n";
  nlohmann::ordered_json stages = nlohmann::ordered_json::object();
  for (const Row& row : rows) {
    const double p50 = percentile(*row.values, 0.50), p95 = percentile(*row.values, 0.95),
                 p99 = percentile(*row.values, 0.99);
    out << fmt::format("  {:<8} {:8.2f} {:8.2f} {:8.2f}\n", row.name, p50, p95, p99);
    stages[row.name] = {{"p50_ms", p50}, {"p95_ms", p95}, {"p99_ms", p99}};
  }
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
  pipeline::FramePipeline pipeline(settings.scene, renderer, {}, image_loader(), albedo_loader());
  const BenchSamples samples = run_bench_frames(settings, renderer, pipeline);
  const std::string device = renderer.device().name;
  nlohmann::ordered_json stages = print_bench_table(settings, samples, device, out);
  if (!settings.json.empty()) {
    const nlohmann::ordered_json json = bench_json(settings, samples, std::move(stages), device);
    write_atomically(settings.json, [&](const std::filesystem::path& file) {
      std::ofstream stream(file);
      stream << json.dump(2) << '\n';
      if (!stream) throw runtime_error(fmt::format("cannot write '{}'", file.string()));
    });
    out << "  wrote " << settings.json.string() << '\n';
  }
  if (settings.renderer.validate && renderer.validation_messages() > 0) {
    throw runtime_error(
        fmt::format("{} Vulkan validation messages (printed above)", renderer.validation_messages()));
  }
}

}  // namespace displace::app
