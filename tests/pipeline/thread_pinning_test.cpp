// tests/pipeline/thread_pinning_test.cpp - thread pinning (pipeline/thread_pinning.cpp).
#include "pipeline/thread_pinning.h"

#include <gtest/gtest.h>
#include <sched.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <set>
#include <string>
#include <string_view>
#include <thread>

#include "pipeline/frame_pipeline.h"
#include "pipeline/scene.h"
#include "render/render.h"
#include "tests/pipeline/pipeline_checks.h"
#include "tests/render_fixtures.h"

namespace {

using namespace displace;
using displace::testing::shared_renderer;
using pipeline::FramePipeline;
using pipeline::FrameRecord;
using pipeline::Scene;
using pipeline::SceneError;

// --pin-threads: while a ThreadPinning lives, every TBB thread that works and every lavapipe
// rasterizer thread runs on one CPU of its own (llvmpipe-N on the N-th), and afterwards each has
// the CPUs it had.
TEST(ThreadPinning, GivesEachThreadItsOwnCpuAndGivesItBack) {
  cpu_set_t original;
  ASSERT_EQ(sched_getaffinity(0, sizeof original, &original), 0);
  std::vector<int> cpus;
  for (int cpu = 0; cpu < CPU_SETSIZE; ++cpu)
    if (CPU_ISSET(cpu, &original)) cpus.push_back(cpu);
  if (cpus.size() < 2) GTEST_SKIP() << "one CPU: nothing to pin";
  shared_renderer();  // its rasterizer threads exist before the pinning
  auto affinity = [](pid_t thread) {
    cpu_set_t set;
    CPU_ZERO(&set);
    EXPECT_EQ(sched_getaffinity(thread, sizeof set, &set), 0) << thread;
    return set;
  };
  auto rasterizers = [] {
    std::vector<std::pair<pid_t, int>> found;  // thread, N
    for (const auto& entry : std::filesystem::directory_iterator("/proc/self/task")) {
      std::ifstream comm(entry.path() / "comm");
      std::string name;
      if (std::getline(comm, name) && name.rfind("llvmpipe-", 0) == 0) {
        found.emplace_back(pid_t(std::atoi(entry.path().filename().c_str())), std::atoi(name.c_str() + 9));
      }
    }
    return found;
  };
  // the threads that take part in a parallel loop, with their CPU sets (each task waits a little,
  // so that every thread of the arena gets some)
  auto workers = [] {
    std::mutex mutex;
    std::map<pid_t, cpu_set_t> seen;
    tbb::parallel_for(0, 64, [&](int) {
      cpu_set_t set;
      sched_getaffinity(0, sizeof set, &set);
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
      const std::lock_guard<std::mutex> lock(mutex);
      seen[gettid()] = set;
    });
    return seen;
  };
  const int threads = std::min(tbb::this_task_arena::max_concurrency(), int(cpus.size()));
  ASSERT_GE(threads, 2);
  std::map<pid_t, cpu_set_t> pinned;
  {
    pipeline::ThreadPinning pinning;
    EXPECT_EQ(pinning.cpu_count(), int(cpus.size()));
    pinned = workers();
    EXPECT_EQ(int(pinned.size()), threads);
    std::set<int> used;
    for (const auto& [thread, set] : pinned) {
      ASSERT_EQ(CPU_COUNT(&set), 1) << thread;
      for (int cpu : cpus)
        if (CPU_ISSET(cpu, &set)) {
          EXPECT_TRUE(used.insert(cpu).second) << "two threads on CPU " << cpu;
        }
    }
    for (const auto& [thread, index] : rasterizers()) {
      const cpu_set_t set = affinity(thread);
      EXPECT_EQ(CPU_COUNT(&set), 1) << "llvmpipe-" << index;
      EXPECT_TRUE(CPU_ISSET(cpus[std::size_t(index) % cpus.size()], &set)) << "llvmpipe-" << index;
    }
    EXPECT_GE(pinning.pinned_threads(), int(pinned.size()));
  }
  for (const auto& [thread, set] : pinned) {
    const cpu_set_t now = affinity(thread);
    EXPECT_TRUE(CPU_EQUAL(&now, &original)) << thread;
  }
  {  // a second pinning (perhaps at the first one's address) pins the same threads again
    pipeline::ThreadPinning again;
    for (const auto& [thread, set] : workers()) EXPECT_EQ(CPU_COUNT(&set), 1) << thread;
  }
  for (const auto& [thread, index] : rasterizers()) {
    const cpu_set_t now = affinity(thread);
    EXPECT_TRUE(CPU_EQUAL(&now, &original)) << "llvmpipe-" << index;
  }
}

}  // namespace
