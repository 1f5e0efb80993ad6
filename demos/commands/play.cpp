// demos/commands/play.cpp - `displace play`: a scene animated in a window (demos/play.cpp runs it).
#include <fmt/format.h>

#include <cmath>
#include <ostream>

#include "demos/cli/command.h"
#include "demos/cli/flags.h"
#include "demos/cli/scene_flags.h"
#include "demos/commands/settings.h"
#include "demos/error.h"

namespace displace::app {
namespace {

// The keys of the play window, for `displace play --help` (demos/play.cpp acts on them).
constexpr const char* play_keys = R"(Keys:
  M / Shift+M      next / previous method (those the scene's surface supports)
  Up / Down        search steps x2 / /2
  Right / Left     frame budget up / down (unlimited, 100 .. 1 ms, 0: the bake's share is what is left);
                   a scene without a budget starts at 33 ms (with --frames: the scene's, deterministic)
  Space            pause / resume
  N                one frame forward (while paused)
  L / Shift+L      cone maps made over one frame more / fewer (lagged maps, 0 .. 64, with a budget;
                   the title shows their age and how far their apexes were raised)
  S                screenshot: play_NNNNNN.png (the frame index) in the working directory (the picture
                   without the overlay)
  H                hide / show the overlay: stage times, budget, texels waiting, cone maps' age, and
                   controls for method, steps, budget, lag, backends, foam and the ocean loop
  R                camera back to the scene's
  Esc / Q          quit
  mouse drag       orbit the camera around its look-at point; wheel: closer / farther)";

}  // namespace

pipeline::Scene play_scene(const PlaySettings& settings) {
  pipeline::Scene scene = settings.scene;
  // Interactive play is real time: a scene that sets neither a frame budget nor a work limit (every
  // built-in one) starts at interactive_budget_ms a frame, not at an unlimited bake (a 256 x 256
  // ocean's unlimited bake is about 0.33 s, three frames a second). With --frames the scene's
  // budget stays, so that the frames are the deterministic ones `displace sequence` renders.
  if (settings.frames <= 0 && !std::isfinite(scene.frame_ms) && scene.bake_work < 0) {
    scene.frame_ms = interactive_budget_ms;
  }
  return scene;
}

Finish add_play_command(CLI::App& command) {
  command.description(
      "The frame pipeline's scene animated in a window (GLFW, a Vulkan swapchain). An overlay (Dear ImGui; "
      "H hides it) graphs the frame time's split (sim, bake, upload, render) against the budget, the "
      "texels left to refine and the cone maps' age, with controls for the scene; the title and the "
      "terminal show the same figures (docs/play-overlay.png). Needs a display: without one, run it under "
      "'xvfb-run -a'.");
  command.footer(play_keys);
  struct Draft {
    cli::SceneFlags scene;
    PlaySettings settings;
    std::string screenshot;
    std::string window_shot;
    bool no_overlay = false;
  };
  auto draft = std::make_shared<Draft>();
  cli::add_scene_flags(command, draft->scene, cli::scene_all, "water");
  command.option_defaults()->group("Window");
  cli::add_value(command, "--frames", draft->settings.frames,
                 "render exactly N fixed-step frames (scene time start + n / fps), then exit", "N",
                 cli::integer_in(1, 1000000000));
  cli::add_value(command, "--screenshot", draft->screenshot,
                 "with --frames: write the last frame (the scene's picture, without the overlay)", "F.png",
                 cli::output_file({".png"}));
  cli::add_value(command, "--window-shot", draft->window_shot,
                 "with --frames: write the last frame as the window shows it (overlay included)", "F.png",
                 cli::output_file({".png"}));
  cli::add_switch(command, "--no-overlay", draft->no_overlay, "start with the overlay hidden (H shows it)");
  cli::add_switch(command, "--vsync", draft->settings.vsync,
                  "present at the display's rate (default: as fast as frames come)");
  cli::add_switch(
      command, "--pin-threads", draft->settings.pin_threads,
      "run TBB's threads and lavapipe's rasterizer threads one per CPU (Linux): steadier frame times");
  cli::add_renderer_flags(command, draft->settings.renderer);
  return [&command, draft] {
    PlaySettings settings = draft->settings;
    settings.scene = cli::finish_scene(command, draft->scene);
    if (cli::given(command, "--cone-lag") && cli::given(command, "--frames")) {
      throw usage_error("--cone-lag applies to real-time play, not --frames (its frames are deterministic)");
    }
    if (cli::given(command, "--screenshot")) {
      if (!cli::given(command, "--frames")) {
        throw usage_error("--screenshot needs --frames N (in the window, S writes a screenshot)");
      }
      settings.screenshot = draft->screenshot;
    }
    if (cli::given(command, "--window-shot")) {
      if (!cli::given(command, "--frames")) throw usage_error("--window-shot needs --frames N");
      settings.window_shot = draft->window_shot;
    }
    settings.overlay = !draft->no_overlay;
    cli::finish_renderer(settings.renderer);
    return ParsedCommand{"play", settings, [settings](std::ostream& out) { run_play(settings, out); }};
  };
}

}  // namespace displace::app
