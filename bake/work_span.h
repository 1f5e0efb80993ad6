// bake/work_span.h - an opt-in record of how a bake would scale (internal to bake/, read by the
// benchmarks): per parallel region its work (the sum of its tasks' thread CPU times) and span (its
// longest task), and the calling thread's CPU time outside the regions (serial). On T threads the
// bake takes at least serial + the sum over regions of max(work / T, span) (work_span_bound), so a
// run on two cores predicts sixteen.
//
// While a WorkSpanRecording lives (one at a time in a process), the regions run their tasks as the
// finest pieces their grain allows (tbb::simple_partitioner) and time each; otherwise a region costs
// one relaxed load of a flag. Pieces are as a 16-thread run could at best get them; the bound leaves
// out the scheduler's overhead, memory bandwidth and waits for threads.
#pragma once

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/partitioner.h>

#include <atomic>
#include <string>
#include <vector>

namespace displace::bake::detail {

struct WorkSpanRegion {
  std::string name;
  double work = 0.0;  // seconds of thread CPU time, all tasks
  double span = 0.0;  // seconds, the longest task
  long long tasks = 0;
};

struct WorkSpan {
  double serial = 0.0;                  // seconds of the calling thread's CPU time outside the regions
  std::vector<WorkSpanRegion> regions;  // in the order they ran, one entry per run
};

// serial + the sum over regions of max(work / threads, span), in seconds
double work_span_bound(const WorkSpan& record, int threads);
// serial + every region's work: what one thread would take
double work_span_total(const WorkSpan& record);

// Records into `record` (added to what it holds) from construction to destruction; the thread that
// makes it is the one whose time outside the regions counts as serial.
class WorkSpanRecording {
 public:
  explicit WorkSpanRecording(WorkSpan& record);
  ~WorkSpanRecording();
  WorkSpanRecording(const WorkSpanRecording&) = delete;
  WorkSpanRecording& operator=(const WorkSpanRecording&) = delete;
};

// Whether a recording is under way (any thread).
inline std::atomic<bool> work_span_active{false};

// A parallel region's scope on the calling thread (nested regions count into the outermost), and one
// task of it on whichever thread runs it; both do nothing without a recording.
class WorkSpanScope {
 public:
  explicit WorkSpanScope(const char* name);
  ~WorkSpanScope();
  WorkSpanScope(const WorkSpanScope&) = delete;
  WorkSpanScope& operator=(const WorkSpanScope&) = delete;

 private:
  bool open_ = false;
};
class WorkSpanTask {
 public:
  WorkSpanTask();
  ~WorkSpanTask();
  WorkSpanTask(const WorkSpanTask&) = delete;
  WorkSpanTask& operator=(const WorkSpanTask&) = delete;

 private:
  double start_ = -1.0;
};

// tbb::parallel_for over a blocked_range as a named region: the default partitioner, or timed pieces
// of at most the grain while recording.
template <class Range, class Body>
void parallel_for_region(const char* name, const Range& range, const Body& body) {
  if (!work_span_active.load(std::memory_order_relaxed)) {
    tbb::parallel_for(range, body);
    return;
  }
  const WorkSpanScope scope(name);
  tbb::parallel_for(
      range,
      [&](const Range& piece) {
        const WorkSpanTask task;
        body(piece);
      },
      tbb::simple_partitioner());
}

// tbb::parallel_for over [first, last) of single indices as a named region (each index a task).
template <class Body>
void parallel_for_each_region(const char* name, int first, int last, const Body& body) {
  if (!work_span_active.load(std::memory_order_relaxed)) {
    tbb::parallel_for(first, last, body);
    return;
  }
  const WorkSpanScope scope(name);
  tbb::parallel_for(
      tbb::blocked_range<int>(first, last, 1),
      [&](const tbb::blocked_range<int>& piece) {
        for (int n = piece.begin(); n < piece.end(); ++n) {
          const WorkSpanTask task;
          body(n);
        }
      },
      tbb::simple_partitioner());
}

// tbb::parallel_reduce (functional form) as a named region.
template <class Range, class Value, class Body, class Join>
Value parallel_reduce_region(const char* name, const Range& range, const Value& identity, const Body& body,
                             const Join& join) {
  if (!work_span_active.load(std::memory_order_relaxed))
    return tbb::parallel_reduce(range, identity, body, join);
  const WorkSpanScope scope(name);
  return tbb::parallel_reduce(
      range, identity,
      [&](const Range& piece, Value value) {
        const WorkSpanTask task;
        return body(piece, value);
      },
      join, tbb::simple_partitioner());
}

}  // namespace displace::bake::detail
