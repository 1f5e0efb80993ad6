// sim/device/device_fft.cpp - the device ocean's inverse FFTs through VkFFT (Tolmachev, "VkFFT - a
// performant, cross-platform and open-source GPU FFT library", IEEE Access 2023), Vulkan backend: it
// generates its kernels for the sizes and compiles them with glslang when the plan is made.
#define VKFFT_BACKEND 0
#include "sim/device/device_fft.h"

#include <vkFFT.h>

#include <string>

#include "vulkan/compute.h"
#include "vulkan/device_maps.h"
#include "vulkan/frames.h"

namespace displace::sim {

using namespace vulkan;  // the Vulkan base (vulkan/): Context, Buffer, Image, kernels, barriers

struct DeviceFft::State {
  VkFFTApplication app{};
  // what VkFFT's configuration points at, for the plan's life
  VkPhysicalDevice physical_device = VK_NULL_HANDLE;
  VkDevice device = VK_NULL_HANDLE;
  VkQueue queue = VK_NULL_HANDLE;
  VkCommandPool command_pool = VK_NULL_HANDLE;
  OwnedFence fence;  // VkFFT's, for the uploads it makes while planning
  VkFence fence_handle = VK_NULL_HANDLE;
  VkBuffer buffer = VK_NULL_HANDLE;
  std::uint64_t bytes = 0;
  bool planned = false;
  ~State() {
    if (planned) deleteVkFFT(&app);
  }
};

DeviceFft::DeviceFft(const Context& context, VkBuffer buffer, VkDeviceSize bytes, int size, int batches)
    : state_(std::make_unique<State>()) {
  State& s = *state_;
  s.physical_device = context.physical_device();
  s.device = context.device();
  s.queue = context.queue();
  s.command_pool = context.command_pool();
  s.fence = OwnedFence(context.device(), context.create_fence(false));
  s.fence_handle = s.fence.get();
  s.buffer = buffer;
  s.bytes = bytes;
  VkFFTConfiguration configuration{};
  configuration.FFTdim = 2;
  configuration.size[0] = std::uint64_t(size);  // x: the real axis, halved in the spectrum
  configuration.size[1] = std::uint64_t(size);
  configuration.numberBatches = std::uint64_t(batches);
  configuration.performR2C = 1;
  configuration.makeInversePlanOnly = 1;
  configuration.physicalDevice = &s.physical_device;
  configuration.device = &s.device;
  configuration.queue = &s.queue;
  configuration.commandPool = &s.command_pool;
  configuration.fence = &s.fence_handle;
  configuration.buffer = &s.buffer;
  configuration.bufferSize = &s.bytes;
  const VkFFTResult result = initializeVkFFT(&s.app, configuration);
  if (result != VKFFT_SUCCESS) {
    throw vulkan::Error("VkFFT could not plan the ocean's " + std::to_string(size) + "x" +
                        std::to_string(size) + " inverse FFT (VkFFTResult " + std::to_string(int(result)) +
                        ")");
  }
  s.planned = true;
}

DeviceFft::~DeviceFft() = default;

void DeviceFft::record_inverse(VkCommandBuffer commands) {
  VkFFTLaunchParams launch{};
  launch.commandBuffer = &commands;
  launch.buffer = &state_->buffer;
  const VkFFTResult result = VkFFTAppend(&state_->app, 1, &launch);
  if (result != VKFFT_SUCCESS) {
    throw vulkan::Error("VkFFT could not record the ocean's inverse FFT (VkFFTResult " +
                        std::to_string(int(result)) + ")");
  }
}

}  // namespace displace::sim
