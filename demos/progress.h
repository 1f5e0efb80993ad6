// demos/progress.h - one updating line of progress on a terminal while a long bake runs.
//
// The one fact: it only ever draws on a terminal, and only once the bake has run for
// show_after_seconds, so quick bakes, pipes and files never see it; the line ("displace: baking
// bilinear cones  42% (3.1 s)") is rewritten in place with '\r' and erased when the bake ends, so
// the result line that follows on stdout is all that stays on the screen.
#pragma once

#include <functional>
#include <mutex>
#include <ostream>
#include <string>
#include <string_view>
#include <vector>

#include "bake/bake.h"

namespace displace::app {

// Seconds on the steady clock (for intervals: its epoch is arbitrary).
double steady_seconds();

class ProgressLine {
 public:
  using Clock = std::function<double()>;  // seconds; a steady clock when empty (tests inject one)

  // `terminal`: whether `stream` is a terminal; nothing is drawn otherwise. `what` names the work.
  ProgressLine(std::ostream& stream, bool terminal, std::string what, Clock clock = {});
  ~ProgressLine();  // finish()
  ProgressLine(const ProgressLine&) = delete;
  ProgressLine& operator=(const ProgressLine&) = delete;

  // A bake's report (bake::Progress): redraws the line when it is due. Safe from any thread.
  void update(double fraction_done);
  // Erases the line if one was drawn; later updates draw nothing.
  void finish();
  // A bake::Progress that calls update(); valid while this object lives.
  bake::Progress callback();

 private:
  std::mutex mutex_;
  std::ostream& stream_;
  bool terminal_;
  std::string what_;
  Clock clock_;
  double start_seconds_ = 0.0;
  double drawn_at_seconds_ = -1.0;  // when the line was last drawn, -1 before the first time
  std::size_t drawn_length_ = 0;    // characters on the line now
  bool finished_ = false;
};

// One line per stage of a long command ("displace render: cone maps baked in 1.41 s"): nothing while
// the command is quick; once it has run for show_after_seconds, the lines held so far and every
// later one, each as its stage ends, on a terminal or not - so that a long render says what it does
// where no progress line can be drawn (a pipe, a log file).
class StageLines {
 public:
  using Clock = ProgressLine::Clock;
  StageLines(std::ostream& stream, std::string command, Clock clock = {});
  void done(std::string_view stage);  // the stage that just ended, e.g. "cone maps baked"

 private:
  std::ostream& stream_;
  std::string command_;
  Clock clock_;
  double start_seconds_ = 0.0, last_seconds_ = 0.0;
  std::vector<std::string> held_;
  bool showing_ = false;
};

// Whether the process's stderr is a terminal.
bool stderr_is_terminal();

}  // namespace displace::app
