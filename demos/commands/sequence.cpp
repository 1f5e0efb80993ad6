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
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <ostream>
#include <set>
#include <string>
#include <vector>

#include "demos/cli/command.h"
#include "demos/cli/flags.h"
#include "demos/cli/scene_flags.h"
#include "demos/commands/settings.h"
#include "demos/error.h"
#include "demos/frame_manifest.h"
#include "demos/frame_output.h"
#include "demos/heights.h"
#include "demos/image_io.h"
#include "demos/interrupt.h"
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

// The name the per-frame CSVs and manifests of a sequence start with: the pattern without its '#'s.
std::string csv_stem(const SequenceSettings& settings) {
  std::string stem = settings.output.stem().string();
  stem.erase(std::remove(stem.begin(), stem.end(), '#'), stem.end());
  while (!stem.empty() && (stem.back() == '_' || stem.back() == '-' || stem.back() == '.')) stem.pop_back();
  return stem.empty() ? "frames" : stem;
}

// The per-frame CSV of a sequence (or of one shard): next to the frames. Its manifest
// (demos/frame_manifest.h) has the same name ending in .manifest.
std::filesystem::path csv_file(const SequenceSettings& settings) {
  std::string stem = csv_stem(settings);
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

// The CSV and the manifest are saved at most this often (seconds) while frames are written, and at
// the end: a killed run loses at most this much of its manifest (those frames are then decoded).
constexpr double manifest_save_seconds = 5.0;

const std::string sequence_csv_header =
    "frame,time_s,sim_ms,bake_ms,upload_ms,render_ms,frame_ms,bake_budget_ms,overrun,ffts,effects,cone_"
    "mean_ratio,texels_pending,cone_lag_frames,cone_lift,sim_backend,bake_backend,sim_device_ms,"
    "bake_device_ms,render_device_ms,cones_updated\n";

std::string sequence_csv_row(long long n, const pipeline::FrameRecord& record) {
  return fmt::format(
      "{},{:.17g},{:.3f},{:.3f},{:.3f},{:.3f},{:.3f},{},{},{},{},{:.6f},{},{},{:.6f},{},{},{:.3f},{:.3f},{:."
      "3f},{}\n",
      n, record.time, record.sim_ms, record.bake_ms, record.upload_ms, record.render_ms, record.frame_ms,
      std::isfinite(record.bake_budget_ms) ? fmt::format("{:.3f}", record.bake_budget_ms) : "inf",
      record.overrun ? 1 : 0, record.ffts, fmt::join(effect_names(record.effects), "+"),
      record.cones.mean_ratio, record.pending, record.cone_lag, record.cone_lift,
      record.sim_on_device ? "device" : "cpu", record.bake_on_device ? "device" : "cpu", record.sim_device_ms,
      record.bake_device_ms, record.render_device_ms, record.cones_updated ? 1 : 0);
}

// Frame n's picture and AOVs, each written whole by the checked writer and entered in the manifest.
void write_sequence_frame(const SequenceSettings& settings, long long n, const pipeline::FrameRecord& record,
                          const render::Frame& frame, const std::filesystem::path& picture,
                          const std::vector<AovOutput>& aovs, FrameManifest& manifest) {
  const pipeline::Scene& scene = settings.scene;
  Metadata metadata = {{"displace:scene", scene.name},
                       {"displace:frame", int(n)},
                       {"displace:time", fmt::format("{:.17g}", record.time)},
                       {"displace:method", std::string(render::method_info(scene.method).name)},
                       {"displace:steps", scene.steps}};
  manifest.add(picture, write_frame_image(picture, frame, metadata));
  for (const AovOutput& aov : aovs) manifest.add(aov.file, write_aov(aov, frame, metadata));
}

// The rows by frame of the sequence's per-frame CSVs beside `csv` (any shard layout) whose header is
// this version's: what a resumed run keeps for the frames it skips.
std::map<long long, std::string> read_csv_rows(const std::filesystem::path& csv, const std::string& stem) {
  std::map<long long, std::string> rows;
  std::error_code error;
  const std::filesystem::path directory = csv.parent_path().empty() ? "." : csv.parent_path();
  for (const auto& entry : std::filesystem::directory_iterator(directory, error)) {
    if (!is_sequence_file(entry.path(), stem, ".csv")) continue;
    std::ifstream stream(entry.path());
    std::string line;
    if (!std::getline(stream, line) || line + '\n' != sequence_csv_header) continue;
    while (std::getline(stream, line)) {
      long long frame = 0;
      char comma = 0;
      if (std::sscanf(line.c_str(), "%lld%c", &frame, &comma) == 2 && comma == ',') rows[frame] = line + '\n';
    }
  }
  return rows;
}

// Temporaries a killed run of this shard left (".NAME.partial-PID-N", render/files.h) beside the
// frames it owns: removed before the first frame. Only this shard's names, so that shards sharing a
// directory never touch each other's writes.
void remove_stale_partials(const std::vector<std::vector<std::filesystem::path>>& outputs) {
  std::map<std::filesystem::path, std::set<std::string>> owned;
  for (const auto& frame_files : outputs) {
    for (const std::filesystem::path& file : frame_files) {
      owned[file.parent_path().empty() ? "." : file.parent_path()].insert(file.filename().string());
    }
  }
  std::error_code error;
  for (const auto& [directory, names] : owned) {
    for (const auto& entry : std::filesystem::directory_iterator(directory, error)) {
      const std::string name = entry.path().filename().string();
      const std::size_t partial = name.rfind(".partial-");
      if (name.size() < 2 || name[0] != '.' || partial == std::string::npos) continue;
      if (names.count(name.substr(1, partial - 1))) std::filesystem::remove(entry.path(), error);
    }
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

  // the files of each frame: its picture, then its AOVs
  std::vector<std::vector<std::filesystem::path>> frame_files;
  for (const long long n : frames) {
    std::vector<std::filesystem::path> names{pipeline::image_for_frame(settings.output, n)};
    for (const AovOutput& aov : settings.aovs) names.push_back(pipeline::image_for_frame(aov.file, n));
    frame_files.push_back(std::move(names));
  }
  const StopBetweenFrames stop;
  remove_stale_partials(frame_files);

  // the per-frame CSV and the manifest, saved together: they list only frames written whole
  const std::filesystem::path csv_path = csv_file(settings);
  FrameManifest manifest(std::filesystem::path(csv_path).replace_extension(".manifest"));
  const bool resume = settings.resume && !video && settings.preview.empty();
  std::map<long long, std::string> earlier_rows;
  if (resume) {
    manifest.read_beside(csv_stem(settings));
    earlier_rows = read_csv_rows(csv_path, csv_stem(settings));
  }
  std::string rows;
  double last_save = steady_seconds();
  const auto save = [&] {
    files::write_file(csv_path, sequence_csv_header + rows);
    manifest.save();
    last_save = steady_seconds();
  };
  // on the way out after a failure or a signal: what can still be saved, the first error kept
  const auto save_after_stop = [&] {
    try {
      if (!rows.empty()) save();
    } catch (const files::WriteError&) {
    }
  };

  const bool terminal = stderr_is_terminal();
  const double start = steady_seconds();
  render::Frame frame;
  std::vector<std::vector<std::uint8_t>> preview;
  long long done = 0, skipped = 0;
  for (std::size_t position = 0; position < frames.size(); ++position) {
    const long long n = frames[position];
    if (const int signal = stop.requested()) {
      save_after_stop();
      throw Interrupted(
          signal, fmt::format("stopped before frame {}, {} frames written whole; --resume goes on", n, done));
    }
    const std::filesystem::path& picture = frame_files[position][0];
    std::vector<AovOutput> aovs = settings.aovs;
    for (std::size_t a = 0; a < aovs.size(); ++a) aovs[a].file = frame_files[position][a + 1];
    if (resume && std::all_of(frame_files[position].begin(), frame_files[position].end(),
                              [&](const std::filesystem::path& file) { return manifest.whole(file); })) {
      ++skipped;
      if (const auto row = earlier_rows.find(n); row != earlier_rows.end()) rows += row->second;
      continue;
    }
    const pipeline::FrameRecord record = pipeline.run(n, frame, outputs);
    try {
      write_sequence_frame(settings, n, record, frame, picture, aovs, manifest);
    } catch (const files::WriteError& error) {
      save_after_stop();
      throw runtime_error(
          fmt::format("frame {}: {} (the frames before it are whole; --resume goes on)", n, error.what()));
    }
    if (!settings.preview.empty()) preview.push_back(frame.color);
    if (video && std::fwrite(frame.color.data(), 1, frame.color.size(), video) != frame.color.size()) {
      ::pclose(video);
      throw runtime_error("ffmpeg stopped taking frames for --video");
    }
    rows += sequence_csv_row(n, record);
    ++done;
    if (steady_seconds() - last_save >= manifest_save_seconds) save();
    const double rate = double(done) / std::max(steady_seconds() - start, 1e-9);
    report_sequence_progress(out, terminal, n, done + skipped, frames.size(), rate, record, picture);
  }
  if (terminal) std::fprintf(stderr, "\r%*s\r", 90, "");
  if (video && ::pclose(video) != 0) throw runtime_error("ffmpeg failed to encode --video");
  if (!preview.empty()) {
    write_animated_gif(settings.preview, scene.camera.width, scene.camera.height, preview,
                       int(std::lround(scene.fps)));
    out << "  animated preview: " << settings.preview.string() << '\n';
  }
  if (done > 0 || resume) save();  // a resume keeps what it judged whole for the next one
  if (const int signal = stop.requested()) {
    throw Interrupted(signal, fmt::format("after the last frame: all {} frames are whole", frames.size()));
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
      "(cpu, device), sim_device_ms, bake_device_ms, render_device_ms (GPU timestamps; 0: none),\n"
      "cones_updated (1: the cone map was updated where an image sequence's frame changed, not baked "
      "whole).\n"
      "It lists only frames written whole, as does OUTPUT_STEM.manifest (each file's size, time and\n"
      "checksum: what --resume trusts); both are saved every few seconds and when the run ends.\n"
      "Every file is written whole or not at all (a temporary, fsync, rename): the first frame that\n"
      "cannot be written ends the run (exit 1). SIGINT and SIGTERM stop it after the frame in progress\n"
      "(exit 130, 143); a second one stops it at once; neither leaves a partial file.");
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
  cli::add_switch(command, "--resume", draft->settings.resume,
                  "skip frames whose files are all whole: a file is whole when its size and time are the "
                  "manifest's (OUTPUT_STEM*.manifest, no byte read), else when its bytes' checksum is, else "
                  "when it decodes whole; empty, truncated and corrupt files are rendered again");
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
