// demos/error.h - the one exception type of the application layer.
//
// Everything the user or the environment got wrong (bad flag, missing file, unreadable image) is
// thrown as AppError with a message that names the flag or file; `main` catches it at the CLI
// boundary, prints "displace: error: <message>" and exits 2 for usage errors, 1 for runtime errors.
#pragma once

#include <stdexcept>
#include <string>

namespace displace::app {

// The rule (demos/cli/command.h has it in full): usage when changing the command line fixes it, runtime
// when the problem lies outside it.
enum class ErrorKind {
  usage,  // the command line is wrong: flags, values, limits, a flag that does not fit its input (exit status
          // 2)
  runtime,  // the command line was fine but the work failed: files, devices, memory, bakers (exit status 1)
};

struct AppError : std::runtime_error {
  AppError(ErrorKind error_kind, const std::string& message)
      : std::runtime_error(message), kind(error_kind) {}
  ErrorKind kind;
};

inline AppError usage_error(const std::string& message) { return AppError(ErrorKind::usage, message); }
inline AppError runtime_error(const std::string& message) { return AppError(ErrorKind::runtime, message); }

// Under --validate, a run that drew validation messages (printed as they came) fails once its work
// is done: a runtime error that counts them.
inline void require_no_validation_messages(bool validate, long long messages) {
  if (validate && messages > 0)
    throw runtime_error(std::to_string(messages) + " Vulkan validation messages (printed above)");
}

}  // namespace displace::app
