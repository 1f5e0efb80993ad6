// bake/budget_clock.h - a Budget's clock and work limit as the budgeted bakers spend them
// (internal to bake/): milliseconds from the budget's clock (steady clock if none) since the call
// began, and the work units spent.
#pragma once

#include <atomic>
#include <chrono>
#include <cmath>
#include <functional>

#include "bake/bake.h"

namespace displace::bake::detail {

struct BudgetClock {
  std::function<double()> clock;
  double start = 0.0;
  double limit = 0.0;
  long long max_work = -1;
  std::atomic<long long> work{0};

  explicit BudgetClock(const Budget& budget)
      : clock(budget.clock), limit(budget.milliseconds), max_work(budget.max_work) {
    if (!clock) {
      clock = [] {
        return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now().time_since_epoch())
            .count();
      };
    }
    start = clock();
  }
  double elapsed() const { return clock() - start; }
  // no milliseconds and no work limit: nothing to look at between steps but progress
  bool unlimited() const { return std::isinf(limit) && limit > 0.0 && max_work < 0; }
  bool exhausted() const {
    if (max_work >= 0 && work.load(std::memory_order_relaxed) >= max_work) return true;
    return !(elapsed() < limit);
  }
};

}  // namespace displace::bake::detail
