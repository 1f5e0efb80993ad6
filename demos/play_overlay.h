// demos/play_overlay.h - the overlay of `displace play`: Dear ImGui over the picture in the window.
//
// It shows the frame pipeline's stage times as rolling graphs (sim, bake, upload, render, frame, and
// the device's times when a stage runs there) against the frame budget, the texels waiting for
// refinement and the cone maps' age and lift, with controls for the scene's method, steps, budget,
// cone lag, backends, foam and ocean loop. It draws through render::Swapchain::Overlay, into the
// swapchain image only: the renderer's colour target (screenshots, `displace sequence`) never sees
// it. Only this file's .cpp and demos/play.cpp include Dear ImGui and GLFW.
#pragma once

#include <memory>
#include <optional>
#include <string>

#include "pipeline/frame_pipeline.h"
#include "pipeline/scene.h"
#include "render/render.h"

struct GLFWwindow;

namespace displace::app {

inline constexpr int overlay_history_frames = 240;  // frames the rolling graphs show

class PlayOverlay {
 public:
  // Starts Dear ImGui on the window (its GLFW callbacks chained before the window's own, which must
  // be installed already) and on the swapchain, which must outlive the overlay. Throws AppError
  // when a Vulkan object cannot be made.
  PlayOverlay(GLFWwindow* window, render::Swapchain& swapchain);
  ~PlayOverlay();  // waits for the device, then stops Dear ImGui
  PlayOverlay(const PlayOverlay&) = delete;
  PlayOverlay& operator=(const PlayOverlay&) = delete;

  // A frame made anew: its times join the graphs.
  void add(const pipeline::FrameRecord& record);
  // A message shown under the controls until the next one (e.g. a scene they asked for that failed).
  void set_message(std::string message);

  // Lays out this frame's overlay (shown: drawn by the next present; hidden: nothing is drawn).
  // `live`: the controls may change the scene (with --frames they are shown disabled). Returns the
  // scene the controls asked for, when they changed it.
  std::optional<pipeline::Scene> build(const pipeline::Scene& scene, const pipeline::FrameRecord& record,
                                       double frames_per_second, bool shown, bool live);

  // After build(): whether the mouse is over the overlay, and whether one of its fields takes the keys.
  bool wants_pointer() const;
  bool wants_keys() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace displace::app
