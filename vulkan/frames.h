// vulkan/frames.h - one device and its frames in flight: the command buffers every layer records a
// frame's work into (the device stages' compute, the renderer's copies and draw), the fence of each
// frame, and a second queue for work beside the frames. Not installed; the device stages
// (sim/device, bake/device) and the renderer share one Frames (Renderer::frames()).
//
// A frame slot begins recording when someone first records into it (begin(), after waiting for the
// slot's previous frame), and submit() ends it, submits it with the slot's fence and moves on to the
// next slot: what the stages record before the renderer's draw runs before it, in order, on one queue.
// Async work (submit_async) goes to Context::async_queue, ordered against the frames by two timeline
// semaphores: every frame submission signals the next value of one, every async one of the other.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "vulkan/compute.h"
#include "vulkan/context.h"

namespace displace::vulkan {

inline constexpr int frames_in_flight = 2;

using OwnedFence = Owned<VkFence, vkDestroyFence>;

class Frames {
 public:
  explicit Frames(const DeviceOptions& options);
  ~Frames();  // waits for everything submitted
  Frames(const Frames&) = delete;
  Frames& operator=(const Frames&) = delete;

  Context& context() { return context_; }
  const Context& context() const { return context_; }

  // The slot the next frame records into (0 .. frames_in_flight - 1), and whether it is recording.
  int slot() const { return slot_; }
  bool recording() const { return slots_[std::size_t(slot_)].recording; }
  // The current slot's command buffer, recording: begins it when it is not (waits for the slot's
  // previous frame first).
  VkCommandBuffer begin();
  // Ends and submits the current slot (nothing when it is not recording) with its fence, waiting for
  // it when `wait`; the next frame takes the next slot.
  void submit(bool wait);
  // Ends and submits what the current slot recorded so far (no fence: the slot's own submission still
  // follows) and goes on recording in the slot's other command buffer; returns the frame timeline's
  // value that submission signals.
  std::uint64_t flush();
  // Whether the frame last submitted from slot `index` has finished (and nothing is recorded there).
  bool finished(int index) const;
  // Waits for every frame submitted and every async submission.
  void wait_submitted();
  // Submits what is recorded and waits until the device is idle.
  void drain();

  // Submits `commands` (from Context::allocate_async_command_buffer) to the async queue, after the
  // frame timeline's value `after_frame` (0: nothing); returns the async value it signals.
  std::uint64_t submit_async(VkCommandBuffer commands, std::uint64_t after_frame);
  // The frame queue's next submission (and every later one) waits for async `value`.
  void frame_waits_for_async(std::uint64_t value) { frame_waits_for_ = std::max(frame_waits_for_, value); }
  bool async_finished(std::uint64_t value) const;
  void wait_async(std::uint64_t value);  // on the host
  // Where the async queue is the frame's own (lavapipe): each async submission is held on the host
  // until a frame submission or a host wait needs it, so that it runs as late as a GPU's other queue
  // may run it (the tests' switch, render/testing.h).
  void hold_async_work(bool hold) { hold_async_ = hold; }

  // A stage's milliseconds (StageTimer), the timestamps of its last frame read first when that frame
  // has finished.
  double finished_milliseconds(StageTimer& timer) const;

  // What a kind of stage makes once per device and shares (its compiled kernels), by a name of its
  // own; null until the first stage of that kind sets it.
  std::shared_ptr<void>& shared(const std::string& name) { return shared_[name]; }

 private:
  struct Slot {
    VkCommandBuffer commands = VK_NULL_HANDLE;  // the one recording (flush swaps in `spare`)
    VkCommandBuffer spare = VK_NULL_HANDLE;
    std::uint64_t flushed = 0;  // the frame timeline value of this recording's flush (0: none)
    OwnedFence fence;           // signalled: nothing of this slot is in flight
    bool recording = false;     // begun, not yet submitted
  };
  struct DeferredAsync {
    VkCommandBuffer commands;
    std::uint64_t after_frame, value;
  };
  std::uint64_t submit_frame(VkCommandBuffer commands, VkFence fence);
  void release_async(std::uint64_t value);  // submits the held ones up to `value`
  void wait_timeline(VkSemaphore timeline, std::uint64_t value) const;

  Context context_;
  std::array<Slot, frames_in_flight> slots_;
  int slot_ = 0;
  OwnedSemaphore frame_timeline_, async_timeline_;
  std::uint64_t frame_signalled_ = 0, async_signalled_ = 0;
  std::uint64_t frame_waits_for_ = 0;  // the async value the frame queue's next submission waits for
  std::uint64_t frame_waited_ = 0;     // the largest one a submission waited for already
  bool hold_async_ = false;
  std::vector<DeferredAsync> deferred_async_;  // in submission order
  std::map<std::string, std::shared_ptr<void>> shared_;
};

}  // namespace displace::vulkan
