// bake/work_span.cpp - work and span of a bake's parallel regions (work_span.h): thread CPU times
// (CLOCK_THREAD_CPUTIME_ID, so that a machine shared with other programs does not count their time),
// gathered under one mutex while a recording lives.
#include "bake/work_span.h"

#include <time.h>

#include <algorithm>
#include <mutex>
#include <stdexcept>
#include <thread>

namespace displace::bake::detail {
namespace {

double thread_cpu_seconds() {
  timespec now{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &now);
  return double(now.tv_sec) + 1e-9 * double(now.tv_nsec);
}

struct Recorder {
  std::mutex mutex;
  WorkSpan* record = nullptr;
  std::thread::id caller;
  double caller_mark = 0.0;  // the caller's CPU time when its last serial stretch began
  WorkSpanRegion* open = nullptr;
  int depth = 0;  // nested scopes on the caller
};

Recorder& recorder() {
  static Recorder instance;
  return instance;
}

}  // namespace

double work_span_bound(const WorkSpan& record, int threads) {
  double bound = record.serial;
  for (const WorkSpanRegion& region : record.regions) bound += std::max(region.work / threads, region.span);
  return bound;
}

double work_span_total(const WorkSpan& record) {
  double total = record.serial;
  for (const WorkSpanRegion& region : record.regions) total += region.work;
  return total;
}

WorkSpanRecording::WorkSpanRecording(WorkSpan& record) {
  Recorder& r = recorder();
  const std::lock_guard<std::mutex> lock(r.mutex);
  if (r.record) throw std::logic_error("work_span: one recording at a time");
  r.record = &record;
  r.caller = std::this_thread::get_id();
  r.caller_mark = thread_cpu_seconds();
  r.open = nullptr;
  r.depth = 0;
  work_span_active.store(true, std::memory_order_relaxed);
}

WorkSpanRecording::~WorkSpanRecording() {
  Recorder& r = recorder();
  const std::lock_guard<std::mutex> lock(r.mutex);
  r.record->serial += thread_cpu_seconds() - r.caller_mark;
  r.record = nullptr;
  work_span_active.store(false, std::memory_order_relaxed);
}

WorkSpanScope::WorkSpanScope(const char* name) {
  Recorder& r = recorder();
  const std::lock_guard<std::mutex> lock(r.mutex);
  if (!r.record || std::this_thread::get_id() != r.caller) return;
  open_ = true;
  if (r.depth++ > 0) return;
  r.record->serial += thread_cpu_seconds() - r.caller_mark;
  r.record->regions.push_back({name});
  r.open = &r.record->regions.back();
}

WorkSpanScope::~WorkSpanScope() {
  if (!open_) return;
  Recorder& r = recorder();
  const std::lock_guard<std::mutex> lock(r.mutex);
  if (--r.depth > 0) return;
  r.open = nullptr;
  r.caller_mark = thread_cpu_seconds();
}

WorkSpanTask::WorkSpanTask() {
  if (work_span_active.load(std::memory_order_relaxed)) start_ = thread_cpu_seconds();
}

WorkSpanTask::~WorkSpanTask() {
  if (start_ < 0.0) return;
  const double seconds = thread_cpu_seconds() - start_;
  Recorder& r = recorder();
  const std::lock_guard<std::mutex> lock(r.mutex);
  if (!r.open) return;
  r.open->work += seconds;
  r.open->span = std::max(r.open->span, seconds);
  ++r.open->tasks;
}

}  // namespace displace::bake::detail
