// vulkan/compute.cpp - compute kernels, barriers and stage timers (compute.h).
#include "vulkan/compute.h"

#include <vector>

namespace displace::vulkan {

ComputeKernel::ComputeKernel(const Context& context, std::span<const std::uint32_t> spirv,
                             std::span<const VkDescriptorType> bindings, std::uint32_t push_constant_bytes,
                             std::span<const std::int32_t> constants)
    : device_(context.device()),
      bindings_(bindings.begin(), bindings.end()),
      push_bytes_(push_constant_bytes) {
  auto shared = std::make_shared<Pipeline>();
  std::vector<VkDescriptorSetLayoutBinding> layout_bindings;
  for (std::uint32_t i = 0; i < bindings.size(); ++i)
    layout_bindings.push_back({i, bindings[i], 1, VK_SHADER_STAGE_COMPUTE_BIT, nullptr});
  VkDescriptorSetLayoutCreateInfo set_info{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
  set_info.bindingCount = std::uint32_t(layout_bindings.size());
  set_info.pBindings = layout_bindings.data();
  VkDescriptorSetLayout set_layout = VK_NULL_HANDLE;
  DISPLACE_VK_CHECK(vkCreateDescriptorSetLayout(device_, &set_info, nullptr, &set_layout));
  shared->set_layout = OwnedDescriptorSetLayout(device_, set_layout);

  VkPushConstantRange push{VK_SHADER_STAGE_COMPUTE_BIT, 0, push_constant_bytes};
  VkPipelineLayoutCreateInfo layout_info{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
  layout_info.setLayoutCount = 1;
  layout_info.pSetLayouts = &set_layout;
  layout_info.pushConstantRangeCount = push_constant_bytes > 0 ? 1 : 0;
  layout_info.pPushConstantRanges = &push;
  VkPipelineLayout layout = VK_NULL_HANDLE;
  DISPLACE_VK_CHECK(vkCreatePipelineLayout(device_, &layout_info, nullptr, &layout));
  shared->layout = OwnedPipelineLayout(device_, layout);

  // the specialization constants frozen into the module (specialised_shader), where there are any
  shared->module =
      constants.empty() ? shader_module(device_, spirv) : specialised_shader(device_, spirv, constants);

  VkComputePipelineCreateInfo pipeline_info{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
  pipeline_info.stage = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
  pipeline_info.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
  pipeline_info.stage.module = shared->module.get();
  pipeline_info.stage.pName = "main";
  pipeline_info.layout = layout;
  VkPipeline pipeline = VK_NULL_HANDLE;
  DISPLACE_VK_CHECK(vkCreateComputePipelines(device_, VK_NULL_HANDLE, 1, &pipeline_info, nullptr, &pipeline));
  shared->pipeline = OwnedPipeline(device_, pipeline);
  shared_ = std::move(shared);
  allocate_set();
}

ComputeKernel ComputeKernel::sibling() const {
  ComputeKernel kernel;
  kernel.device_ = device_;
  kernel.bindings_ = bindings_;
  kernel.push_bytes_ = push_bytes_;
  kernel.shared_ = shared_;
  kernel.allocate_set();
  return kernel;
}

void ComputeKernel::allocate_set() {
  std::vector<VkDescriptorPoolSize> sizes;
  for (VkDescriptorType type : bindings_) sizes.push_back({type, 1});
  VkDescriptorPoolCreateInfo pool_info{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
  pool_info.maxSets = 1;
  pool_info.poolSizeCount = std::uint32_t(sizes.size());
  pool_info.pPoolSizes = sizes.data();
  VkDescriptorPool pool = VK_NULL_HANDLE;
  DISPLACE_VK_CHECK(vkCreateDescriptorPool(device_, &pool_info, nullptr, &pool));
  pool_ = OwnedDescriptorPool(device_, pool);
  const VkDescriptorSetLayout set_layout = shared_->set_layout.get();
  VkDescriptorSetAllocateInfo allocate{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
  allocate.descriptorPool = pool;
  allocate.descriptorSetCount = 1;
  allocate.pSetLayouts = &set_layout;
  DISPLACE_VK_CHECK(vkAllocateDescriptorSets(device_, &allocate, &set_));
}

void ComputeKernel::bind_buffer(std::uint32_t binding, VkBuffer buffer, VkDeviceSize offset,
                                VkDeviceSize range) {
  VkDescriptorBufferInfo info{buffer, offset, range};
  VkWriteDescriptorSet write{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
  write.dstSet = set_;
  write.dstBinding = binding;
  write.descriptorCount = 1;
  write.descriptorType = bindings_[binding];
  write.pBufferInfo = &info;
  vkUpdateDescriptorSets(device_, 1, &write, 0, nullptr);
}

void ComputeKernel::bind_image(std::uint32_t binding, VkImageView view, VkImageLayout layout,
                               VkSampler sampler) {
  VkDescriptorImageInfo info{sampler, view, layout};
  VkWriteDescriptorSet write{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
  write.dstSet = set_;
  write.dstBinding = binding;
  write.descriptorCount = 1;
  write.descriptorType = bindings_[binding];
  write.pImageInfo = &info;
  vkUpdateDescriptorSets(device_, 1, &write, 0, nullptr);
}

void ComputeKernel::record(VkCommandBuffer commands, std::uint32_t groups_x, std::uint32_t groups_y,
                           std::uint32_t groups_z, const void* push) const {
  vkCmdBindPipeline(commands, VK_PIPELINE_BIND_POINT_COMPUTE, shared_->pipeline.get());
  VkDescriptorSet set = set_;
  vkCmdBindDescriptorSets(commands, VK_PIPELINE_BIND_POINT_COMPUTE, shared_->layout.get(), 0, 1, &set, 0,
                          nullptr);
  if (push_bytes_ > 0) {
    vkCmdPushConstants(commands, shared_->layout.get(), VK_SHADER_STAGE_COMPUTE_BIT, 0, push_bytes_, push);
  }
  vkCmdDispatch(commands, groups_x, groups_y, groups_z);
}

StageTimer::StageTimer(const Context& context)
    : device_(context.device()), period_ns_(context.timestamp_period_ns()) {
  if (!context.has_timestamps()) return;
  VkQueryPoolCreateInfo info{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
  info.queryType = VK_QUERY_TYPE_TIMESTAMP;
  info.queryCount = 2 * 32;  // two per frame slot
  VkQueryPool pool = VK_NULL_HANDLE;
  DISPLACE_VK_CHECK(vkCreateQueryPool(device_, &info, nullptr, &pool));
  queries_ = OwnedQueryPool(device_, pool);
}

void StageTimer::read(int slot) {
  if (!queries_.get() || slot < 0 || slot >= 32 || !(written_ & (1u << slot))) return;
  std::uint64_t ticks[2] = {};
  if (vkGetQueryPoolResults(device_, queries_.get(), std::uint32_t(2 * slot), 2, sizeof ticks, ticks,
                            sizeof(std::uint64_t), VK_QUERY_RESULT_64_BIT) == VK_SUCCESS) {
    milliseconds_ = double(ticks[1] - ticks[0]) * double(period_ns_) * 1e-6;
  }
}

void StageTimer::begin(VkCommandBuffer commands, int slot) {
  if (!queries_.get() || slot < 0 || slot >= 32) return;
  const auto first = std::uint32_t(2 * slot);
  read(slot);  // the slot's last frame has finished (begin_slot waited for it)
  written_ &= ~(1u << slot);
  vkCmdResetQueryPool(commands, queries_.get(), first, 2);
  vkCmdWriteTimestamp(commands, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, queries_.get(), first);
}

void StageTimer::end(VkCommandBuffer commands, int slot) {
  if (!queries_.get() || slot < 0 || slot >= 32) return;
  vkCmdWriteTimestamp(commands, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, queries_.get(),
                      std::uint32_t(2 * slot + 1));
  written_ |= 1u << slot;
  last_slot_ = slot;
}

void host_read_barrier(VkCommandBuffer commands) {
  VkMemoryBarrier to_host{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  to_host.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
  to_host.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
  vkCmdPipelineBarrier(commands, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &to_host,
                       0, nullptr, 0, nullptr);
}

void rewrite_barrier(VkCommandBuffer commands) {
  VkMemoryBarrier barrier{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  barrier.srcAccessMask =
      VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_READ_BIT;
  barrier.dstAccessMask = VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT;
  vkCmdPipelineBarrier(commands,
                       VK_PIPELINE_STAGE_VERTEX_SHADER_BIT | VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT |
                           VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
                       VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 1, &barrier,
                       0, nullptr, 0, nullptr);
}

void compute_barrier(VkCommandBuffer commands) {
  VkMemoryBarrier barrier{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  barrier.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
  barrier.dstAccessMask =
      VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_READ_BIT;
  vkCmdPipelineBarrier(commands, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                       VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT |
                           VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT | VK_PIPELINE_STAGE_VERTEX_SHADER_BIT,
                       0, 1, &barrier, 0, nullptr, 0, nullptr);
}

void image_barrier(VkCommandBuffer commands, VkImage image, std::uint32_t layers, VkImageLayout from,
                   VkImageLayout to, VkAccessFlags src_access, VkAccessFlags dst_access,
                   VkPipelineStageFlags src_stage, VkPipelineStageFlags dst_stage) {
  VkImageMemoryBarrier barrier{VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER};
  barrier.srcAccessMask = src_access;
  barrier.dstAccessMask = dst_access;
  barrier.oldLayout = from;
  barrier.newLayout = to;
  barrier.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  barrier.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  barrier.image = image;
  barrier.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, layers};
  vkCmdPipelineBarrier(commands, src_stage, dst_stage, 0, 0, nullptr, 0, nullptr, 1, &barrier);
}

}  // namespace displace::vulkan
