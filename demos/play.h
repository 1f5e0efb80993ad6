// demos/play.h - `displace play`: the frame pipeline's scene animated in a window.
//
// The only place that includes GLFW. Frames come from pipeline::FramePipeline, are rendered with
// render::output_none and shown through render::Swapchain (a blit on the device, no readback); only a
// screenshot reads its frame back. With --frames N the run is fixed-step and deterministic: frame n
// is shown at scene time start + n / fps, and the last one equals FramePipeline::run(N - 1).
#pragma once

#include <iosfwd>

#include "demos/commands/settings.h"
#include "pipeline/scene.h"

namespace displace::app {

// The error when there is no display (no DISPLAY / WAYLAND_DISPLAY, or GLFW cannot start).
inline constexpr const char* no_display_message =
    "no display: run 'xvfb-run -a displace play ...' or render frames headless with 'displace sequence'";

// run_play (commands/settings.h) opens the window and plays until it is closed (or --frames N are
// done); it throws AppError (runtime) without a display.

}  // namespace displace::app
