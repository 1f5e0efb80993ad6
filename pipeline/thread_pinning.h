// pipeline/thread_pinning.h - the frame loop's threads one per CPU while it runs (Linux), for frame
// times that do not depend on where the scheduler puts a thread it wakes.
//
// Why: on this project's 2-vCPU machine (a Firecracker VM), `perf sched timehist` over the 512 water
// loop showed TBB's worker, woken for the sim after sleeping through the render, queued behind its
// waker on the busy CPU while the other CPU sat idle, and the two sharing one CPU in 3-4 ms slices:
// the sim or the bake at one core's speed, lavapipe's two rasterizer threads likewise - the frames
// that make the p95. With each thread on its own CPU that cannot happen
// (docs/design/pipeline.md#two-cores-what-the-frame-loop-can-and-cannot-reach).
#pragma once

#include <memory>

namespace displace::pipeline {

// While it lives: the thread that constructs it runs on the first CPU the process may use, each of
// TBB's worker threads (when it first enters the arena) on the next ones in turn, and lavapipe's
// rasterizer threads ("llvmpipe-N", made with the renderer: construct this after it) on CPU N in
// turn. The destructor gives every thread it pinned the CPUs it had. With fewer than two CPUs, or
// where affinity cannot be set, it pins nothing (pinned_threads() says so).
class ThreadPinning {
 public:
  ThreadPinning();
  ~ThreadPinning();
  ThreadPinning(const ThreadPinning&) = delete;
  ThreadPinning& operator=(const ThreadPinning&) = delete;

  int cpu_count() const;       // CPUs the threads are spread over (0: pinning is off)
  int pinned_threads() const;  // threads pinned so far

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace displace::pipeline
