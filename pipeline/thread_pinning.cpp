// pipeline/thread_pinning.cpp - one CPU per frame-loop thread (thread_pinning.h): the constructing
// thread directly, TBB's workers through a task_scheduler_observer as they enter the arena,
// lavapipe's rasterizer threads found by name in /proc/self/task.
#include "pipeline/thread_pinning.h"

#include <sched.h>
#include <sys/types.h>
#include <tbb/task_arena.h>
#include <tbb/task_scheduler_observer.h>
#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <string>
#include <system_error>
#include <vector>

namespace displace::pipeline {
namespace {

bool pin(pid_t thread, int cpu) {
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(cpu, &set);
  return sched_setaffinity(thread, sizeof set, &set) == 0;
}

std::atomic<unsigned long long> generations{0};

}  // namespace

struct ThreadPinning::State : tbb::task_scheduler_observer {
  std::vector<int> cpus;  // the CPUs the process may use, in order
  cpu_set_t original{};   // the constructing thread's set, given back to every pinned thread
  std::mutex mutex;
  std::vector<pid_t> pinned;  // under mutex
  std::atomic<int> next_worker{1};

  void record(pid_t thread) {
    const std::lock_guard<std::mutex> lock(mutex);
    pinned.push_back(thread);
  }

  // Each worker once per pinning, on its first entry (workers leave and re-enter the arena when idle);
  // pinnings are told apart by a number, not an address that a later one may reuse.
  const unsigned long long generation = ++generations;
  void on_scheduler_entry(bool is_worker) override {
    thread_local unsigned long long pinned_by = 0;
    if (!is_worker || pinned_by == generation) return;
    pinned_by = generation;
    const int cpu = cpus[std::size_t(next_worker++) % cpus.size()];
    if (pin(0, cpu)) record(gettid());
  }
};

ThreadPinning::ThreadPinning() : state_(std::make_unique<State>()) {
  State& s = *state_;
  if (sched_getaffinity(0, sizeof s.original, &s.original) != 0) return;
  for (int cpu = 0; cpu < CPU_SETSIZE; ++cpu)
    if (CPU_ISSET(cpu, &s.original)) s.cpus.push_back(cpu);
  if (s.cpus.size() < 2) {
    s.cpus.clear();
    return;
  }
  // TBB sizes its arena from the CPUs the calling thread may use when it first needs to: before
  // this thread is pinned, or every parallel loop after it would run on one thread
  tbb::this_task_arena::max_concurrency();
  if (pin(0, s.cpus[0])) s.record(gettid());
  // lavapipe's rasterizer threads: "llvmpipe-N" (Mesa's lp_rast), N from 0
  std::error_code error;
  for (const auto& entry : std::filesystem::directory_iterator("/proc/self/task", error)) {
    std::ifstream comm(entry.path() / "comm");
    std::string name;
    if (!std::getline(comm, name) || name.rfind("llvmpipe-", 0) != 0) continue;
    const int index = std::atoi(name.c_str() + 9);
    const pid_t thread = pid_t(std::atoi(entry.path().filename().c_str()));
    if (thread > 0 && pin(thread, s.cpus[std::size_t(index) % s.cpus.size()])) s.record(thread);
  }
  s.observe(true);
}

ThreadPinning::~ThreadPinning() {
  State& s = *state_;
  if (s.cpus.empty()) return;
  s.observe(false);
  const std::lock_guard<std::mutex> lock(s.mutex);
  for (const pid_t thread : s.pinned)
    sched_setaffinity(thread, sizeof s.original, &s.original);  // gone: ESRCH
}

int ThreadPinning::cpu_count() const { return int(state_->cpus.size()); }

int ThreadPinning::pinned_threads() const {
  const std::lock_guard<std::mutex> lock(state_->mutex);
  return int(state_->pinned.size());
}

}  // namespace displace::pipeline
