// demos/play.h - `displace play`: the frame pipeline's scene animated in a window.
//
// The only place that includes GLFW. Frames come from pipeline::FramePipeline, are rendered with
// render::output_none and shown through render::Swapchain (a blit on the device, no readback); only a
// screenshot reads its frame back. With --frames N the run is fixed-step and deterministic: frame n
// is shown at scene time start + n / fps, and the last one equals FramePipeline::run(N - 1).
#pragma once

#include <iosfwd>

#include "demos/options.h"
#include "pipeline/scene.h"

namespace displace::app {

// The frame budget interactive play starts at when the scene sets none (ms; one of the levels the
// Right / Left keys step through).
inline constexpr double interactive_budget_ms = 33.0;

// The scene play animates: the built-in or the file's, with --size and --map-size applied, and
// without --frames a scene with no frame budget and no work limit at interactive_budget_ms. Throws
// pipeline::SceneError (a bad file) or AppError (an unknown name).
pipeline::Scene play_scene(const PlaySettings& settings);

// The error when there is no display (no DISPLAY / WAYLAND_DISPLAY, or GLFW cannot start).
inline constexpr const char* no_display_message =
    "no display: run 'xvfb-run -a displace play ...' or render frames headless with 'displace sequence'";

// Opens the window and plays until it is closed (or --frames N are done); throws AppError (runtime)
// without a display.
void run_play(const PlaySettings& settings, std::ostream& out);

}  // namespace displace::app
