// tests/render/queue_family_test.cpp - which queue family takes the work beside the frame's
// (vulkan/context.h's pick_async_family): only a GPU has one apart, so the choice is checked
// here on the families such devices report.
#include <gtest/gtest.h>

#include <vector>

#include "vulkan/context.h"

namespace {

using displace::vulkan::pick_async_family;

VkQueueFamilyProperties family(VkQueueFlags flags, std::uint32_t count, std::uint32_t timestamp_bits) {
  VkQueueFamilyProperties properties{};
  properties.queueFlags = flags;
  properties.queueCount = count;
  properties.timestampValidBits = timestamp_bits;
  return properties;
}

constexpr VkQueueFlags graphics = VK_QUEUE_GRAPHICS_BIT | VK_QUEUE_COMPUTE_BIT | VK_QUEUE_TRANSFER_BIT;
constexpr VkQueueFlags compute = VK_QUEUE_COMPUTE_BIT | VK_QUEUE_TRANSFER_BIT;
constexpr VkQueueFlags transfer = VK_QUEUE_TRANSFER_BIT;

TEST(QueueFamily, TheAsyncQueueIsAComputeOnlyFamilysWithTimestampsWhereAsked) {
  // an NVIDIA GPU's families: graphics, transfer, compute (and video ones with no compute)
  const std::vector<VkQueueFamilyProperties> nvidia = {family(graphics, 16, 64), family(transfer, 2, 64),
                                                       family(compute, 8, 64), family(0x20, 1, 32)};
  EXPECT_EQ(pick_async_family(nvidia, true), 2);
  // an AMD GPU's: compute before transfer
  const std::vector<VkQueueFamilyProperties> amd = {family(graphics, 1, 64), family(compute, 4, 64),
                                                    family(transfer, 2, 64)};
  EXPECT_EQ(pick_async_family(amd, true), 1);
  // lavapipe: one family, graphics and compute: none apart
  const std::vector<VkQueueFamilyProperties> lavapipe = {family(graphics, 1, 64)};
  EXPECT_EQ(pick_async_family(lavapipe, true), -1);
  // a compute family without timestamps is passed over when the frame's stages are timed
  const std::vector<VkQueueFamilyProperties> untimed = {family(graphics, 1, 64), family(compute, 2, 0)};
  EXPECT_EQ(pick_async_family(untimed, true), -1);
  EXPECT_EQ(pick_async_family(untimed, false), 1);
  // a family with no queues is none
  const std::vector<VkQueueFamilyProperties> empty = {family(graphics, 1, 64), family(compute, 0, 64)};
  EXPECT_EQ(pick_async_family(empty, true), -1);
}

}  // namespace
