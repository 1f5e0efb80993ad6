// demos/displace_main.cpp - the `displace` CLI: parse, run, and the one place errors are caught.
//
// A user sees "displace: error: <message>" on stderr and exit status 2 (usage) or 1 (runtime),
// never a stack trace; a run that SIGINT or SIGTERM stopped exits 130 or 143 (demos/interrupt.h).
#include <cstdio>
#include <exception>
#include <iostream>
#include <new>
#include <stdexcept>
#include <string_view>
#include <vector>

#include "bake/bake.h"
#include "demos/cli/command.h"
#include "demos/error.h"
#include "demos/interrupt.h"

namespace {

constexpr int exit_runtime_error = 1;
constexpr int exit_usage_error = 2;

// `command`: the command the user ran, for the help hint of a usage error; empty when none.
// The libraries' messages name their fields; the user sees the flags that set them.
int report(std::string_view message, int status, std::string_view command = {}) {
  std::cerr << "displace: error: " << displace::app::cli::flag_words(message) << '\n';
  if (status == exit_usage_error) {
    std::cerr << "run 'displace " << command << (command.empty() ? "" : " ") << "--help' for usage\n";
  }
  return status;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace displace;
  const std::vector<std::string_view> args(argv + 1, argv + argc);
  if (args.empty()) {
    std::cerr << app::overview();
    return exit_usage_error;
  }
  app::install_interrupt_handlers();
  try {
    const app::ParsedCommand command = app::parse_command_line(args);
    command.run(std::cout);
    std::cout.flush();
    return 0;
  } catch (const app::Interrupted& stop) {
    std::cerr << "displace: stopped by " << app::signal_name(stop.signal) << ": " << stop.what() << '\n';
    return stop.status();
  } catch (const app::AppError& error) {
    const std::string_view command = app::is_command(args.front()) ? args.front() : std::string_view{};
    return report(error.what(), error.kind == app::ErrorKind::usage ? exit_usage_error : exit_runtime_error,
                  command);
  } catch (const bake::BakeError& error) {
    return report(std::string("bake: ") + error.what(), exit_runtime_error);
  } catch (const std::invalid_argument& error) {
    return report(error.what(), exit_usage_error);
  } catch (const std::bad_alloc&) {
    return report("out of memory", exit_runtime_error);
  } catch (const std::exception& error) {
    return report(error.what(), exit_runtime_error);
  } catch (...) {
    return report("unexpected failure", exit_runtime_error);
  }
}
