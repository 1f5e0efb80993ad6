// bake/progress.h - throttled progress reports of a bake that works row by row on many threads,
// and the row loop of the bakers that search each texel on its own (internal to bake/; the
// contract is bake.h's Progress).
//
// The one fact: reports are serialized by a mutex that a worker only try-locks (a busy reporter
// is skipped, never waited for), and each report reads the rows-done counter inside the lock, so
// the fractions strictly increase whichever thread reports.
#pragma once

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cstddef>
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

// Every texel (i, j) of the map, rows spread over threads: its sectors' ratios in out set to 1,
// then texel(i, j, ratios) searches them and returns the work it did; progress after each row,
// and 1 at the end. Returns the work of all texels.
template <typename Texel>
long long search_every_texel(HeightView heights, int sectors, float* out, const Progress& progress,
                             const Texel& texel) {
  std::atomic<long long> total_work{0};
  RowProgress rows_done(progress, heights.height);
  tbb::parallel_for(tbb::blocked_range<int>(0, heights.height), [&](const tbb::blocked_range<int>& rows) {
    long long work = 0;
    for (int i = rows.begin(); i < rows.end(); ++i) {
      for (int j = 0; j < heights.width; ++j) {
        float* ratios = out + (std::size_t(i) * heights.width + j) * sectors;
        std::fill(ratios, ratios + sectors, 1.0f);
        work += texel(i, j, ratios);
      }
      rows_done.row_done();
    }
    total_work += work;
  });
  rows_done.finish();
  return total_work;
}

}  // namespace displace::bake::detail
