// vulkan/compute.h - one compute shader as a pipeline with its own descriptor set and push constants:
// the device stages' kernels (the ocean, the cone maps, the levels), with the barriers and timers
// they record. Not installed.
//
// A kernel is made once from its SPIR-V, the descriptor types of its bindings 0..n-1 (set 0) and the
// values of its 32-bit specialization constants 0..m-1 (ints, or bools as 0 and 1), if any;
// bind_*() write its one descriptor set (only while no submitted work uses it), record() binds the
// pipeline and set, pushes the constants and dispatches. compute_barrier() orders one kernel's writes
// before the next one's reads.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "vulkan/context.h"

namespace displace::vulkan {

class ComputeKernel {
 public:
  ComputeKernel() = default;
  ComputeKernel(const Context& context, std::span<const std::uint32_t> spirv,
                std::span<const VkDescriptorType> bindings, std::uint32_t push_constant_bytes,
                std::span<const std::int32_t> constants = {});
  ComputeKernel(ComputeKernel&&) noexcept = default;
  ComputeKernel& operator=(ComputeKernel&&) noexcept = default;
  // A kernel with this one's pipeline (made once: a driver may take long to compile one) and a
  // descriptor set of its own, for other resources.
  ComputeKernel sibling() const;
  bool made() const { return shared_ != nullptr; }

  void bind_buffer(std::uint32_t binding, VkBuffer buffer, VkDeviceSize offset = 0,
                   VkDeviceSize range = VK_WHOLE_SIZE);
  // A storage image (VK_IMAGE_LAYOUT_GENERAL) or, with a sampler, a combined image sampler.
  void bind_image(std::uint32_t binding, VkImageView view, VkImageLayout layout = VK_IMAGE_LAYOUT_GENERAL,
                  VkSampler sampler = VK_NULL_HANDLE);
  // Dispatches groups (x, y, z) with `push` (push_constant_bytes) as the push constants.
  void record(VkCommandBuffer commands, std::uint32_t groups_x, std::uint32_t groups_y,
              std::uint32_t groups_z, const void* push) const;

 private:
  // the pipeline and its layouts, shared with siblings
  struct Pipeline {
    OwnedDescriptorSetLayout set_layout;
    OwnedPipelineLayout layout;
    OwnedShaderModule module;
    OwnedPipeline pipeline;
  };
  void allocate_set();

  VkDevice device_ = VK_NULL_HANDLE;
  std::vector<VkDescriptorType> bindings_;
  std::uint32_t push_bytes_ = 0;
  std::shared_ptr<const Pipeline> shared_;
  OwnedDescriptorPool pool_;
  VkDescriptorSet set_ = VK_NULL_HANDLE;  // freed with the pool
};

// Shader writes (storage buffers and images) of the compute work recorded so far made visible to the
// compute, transfer and fragment/vertex work recorded after it.
void compute_barrier(VkCommandBuffer commands);

// A device stage's own time: two timestamps per frame slot around its commands, read back once that
// slot's frame has finished (the next begin() on the slot, after begin_slot waited for it). Nothing
// where the device has no timestamps.
class StageTimer {
 public:
  StageTimer() = default;
  explicit StageTimer(const Context& context);
  void begin(VkCommandBuffer commands, int slot);
  void end(VkCommandBuffer commands, int slot);
  // The slot of the last end() (-1: none); read its timestamps now when the caller knows that slot's
  // frame has finished.
  int last_slot() const { return last_slot_; }
  void read(int slot);
  // Milliseconds of the last finished stage read (0: none yet, or no timestamps).
  double milliseconds() const { return milliseconds_; }

 private:
  VkDevice device_ = VK_NULL_HANDLE;
  float period_ns_ = 0.0f;
  OwnedQueryPool queries_;
  std::uint32_t written_ = 0;  // bit s: slot s holds a stage's two timestamps
  int last_slot_ = -1;
  double milliseconds_ = 0.0;
};

// Transfer writes recorded so far (copies into host-visible buffers) made visible to the host once
// the submission has finished.
void host_read_barrier(VkCommandBuffer commands);

// Before a device stage writes again what earlier frames' shaders and copies read or wrote (its maps
// and buffers): their vertex, fragment, compute and transfer work ends first.
void rewrite_barrier(VkCommandBuffer commands);

// A layout transition of every layer of `image`'s colour, after `src` work and before `dst` work.
void image_barrier(VkCommandBuffer commands, VkImage image, std::uint32_t layers, VkImageLayout from,
                   VkImageLayout to, VkAccessFlags src_access, VkAccessFlags dst_access,
                   VkPipelineStageFlags src_stage, VkPipelineStageFlags dst_stage);
// Groups of `local` invocations that cover `count`.
inline std::uint32_t group_count(std::uint32_t count, std::uint32_t local) {
  return (count + local - 1) / local;
}

}  // namespace displace::vulkan
