// render/swapchain.cpp - presenting the renderer's frames in a window (render.h, Swapchain).
//
// The one fact to know: the picture never leaves the device. present() records a blit from the
// renderer's colour target (TRANSFER_SRC_OPTIMAL after every frame) into the acquired swapchain image
// and submits it on the renderer's queue after the frame; the render pass's external dependencies
// (colour writes -> transfer reads, transfer reads -> the next frame's writes) order the two. An
// overlay (Swapchain::Overlay) is drawn in a render pass of its own over the blitted image, between
// explicit barriers (transfer write -> colour attachment -> present or the shown picture's copy).
#include <algorithm>
#include <array>
#include <limits>
#include <utility>
#include <vector>

#include "render/renderer_impl.h"

namespace displace::render {
namespace {

constexpr std::uint64_t no_timeout = std::numeric_limits<std::uint64_t>::max();

// 8-bit UNORM formats only: the renderer's bytes are shown as they are (no sRGB encoding on top).
constexpr std::array<VkFormat, 2> wanted_formats = {VK_FORMAT_B8G8R8A8_UNORM, VK_FORMAT_R8G8B8A8_UNORM};

using OwnedImageView = Owned<VkImageView, vkDestroyImageView>;

// The overlay's render pass: one colour attachment, its picture loaded and kept, in
// COLOR_ATTACHMENT_OPTIMAL before and after (the barriers around the pass move it).
VkRenderPass create_overlay_pass(VkDevice device, VkFormat format) {
  VkAttachmentDescription attachment{};
  attachment.format = format;
  attachment.samples = VK_SAMPLE_COUNT_1_BIT;
  attachment.loadOp = VK_ATTACHMENT_LOAD_OP_LOAD;
  attachment.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
  attachment.stencilLoadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE;
  attachment.stencilStoreOp = VK_ATTACHMENT_STORE_OP_DONT_CARE;
  attachment.initialLayout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL;
  attachment.finalLayout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL;
  VkAttachmentReference reference{0, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL};
  VkSubpassDescription subpass{};
  subpass.pipelineBindPoint = VK_PIPELINE_BIND_POINT_GRAPHICS;
  subpass.colorAttachmentCount = 1;
  subpass.pColorAttachments = &reference;
  VkRenderPassCreateInfo info{VK_STRUCTURE_TYPE_RENDER_PASS_CREATE_INFO};
  info.attachmentCount = 1;
  info.pAttachments = &attachment;
  info.subpassCount = 1;
  info.pSubpasses = &subpass;
  VkRenderPass pass = VK_NULL_HANDLE;
  DISPLACE_VK_CHECK(vkCreateRenderPass(device, &info, nullptr, &pass));
  return pass;
}

}  // namespace

struct Swapchain::Impl {
  // the caller's surface, destroyed last
  struct Surface {
    VkInstance instance = VK_NULL_HANDLE;
    VkSurfaceKHR handle = VK_NULL_HANDLE;
    ~Surface() {
      if (handle != VK_NULL_HANDLE) vkDestroySurfaceKHR(instance, handle, nullptr);
    }
  };
  // per present in flight: its command buffer, fence and acquire semaphore
  struct PresentSlot {
    VkCommandBuffer commands = VK_NULL_HANDLE;
    OwnedFence fence;  // signalled: the slot's blit has finished
    OwnedSemaphore acquired;
  };

  Impl(Renderer& r, const SurfaceFactory& make_surface, bool vsync_wanted);
  ~Impl();
  void recreate(int width, int height);
  void make_overlay_framebuffers();
  void record_overlay(VkCommandBuffer commands, std::uint32_t index);
  void record_shown_copy(VkCommandBuffer commands, VkImage image);
  void copy_shown(Frame& shown);
  bool present(int width, int height, Frame* shown);

  Renderer& renderer;
  const Context& context;
  Surface surface;
  bool vsync = false;
  VkSurfaceFormatKHR format{};
  VkPresentModeKHR present_mode = VK_PRESENT_MODE_FIFO_KHR;
  OwnedSwapchain swapchain;
  VkExtent2D extent{0, 0};
  int requested_width = 0, requested_height = 0;  // the window size the swapchain was made for
  bool stale = true;                              // out of date or suboptimal: make it again
  std::vector<VkImage> images;
  std::vector<OwnedSemaphore> blitted;  // per swapchain image: the present waits for its blit
  std::array<PresentSlot, frames_in_flight> slots;
  int slot = 0;
  VkImageUsageFlags usage = 0;  // of the swapchain images
  // the overlay: its pass (made once, for the format) and per swapchain image a view and framebuffer
  Swapchain::Overlay overlay;
  OwnedRenderPass overlay_pass;
  std::vector<OwnedImageView> views;
  std::vector<OwnedFramebuffer> framebuffers;
  Buffer shown_readback;  // present(..., shown): the presented picture, per swapchain size
};

Swapchain::Impl::Impl(Renderer& r, const SurfaceFactory& make_surface, bool vsync_wanted)
    : renderer(r), context(r.frames().context()), vsync(vsync_wanted) {
  const VkDevice device = context.device();
  surface.instance = context.instance();
  surface.handle = make_surface(context.instance());
  if (surface.handle == VK_NULL_HANDLE) throw RenderError("the window system made no Vulkan surface");

  VkBool32 supported = VK_FALSE;
  DISPLACE_VK_CHECK(vkGetPhysicalDeviceSurfaceSupportKHR(context.physical_device(), context.queue_family(),
                                                         surface.handle, &supported));
  if (!supported) {
    throw RenderError("device '" + context.info().name +
                      "' cannot present to this window (its graphics queue has no "
                      "present support); pick another with RendererOptions::device");
  }

  // surface format: an 8-bit UNORM one the blit can write
  std::uint32_t count = 0;
  DISPLACE_VK_CHECK(
      vkGetPhysicalDeviceSurfaceFormatsKHR(context.physical_device(), surface.handle, &count, nullptr));
  std::vector<VkSurfaceFormatKHR> formats(count);
  DISPLACE_VK_CHECK(vkGetPhysicalDeviceSurfaceFormatsKHR(context.physical_device(), surface.handle, &count,
                                                         formats.data()));
  bool found = false;
  for (VkFormat wanted : wanted_formats) {
    for (const VkSurfaceFormatKHR& offered : formats) {
      VkFormatProperties properties;
      vkGetPhysicalDeviceFormatProperties(context.physical_device(), offered.format, &properties);
      if (!found && offered.format == wanted &&
          (properties.optimalTilingFeatures & VK_FORMAT_FEATURE_BLIT_DST_BIT)) {
        format = offered;
        found = true;
      }
    }
  }
  if (!found)
    throw RenderError("the window offers no 8-bit UNORM (B8G8R8A8 or R8G8B8A8) swapchain format to blit to");

  // present mode: FIFO always exists; without vsync take mailbox, else immediate, when offered
  DISPLACE_VK_CHECK(
      vkGetPhysicalDeviceSurfacePresentModesKHR(context.physical_device(), surface.handle, &count, nullptr));
  std::vector<VkPresentModeKHR> modes(count);
  DISPLACE_VK_CHECK(vkGetPhysicalDeviceSurfacePresentModesKHR(context.physical_device(), surface.handle,
                                                              &count, modes.data()));
  present_mode = VK_PRESENT_MODE_FIFO_KHR;
  if (!vsync) {
    for (VkPresentModeKHR mode : {VK_PRESENT_MODE_IMMEDIATE_KHR, VK_PRESENT_MODE_MAILBOX_KHR}) {
      if (std::find(modes.begin(), modes.end(), mode) != modes.end()) present_mode = mode;
    }
  }

  overlay_pass = OwnedRenderPass(device, create_overlay_pass(device, format.format));

  for (PresentSlot& present_slot : slots) {
    present_slot.commands = context.allocate_command_buffer();
    present_slot.fence = OwnedFence(device, context.create_fence(true));
    VkSemaphoreCreateInfo semaphore_info{VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO};
    VkSemaphore semaphore = VK_NULL_HANDLE;
    DISPLACE_VK_CHECK(vkCreateSemaphore(device, &semaphore_info, nullptr, &semaphore));
    present_slot.acquired = OwnedSemaphore(device, semaphore);
  }
}

Swapchain::Impl::~Impl() {
  const VkDevice device = context.device();
  vkDeviceWaitIdle(device);  // the presents and blits in flight
  for (PresentSlot& present_slot : slots) {
    if (present_slot.commands)
      vkFreeCommandBuffers(device, context.command_pool(), 1, &present_slot.commands);
  }
}

void Swapchain::Impl::recreate(int width, int height) {
  const VkDevice device = context.device();
  DISPLACE_VK_CHECK(vkDeviceWaitIdle(device));
  VkSurfaceCapabilitiesKHR capabilities;
  DISPLACE_VK_CHECK(
      vkGetPhysicalDeviceSurfaceCapabilitiesKHR(context.physical_device(), surface.handle, &capabilities));
  if (!(capabilities.supportedUsageFlags & VK_IMAGE_USAGE_TRANSFER_DST_BIT)) {
    throw RenderError(
        "the window's swapchain images cannot be written by a transfer (no TRANSFER_DST usage)");
  }
  // colour attachment: the overlay (always supported); transfer source: the shown picture, when offered
  usage = VK_IMAGE_USAGE_TRANSFER_DST_BIT | VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT |
          (capabilities.supportedUsageFlags & VK_IMAGE_USAGE_TRANSFER_SRC_BIT);
  requested_width = width;
  requested_height = height;
  extent = capabilities.currentExtent;
  if (extent.width == std::numeric_limits<std::uint32_t>::max()) {
    extent.width = std::clamp(std::uint32_t(width), capabilities.minImageExtent.width,
                              capabilities.maxImageExtent.width);
    extent.height = std::clamp(std::uint32_t(height), capabilities.minImageExtent.height,
                               capabilities.maxImageExtent.height);
  }
  if (extent.width == 0 || extent.height == 0) return;  // minimized: made when the window has a size again

  std::uint32_t image_count = std::max(capabilities.minImageCount + 1, 2u);
  if (capabilities.maxImageCount > 0) image_count = std::min(image_count, capabilities.maxImageCount);
  VkSwapchainCreateInfoKHR info{VK_STRUCTURE_TYPE_SWAPCHAIN_CREATE_INFO_KHR};
  info.surface = surface.handle;
  info.minImageCount = image_count;
  info.imageFormat = format.format;
  info.imageColorSpace = format.colorSpace;
  info.imageExtent = extent;
  info.imageArrayLayers = 1;
  info.imageUsage = usage;
  info.imageSharingMode = VK_SHARING_MODE_EXCLUSIVE;
  info.preTransform = (capabilities.supportedTransforms & VK_SURFACE_TRANSFORM_IDENTITY_BIT_KHR)
                          ? VK_SURFACE_TRANSFORM_IDENTITY_BIT_KHR
                          : capabilities.currentTransform;
  info.compositeAlpha = VK_COMPOSITE_ALPHA_OPAQUE_BIT_KHR;
  for (VkCompositeAlphaFlagBitsKHR alpha :
       {VK_COMPOSITE_ALPHA_OPAQUE_BIT_KHR, VK_COMPOSITE_ALPHA_INHERIT_BIT_KHR,
        VK_COMPOSITE_ALPHA_PRE_MULTIPLIED_BIT_KHR, VK_COMPOSITE_ALPHA_POST_MULTIPLIED_BIT_KHR}) {
    if (capabilities.supportedCompositeAlpha & alpha) {
      info.compositeAlpha = alpha;
      break;
    }
  }
  info.presentMode = present_mode;
  info.clipped = VK_TRUE;
  info.oldSwapchain = swapchain.get();
  VkSwapchainKHR made = VK_NULL_HANDLE;
  DISPLACE_VK_CHECK(vkCreateSwapchainKHR(device, &info, nullptr, &made));
  swapchain = OwnedSwapchain(device, made);  // destroys the old one

  std::uint32_t count = 0;
  DISPLACE_VK_CHECK(vkGetSwapchainImagesKHR(device, swapchain.get(), &count, nullptr));
  images.resize(count);
  DISPLACE_VK_CHECK(vkGetSwapchainImagesKHR(device, swapchain.get(), &count, images.data()));
  images.resize(count);
  while (blitted.size() < images.size()) {
    VkSemaphoreCreateInfo semaphore_info{VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO};
    VkSemaphore semaphore = VK_NULL_HANDLE;
    DISPLACE_VK_CHECK(vkCreateSemaphore(device, &semaphore_info, nullptr, &semaphore));
    blitted.emplace_back(device, semaphore);
  }
  make_overlay_framebuffers();
  shown_readback = Buffer{};
  stale = false;
}

void Swapchain::Impl::make_overlay_framebuffers() {
  const VkDevice device = context.device();
  framebuffers.clear();
  views.clear();
  for (VkImage image : images) {
    VkImageViewCreateInfo view_info{VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO};
    view_info.image = image;
    view_info.viewType = VK_IMAGE_VIEW_TYPE_2D;
    view_info.format = format.format;
    view_info.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
    VkImageView view = VK_NULL_HANDLE;
    DISPLACE_VK_CHECK(vkCreateImageView(device, &view_info, nullptr, &view));
    views.emplace_back(device, view);
    VkFramebufferCreateInfo framebuffer_info{VK_STRUCTURE_TYPE_FRAMEBUFFER_CREATE_INFO};
    framebuffer_info.renderPass = overlay_pass.get();
    framebuffer_info.attachmentCount = 1;
    framebuffer_info.pAttachments = &view;
    framebuffer_info.width = extent.width;
    framebuffer_info.height = extent.height;
    framebuffer_info.layers = 1;
    VkFramebuffer framebuffer = VK_NULL_HANDLE;
    DISPLACE_VK_CHECK(vkCreateFramebuffer(device, &framebuffer_info, nullptr, &framebuffer));
    framebuffers.emplace_back(device, framebuffer);
  }
}

// transfer dst -> colour attachment; the caller's uploads, then its pass over the image
void Swapchain::Impl::record_overlay(VkCommandBuffer commands, std::uint32_t index) {
  const VkImage image = images[index];
  image_barrier(commands, image, 1, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, VK_ACCESS_TRANSFER_WRITE_BIT,
                VK_ACCESS_COLOR_ATTACHMENT_READ_BIT | VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT,
                VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT);
  if (overlay.prepare) overlay.prepare(commands);
  VkRenderPassBeginInfo begin{VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO};
  begin.renderPass = overlay_pass.get();
  begin.framebuffer = framebuffers[index].get();
  begin.renderArea.extent = extent;
  vkCmdBeginRenderPass(commands, &begin, VK_SUBPASS_CONTENTS_INLINE);
  overlay.draw(commands);
  vkCmdEndRenderPass(commands);
}

// the presented picture (TRANSFER_SRC_OPTIMAL) into the readback buffer, for the host
void Swapchain::Impl::record_shown_copy(VkCommandBuffer commands, VkImage image) {
  if (!(usage & VK_IMAGE_USAGE_TRANSFER_SRC_BIT)) {
    throw RenderError("the window's swapchain images cannot be read back (no TRANSFER_SRC usage)");
  }
  const VkDeviceSize bytes = VkDeviceSize(extent.width) * extent.height * 4;
  if (!shown_readback.handle()) {
    shown_readback = Buffer(context, bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                            VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
  }
  VkBufferImageCopy region{};
  region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
  region.imageExtent = {extent.width, extent.height, 1};
  vkCmdCopyImageToBuffer(commands, image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, shown_readback.handle(), 1,
                         &region);
  VkMemoryBarrier to_host{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  to_host.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
  to_host.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
  vkCmdPipelineBarrier(commands, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &to_host,
                       0, nullptr, 0, nullptr);
}

// the readback as RGBA8 (the swapchain's B8G8R8A8 swizzled); its present's fence has signalled
void Swapchain::Impl::copy_shown(Frame& shown) {
  shown.width = int(extent.width);
  shown.height = int(extent.height);
  const std::size_t bytes = std::size_t(extent.width) * extent.height * 4;
  shown.color.resize(bytes);
  const auto* source = static_cast<const std::uint8_t*>(shown_readback.mapped());
  const bool bgra = format.format == VK_FORMAT_B8G8R8A8_UNORM;
  for (std::size_t i = 0; i < bytes; i += 4) {
    shown.color[i + 0] = source[i + (bgra ? 2 : 0)];
    shown.color[i + 1] = source[i + 1];
    shown.color[i + 2] = source[i + (bgra ? 0 : 2)];
    shown.color[i + 3] = source[i + 3];
  }
}

bool Swapchain::Impl::present(int width, int height, Frame* shown) {
  if (width <= 0 || height <= 0) return false;
  const Renderer::ColorTarget target = renderer.color_target();
  if (target.width == 0 || target.image == VK_NULL_HANDLE) return false;  // nothing rendered yet
  if (stale || !swapchain.get() || width != requested_width || height != requested_height)
    recreate(width, height);
  if (!swapchain.get() || extent.width == 0 || extent.height == 0) return false;

  // the slot's previous blit has finished
  const VkDevice device = context.device();
  PresentSlot& present_slot = slots[std::size_t(slot)];
  const VkFence fence = present_slot.fence.get();
  DISPLACE_VK_CHECK(vkWaitForFences(device, 1, &fence, VK_TRUE, no_timeout));

  std::uint32_t index = 0;
  const VkResult acquired = vkAcquireNextImageKHR(device, swapchain.get(), no_timeout,
                                                  present_slot.acquired.get(), VK_NULL_HANDLE, &index);
  if (acquired == VK_ERROR_OUT_OF_DATE_KHR) {
    stale = true;
    return false;
  }
  if (acquired == VK_SUBOPTIMAL_KHR) {
    stale = true;  // the image is acquired: show it, then make the swapchain again
  } else {
    DISPLACE_VK_CHECK(acquired);
  }

  // record: swapchain image -> transfer dst, blit the colour target, the overlay, (the shown copy,) ->
  // present
  const VkCommandBuffer commands = present_slot.commands;
  DISPLACE_VK_CHECK(vkResetCommandBuffer(commands, 0));
  VkCommandBufferBeginInfo begin{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  DISPLACE_VK_CHECK(vkBeginCommandBuffer(commands, &begin));
  const VkImage image = images[index];
  image_barrier(commands, image, 1, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 0,
                VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT);
  VkImageBlit blit{};
  blit.srcSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
  blit.srcOffsets[1] = {target.width, target.height, 1};
  blit.dstSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
  blit.dstOffsets[1] = {std::int32_t(extent.width), std::int32_t(extent.height), 1};
  vkCmdBlitImage(commands, target.image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, image,
                 VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &blit, VK_FILTER_NEAREST);
  VkImageLayout layout = VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL;
  VkAccessFlags written = VK_ACCESS_TRANSFER_WRITE_BIT;
  VkPipelineStageFlags written_stage = VK_PIPELINE_STAGE_TRANSFER_BIT;
  if (overlay.draw) {
    record_overlay(commands, index);
    layout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL;
    written = VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT;
    written_stage = VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT;
  }
  if (shown) {
    image_barrier(commands, image, 1, layout, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, written,
                  VK_ACCESS_TRANSFER_READ_BIT, written_stage, VK_PIPELINE_STAGE_TRANSFER_BIT);
    record_shown_copy(commands, image);
    layout = VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL;
    written = 0;
    written_stage = VK_PIPELINE_STAGE_TRANSFER_BIT;
  }
  image_barrier(commands, image, 1, layout, VK_IMAGE_LAYOUT_PRESENT_SRC_KHR, written, 0, written_stage,
                VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT);
  DISPLACE_VK_CHECK(vkEndCommandBuffer(commands));

  // submit after the renderer's frame (same queue), then present
  DISPLACE_VK_CHECK(vkResetFences(device, 1, &fence));
  const VkSemaphore signal = blitted[index].get();
  submit_commands(context.queue(), commands, {present_slot.acquired.get()}, VK_PIPELINE_STAGE_TRANSFER_BIT,
                  {signal}, fence);
  slot = (slot + 1) % frames_in_flight;
  if (shown) {
    DISPLACE_VK_CHECK(vkWaitForFences(device, 1, &fence, VK_TRUE, no_timeout));
    copy_shown(*shown);
  }

  const VkSwapchainKHR handle = swapchain.get();
  VkPresentInfoKHR present_info{VK_STRUCTURE_TYPE_PRESENT_INFO_KHR};
  present_info.waitSemaphoreCount = 1;
  present_info.pWaitSemaphores = &signal;
  present_info.swapchainCount = 1;
  present_info.pSwapchains = &handle;
  present_info.pImageIndices = &index;
  const VkResult presented = vkQueuePresentKHR(context.queue(), &present_info);
  if (presented == VK_ERROR_OUT_OF_DATE_KHR || presented == VK_SUBOPTIMAL_KHR) {
    stale = true;
    return presented == VK_SUBOPTIMAL_KHR;
  }
  DISPLACE_VK_CHECK(presented);
  return true;
}

Swapchain::Swapchain(Renderer& renderer, const SurfaceFactory& make_surface, int width, int height,
                     bool vsync)
    : impl_(std::make_unique<Impl>(renderer, make_surface, vsync)) {
  impl_->recreate(width, height);
}
Swapchain::~Swapchain() = default;
Swapchain::Swapchain(Swapchain&&) noexcept = default;
Swapchain& Swapchain::operator=(Swapchain&&) noexcept = default;

bool Swapchain::present(int width, int height, Frame* shown) { return impl_->present(width, height, shown); }
int Swapchain::width() const { return int(impl_->extent.width); }
int Swapchain::height() const { return int(impl_->extent.height); }

void Swapchain::set_overlay(Overlay overlay) noexcept { impl_->overlay = std::move(overlay); }

Swapchain::Handles Swapchain::handles() const {
  const Context& context = impl_->context;
  Handles handles;
  handles.instance = context.instance();
  handles.physical_device = context.physical_device();
  handles.device = context.device();
  handles.queue_family = context.queue_family();
  handles.queue = context.queue();
  handles.overlay_render_pass = impl_->overlay_pass.get();
  return handles;
}

}  // namespace displace::render
