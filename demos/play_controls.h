// demos/play_controls.h - what the keys and the mouse of `displace play` do to its scene and view,
// apart from the window system (demos/play.cpp turns GLFW's events into Controls).
#pragma once

#include <array>
#include <limits>
#include <vector>

#include "pipeline/scene.h"
#include "render/render.h"

namespace displace::app {

inline constexpr int max_play_steps = render::max_steps;  // Up doubles the steps up to here
// the frame budgets the Right / Left keys (and the overlay) step through (ms; infinity: unlimited)
inline constexpr std::array<double, 10> budget_levels = {
    0.0, 1.0, 2.0, 4.0, 8.0, 16.0, 33.0, 50.0, 100.0, std::numeric_limits<double>::infinity()};

// The user's input between frames.
struct Controls {
  bool paused = false;
  bool step = false;          // one frame forward while paused
  bool screenshot = false;    // read the next frame back and write it
  int method_delta = 0;       // methods to move by in the table
  int steps_factor = 0;       // +1: double, -1: halve
  int budget_delta = 0;       // budget levels to move by
  int lag_delta = 0;          // frames to add to the cone maps' lag
  bool camera_moved = false;  // draw the shown frame again (while paused)
  bool dragging = false;
  double last_x = 0.0, last_y = 0.0;
  float yaw = 0.0f, pitch = 0.0f;   // radians added to the scene camera's azimuth and elevation
  float zoom = 1.0f;                // factor on its distance
  bool orbited = false;             // the camera is not the scene's
  bool overlay_shown = true;        // H: the overlay (demos/play_overlay.h) over the picture
  bool pointer_on_overlay = false;  // the mouse is over the overlay: it gets clicks and the wheel
  bool typing_in_overlay = false;   // a field of the overlay takes the keys
};

// The methods M cycles through: those `surface` supports, in the table's order.
std::vector<const render::MethodInfo*> play_methods(render::Surface surface);

// The scene camera turned by the orbit controls around its look-at point.
render::View orbit_view(render::View view, const Controls& controls);
// Applies the keys that change the scene (method, steps, budget, lag) and clears them; true when the
// pipeline must be made again.
bool apply_scene_keys(Controls& controls, pipeline::Scene& scene);

}  // namespace displace::app
