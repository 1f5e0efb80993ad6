// bake/progress.h - throttled progress reports of a bake that works row by row on many threads
// (internal to bake/; the contract is bake.h's Progress).
//
// The one fact: reports are serialized by a mutex that a worker only try-locks (a busy reporter
// is skipped, never waited for), and each report reads the rows-done counter inside the lock, so
// the fractions strictly increase whichever thread reports.
#pragma once

#include <algorithm>
#include <atomic>
#include <mutex>

#include "bake/bake.h"

namespace displace::bake::detail {

class RowProgress {
 public:
  // `progress` may be empty (then nothing is reported); it must outlive this object.
  RowProgress(const Progress& progress, int rows)
      : progress_(progress ? &progress : nullptr),
        rows_(std::max(rows, 1)),
        rows_per_report_(std::max(1, (rows_ + max_progress_reports - 1) / max_progress_reports)),
        next_report_(rows_per_report_) {}

  // Any thread, after finishing one row.
  void row_done() {
    if (!progress_) return;
    const int done = rows_done_.fetch_add(1, std::memory_order_relaxed) + 1;
    if (done < next_report_.load(std::memory_order_relaxed) || done >= rows_) return;  // 1 is finish()'s
    std::unique_lock lock(mutex_, std::try_to_lock);
    if (!lock.owns_lock()) return;
    const int now = rows_done_.load(std::memory_order_relaxed);
    if (now < next_report_.load(std::memory_order_relaxed) || now >= rows_) return;
    next_report_.store(now + rows_per_report_, std::memory_order_relaxed);
    (*progress_)(double(now) / rows_);
  }

  // The calling thread, once every row is done: the last report, 1.
  void finish() {
    if (progress_) (*progress_)(1.0);
  }

 private:
  const Progress* progress_;
  int rows_;
  int rows_per_report_;
  std::atomic<int> rows_done_{0};
  std::atomic<int> next_report_;  // rows done before the next report; raised under mutex_
  std::mutex mutex_;
};

}  // namespace displace::bake::detail
