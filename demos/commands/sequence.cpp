// demos/commands/sequence.cpp - `displace sequence`: frames A..B of a scene, headless, each to its own
// file; deterministic, so any split into shards, any order and a resumed run give the same files.
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
    "mean_ratio,texels_pending,cone_lag_frames,cone_lift,sim_backend,bake_backend,sim_device_ms,"
    "bake_device_ms,render_device_ms\n";

std::string sequence_csv_row(long long n, const pipeline::FrameRecord& record) {
  return fmt::format(
      "{},{:.17g},{:.3f},{:.3f},{:.3f},{:.3f},{:.3f},{},{},{},{},{:.6f},{},{},{:.6f},{},{},{:.3f},{:.3f},{:."
      "3f}\n",
      n, record.time, record.sim_ms, record.bake_ms, record.upload_ms, record.render_ms, record.frame_ms,
      std::isfinite(record.bake_budget_ms) ? fmt::format("{:.3f}", record.bake_budget_ms) : "inf",
      record.overrun ? 1 : 0, record.ffts, fmt::join(effect_names(record.effects), "+"),
      record.cones.mean_ratio, record.pending, record.cone_lag, record.cone_lift,
      record.sim_on_device ? "device" : "cpu", record.bake_on_device ? "device" : "cpu", record.sim_device_ms,
      record.bake_device_ms, record.render_device_ms);
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
  const unsigned outputs = frame_outputs(settings.aovs);
  render::Renderer renderer(settings.renderer);
  require_memory(pipeline_memory(settings.scene), renderer.memory_limits());
  load_scene_mesh(renderer, settings.scene);
  pipeline::FramePipeline pipeline(settings.scene, renderer, {}, height_loader(settings.scene.image_read),
                                   albedo_loader());
  const pipeline::Scene& scene = settings.scene;
  std::FILE* video = start_video(settings);

  const std::filesystem::path csv_path = csv_file(settings);
  std::string csv = sequence_csv_header;
  const bool terminal = stderr_is_terminal();
  const double start = steady_seconds();
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
    const double rate = double(done) / std::max(steady_seconds() - start, 1e-9);
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
      done, skipped, steady_seconds() - start, renderer.device().name);
  if (const long long loop = pipeline::loop_frames(scene); loop > 0) {
    const bool whole =
        settings.first % loop == 0 && settings.last - settings.first + 1 == loop && settings.step == 1;
    out << fmt::format(
        "  a seamless loop of {:g} s: frame n + {} is frame n bit for bit (wave frequencies moved by at most "
        "{:.2f}%){}\n",
        scene.ocean.loop_seconds, loop, 100.0 * pipeline.loop_error(),
        whole ? fmt::format(": frames {}..{} are one whole loop", settings.first, settings.last)
              : std::string());
  }
  if (done > 0) out << "  per-frame stage times: " << csv_path.string() << '\n';
  require_no_validation_messages(settings.renderer.validate, renderer.validation_messages());
}

Finish add_sequence_command(CLI::App& command) {
  command.description(
      "Render frames A..B of a scene headless, each to its own file; deterministic, so any split into "
      "shards, any order and a resumed run give the same files.");
  command.footer(
      "Next to the frames, OUTPUT_STEM.csv has a row per frame (snake_case columns, units in the names):\n"
      "frame, time_s, sim_ms, bake_ms, upload_ms, render_ms, frame_ms (wall times of the stages and the\n"
      "frame), bake_budget_ms (the bake's share; inf: unlimited), overrun (1: the frame took longer than\n"
      "the budget), ffts, effects (+-joined), cone_mean_ratio, texels_pending (left to refine),\n"
      "cone_lag_frames, cone_lift (apexes raised, fraction of the height range), sim_backend, bake_backend\n"
      "(cpu, device), sim_device_ms, bake_device_ms, render_device_ms (GPU timestamps; 0: none).");
  struct Draft {
    cli::SceneFlags scene;
    SequenceSettings settings;
    std::string frames, output, shard, video, preview;
    std::vector<std::string> aovs;
  };
  auto draft = std::make_shared<Draft>();
  cli::add_scene_flags(command, draft->scene, cli::scene_all, "water");
  cli::add_renderer_flags(command, draft->settings.renderer);
  command.option_defaults()->group("Frames");
  command
      .add_option("--frames", draft->frames,
                  "frames A to B inclusive, every STEP-th (frame n is at start + n / fps)")
      ->type_name("A:B[:STEP]")
      ->check(cli::text_check([](const std::string& text) -> std::string {
        long long a = 0, b = 0, step = 1;
        char extra = 0;
        const int read = std::sscanf(text.c_str(), "%lld:%lld:%lld%c", &a, &b, &step, &extra);
        if ((read != 2 && read != 3) || a < 0 || b < a || step < 1 || b - a > 10000000) {
          return "expects A:B[:STEP] with 0 <= A <= B and STEP >= 1, got " + cli::in_quotes(text);
        }
        return {};
      }))
      ->required();
  cli::add_value(command, "--output", draft->output, "the frames: '#' runs become the frame number",
                 "DIR/name_####.png|.exr", cli::frame_pattern({".png", ".exr"}))
      ->required();
  cli::add_aov_option(command, draft->aovs,
                      "also write uv=DIR/uv_####.exr, depth=..., iterations=..., fetches=... per frame",
                      true);
  command.add_option("--shard", draft->shard, "render shard I of N (round robin over the frames, I from 1)")
      ->type_name("I/N")
      ->check(cli::text_check([](const std::string& text) -> std::string {
        int i = 0, n = 0;
        char extra = 0;
        if (std::sscanf(text.c_str(), "%d/%d%c", &i, &n, &extra) != 2 || n < 1 || n > 100000 || i < 1 ||
            i > n) {
          return "expects I/N with 1 <= I <= N, got " + cli::in_quotes(text);
        }
        return {};
      }));
  cli::add_switch(command, "--resume", draft->settings.resume, "skip frames whose outputs all exist");
  cli::add_value(command, "--video", draft->video,
                 "also encode the frames with ffmpeg (needs ffmpeg on the PATH)", "FILE.mp4|FILE.webm",
                 cli::output_file({".mp4", ".webm"}));
  cli::add_value(command, "--preview", draft->preview, "also an animated GIF of the frames (a preview)",
                 "FILE.gif", cli::output_file({".gif"}));
  return [&command, draft] {
    SequenceSettings settings = draft->settings;
    settings.scene = cli::finish_scene(command, draft->scene);
    cli::check_cone_lag(command, settings.scene);
    settings.preview = draft->preview;
    long long step = 1;
    std::sscanf(draft->frames.c_str(), "%lld:%lld:%lld", &settings.first, &settings.last, &step);
    settings.step = step;
    if (!draft->shard.empty())
      std::sscanf(draft->shard.c_str(), "%d/%d", &settings.shard_index, &settings.shard_count);
    if (!settings.preview.empty() && settings.shard_count > 1) {
      throw usage_error("--preview shows one run's frames: not with --shard");
    }
    // shards and resumed runs give one run's files only when a frame depends on its index alone
    if (std::isfinite(settings.scene.frame_ms) && (settings.shard_count > 1 || settings.resume)) {
      throw usage_error(fmt::format(
          "--shard and --resume need frames that depend on their index only, and a wall-clock frame budget "
          "({:g} ms, from --budget-ms or the scene's [budget] frame_ms) makes them depend on timing: give a "
          "work budget instead (--bake-work N)",
          settings.scene.frame_ms));
    }
    settings.output = draft->output;
    settings.aovs = cli::aov_outputs(draft->aovs);
    settings.video = draft->video;
    if (!settings.video.empty() && settings.shard_count > 1) {
      throw usage_error("--video encodes one run's frames: not with --shard");
    }
    cli::finish_renderer(settings.renderer);
    return ParsedCommand{"sequence", settings,
                         [settings](std::ostream& out) { run_sequence(settings, out); }};
  };
}
}  // namespace displace::app
