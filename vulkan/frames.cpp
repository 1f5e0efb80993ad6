// vulkan/frames.cpp - the frame slots and the async queue's ordering (frames.h).
#include "vulkan/frames.h"

#include <algorithm>
#include <limits>

namespace displace::vulkan {

namespace {
constexpr std::uint64_t forever = std::numeric_limits<std::uint64_t>::max();
}

Frames::Frames(const DeviceOptions& options) : context_(options) {
  const VkDevice device = context_.device();
  frame_timeline_ = OwnedSemaphore(device, context_.create_timeline());
  async_timeline_ = OwnedSemaphore(device, context_.create_timeline());
  deferred_async_.reserve(4 * frames_in_flight);
  for (Slot& slot : slots_) {
    slot.commands = context_.allocate_command_buffer();
    slot.spare = context_.allocate_command_buffer();
    slot.fence = OwnedFence(device, context_.create_fence(true));
  }
}

Frames::~Frames() {
  try {
    drain();
  } catch (...) {
  }
}

VkCommandBuffer Frames::begin() {
  Slot& slot = slots_[std::size_t(slot_)];
  if (slot.recording) return slot.commands;
  const VkFence fence = slot.fence.get();
  DISPLACE_VK_CHECK(vkWaitForFences(context_.device(), 1, &fence, VK_TRUE, forever));
  DISPLACE_VK_CHECK(vkResetCommandBuffer(slot.commands, 0));
  DISPLACE_VK_CHECK(vkResetCommandBuffer(slot.spare, 0));
  VkCommandBufferBeginInfo begin{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  DISPLACE_VK_CHECK(vkBeginCommandBuffer(slot.commands, &begin));
  slot.recording = true;
  slot.flushed = 0;
  return slot.commands;
}

// The frame queue's submission of `commands`: after the async work it must wait for, signalling
// the frame timeline's next value.
std::uint64_t Frames::submit_frame(VkCommandBuffer commands, VkFence fence) {
  const bool waits = frame_waits_for_ > frame_waited_;
  if (waits) release_async(frame_waits_for_);
  submit_commands(context_.queue(), commands,
                  {waits ? async_timeline_.get() : VK_NULL_HANDLE, frame_waits_for_},
                  VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, {frame_timeline_.get(), frame_signalled_ + 1}, fence);
  if (waits) frame_waited_ = frame_waits_for_;
  return ++frame_signalled_;
}

void Frames::submit(bool wait) {
  Slot& slot = slots_[std::size_t(slot_)];
  if (!slot.recording) return;
  DISPLACE_VK_CHECK(vkEndCommandBuffer(slot.commands));
  slot.recording = false;
  const VkFence fence = slot.fence.get();
  DISPLACE_VK_CHECK(vkResetFences(context_.device(), 1, &fence));
  submit_frame(slot.commands, fence);
  if (wait) DISPLACE_VK_CHECK(vkWaitForFences(context_.device(), 1, &fence, VK_TRUE, forever));
  slot_ = (slot_ + 1) % frames_in_flight;
}

std::uint64_t Frames::flush() {
  begin();
  Slot& slot = slots_[std::size_t(slot_)];
  DISPLACE_VK_CHECK(vkEndCommandBuffer(slot.commands));
  if (slot.flushed > 0) {  // a second flush of this recording: the spare holds the first
    wait_timeline(frame_timeline_.get(), slot.flushed);
    DISPLACE_VK_CHECK(vkResetCommandBuffer(slot.spare, 0));
  }
  const std::uint64_t value = submit_frame(slot.commands, VK_NULL_HANDLE);
  slot.flushed = value;
  std::swap(slot.commands, slot.spare);  // reset by begin (or just above)
  VkCommandBufferBeginInfo begin_info{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  begin_info.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  DISPLACE_VK_CHECK(vkBeginCommandBuffer(slot.commands, &begin_info));
  return value;
}

bool Frames::finished(int index) const {
  const Slot& slot = slots_[std::size_t(index)];
  return !slot.recording && vkGetFenceStatus(context_.device(), slot.fence.get()) == VK_SUCCESS;
}

void Frames::wait_submitted() {
  for (const Slot& slot : slots_) {
    if (slot.recording) continue;  // nothing of it submitted since its fence was waited for
    const VkFence fence = slot.fence.get();
    DISPLACE_VK_CHECK(vkWaitForFences(context_.device(), 1, &fence, VK_TRUE, forever));
  }
  wait_async(async_signalled_);
}

void Frames::drain() {
  submit(false);
  release_async(async_signalled_);
  DISPLACE_VK_CHECK(vkDeviceWaitIdle(context_.device()));
}

std::uint64_t Frames::submit_async(VkCommandBuffer commands, std::uint64_t after_frame) {
  const std::uint64_t value = ++async_signalled_;
  if (!hold_async_ || context_.async_apart()) {
    submit_commands(context_.async_queue(), commands,
                    {after_frame > 0 ? frame_timeline_.get() : VK_NULL_HANDLE, after_frame},
                    VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, {async_timeline_.get(), value}, VK_NULL_HANDLE);
  } else {
    deferred_async_.push_back({commands, after_frame, value});
  }
  return value;
}

void Frames::release_async(std::uint64_t value) {
  std::size_t released = 0;
  for (; released < deferred_async_.size() && deferred_async_[released].value <= value; ++released) {
    const DeferredAsync& work = deferred_async_[released];
    submit_commands(context_.async_queue(), work.commands,
                    {work.after_frame > 0 ? frame_timeline_.get() : VK_NULL_HANDLE, work.after_frame},
                    VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, {async_timeline_.get(), work.value}, VK_NULL_HANDLE);
  }
  deferred_async_.erase(deferred_async_.begin(), deferred_async_.begin() + std::ptrdiff_t(released));
}

bool Frames::async_finished(std::uint64_t value) const {
  std::uint64_t reached = 0;
  DISPLACE_VK_CHECK(vkGetSemaphoreCounterValue(context_.device(), async_timeline_.get(), &reached));
  return reached >= value;
}

void Frames::wait_async(std::uint64_t value) {
  release_async(value);
  wait_timeline(async_timeline_.get(), value);
}

void Frames::wait_timeline(VkSemaphore semaphore, std::uint64_t value) const {
  if (value == 0) return;
  VkSemaphoreWaitInfo info{VK_STRUCTURE_TYPE_SEMAPHORE_WAIT_INFO};
  info.semaphoreCount = 1;
  info.pSemaphores = &semaphore;
  info.pValues = &value;
  DISPLACE_VK_CHECK(vkWaitSemaphores(context_.device(), &info, forever));
}

double Frames::finished_milliseconds(StageTimer& timer) const {
  if (timer.last_slot() >= 0 && finished(timer.last_slot())) timer.read(timer.last_slot());
  return timer.milliseconds();
}

}  // namespace displace::vulkan
