// demos/play.cpp - `displace play` (play.h): a GLFW window, the frame pipeline, the swapchain.
//
// The one fact to know: the loop is a sequence of named steps - poll input (Controls), remake the
// pipeline when a key or the overlay changed the scene, run one frame (FramePipeline::run,
// output_none), lay out the overlay (PlayOverlay), present it (a blit on the device, the overlay drawn
// over it in the swapchain image), report - and a frame is read back only for a screenshot, which
// is the renderer's picture without the overlay.
#define GLFW_INCLUDE_VULKAN
#include "demos/play.h"

#include <GLFW/glfw3.h>
#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <memory>
#include <optional>
#include <ostream>
#include <string>

#include "demos/error.h"
#include "demos/heights.h"
#include "demos/image_io.h"
#include "demos/memory.h"
#include "demos/play_controls.h"
#include "demos/play_overlay.h"
#include "pipeline/frame_pipeline.h"
#include "pipeline/thread_pinning.h"
#include "render/render.h"

namespace displace::app {
namespace {

constexpr double status_period_seconds = 1.0;  // terminal and title updates
// frames before nothing is allocated any more: every frame slot has made its targets and readback
// buffers, and the staging ring's parts have grown to a frame's uploads (frame 0's are smaller)
constexpr long long warm_up_frames = render::frames_in_flight + 1;
constexpr float orbit_radians_per_pixel = 0.005f;  // mouse drag
constexpr float zoom_per_wheel_step = 0.9f;        // distance factor per wheel step

double now_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

std::string budget_text(double milliseconds) {
  return std::isfinite(milliseconds) ? fmt::format("{:g} ms", milliseconds) : std::string("unlimited");
}

// glfwInit / glfwTerminate.
class Glfw {
 public:
  Glfw() {
    const char* x11 = std::getenv("DISPLAY");
    const char* wayland = std::getenv("WAYLAND_DISPLAY");
    if ((!x11 || !*x11) && (!wayland || !*wayland)) throw runtime_error(no_display_message);
    glfwSetErrorCallback(nullptr);
    if (glfwInit() != GLFW_TRUE) throw runtime_error(no_display_message);
    if (glfwVulkanSupported() != GLFW_TRUE) {
      glfwTerminate();
      throw runtime_error("the window system finds no Vulkan loader with surface support (libvulkan1)");
    }
  }
  ~Glfw() { glfwTerminate(); }
  Glfw(const Glfw&) = delete;
  Glfw& operator=(const Glfw&) = delete;

  // What a surface for GLFW's windows needs on the instance.
  std::vector<std::string> instance_extensions() const {
    std::uint32_t count = 0;
    const char** names = glfwGetRequiredInstanceExtensions(&count);
    if (!names) throw runtime_error("the window system names no Vulkan surface extensions");
    return {names, names + count};
  }
};

void on_key(GLFWwindow* window, int key, int, int action, int mods) {
  if (action != GLFW_PRESS && action != GLFW_REPEAT) return;
  auto& controls = *static_cast<Controls*>(glfwGetWindowUserPointer(window));
  if (controls.typing_in_overlay) return;
  const bool shift = mods & GLFW_MOD_SHIFT;
  switch (key) {
    case GLFW_KEY_M: controls.method_delta += shift ? -1 : 1; break;
    case GLFW_KEY_UP: controls.steps_factor = 1; break;
    case GLFW_KEY_DOWN: controls.steps_factor = -1; break;
    case GLFW_KEY_RIGHT: controls.budget_delta += 1; break;
    case GLFW_KEY_LEFT: controls.budget_delta -= 1; break;
    case GLFW_KEY_L: controls.lag_delta += shift ? -1 : 1; break;
    case GLFW_KEY_SPACE: controls.paused = !controls.paused; break;
    case GLFW_KEY_N: controls.step = true; break;
    case GLFW_KEY_S: controls.screenshot = true; break;
    case GLFW_KEY_H: controls.overlay_shown = !controls.overlay_shown; break;
    case GLFW_KEY_R:
      controls.yaw = controls.pitch = 0.0f;
      controls.zoom = 1.0f;
      controls.orbited = false;
      controls.camera_moved = true;
      break;
    case GLFW_KEY_ESCAPE:
    case GLFW_KEY_Q: glfwSetWindowShouldClose(window, GLFW_TRUE); break;
    default: break;
  }
}

void on_mouse_button(GLFWwindow* window, int button, int action, int) {
  auto& controls = *static_cast<Controls*>(glfwGetWindowUserPointer(window));
  if (button != GLFW_MOUSE_BUTTON_LEFT) return;
  if (action == GLFW_PRESS && controls.pointer_on_overlay) return;  // a click on the overlay's controls
  controls.dragging = action == GLFW_PRESS;
  glfwGetCursorPos(window, &controls.last_x, &controls.last_y);
}

void on_cursor(GLFWwindow* window, double x, double y) {
  auto& controls = *static_cast<Controls*>(glfwGetWindowUserPointer(window));
  if (!controls.dragging) return;
  controls.yaw -= float(x - controls.last_x) * orbit_radians_per_pixel;
  controls.pitch += float(y - controls.last_y) * orbit_radians_per_pixel;
  controls.last_x = x;
  controls.last_y = y;
  controls.orbited = true;
  controls.camera_moved = true;
}

void on_scroll(GLFWwindow* window, double, double y_offset) {
  auto& controls = *static_cast<Controls*>(glfwGetWindowUserPointer(window));
  if (controls.pointer_on_overlay) return;
  controls.zoom = std::clamp(controls.zoom * std::pow(zoom_per_wheel_step, float(y_offset)), 0.05f, 20.0f);
  controls.orbited = true;
  controls.camera_moved = true;
}

// The GLFW window (no client API: Vulkan presents into it).
class Window {
 public:
  Window(int width, int height, const std::string& title, Controls& controls) {
    glfwWindowHint(GLFW_CLIENT_API, GLFW_NO_API);
    glfwWindowHint(GLFW_RESIZABLE, GLFW_TRUE);
    window_ = glfwCreateWindow(width, height, title.c_str(), nullptr, nullptr);
    if (!window_) throw runtime_error(no_display_message);
    glfwSetWindowUserPointer(window_, &controls);
    glfwSetKeyCallback(window_, on_key);
    glfwSetMouseButtonCallback(window_, on_mouse_button);
    glfwSetCursorPosCallback(window_, on_cursor);
    glfwSetScrollCallback(window_, on_scroll);
  }
  ~Window() { glfwDestroyWindow(window_); }
  Window(const Window&) = delete;
  Window& operator=(const Window&) = delete;
  GLFWwindow* get() const { return window_; }

 private:
  GLFWwindow* window_ = nullptr;
};

std::string status_text(const pipeline::Scene& scene, const pipeline::FrameRecord& record,
                        double frames_per_second, bool paused) {
  return fmt::format(
      "{} {} {} steps | frame {} t {:.2f} s | {:.1f} ms ({:.0f} fps): sim {:.1f} bake {:.1f} upload {:.1f} "
      "render {:.1f}{} | budget {} (bake {}) | pending {}{}{}",
      scene.name, render::method_info(scene.method).name, scene.steps, record.index, record.time,
      record.frame_ms, frames_per_second, record.sim_ms, record.bake_ms, record.upload_ms, record.render_ms,
      record.sim_on_device || record.bake_on_device
          ? fmt::format(" | device: sim {:.2f} bake {:.2f} render {:.2f}", record.sim_device_ms,
                        record.bake_device_ms, record.render_device_ms)
          : std::string(),
      budget_text(scene.frame_ms), budget_text(record.bake_budget_ms), record.pending,
      record.cone_lag > 0 ? fmt::format(" | cones {} frames old, +{:.3f}", record.cone_lag, record.cone_lift)
                          : "",
      paused ? " | paused" : "");
}

void write_screenshot(const std::filesystem::path& file, const render::Frame& frame,
                      const pipeline::Scene& scene, const pipeline::FrameRecord& record) {
  Metadata metadata;
  metadata.push_back({"displace:scene", scene.name});
  metadata.push_back({"displace:method", render::method_info(scene.method).name});
  metadata.push_back({"displace:frame", int(record.index)});
  metadata.push_back({"displace:time", fmt::format("{}", record.time)});
  write_png_rgba8(file, frame.width, frame.height, frame.color, metadata);
}

// The renderer's options with what presenting to a GLFW window needs.
render::RendererOptions presenting_options(const PlaySettings& settings, const Glfw& glfw) {
  render::RendererOptions options = settings.renderer;
  options.instance_extensions = glfw.instance_extensions();
  options.can_present = [](VkInstance instance, VkPhysicalDevice device, std::uint32_t family) {
    return glfwGetPhysicalDevicePresentationSupport(instance, device, family) == GLFW_TRUE;
  };
  return options;
}

// The window's Vulkan surface, made when the swapchain asks for it.
render::SurfaceFactory window_surface(GLFWwindow* window) {
  return [window](VkInstance instance) {
    VkSurfaceKHR surface = VK_NULL_HANDLE;
    const VkResult result = glfwCreateWindowSurface(instance, window, nullptr, &surface);
    if (result != VK_SUCCESS) {
      throw runtime_error(fmt::format("glfwCreateWindowSurface failed with VkResult {}", int(result)));
    }
    return surface;
  };
}

using PipelinePointer = std::unique_ptr<pipeline::FramePipeline>;

PipelinePointer make_pipeline(const pipeline::Scene& scene, render::Renderer& renderer) {
  return std::make_unique<pipeline::FramePipeline>(scene, renderer, std::function<double()>{},
                                                   height_loader(scene.image_read), albedo_loader());
}

// The scene the keys or the overlay asked for, with its pipeline; a scene that cannot run (a
// backend the device lacks) leaves the current one, and the overlay says why.
void change_scene(pipeline::Scene& scene, const pipeline::Scene& wanted, render::Renderer& renderer,
                  PipelinePointer& pipeline, PlayOverlay& overlay) {
  renderer.wait_idle();
  pipeline.reset();
  try {
    pipeline = make_pipeline(wanted, renderer);
    scene = wanted;
    overlay.set_message({});
  } catch (const pipeline::SceneError& error) {
    overlay.set_message(std::string("not changed: ") + error.what());
  } catch (const render::RenderError& error) {
    overlay.set_message(std::string("not changed: ") + error.what());
  }
  if (!pipeline) pipeline = make_pipeline(scene, renderer);
}

// The last line: frames shown, the device allocations after the warm-up, the screenshot.
void print_play_summary(std::ostream& out, const PlaySettings& settings, const pipeline::Scene& scene,
                        long long frames_shown, const pipeline::FrameRecord& record,
                        long long warm_allocations, long long settled_allocations) {
  out << fmt::format("play: {} frames of {} ({}x{}, map {}), last at t {:.4f} s", frames_shown, scene.name,
                     scene.camera.width, scene.camera.height, scene.map_size, record.time);
  if (warm_allocations >= 0 && settled_allocations >= 0 && frames_shown - 2 >= warm_up_frames) {
    out << fmt::format(", {} device allocations in frames {}..{}", settled_allocations - warm_allocations,
                       warm_up_frames, frames_shown - 2);
  }
  out << (settings.screenshot.empty() ? std::string() : ", screenshot " + settings.screenshot.string())
      << (settings.window_shot.empty() ? std::string() : ", window " + settings.window_shot.string()) << '\n';
}

}  // namespace

void run_play(const PlaySettings& settings, std::ostream& out) {
  pipeline::Scene scene = play_scene(settings);
  const bool fixed = settings.frames > 0;
  const bool terminal = ::isatty(STDOUT_FILENO);

  // window system, renderer (able to present), window, swapchain - destroyed in reverse
  Glfw glfw;
  render::Renderer renderer(presenting_options(settings, glfw));
  require_memory(pipeline_memory(scene), renderer.memory_limits());
  load_scene_mesh(renderer, scene);
  Controls controls;
  Window window(scene.camera.width, scene.camera.height, "displace play", controls);
  int framebuffer_width = 0, framebuffer_height = 0;
  glfwGetFramebufferSize(window.get(), &framebuffer_width, &framebuffer_height);
  render::Swapchain swapchain(renderer, window_surface(window.get()), framebuffer_width, framebuffer_height,
                              settings.vsync);
  PlayOverlay overlay(window.get(), swapchain);  // after the window's callbacks: it chains them
  controls.overlay_shown = settings.overlay;

  PipelinePointer pipeline = make_pipeline(scene, renderer);
  // after the renderer and the swapchain: lavapipe's rasterizer threads exist now
  std::optional<pipeline::ThreadPinning> pinning;
  if (settings.pin_threads) pinning.emplace();
  render::Frame frame;
  render::Frame window_picture;  // --window-shot: the last frame as presented
  pipeline::FrameRecord record;
  std::optional<pipeline::Scene> overlay_asked;  // the scene the overlay's controls asked for
  long long index = 0;                           // the next frame
  bool have_frame = false;
  double status_time = now_seconds();
  long long status_frames = 0;
  double frames_per_second = 0.0;
  // vkAllocateMemory calls after the warm-up frames, and before the last frame (its readback buffer)
  long long warm_allocations = -1, settled_allocations = -1;

  while (!glfwWindowShouldClose(window.get())) {
    glfwPollEvents();
    if (fixed && index >= settings.frames) break;

    // keys or controls that change the scene: the pipeline is made again (its maps and budget follow
    // the scene)
    if (!fixed) {
      pipeline::Scene wanted = overlay_asked ? *overlay_asked : scene;
      const bool keys_changed = apply_scene_keys(controls, wanted);
      if (keys_changed || overlay_asked) {
        change_scene(scene, wanted, renderer, pipeline, overlay);
        have_frame = false;
      }
      overlay_asked.reset();
    }

    // one frame: the next one, or the shown one again (paused, the camera moved or a screenshot)
    const bool advance = fixed || !controls.paused || controls.step || !have_frame;
    const long long shown = advance ? index : std::max(index - 1, 0LL);
    const bool last = fixed && shown == settings.frames - 1;
    const bool read_back = (last && !settings.screenshot.empty()) || controls.screenshot;
    const bool redraw = advance || read_back || controls.camera_moved;
    glfwGetFramebufferSize(window.get(), &framebuffer_width, &framebuffer_height);
    if (redraw) {
      render::View view =
          orbit_view(pipeline::scene_view(scene, pipeline::frame_time(scene, shown)), controls);
      if (!fixed && framebuffer_width > 0 && framebuffer_height > 0) {
        // the picture follows the window (with --frames it keeps --size: the frames are fixed)
        view.camera.width = framebuffer_width;
        view.camera.height = framebuffer_height;
      }
      if (last)
        settled_allocations = renderer.memory_allocations();  // before the screenshot's readback buffer
      record = pipeline->run(shown, view, frame, read_back ? render::output_color : render::output_none);
      overlay.add(record);
      have_frame = true;
      if (advance) index = shown + 1;
      if (fixed && index == warm_up_frames) warm_allocations = renderer.memory_allocations();
      controls.step = false;
      controls.camera_moved = false;
      ++status_frames;
    }
    if (read_back && controls.screenshot) {
      const std::filesystem::path file = fmt::format("play_{:06d}.png", record.index);
      write_screenshot(file, frame, scene, record);
      out << (terminal ? "\r\033[K" : "") << "screenshot: " << file.string() << '\n';
      controls.screenshot = false;
    }
    if (last && !settings.screenshot.empty()) write_screenshot(settings.screenshot, frame, scene, record);

    overlay_asked = overlay.build(scene, record, frames_per_second, controls.overlay_shown, !fixed);
    controls.pointer_on_overlay = overlay.wants_pointer();
    controls.typing_in_overlay = overlay.wants_keys();
    const bool window_shot = last && !settings.window_shot.empty();
    const bool presented =
        swapchain.present(framebuffer_width, framebuffer_height, window_shot ? &window_picture : nullptr);
    if (window_shot) {
      if (!presented) throw runtime_error("the window did not show the last frame: no --window-shot written");
      write_screenshot(settings.window_shot, window_picture, scene, record);
    }

    // report: the title and the terminal, once a second
    const double now = now_seconds();
    if (now - status_time >= status_period_seconds || last) {
      frames_per_second = double(status_frames) / std::max(now - status_time, 1e-9);
      status_time = now;
      status_frames = 0;
      const std::string text = status_text(scene, record, frames_per_second, controls.paused);
      glfwSetWindowTitle(window.get(), ("displace play | " + text).c_str());
      out << (terminal ? "\r\033[K" : "") << text << (terminal ? "" : "\n") << std::flush;
    }
    if (!redraw) glfwWaitEventsTimeout(0.05);  // paused and still: no busy loop
  }
  renderer.wait_idle();
  if (terminal) out << '\n';
  if (fixed && index < settings.frames) {
    throw runtime_error(
        fmt::format("the window was closed after {} of the {} frames asked for", index, settings.frames));
  }
  require_no_validation_messages(settings.renderer.validate, renderer.validation_messages());
  print_play_summary(out, settings, scene, index, record, warm_allocations, settled_allocations);
}

}  // namespace displace::app
