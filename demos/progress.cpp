// demos/progress.cpp - the progress line of long bakes (progress.h).
#include "demos/progress.h"

#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>

namespace displace::app {
namespace {

constexpr double show_after_seconds = 1.0;  // seconds: a bake shorter than this shows nothing
constexpr double redraw_seconds = 0.1;      // seconds between redraws at most (the last one is always drawn)

}  // namespace

double steady_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

ProgressLine::ProgressLine(std::ostream& stream, bool terminal, std::string what, Clock clock)
    : stream_(stream), terminal_(terminal), what_(std::move(what)), clock_(std::move(clock)) {
  if (!clock_) clock_ = steady_seconds;
  start_seconds_ = clock_();
}

ProgressLine::~ProgressLine() { finish(); }

void ProgressLine::update(double fraction_done) {
  const std::lock_guard lock(mutex_);
  if (!terminal_ || finished_) return;
  const double elapsed = clock_() - start_seconds_;
  if (elapsed < show_after_seconds) return;
  if (drawn_at_seconds_ >= 0.0 && elapsed - drawn_at_seconds_ < redraw_seconds && fraction_done < 1.0) return;
  const std::string line = fmt::format("displace: {} {:3d}% ({:.1f} s)", what_,
                                       int(std::floor(100.0 * std::clamp(fraction_done, 0.0, 1.0))), elapsed);
  // pad over what the previous line left
  stream_ << '\r' << line << std::string(drawn_length_ > line.size() ? drawn_length_ - line.size() : 0, ' ')
          << std::flush;
  drawn_length_ = std::max(drawn_length_, line.size());
  drawn_at_seconds_ = elapsed;
}

StageLines::StageLines(std::ostream& stream, std::string command, Clock clock)
    : stream_(stream), command_(std::move(command)), clock_(std::move(clock)) {
  if (!clock_) clock_ = steady_seconds;
  start_seconds_ = last_seconds_ = clock_();
}

void StageLines::done(std::string_view stage) {
  const double now = clock_();
  held_.push_back(fmt::format("{}: {} in {:.2f} s", command_, stage, now - last_seconds_));
  last_seconds_ = now;
  showing_ = showing_ || now - start_seconds_ >= show_after_seconds;
  if (!showing_) return;
  for (const std::string& line : held_) stream_ << line << '\n';
  stream_ << std::flush;
  held_.clear();
}

void ProgressLine::finish() {
  const std::lock_guard lock(mutex_);
  if (finished_) return;
  finished_ = true;
  if (drawn_length_ > 0) stream_ << '\r' << std::string(drawn_length_, ' ') << '\r' << std::flush;
}

bake::Progress ProgressLine::callback() {
  return [this](double fraction_done) { update(fraction_done); };
}

bool stderr_is_terminal() { return ::isatty(STDERR_FILENO) == 1; }

}  // namespace displace::app
