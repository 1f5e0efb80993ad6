// demos/interrupt.h - SIGINT and SIGTERM (Ctrl-C, Slurm's preemption, scancel): nothing half-written
// is left under any name, and the exit status is 128 + the signal (130, 143).
//
// install_interrupt_handlers() (main) makes a signal end the process at once: the temporaries being
// written are unlinked (files::remove_partial_files) and it exits 128 + signal. Inside a
// StopBetweenFrames scope (`sequence`) the first signal only asks the run to stop: the loop asks
// requested() between frames, saves what it keeps and throws Interrupted; a second signal ends the
// process at once as above.
#pragma once

#include <stdexcept>
#include <string>

namespace displace::app {

void install_interrupt_handlers();

// Thrown by a loop that stopped at a signal's request; main exits with status().
struct Interrupted : std::runtime_error {
  Interrupted(int signal_number, const std::string& message);
  int signal;
  int status() const { return 128 + signal; }
};

class StopBetweenFrames {
 public:
  StopBetweenFrames();  // installs the handlers, so that it holds in-process too (tests)
  ~StopBetweenFrames();
  StopBetweenFrames(const StopBetweenFrames&) = delete;
  StopBetweenFrames& operator=(const StopBetweenFrames&) = delete;
  // the signal that asked the run to stop (SIGINT, SIGTERM), 0 when none did
  int requested() const;
};

// "SIGTERM", "SIGINT", or "signal N".
std::string signal_name(int signal_number);

}  // namespace displace::app
