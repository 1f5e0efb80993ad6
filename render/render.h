// render/render.h - the Vulkan renderer: every per-pixel displacement method of
// render/shaders/methods.inc.glsl, side by side with a true-displacement reference, on the same camera
// and the same shading, so that differences in the pictures come only from the hit points.
//
// A Renderer owns the instance, the device and the per-frame resources; set_maps hands it the maps a
// frame samples (render/map_set.h), render() draws a View (render/view.h) with one method and reads back
// the outputs asked for, a Swapchain presents its frames in a window. The memory guards
// (render/memory.h) refuse work that cannot fit before it starts; render/reference.h holds the exact
// CPU answers the pictures are checked against. This header includes them all.
#pragma once

#include <vulkan/vulkan_core.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "render/map_set.h"
#include "render/memory.h"
#include "render/mesh.h"
#include "render/reference.h"
#include "render/view.h"
#include "vulkan/device_info.h"

namespace displace::vulkan {
class Frames;
}

namespace displace::render {

struct RendererOptions {
  // Empty: the best device (a discrete GPU, else an integrated one, else any, else the CPU driver).
  // Otherwise a device index or a case-insensitive part of its name.
  std::string device;
  bool validate = false;  // Khronos validation layer; every message is printed and counted
  // Where the VkPipelineCache is kept between runs: a directory; empty for the default
  // (default_pipeline_cache_dir()); "off" for none.
  std::string pipeline_cache;
  // Instance extensions a window system needs to make a surface (glfwGetRequiredInstanceExtensions).
  // Non-empty: the renderer can present (Swapchain): the device also gets VK_KHR_swapchain, and only
  // devices that have it are chosen.
  std::vector<std::string> instance_extensions;
  // With instance_extensions: whether a device's queue family can present to the caller's window
  // system (glfwGetPhysicalDevicePresentationSupport), asked before any surface exists, so that a
  // device that cannot show the window (a GPU under Xvfb) is passed over. Empty: not asked.
  std::function<bool(VkInstance, VkPhysicalDevice, std::uint32_t queue_family)> can_present;
  // Bytes of memory the guards may count on, host and device alike, when below what the machine has
  // (memory_limits()); 0: what the machine has. `memory_limit_source` names where it came from in
  // the guards' messages ("DISPLACE_MEMORY_LIMIT_MB").
  std::uint64_t memory_limit = 0;
  std::string memory_limit_source;
  // On the CPU driver (lavapipe), whose device memory is the host's: heights, foam and cone maps
  // are written by the host straight into linear images, with no staging copy (the renderer then
  // waits for frames in flight before it writes a map). Off: every map goes through the staging ring
  // and a device copy, as on a discrete GPU (the tests compare the two).
  bool host_written_maps = true;
  // The device path's lagged cone bands (DeviceCones::bake_lagged) on a queue of a compute-only
  // family where the device has one, so that a GPU runs them beside the frame's draw; off, or where
  // there is none (lavapipe), they go to the frame's own queue. The same submissions and waits either way.
  bool async_compute = true;
};

// $DISPLACE_PIPELINE_CACHE when set ("off" turns the cache off), else $XDG_CACHE_HOME/displace,
// else $HOME/.cache/displace; "off" when none of them is set.
std::string default_pipeline_cache_dir();

// Devices the Vulkan loader sees, and the one a Renderer made with default RendererOptions draws on
// (vulkan/device_info.h). Both throw RenderError (saying what to install) when there is none.
using vulkan::default_device;
using vulkan::DeviceInfo;
using vulkan::list_devices;

class Renderer {
 public:
  // Creates the instance, device, layouts, render pass and the per-frame resources once, and loads
  // the pipeline cache (RendererOptions::pipeline_cache).
  explicit Renderer(const RendererOptions& options = {});
  ~Renderer();  // waits for the frames in flight; saves the pipeline cache
  Renderer(Renderer&&) noexcept;
  Renderer& operator=(Renderer&&) noexcept;

  const DeviceInfo& device() const;

  // Hands over the maps (validated: sizes, finite heights in [0, 1]) and records the copies of what
  // changed into the next frame (MapSet's versions and dirty rectangles). Device images and buffers
  // are kept per map and made again only when a size changes; the staging memory is a ring, one
  // part per frame in flight. Throws RenderError for a map it cannot take.
  void set_maps(const MapSet& maps);

  // The albedo the hit is shaded with, sampled at the hit's texture coordinates (bilinear, the
  // view's address mode, repeated with the tile); its 8-bit values are used as they are (no sRGB
  // decoding). Until one is set, and after clear_albedo, a procedural grid shows the errors.
  void set_albedo(const Albedo& albedo);
  void clear_albedo();

  // The base mesh for Surface::mesh (render/mesh.h): its tangent frames and curvature are computed
  // here; throws RenderError when the mesh cannot carry a relief (see mesh_vertices).
  void set_mesh(const Mesh& mesh);

  // Renders one frame from the maps last set; a method whose maps were not given is refused with a
  // RenderError naming the map. Pipelines are made once per method and surface (through the
  // pipeline cache). `frame`'s vectors are reused (resized, not reallocated once large enough);
  // only `outputs` are read back, and with output_none the frame is not waited for.
  void render(const View& view, const MethodSettings& method, Frame& frame, unsigned outputs = output_all);
  Frame render(const View& view, const MethodSettings& method, unsigned outputs = output_all);

  // Waits until every submitted frame has finished.
  void wait_idle();

  // Validation messages seen so far (only counted with options.validate).
  long long validation_messages() const;
  // vkAllocateMemory calls so far: after warm-up frames of the same sizes, a frame allocates none.
  long long memory_allocations() const;
  // Graphics pipelines created so far (each method and surface once per renderer).
  long long pipelines_created() const;
  // Whether the height map given last is written by the host into device memory (no staging copy).
  bool host_written_maps() const;
  // The memory this renderer's device and the host offer now (RendererOptions::memory_limit applied).
  MemoryLimits memory_limits() const;

  // The device and its frames in flight, which the device stages (sim/device, bake/device) record
  // into ahead of this renderer's draw.
  vulkan::Frames& frames();

  // The last frame's colour target, for a presenter that blits it on this renderer's queue after
  // that frame (Swapchain): TRANSFER_SRC_OPTIMAL after every frame; a null image before the first.
  // Valid until a frame of another size.
  struct ColorTarget {
    VkImage image = VK_NULL_HANDLE;
    int width = 0, height = 0;
  };
  ColorTarget color_target() const;

  struct Impl;  // render/'s own (renderer_impl.h, not installed)

 private:
  std::unique_ptr<Impl> impl_;
};

// ---- Presenting: a window's swapchain, fed on the device from the renderer's colour target.
//
// render/ knows no window system: the caller makes the surface for the renderer's instance (the
// callback, e.g. glfwCreateWindowSurface) and the Swapchain owns it from then on. present() blits the
// colour target of the renderer's last frame (rendered with output_none: nothing is read back) into
// the next swapchain image on the same queue, after that frame. Out-of-date or suboptimal swapchains
// and size changes are handled by making the swapchain again; after the first frames of a size,
// present() allocates nothing.
using SurfaceFactory = std::function<VkSurfaceKHR(VkInstance instance)>;

class Swapchain {
 public:
  // `renderer` (made with RendererOptions::instance_extensions) must outlive the swapchain. Throws
  // RenderError when the device cannot present to the surface. vsync: FIFO; otherwise MAILBOX or
  // IMMEDIATE when offered (FIFO when not).
  Swapchain(Renderer& renderer, const SurfaceFactory& make_surface, int width, int height,
            bool vsync = false);
  ~Swapchain();  // waits for the presents in flight
  Swapchain(Swapchain&&) noexcept;
  Swapchain& operator=(Swapchain&&) noexcept;

  // Presents the renderer's last frame in a window of `width` x `height` pixels (the framebuffer
  // size now; the picture is scaled when its size differs). Returns false when nothing was shown:
  // a zero-sized (minimized) window, or a swapchain that went out of date (made again for the next
  // call).
  // With `shown`, the window's picture as presented (overlay included) is also copied back into its
  // width, height and color (RGBA8, top row first) when present() returns true, waited for; the
  // copy's buffer is allocated for the first such call of a swapchain size.
  bool present(int width, int height, Frame* shown = nullptr);
  int width() const;  // of the swapchain images
  int height() const;

  // An overlay drawn over the picture in the window by the caller's own Vulkan code (a GUI). After
  // the blit, present() records `prepare` outside any render pass (the overlay's uploads), then
  // begins overlay_render_pass over the swapchain image (the blitted picture loaded, colour
  // attachment optimal), records `draw` inside it and ends it. Both record into present()'s command
  // buffer on its thread; what they use must live until that present has finished (at most
  // frames_in_flight are in flight). An empty `draw` (the default) records no overlay pass. The
  // callbacks are only called inside present(): replacing them waits for nothing.
  struct Overlay {
    std::function<void(VkCommandBuffer commands)> prepare;
    std::function<void(VkCommandBuffer commands)> draw;
  };
  void set_overlay(Overlay overlay) noexcept;
  // What the overlay's code needs to make its own objects (Dear ImGui's ImGui_ImplVulkan_InitInfo).
  // render/ does not count those objects' memory; the queue is the renderer's: submit nothing to it
  // while a frame is being rendered or presented on another thread.
  struct Handles {
    VkInstance instance = VK_NULL_HANDLE;
    VkPhysicalDevice physical_device = VK_NULL_HANDLE;
    VkDevice device = VK_NULL_HANDLE;
    std::uint32_t queue_family = 0;
    VkQueue queue = VK_NULL_HANDLE;
    VkRenderPass overlay_render_pass = VK_NULL_HANDLE;  // one colour attachment of the swapchain's format
    std::uint32_t present_slots = frames_in_flight;     // presents in flight: buffers the overlay rotates
  };
  Handles handles() const;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace displace::render
