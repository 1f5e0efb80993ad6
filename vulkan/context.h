// vulkan/context.h - the one place that creates the Vulkan instance and device (headless, or able
// to present when DeviceOptions::instance_extensions asks), and move-only RAII owners for buffers,
// images (each with its memory) and other handles, destroyed in reverse order. The base of every
// layer that uses the device (sim/device, bake/device, render); not installed.
#pragma once

#include <vulkan/vulkan.h>

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "vulkan/device_info.h"
#include "vulkan/error.h"

namespace displace::vulkan {

// The queue family for work beside the frame's (Context::async_queue): the first with compute and
// without graphics, with timestamps where `timestamps` (the frame's family has them, so that the
// async stages are timed too); -1: none.
int pick_async_family(std::span<const VkQueueFamilyProperties> families, bool timestamps);

// Throws Error naming the call, file and line when a Vulkan call fails.
void check_vk(VkResult result, const char* call, const char* file, int line);
#define DISPLACE_VK_CHECK(call) ::displace::vulkan::check_vk((call), #call, __FILE__, __LINE__)

// A semaphore a submission waits for or signals: a timeline semaphore at `value`, or a binary one
// (its value ignored); none where `semaphore` is null.
struct SemaphorePoint {
  VkSemaphore semaphore = VK_NULL_HANDLE;
  std::uint64_t value = 0;
};
// Submits `commands` to `queue` after `wait` (its work at `wait_stage` waits), signalling `signal`,
// with `fence` (may be null); throws Error when the submission fails.
void submit_commands(VkQueue queue, VkCommandBuffer commands, SemaphorePoint wait,
                     VkPipelineStageFlags wait_stage, SemaphorePoint signal, VkFence fence);

// What device a Context picks and how it is set up.
struct DeviceOptions {
  // Empty: the best device (a discrete GPU, else an integrated one, else any, else the CPU driver).
  // Otherwise a device index or a case-insensitive part of its name.
  std::string device;
  bool validate = false;  // Khronos validation layer; every message is printed and counted
  // Instance extensions a window system needs to make a surface. Non-empty: the device also gets
  // VK_KHR_swapchain, and only devices that have it are chosen.
  std::vector<std::string> instance_extensions;
  // With instance_extensions: whether a device's queue family can present to the caller's window
  // system, asked before any surface exists. Empty: not asked.
  std::function<bool(VkInstance, VkPhysicalDevice, std::uint32_t queue_family)> can_present;
  // Work beside the frame's (async_queue) on a queue of a compute-only family where the device has
  // one; off, or where there is none, on the frame's own queue.
  bool async_compute = true;
};

class Context {
 public:
  explicit Context(const DeviceOptions& options);
  ~Context();
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;

  VkInstance instance() const { return instance_; }
  VkDevice device() const { return device_; }
  VkPhysicalDevice physical_device() const { return physical_device_; }
  VkQueue queue() const { return queue_; }
  std::uint32_t queue_family() const { return queue_family_; }
  VkCommandPool command_pool() const { return command_pool_; }
  // The queue that takes work meant to run beside the frame's (DeviceCones' lagged bands): a
  // compute-only family's (DeviceOptions::async_compute) or, where there is none, queue() itself.
  VkQueue async_queue() const { return async_queue_; }
  std::uint32_t async_family() const { return async_family_; }
  bool async_apart() const { return async_family_ != queue_family_; }
  // A primary command buffer of the async family's pool (resettable), owned by the caller.
  VkCommandBuffer allocate_async_command_buffer() const;
  void free_async_command_buffer(VkCommandBuffer commands) const;
  // A timeline semaphore at value 0; the caller destroys it (OwnedSemaphore).
  VkSemaphore create_timeline() const;
  const DeviceInfo& info() const { return info_; }
  float timestamp_period_ns() const { return timestamp_period_ns_; }
  bool has_timestamps() const { return has_timestamps_; }
  long long validation_messages() const { return validation_messages_->load(); }

  std::uint32_t memory_type(std::uint32_t type_bits, VkMemoryPropertyFlags properties) const;
  bool has_memory_type(std::uint32_t type_bits, VkMemoryPropertyFlags properties) const;
  // vkAllocateMemory, counted (memory_allocations()).
  VkDeviceMemory allocate(const VkMemoryRequirements& requirements, VkMemoryPropertyFlags properties) const;
  long long memory_allocations() const { return memory_allocations_->load(); }
  // The device's heaps and largest allocation with the host's available memory (render.h's
  // MemoryLimits), lowered to `limit` bytes when that is not 0 (`source` names it).
  MemoryLimits memory_limits(std::uint64_t limit, const std::string& source) const;
  // Whether a 2D (array) image of `format` can be a host-written one (Image::host_written): the
  // device is the CPU driver (lavapipe), with a memory type that is device-local, host-visible and
  // coherent, and samples linear images of that size and layer count.
  bool host_images(VkFormat format, std::uint32_t width, std::uint32_t height, std::uint32_t layers) const;
  // A fence, signalled from the start when `signaled`; the caller destroys it (OwnedFence).
  VkFence create_fence(bool signaled) const;
  // A primary command buffer from the pool (resettable), owned by the caller until the pool goes.
  VkCommandBuffer allocate_command_buffer() const;

  // Records with `record` into the one reusable command buffer, submits and waits (set-up uploads).
  template <typename Record>
  void submit_and_wait(Record&& record) const {
    VkCommandBuffer commands = begin_commands();
    std::forward<Record>(record)(commands);
    end_submit_wait(commands);
  }

 private:
  void destroy() noexcept;
  VkCommandBuffer begin_commands() const;
  void end_submit_wait(VkCommandBuffer commands) const;

  VkInstance instance_ = VK_NULL_HANDLE;
  VkDebugUtilsMessengerEXT messenger_ = VK_NULL_HANDLE;
  VkPhysicalDevice physical_device_ = VK_NULL_HANDLE;
  VkDevice device_ = VK_NULL_HANDLE;
  VkQueue queue_ = VK_NULL_HANDLE;
  std::uint32_t queue_family_ = 0;
  VkCommandPool command_pool_ = VK_NULL_HANDLE;
  VkQueue async_queue_ = VK_NULL_HANDLE;
  std::uint32_t async_family_ = 0;
  VkCommandPool async_pool_ = VK_NULL_HANDLE;  // only where async_apart()
  VkFence fence_ = VK_NULL_HANDLE;
  VkCommandBuffer one_time_commands_ = VK_NULL_HANDLE;
  DeviceInfo info_;
  float timestamp_period_ns_ = 0.0f;
  bool has_timestamps_ = false;
  VkPhysicalDeviceMemoryProperties memory_properties_{};
  VkDeviceSize max_allocation_ = 0;  // maxMemoryAllocationSize
  std::unique_ptr<std::atomic<long long>> validation_messages_ = std::make_unique<std::atomic<long long>>(0);
  std::unique_ptr<std::atomic<long long>> memory_allocations_ = std::make_unique<std::atomic<long long>>(0);
};

// A buffer with its own memory; host-visible buffers stay mapped.
class Buffer {
 public:
  Buffer() = default;
  // shared: used by the frame's queue and the async one (concurrent sharing where they differ)
  Buffer(const Context& context, VkDeviceSize size, VkBufferUsageFlags usage,
         VkMemoryPropertyFlags properties, bool shared = false);
  ~Buffer();
  Buffer(Buffer&& other) noexcept { swap(other); }
  Buffer& operator=(Buffer&& other) noexcept {
    Buffer moved(std::move(other));
    swap(moved);
    return *this;
  }

  VkBuffer handle() const { return buffer_; }
  VkDeviceSize size() const { return size_; }
  void* mapped() const { return mapped_; }

 private:
  void swap(Buffer& other) noexcept {
    std::swap(device_, other.device_);
    std::swap(buffer_, other.buffer_);
    std::swap(memory_, other.memory_);
    std::swap(size_, other.size_);
    std::swap(mapped_, other.mapped_);
  }
  VkDevice device_ = VK_NULL_HANDLE;
  VkBuffer buffer_ = VK_NULL_HANDLE;
  VkDeviceMemory memory_ = VK_NULL_HANDLE;
  VkDeviceSize size_ = 0;
  void* mapped_ = nullptr;
};

// A 2D (array) image with its memory and a view over all its layers; with VK_IMAGE_VIEW_TYPE_3D a 3D
// image whose depth is `layers`.
class Image {
 public:
  Image() = default;
  Image(const Context& context, VkFormat format, std::uint32_t width, std::uint32_t height,
        std::uint32_t layers, VkImageUsageFlags usage, VkImageAspectFlags aspect, VkImageViewType view_type,
        bool shared = false);  // shared: as Buffer's
  // A sampled 2D (array) colour image in linear tiling, in host-visible coherent device-local memory
  // mapped for as long as it lives: the host writes its texels (at row_pitch() and layer_pitch()
  // bytes) and shaders sample it in VK_IMAGE_LAYOUT_GENERAL. Made in VK_IMAGE_LAYOUT_PREINITIALIZED.
  // Only where Context::host_images says so; an empty Image (no handle) where the image may not
  // live in such memory after all.
  static Image host_written(const Context& context, VkFormat format, std::uint32_t width,
                            std::uint32_t height, std::uint32_t layers, VkImageViewType view_type);
  ~Image();
  Image(Image&& other) noexcept { swap(other); }
  Image& operator=(Image&& other) noexcept {
    Image moved(std::move(other));
    swap(moved);
    return *this;
  }

  VkImage handle() const { return image_; }
  VkImageView view() const { return view_; }
  VkFormat format() const { return format_; }
  std::uint32_t width() const { return width_; }
  std::uint32_t height() const { return height_; }
  std::uint32_t layers() const { return layers_; }
  // host_written images: texel (0, 0) of layer 0, and the bytes between rows and between layers
  std::byte* mapped() const { return mapped_; }
  VkDeviceSize row_pitch() const { return row_pitch_; }
  VkDeviceSize layer_pitch() const { return layer_pitch_; }

 private:
  // Creates the image, its memory (of `memory` properties) and its view; false, with only the image
  // made, when none of the device's memory types with those properties may hold it.
  bool make(const Context& context, VkFormat format, std::uint32_t width, std::uint32_t height,
            std::uint32_t layers, VkImageUsageFlags usage, VkImageAspectFlags aspect,
            VkImageViewType view_type, VkImageTiling tiling, VkImageLayout initial_layout,
            VkMemoryPropertyFlags memory, bool shared = false);
  void swap(Image& other) noexcept {
    std::swap(mapped_, other.mapped_);
    std::swap(row_pitch_, other.row_pitch_);
    std::swap(layer_pitch_, other.layer_pitch_);
    std::swap(device_, other.device_);
    std::swap(image_, other.image_);
    std::swap(memory_, other.memory_);
    std::swap(view_, other.view_);
    std::swap(format_, other.format_);
    std::swap(width_, other.width_);
    std::swap(height_, other.height_);
    std::swap(layers_, other.layers_);
  }
  VkDevice device_ = VK_NULL_HANDLE;
  VkImage image_ = VK_NULL_HANDLE;
  VkDeviceMemory memory_ = VK_NULL_HANDLE;
  VkImageView view_ = VK_NULL_HANDLE;
  VkFormat format_ = VK_FORMAT_UNDEFINED;
  std::uint32_t width_ = 0, height_ = 0, layers_ = 0;
  std::byte* mapped_ = nullptr;
  VkDeviceSize row_pitch_ = 0, layer_pitch_ = 0;
};

// Move-only owner of one Vulkan handle destroyed with vkDestroy*(device, handle, nullptr).
template <typename Handle, void (*destroy)(VkDevice, Handle, const VkAllocationCallbacks*)>
class Owned {
 public:
  Owned() = default;
  Owned(VkDevice device, Handle handle) : device_(device), handle_(handle) {}
  ~Owned() {
    if (handle_ != VK_NULL_HANDLE) destroy(device_, handle_, nullptr);
  }
  Owned(Owned&& other) noexcept
      : device_(other.device_), handle_(std::exchange(other.handle_, VK_NULL_HANDLE)) {}
  Owned& operator=(Owned&& other) noexcept {
    Owned moved(std::move(other));
    std::swap(device_, moved.device_);
    std::swap(handle_, moved.handle_);
    return *this;
  }
  Handle get() const { return handle_; }

 private:
  VkDevice device_ = VK_NULL_HANDLE;
  Handle handle_ = VK_NULL_HANDLE;
};

using OwnedPipeline = Owned<VkPipeline, vkDestroyPipeline>;
using OwnedPipelineLayout = Owned<VkPipelineLayout, vkDestroyPipelineLayout>;
using OwnedDescriptorSetLayout = Owned<VkDescriptorSetLayout, vkDestroyDescriptorSetLayout>;
using OwnedDescriptorPool = Owned<VkDescriptorPool, vkDestroyDescriptorPool>;
using OwnedRenderPass = Owned<VkRenderPass, vkDestroyRenderPass>;
using OwnedFramebuffer = Owned<VkFramebuffer, vkDestroyFramebuffer>;
using OwnedShaderModule = Owned<VkShaderModule, vkDestroyShaderModule>;
using OwnedSampler = Owned<VkSampler, vkDestroySampler>;
using OwnedQueryPool = Owned<VkQueryPool, vkDestroyQueryPool>;
using OwnedSemaphore = Owned<VkSemaphore, vkDestroySemaphore>;
using OwnedSwapchain = Owned<VkSwapchainKHR, vkDestroySwapchainKHR>;

// A shader module of `code` as it is.
OwnedShaderModule shader_module(VkDevice device, std::span<const std::uint32_t> code);
// A shader module of `code` with its specialization constants (id k = constants[k], the 32 bits a
// 4-byte VkSpecializationInfo entry would hand over) frozen into it and the code they rule out
// removed, so that the driver never translates it (render/pipelines.cpp, render/compute.cpp).
OwnedShaderModule specialised_shader(VkDevice device, std::span<const std::uint32_t> code,
                                     std::span<const std::int32_t> constants);

}  // namespace displace::vulkan
