// vulkan/context.cpp - headless instance and device creation, device choice, validation messages,
// the host's memory, and the RAII owners of buffers and images.
#include "vulkan/context.h"

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <spirv-tools/optimizer.hpp>
#include <unordered_map>
#include <vector>

namespace displace::vulkan {
namespace {

constexpr const char* validation_layer = "VK_LAYER_KHRONOS_validation";
constexpr const char* install_hint =
    "install a Vulkan driver: 'apt-get install mesa-vulkan-drivers' gives lavapipe, the CPU driver";

const char* result_name(VkResult result) {
  switch (result) {
    case VK_ERROR_OUT_OF_HOST_MEMORY: return "VK_ERROR_OUT_OF_HOST_MEMORY";
    case VK_ERROR_OUT_OF_DEVICE_MEMORY: return "VK_ERROR_OUT_OF_DEVICE_MEMORY";
    case VK_ERROR_INITIALIZATION_FAILED: return "VK_ERROR_INITIALIZATION_FAILED";
    case VK_ERROR_DEVICE_LOST: return "VK_ERROR_DEVICE_LOST";
    case VK_ERROR_LAYER_NOT_PRESENT: return "VK_ERROR_LAYER_NOT_PRESENT";
    case VK_ERROR_EXTENSION_NOT_PRESENT: return "VK_ERROR_EXTENSION_NOT_PRESENT";
    case VK_ERROR_FEATURE_NOT_PRESENT: return "VK_ERROR_FEATURE_NOT_PRESENT";
    case VK_ERROR_INCOMPATIBLE_DRIVER: return "VK_ERROR_INCOMPATIBLE_DRIVER";
    case VK_ERROR_FORMAT_NOT_SUPPORTED: return "VK_ERROR_FORMAT_NOT_SUPPORTED";
    case VK_TIMEOUT: return "VK_TIMEOUT";
    case VK_SUBOPTIMAL_KHR: return "VK_SUBOPTIMAL_KHR";
    case VK_ERROR_OUT_OF_DATE_KHR: return "VK_ERROR_OUT_OF_DATE_KHR";
    case VK_ERROR_SURFACE_LOST_KHR: return "VK_ERROR_SURFACE_LOST_KHR";
    case VK_ERROR_NATIVE_WINDOW_IN_USE_KHR: return "VK_ERROR_NATIVE_WINDOW_IN_USE_KHR";
    default: return "VkResult error";
  }
}

const char* type_name(VkPhysicalDeviceType type) {
  switch (type) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU: return "discrete-gpu";
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU: return "integrated-gpu";
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU: return "virtual-gpu";
    case VK_PHYSICAL_DEVICE_TYPE_CPU: return "cpu";
    default: return "other";
  }
}

int type_rank(VkPhysicalDeviceType type) {
  switch (type) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU: return 4;
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU: return 3;
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU: return 2;
    case VK_PHYSICAL_DEVICE_TYPE_CPU: return 1;
    default: return 0;
  }
}

VKAPI_ATTR VkBool32 VKAPI_CALL on_validation_message(VkDebugUtilsMessageSeverityFlagBitsEXT,
                                                     VkDebugUtilsMessageTypeFlagsEXT,
                                                     const VkDebugUtilsMessengerCallbackDataEXT* data,
                                                     void* user) {
  static_cast<std::atomic<long long>*>(user)->fetch_add(1);
  std::fprintf(stderr, "displace: vulkan validation: %s\n",
               data && data->pMessage ? data->pMessage : "(no text)");
  return VK_FALSE;
}

bool has_layer(const char* name) {
  std::uint32_t count = 0;
  vkEnumerateInstanceLayerProperties(&count, nullptr);
  std::vector<VkLayerProperties> layers(count);
  vkEnumerateInstanceLayerProperties(&count, layers.data());
  return std::any_of(layers.begin(), layers.end(),
                     [&](const VkLayerProperties& layer) { return std::strcmp(layer.layerName, name) == 0; });
}

bool has_instance_extension(const char* name) {
  std::uint32_t count = 0;
  vkEnumerateInstanceExtensionProperties(nullptr, &count, nullptr);
  std::vector<VkExtensionProperties> extensions(count);
  vkEnumerateInstanceExtensionProperties(nullptr, &count, extensions.data());
  return std::any_of(extensions.begin(), extensions.end(), [&](const VkExtensionProperties& extension) {
    return std::strcmp(extension.extensionName, name) == 0;
  });
}

// `window_extensions`: what the caller's window system needs for a surface (presenting).
VkInstance create_instance(bool validate, const std::vector<std::string>& window_extensions = {}) {
  VkApplicationInfo application{VK_STRUCTURE_TYPE_APPLICATION_INFO};
  application.pApplicationName = "displace";
  application.apiVersion = VK_API_VERSION_1_2;
  VkInstanceCreateInfo info{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
  info.pApplicationInfo = &application;
  std::vector<const char*> extensions;
  for (const std::string& name : window_extensions) {
    if (!has_instance_extension(name.c_str())) {
      throw Error("the Vulkan loader lacks the instance extension " + name + " that the window needs");
    }
    extensions.push_back(name.c_str());
  }
  if (validate) {
    if (!has_layer(validation_layer)) {
      throw Error(
          "DeviceOptions::validate needs the Khronos validation layer: 'apt-get install "
          "vulkan-validationlayers'");
    }
    info.enabledLayerCount = 1;
    info.ppEnabledLayerNames = &validation_layer;
    extensions.push_back(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);
  }
  info.enabledExtensionCount = std::uint32_t(extensions.size());
  info.ppEnabledExtensionNames = extensions.data();
  VkInstance instance = VK_NULL_HANDLE;
  const VkResult result = vkCreateInstance(&info, nullptr, &instance);
  if (result == VK_ERROR_INCOMPATIBLE_DRIVER)
    throw Error(std::string("no Vulkan 1.2 driver found; ") + install_hint);
  check_vk(result, "vkCreateInstance", __FILE__, __LINE__);
  return instance;
}

std::vector<VkPhysicalDevice> physical_devices(VkInstance instance) {
  std::uint32_t count = 0;
  DISPLACE_VK_CHECK(vkEnumeratePhysicalDevices(instance, &count, nullptr));
  std::vector<VkPhysicalDevice> devices(count);
  DISPLACE_VK_CHECK(vkEnumeratePhysicalDevices(instance, &count, devices.data()));
  devices.resize(count);
  return devices;
}

int graphics_queue_family(VkPhysicalDevice device) {
  std::uint32_t count = 0;
  vkGetPhysicalDeviceQueueFamilyProperties(device, &count, nullptr);
  std::vector<VkQueueFamilyProperties> families(count);
  vkGetPhysicalDeviceQueueFamilyProperties(device, &count, families.data());
  for (std::uint32_t i = 0; i < count; ++i) {
    // compute too: the device path's kernels (compute.h) run on the frame's queue
    const VkQueueFlags needed = VK_QUEUE_GRAPHICS_BIT | VK_QUEUE_COMPUTE_BIT;
    if ((families[i].queueFlags & needed) == needed) return int(i);
  }
  return -1;
}

int compute_only_family(VkPhysicalDevice device, bool timestamps) {
  std::uint32_t count = 0;
  vkGetPhysicalDeviceQueueFamilyProperties(device, &count, nullptr);
  std::vector<VkQueueFamilyProperties> families(count);
  vkGetPhysicalDeviceQueueFamilyProperties(device, &count, families.data());
  return pick_async_family(families, timestamps);
}

std::string lower(std::string text) {
  for (char& c : text) c = char(std::tolower(static_cast<unsigned char>(c)));
  return text;
}

struct Candidate {
  VkPhysicalDevice device;
  DeviceInfo info;
  int rank;
};

bool has_device_extension(VkPhysicalDevice device, const char* name) {
  std::uint32_t count = 0;
  if (vkEnumerateDeviceExtensionProperties(device, nullptr, &count, nullptr) != VK_SUCCESS) return false;
  std::vector<VkExtensionProperties> extensions(count);
  if (vkEnumerateDeviceExtensionProperties(device, nullptr, &count, extensions.data()) != VK_SUCCESS)
    return false;
  return std::any_of(extensions.begin(), extensions.end(), [&](const VkExtensionProperties& extension) {
    return std::strcmp(extension.extensionName, name) == 0;
  });
}

// `present`: only devices with VK_KHR_swapchain (and, when `can_present` is given, whose graphics
// queue family it accepts) are usable.
std::vector<Candidate> candidates(VkInstance instance, bool present = false,
                                  const DeviceOptions* options = nullptr) {
  std::vector<Candidate> result;
  int index = 0;
  for (VkPhysicalDevice device : physical_devices(instance)) {
    VkPhysicalDeviceProperties properties;
    vkGetPhysicalDeviceProperties(device, &properties);
    const int family = graphics_queue_family(device);
    bool usable = properties.apiVersion >= VK_API_VERSION_1_2 && family >= 0;
    if (usable && present) {
      usable = has_device_extension(device, VK_KHR_SWAPCHAIN_EXTENSION_NAME) &&
               (!options || !options->can_present ||
                options->can_present(instance, device, std::uint32_t(family)));
    }
    DeviceInfo info{index++, properties.deviceName, type_name(properties.deviceType)};
    result.push_back({device, info, usable ? type_rank(properties.deviceType) : -1});
  }
  return result;
}

Candidate choose_device(VkInstance instance, const DeviceOptions& options) {
  const bool present = !options.instance_extensions.empty();
  const std::string& wanted = options.device;
  const std::vector<Candidate> all = candidates(instance, present, &options);
  if (all.empty()) throw Error(std::string("no Vulkan device found; ") + install_hint);
  if (wanted.empty()) {
    const auto best = std::max_element(
        all.begin(), all.end(), [](const Candidate& a, const Candidate& b) { return a.rank < b.rank; });
    if (best->rank < 0) {
      throw Error(std::string("no Vulkan 1.2 device with graphics") +
                  (present ? " that presents to the window" : "") + " found; " + install_hint);
    }
    return *best;
  }
  std::string names;
  for (const Candidate& candidate : all) {
    int index = -1;
    const auto [end, error] = std::from_chars(wanted.data(), wanted.data() + wanted.size(), index);
    const bool by_index =
        error == std::errc{} && end == wanted.data() + wanted.size() && index == candidate.info.index;
    const bool by_name = lower(candidate.info.name).find(lower(wanted)) != std::string::npos;
    if (by_index || by_name) {
      if (candidate.rank < 0)
        throw Error("device '" + candidate.info.name + "' lacks Vulkan 1.2 graphics" +
                    (present ? std::string(" or cannot present to the window") : std::string()));
      return candidate;
    }
    names += (names.empty() ? "" : ", ") + std::to_string(candidate.info.index) + ": " + candidate.info.name;
  }
  throw Error("DeviceOptions::device '" + wanted + "' matches no Vulkan device (have " + names + ")");
}

}  // namespace

int pick_async_family(std::span<const VkQueueFamilyProperties> families, bool timestamps) {
  for (std::size_t i = 0; i < families.size(); ++i) {
    const VkQueueFlags flags = families[i].queueFlags;
    if ((flags & VK_QUEUE_COMPUTE_BIT) && !(flags & VK_QUEUE_GRAPHICS_BIT) && families[i].queueCount > 0 &&
        (!timestamps || families[i].timestampValidBits > 0))
      return int(i);
  }
  return -1;
}

void submit_commands(VkQueue queue, VkCommandBuffer commands, SemaphorePoint wait,
                     VkPipelineStageFlags wait_stage, SemaphorePoint signal, VkFence fence) {
  // the values are read for timeline semaphores only (Vulkan ignores them for binary ones)
  VkTimelineSemaphoreSubmitInfo timeline{VK_STRUCTURE_TYPE_TIMELINE_SEMAPHORE_SUBMIT_INFO};
  VkSubmitInfo submit{VK_STRUCTURE_TYPE_SUBMIT_INFO};
  submit.pNext = &timeline;
  if (wait.semaphore != VK_NULL_HANDLE) {
    timeline.waitSemaphoreValueCount = 1;
    timeline.pWaitSemaphoreValues = &wait.value;
    submit.waitSemaphoreCount = 1;
    submit.pWaitSemaphores = &wait.semaphore;
    submit.pWaitDstStageMask = &wait_stage;
  }
  if (signal.semaphore != VK_NULL_HANDLE) {
    timeline.signalSemaphoreValueCount = 1;
    timeline.pSignalSemaphoreValues = &signal.value;
    submit.signalSemaphoreCount = 1;
    submit.pSignalSemaphores = &signal.semaphore;
  }
  submit.commandBufferCount = 1;
  submit.pCommandBuffers = &commands;
  DISPLACE_VK_CHECK(vkQueueSubmit(queue, 1, &submit, fence));
}

void check_vk(VkResult result, const char* call, const char* file, int line) {
  if (result == VK_SUCCESS) return;
  throw Error(std::string(call) + " failed with " + result_name(result) + " (" + std::to_string(int(result)) +
              ") at " + file + ":" + std::to_string(line));
}

std::vector<DeviceInfo> list_devices() {
  VkInstance instance = create_instance(false);
  std::vector<DeviceInfo> result;
  try {
    for (const Candidate& candidate : candidates(instance)) result.push_back(candidate.info);
  } catch (...) {
    vkDestroyInstance(instance, nullptr);
    throw;
  }
  vkDestroyInstance(instance, nullptr);
  if (result.empty()) throw Error(std::string("no Vulkan device found; ") + install_hint);
  return result;
}

DeviceInfo default_device() {
  VkInstance instance = create_instance(false);
  try {
    const DeviceInfo info = choose_device(instance, DeviceOptions{}).info;
    vkDestroyInstance(instance, nullptr);
    return info;
  } catch (...) {
    vkDestroyInstance(instance, nullptr);
    throw;
  }
}

Context::Context(const DeviceOptions& options) {
  instance_ = create_instance(options.validate, options.instance_extensions);
  const bool present = !options.instance_extensions.empty();
  try {
    if (options.validate) {
      VkDebugUtilsMessengerCreateInfoEXT info{VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT};
      info.messageSeverity =
          VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
      info.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT |
                         VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                         VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
      info.pfnUserCallback = on_validation_message;
      info.pUserData = validation_messages_.get();
      auto create = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
          vkGetInstanceProcAddr(instance_, "vkCreateDebugUtilsMessengerEXT"));
      if (!create) throw Error("the validation layer offers no VK_EXT_debug_utils messenger");
      DISPLACE_VK_CHECK(create(instance_, &info, nullptr, &messenger_));
    }

    const Candidate chosen = choose_device(instance_, options);
    physical_device_ = chosen.device;
    info_ = chosen.info;
    queue_family_ = std::uint32_t(graphics_queue_family(physical_device_));
    vkGetPhysicalDeviceMemoryProperties(physical_device_, &memory_properties_);

    VkPhysicalDeviceProperties properties;
    vkGetPhysicalDeviceProperties(physical_device_, &properties);
    std::uint32_t family_count = 0;
    vkGetPhysicalDeviceQueueFamilyProperties(physical_device_, &family_count, nullptr);
    std::vector<VkQueueFamilyProperties> families(family_count);
    vkGetPhysicalDeviceQueueFamilyProperties(physical_device_, &family_count, families.data());
    has_timestamps_ =
        properties.limits.timestampComputeAndGraphics && families[queue_family_].timestampValidBits > 0;
    timestamp_period_ns_ = properties.limits.timestampPeriod;
    info_.max_image_dimension_3d = int(properties.limits.maxImageDimension3D);
    info_.max_storage_buffer_range = properties.limits.maxStorageBufferRange;
    info_.sub_texel_precision_bits = int(properties.limits.subTexelPrecisionBits);
    VkPhysicalDeviceMaintenance3Properties maintenance3{
        VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_MAINTENANCE_3_PROPERTIES};
    VkPhysicalDeviceProperties2 properties2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
    properties2.pNext = &maintenance3;
    vkGetPhysicalDeviceProperties2(physical_device_, &properties2);
    max_allocation_ = maintenance3.maxMemoryAllocationSize;

    // the async queue: a compute-only family's where asked and there is one, else the frame's queue
    const int compute_family =
        options.async_compute ? compute_only_family(physical_device_, has_timestamps_) : -1;
    async_family_ = compute_family >= 0 ? std::uint32_t(compute_family) : queue_family_;
    info_.compute_queue_apart = async_apart();

    const float priority = 1.0f;
    VkDeviceQueueCreateInfo queue_infos[2] = {{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO},
                                              {VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO}};
    for (int q = 0; q < 2; ++q) {
      queue_infos[q].queueFamilyIndex = q == 0 ? queue_family_ : async_family_;
      queue_infos[q].queueCount = 1;
      queue_infos[q].pQueuePriorities = &priority;
    }
    // timeline semaphores order the async queue's work against the frame's (required by Vulkan 1.2)
    VkPhysicalDeviceVulkan12Features features12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
    VkPhysicalDeviceFeatures2 supported{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
    supported.pNext = &features12;
    vkGetPhysicalDeviceFeatures2(physical_device_, &supported);
    if (!features12.timelineSemaphore)
      throw Error("device '" + info_.name + "' lacks timeline semaphores, which Vulkan 1.2 requires");
    VkPhysicalDeviceVulkan12Features enabled12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
    enabled12.timelineSemaphore = VK_TRUE;
    VkDeviceCreateInfo device_info{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
    device_info.pNext = &enabled12;
    device_info.queueCreateInfoCount = async_apart() ? 2 : 1;
    device_info.pQueueCreateInfos = queue_infos;
    const char* swapchain_extension = VK_KHR_SWAPCHAIN_EXTENSION_NAME;
    if (present) {
      device_info.enabledExtensionCount = 1;
      device_info.ppEnabledExtensionNames = &swapchain_extension;
    }
    DISPLACE_VK_CHECK(vkCreateDevice(physical_device_, &device_info, nullptr, &device_));
    vkGetDeviceQueue(device_, queue_family_, 0, &queue_);
    async_queue_ = queue_;
    if (async_apart()) vkGetDeviceQueue(device_, async_family_, 0, &async_queue_);

    VkCommandPoolCreateInfo pool_info{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
    pool_info.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT | VK_COMMAND_POOL_CREATE_TRANSIENT_BIT;
    pool_info.queueFamilyIndex = queue_family_;
    DISPLACE_VK_CHECK(vkCreateCommandPool(device_, &pool_info, nullptr, &command_pool_));
    if (async_apart()) {
      pool_info.queueFamilyIndex = async_family_;
      DISPLACE_VK_CHECK(vkCreateCommandPool(device_, &pool_info, nullptr, &async_pool_));
    }
    fence_ = create_fence(false);
    one_time_commands_ = allocate_command_buffer();
  } catch (...) {
    destroy();
    throw;
  }
}

Context::~Context() { destroy(); }

void Context::destroy() noexcept {
  if (device_) {
    vkDeviceWaitIdle(device_);
    if (fence_) vkDestroyFence(device_, fence_, nullptr);
    if (command_pool_) vkDestroyCommandPool(device_, command_pool_, nullptr);
    if (async_pool_) vkDestroyCommandPool(device_, async_pool_, nullptr);
    vkDestroyDevice(device_, nullptr);
    device_ = VK_NULL_HANDLE;
  }
  if (messenger_) {
    auto destroy = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(instance_, "vkDestroyDebugUtilsMessengerEXT"));
    if (destroy) destroy(instance_, messenger_, nullptr);
    messenger_ = VK_NULL_HANDLE;
  }
  if (instance_) {
    vkDestroyInstance(instance_, nullptr);
    instance_ = VK_NULL_HANDLE;
  }
}

std::uint32_t Context::memory_type(std::uint32_t type_bits, VkMemoryPropertyFlags properties) const {
  for (std::uint32_t i = 0; i < memory_properties_.memoryTypeCount; ++i) {
    if ((type_bits & (1u << i)) &&
        (memory_properties_.memoryTypes[i].propertyFlags & properties) == properties) {
      return i;
    }
  }
  throw Error("the Vulkan device has no memory type with the properties a buffer or image needs");
}

bool Context::has_memory_type(std::uint32_t type_bits, VkMemoryPropertyFlags properties) const {
  for (std::uint32_t i = 0; i < memory_properties_.memoryTypeCount; ++i) {
    if ((type_bits & (1u << i)) &&
        (memory_properties_.memoryTypes[i].propertyFlags & properties) == properties) {
      return true;
    }
  }
  return false;
}

MemoryLimits host_memory_limits(std::uint64_t limit, const std::string& source) {
  MemoryLimits limits;
  std::ifstream meminfo("/proc/meminfo");
  std::string line;
  while (std::getline(meminfo, line)) {
    std::uint64_t kilobytes = 0;
    if (std::sscanf(line.c_str(), "MemAvailable: %" SCNu64 " kB", &kilobytes) == 1) {
      limits.host = kilobytes * 1024;
      break;
    }
  }
  if (limits.host == 0) {
    const long pages = ::sysconf(_SC_AVPHYS_PAGES), page_size = ::sysconf(_SC_PAGESIZE);
    if (pages > 0 && page_size > 0) limits.host = std::uint64_t(pages) * std::uint64_t(page_size);
  }
  if (limit > 0 && (limits.host == 0 || limit < limits.host)) {
    limits.host = limit;
    limits.limited_by = source.empty() ? std::string("a memory limit") : source;
  }
  return limits;
}

MemoryLimits Context::memory_limits(std::uint64_t limit, const std::string& source) const {
  MemoryLimits limits = host_memory_limits(limit, source);
  limits.device = info_.name;
  limits.device_is_host = info_.type == "cpu";
  limits.max_allocation = max_allocation_;
  // the heaps of the memory types allocate() picks for images and for mapped buffers
  const std::uint32_t any_type = ~0u;
  const std::uint32_t device_heap =
      memory_properties_.memoryTypes[memory_type(any_type, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT)].heapIndex;
  const std::uint32_t visible_heap =
      memory_properties_
          .memoryTypes[memory_type(
              any_type, VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT)]
          .heapIndex;
  limits.device_local = memory_properties_.memoryHeaps[device_heap].size;
  limits.host_visible = memory_properties_.memoryHeaps[visible_heap].size;
  limits.shared_heap = device_heap == visible_heap;
  if (limit > 0) {
    limits.device_local = std::min<std::uint64_t>(limits.device_local, limit);
    limits.host_visible = std::min<std::uint64_t>(limits.host_visible, limit);
  }
  return limits;
}

VkDeviceMemory Context::allocate(const VkMemoryRequirements& requirements,
                                 VkMemoryPropertyFlags properties) const {
  VkMemoryAllocateInfo allocate{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
  allocate.allocationSize = requirements.size;
  allocate.memoryTypeIndex = memory_type(requirements.memoryTypeBits, properties);
  VkDeviceMemory memory = VK_NULL_HANDLE;
  DISPLACE_VK_CHECK(vkAllocateMemory(device_, &allocate, nullptr, &memory));
  memory_allocations_->fetch_add(1);
  return memory;
}

namespace {
constexpr VkMemoryPropertyFlags shared_memory = VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT |
                                                VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT |
                                                VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
}  // namespace

bool Context::host_images(VkFormat format, std::uint32_t width, std::uint32_t height,
                          std::uint32_t layers) const {
  // only the CPU driver: a discrete GPU's host-visible memory sits across the bus, and GPUs sample
  // linear images more slowly than tiled ones (an integrated GPU might still gain; not measured here)
  if (info_.type != "cpu") return false;
  if (!has_memory_type(~0u, shared_memory)) return false;
  VkImageFormatProperties properties{};
  if (vkGetPhysicalDeviceImageFormatProperties(physical_device_, format, VK_IMAGE_TYPE_2D,
                                               VK_IMAGE_TILING_LINEAR, VK_IMAGE_USAGE_SAMPLED_BIT, 0,
                                               &properties) != VK_SUCCESS) {
    return false;
  }
  return width <= properties.maxExtent.width && height <= properties.maxExtent.height &&
         layers <= properties.maxArrayLayers;
}

VkFence Context::create_fence(bool signaled) const {
  VkFenceCreateInfo info{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
  info.flags = signaled ? VK_FENCE_CREATE_SIGNALED_BIT : 0;
  VkFence fence = VK_NULL_HANDLE;
  DISPLACE_VK_CHECK(vkCreateFence(device_, &info, nullptr, &fence));
  return fence;
}

VkCommandBuffer Context::allocate_command_buffer() const {
  VkCommandBufferAllocateInfo info{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
  info.commandPool = command_pool_;
  info.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  info.commandBufferCount = 1;
  VkCommandBuffer commands = VK_NULL_HANDLE;
  DISPLACE_VK_CHECK(vkAllocateCommandBuffers(device_, &info, &commands));
  return commands;
}

VkCommandBuffer Context::allocate_async_command_buffer() const {
  VkCommandBufferAllocateInfo info{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
  info.commandPool = async_apart() ? async_pool_ : command_pool_;
  info.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  info.commandBufferCount = 1;
  VkCommandBuffer commands = VK_NULL_HANDLE;
  DISPLACE_VK_CHECK(vkAllocateCommandBuffers(device_, &info, &commands));
  return commands;
}

void Context::free_async_command_buffer(VkCommandBuffer commands) const {
  vkFreeCommandBuffers(device_, async_apart() ? async_pool_ : command_pool_, 1, &commands);
}

VkSemaphore Context::create_timeline() const {
  VkSemaphoreTypeCreateInfo type{VK_STRUCTURE_TYPE_SEMAPHORE_TYPE_CREATE_INFO};
  type.semaphoreType = VK_SEMAPHORE_TYPE_TIMELINE;
  type.initialValue = 0;
  VkSemaphoreCreateInfo info{VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO};
  info.pNext = &type;
  VkSemaphore semaphore = VK_NULL_HANDLE;
  DISPLACE_VK_CHECK(vkCreateSemaphore(device_, &info, nullptr, &semaphore));
  return semaphore;
}

namespace {
// Concurrent sharing between the frame's family and the async one where they differ and `shared`.
void set_sharing(const Context& context, bool shared, VkSharingMode& mode, std::uint32_t& count,
                 const std::uint32_t*& families, std::uint32_t (&storage)[2]) {
  mode = VK_SHARING_MODE_EXCLUSIVE;
  if (!shared || !context.async_apart()) return;
  storage[0] = context.queue_family();
  storage[1] = context.async_family();
  mode = VK_SHARING_MODE_CONCURRENT;
  count = 2;
  families = storage;
}
}  // namespace

VkCommandBuffer Context::begin_commands() const {
  VkCommandBuffer commands = one_time_commands_;
  DISPLACE_VK_CHECK(vkResetCommandBuffer(commands, 0));
  VkCommandBufferBeginInfo begin{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  DISPLACE_VK_CHECK(vkBeginCommandBuffer(commands, &begin));
  return commands;
}

void Context::end_submit_wait(VkCommandBuffer commands) const {
  DISPLACE_VK_CHECK(vkEndCommandBuffer(commands));
  VkSubmitInfo submit{VK_STRUCTURE_TYPE_SUBMIT_INFO};
  submit.commandBufferCount = 1;
  submit.pCommandBuffers = &commands;
  DISPLACE_VK_CHECK(vkResetFences(device_, 1, &fence_));
  DISPLACE_VK_CHECK(vkQueueSubmit(queue_, 1, &submit, fence_));
  DISPLACE_VK_CHECK(vkWaitForFences(device_, 1, &fence_, VK_TRUE, UINT64_MAX));
}

Buffer::Buffer(const Context& context, VkDeviceSize size, VkBufferUsageFlags usage,
               VkMemoryPropertyFlags properties, bool shared)
    : device_(context.device()), size_(size) {
  VkBufferCreateInfo info{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
  info.size = size;
  info.usage = usage;
  std::uint32_t families[2];
  set_sharing(context, shared, info.sharingMode, info.queueFamilyIndexCount, info.pQueueFamilyIndices,
              families);
  DISPLACE_VK_CHECK(vkCreateBuffer(device_, &info, nullptr, &buffer_));
  VkMemoryRequirements requirements;
  vkGetBufferMemoryRequirements(device_, buffer_, &requirements);
  memory_ = context.allocate(requirements, properties);
  DISPLACE_VK_CHECK(vkBindBufferMemory(device_, buffer_, memory_, 0));
  if (properties & VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT) {
    DISPLACE_VK_CHECK(vkMapMemory(device_, memory_, 0, VK_WHOLE_SIZE, 0, &mapped_));
  }
}

Buffer::~Buffer() {
  if (!device_) return;
  if (buffer_) vkDestroyBuffer(device_, buffer_, nullptr);
  if (memory_) vkFreeMemory(device_, memory_, nullptr);
}

Image::Image(const Context& context, VkFormat format, std::uint32_t width, std::uint32_t height,
             std::uint32_t layers, VkImageUsageFlags usage, VkImageAspectFlags aspect,
             VkImageViewType view_type, bool shared) {
  if (!make(context, format, width, height, layers, usage, aspect, view_type, VK_IMAGE_TILING_OPTIMAL,
            VK_IMAGE_LAYOUT_UNDEFINED, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, shared)) {
    vkDestroyImage(device_, image_, nullptr);  // a constructor that throws runs no destructor
    throw Error("the Vulkan device has no memory type with the properties a buffer or image needs");
  }
}

bool Image::make(const Context& context, VkFormat format, std::uint32_t width, std::uint32_t height,
                 std::uint32_t layers, VkImageUsageFlags usage, VkImageAspectFlags aspect,
                 VkImageViewType view_type, VkImageTiling tiling, VkImageLayout initial_layout,
                 VkMemoryPropertyFlags memory, bool shared) {
  device_ = context.device();
  format_ = format;
  width_ = width;
  height_ = height;
  layers_ = layers;
  const bool volume = view_type == VK_IMAGE_VIEW_TYPE_3D;  // `layers` is the depth of a 3D image
  VkImageCreateInfo info{VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO};
  info.imageType = volume ? VK_IMAGE_TYPE_3D : VK_IMAGE_TYPE_2D;
  info.format = format;
  info.extent = {width, height, volume ? layers : 1};
  info.mipLevels = 1;
  info.arrayLayers = volume ? 1 : layers;
  info.samples = VK_SAMPLE_COUNT_1_BIT;
  info.tiling = tiling;
  info.usage = usage;
  std::uint32_t families[2];
  set_sharing(context, shared, info.sharingMode, info.queueFamilyIndexCount, info.pQueueFamilyIndices,
              families);
  info.initialLayout = initial_layout;
  DISPLACE_VK_CHECK(vkCreateImage(device_, &info, nullptr, &image_));
  VkMemoryRequirements requirements;
  vkGetImageMemoryRequirements(device_, image_, &requirements);
  if (!context.has_memory_type(requirements.memoryTypeBits, memory)) return false;  // the destructor frees it
  memory_ = context.allocate(requirements, memory);
  DISPLACE_VK_CHECK(vkBindImageMemory(device_, image_, memory_, 0));
  VkImageViewCreateInfo view{VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO};
  view.image = image_;
  view.viewType = view_type;
  view.format = format;
  view.subresourceRange = {aspect, 0, 1, 0, volume ? 1 : layers};
  DISPLACE_VK_CHECK(vkCreateImageView(device_, &view, nullptr, &view_));
  return true;
}

Image Image::host_written(const Context& context, VkFormat format, std::uint32_t width, std::uint32_t height,
                          std::uint32_t layers, VkImageViewType view_type) {
  Image image;
  if (!image.make(context, format, width, height, layers, VK_IMAGE_USAGE_SAMPLED_BIT,
                  VK_IMAGE_ASPECT_COLOR_BIT, view_type, VK_IMAGE_TILING_LINEAR,
                  VK_IMAGE_LAYOUT_PREINITIALIZED, shared_memory)) {
    return Image();  // no shared memory type it may live in: the caller makes an optimal one
  }
  void* mapped = nullptr;
  DISPLACE_VK_CHECK(vkMapMemory(image.device_, image.memory_, 0, VK_WHOLE_SIZE, 0, &mapped));
  const VkImageSubresource first{VK_IMAGE_ASPECT_COLOR_BIT, 0, 0};
  VkSubresourceLayout layout{};
  vkGetImageSubresourceLayout(image.device_, image.image_, &first, &layout);
  image.mapped_ = static_cast<std::byte*>(mapped) + layout.offset;
  image.row_pitch_ = layout.rowPitch;
  image.layer_pitch_ = layout.arrayPitch;
  return image;
}

Image::~Image() {
  if (!device_) return;
  if (view_) vkDestroyImageView(device_, view_, nullptr);
  if (image_) vkDestroyImage(device_, image_, nullptr);
  if (memory_) vkFreeMemory(device_, memory_, nullptr);
}

OwnedShaderModule shader_module(VkDevice device, std::span<const std::uint32_t> code) {
  VkShaderModuleCreateInfo info{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
  info.codeSize = code.size_bytes();
  info.pCode = code.data();
  VkShaderModule module = VK_NULL_HANDLE;
  DISPLACE_VK_CHECK(vkCreateShaderModule(device, &info, nullptr, &module));
  return OwnedShaderModule(device, module);
}

// (context.h) SPIRV-Tools' folding of the constants, dead-branch and dead-code elimination,
// none of which touches arithmetic, so the pipeline computes what the driver's own specialization of
// the whole module would, bit for bit; the stages' interfaces are kept whole (an output that the next
// stage no longer reads is a validation warning). The renderer's fragment module is the uber-shader
// of every method: lavapipe translated all of it for each pipeline before it dropped the other
// methods' code (1.3 s a pipeline here, 0.13 s with the pruned module; docs/design/renderer.md).
OwnedShaderModule specialised_shader(VkDevice device, std::span<const std::uint32_t> code,
                                     std::span<const std::int32_t> constants) {
  spvtools::Optimizer optimizer(SPV_ENV_VULKAN_1_2);
  std::string failure;
  optimizer.SetMessageConsumer(
      [&](spv_message_level_t level, const char*, const spv_position_t&, const char* text) {
        if (level <= SPV_MSG_ERROR) failure += text;
      });
  std::unordered_map<std::uint32_t, std::vector<std::uint32_t>> values;  // a bool: 0 is false
  for (std::size_t id = 0; id < constants.size(); ++id)
    values[std::uint32_t(id)] = {std::uint32_t(constants[id])};
  optimizer.RegisterPass(spvtools::CreateSetSpecConstantDefaultValuePass(values));
  optimizer.RegisterPass(spvtools::CreateFreezeSpecConstantValuePass());
  optimizer.RegisterPass(spvtools::CreateFoldSpecConstantOpAndCompositePass());
  optimizer.RegisterPass(spvtools::CreateDeadBranchElimPass());
  optimizer.RegisterPass(spvtools::CreateAggressiveDCEPass(/*preserve_interface=*/true));
  optimizer.RegisterPass(spvtools::CreateEliminateDeadFunctionsPass());
  std::vector<std::uint32_t> specialised;
  if (!optimizer.Run(code.data(), code.size(), &specialised))
    throw Error("specialising a shader failed: " + failure);
  return shader_module(device, specialised);
}

}  // namespace displace::vulkan
