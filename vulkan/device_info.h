// vulkan/device_info.h - what a Vulkan device is and what memory it and the host offer, as plain
// values: no Vulkan header, so that what only names a device (a scene, pipeline/scene.h) does not
// pull in Vulkan.
//
// DeviceInfo: one device the Vulkan loader sees (list_devices, Renderer::device). MemoryLimits: what
// the memory guards (render/memory.h) count on. list_devices and default_device ask the loader
// without making a device; both throw Error (saying what to install) when there is none.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace displace::vulkan {

// Texels a side of a map any device layer makes or samples at most (render::max_map_side).
inline constexpr int max_map_side = 16384;

struct DeviceInfo {
  int index = 0;
  std::string name;
  std::string type;                // "discrete-gpu", "integrated-gpu", "virtual-gpu", "cpu", "other"
  int max_image_dimension_3d = 0;  // texels a side of a 3D image (the distance map)
  std::uint64_t max_storage_buffer_range = 0;  // bytes of one storage buffer (the max pyramid)
  // Linear filtering's weights are fixed point with this many fraction bits (subTexelPrecisionBits;
  // Vulkan asks for 4 at least, NVIDIA has 8): where a filtered read may be off (the distance map's
  // trilinear reads), the shaders allow for it.
  int sub_texel_precision_bits = 4;
  // The device path's lagged cone bands run on a queue of a compute-only family, beside the frame's
  // draw (DeviceOptions::async_compute, and the device has such a family with timestamps)
  bool compute_queue_apart = false;
};

// What the machine offers. A CPU device (lavapipe) allocates from the process's own memory and
// reports a nominal heap (2 GiB on Mesa 22.3, whatever the machine has): there every byte counts
// against `host` and the heap sizes are not used.
struct MemoryLimits {
  std::string device;                // the device's name, for the messages; empty: no device (host work only)
  std::uint64_t host = 0;            // bytes of host memory available now
  std::uint64_t device_local = 0;    // bytes of the heap device-local memory comes from
  std::uint64_t host_visible = 0;    // bytes of the heap host-visible memory comes from
  bool shared_heap = false;          // both come from one heap
  bool device_is_host = false;       // a CPU device: device memory is host memory
  std::uint64_t max_allocation = 0;  // bytes of one Vulkan allocation at most (maxMemoryAllocationSize)
  std::string limited_by;            // non-empty: the limit was lowered by this (named in the messages)
};

// Host memory available now (MemAvailable of /proc/meminfo, else the free physical pages), lowered
// to `limit` bytes when that is not 0 (`source` names the limit in the messages); no device.
MemoryLimits host_memory_limits(std::uint64_t limit = 0, const std::string& source = {});

// Devices the Vulkan loader sees.
std::vector<DeviceInfo> list_devices();
// The device a Context made with default DeviceOptions uses (the best-ranked usable one), without
// making it; throws Error as that Context would when there is none.
DeviceInfo default_device();

}  // namespace displace::vulkan
