// demos/interrupt.cpp - what SIGINT and SIGTERM do (demos/interrupt.h).
#include "demos/interrupt.h"

#include <unistd.h>

#include <atomic>
#include <csignal>

#include "render/files.h"

namespace displace::app {
namespace {

std::atomic<int> stop_scopes{0};     // StopBetweenFrames alive
std::atomic<int> stop_requested{0};  // the first signal inside a scope

void on_signal(int signal_number) {
  int none = 0;
  if (stop_scopes.load() > 0 && stop_requested.compare_exchange_strong(none, signal_number)) {
    constexpr char notice[] =
        "displace: stopping after the frame in progress (a second signal stops at once)\n";
    [[maybe_unused]] const ::ssize_t written = ::write(2, notice, sizeof(notice) - 1);
    return;
  }
  files::remove_partial_files();
  ::_exit(128 + signal_number);
}

struct sigaction handler_action() {
  struct sigaction action {};
  action.sa_handler = on_signal;
  sigemptyset(&action.sa_mask);
  action.sa_flags = SA_RESTART;
  return action;
}

}  // namespace

void install_interrupt_handlers() {
  const struct sigaction action = handler_action();
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
}

Interrupted::Interrupted(int signal_number, const std::string& message)
    : std::runtime_error(message), signal(signal_number) {}

StopBetweenFrames::StopBetweenFrames() {
  install_interrupt_handlers();
  if (stop_scopes.fetch_add(1) == 0) stop_requested.store(0);
}

StopBetweenFrames::~StopBetweenFrames() { stop_scopes.fetch_sub(1); }

int StopBetweenFrames::requested() const { return stop_requested.load(); }

std::string signal_name(int signal_number) {
  if (signal_number == SIGTERM) return "SIGTERM";
  if (signal_number == SIGINT) return "SIGINT";
  return "signal " + std::to_string(signal_number);
}

}  // namespace displace::app
