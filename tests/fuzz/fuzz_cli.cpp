// tests/fuzz/fuzz_cli.cpp - libFuzzer target: the command-line parser (app::parse_command_line,
// demos/cli/command.h). The input is the argument list, one argument per line. Any input either parses into
// settings or throws AppError (usage or runtime) with a message, never anything else; nothing is run.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "demos/cli/command.h"
#include "demos/error.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  std::vector<std::string_view> args;
  for (std::size_t start = 0; start <= text.size();) {
    const std::size_t end = std::min(text.find('\n', start), text.size());
    args.push_back(text.substr(start, end - start));
    start = end + 1;
  }
  if (args.size() > 64) return 0;  // the CLI's own limit is the shell's; keep runs short
  try {
    (void)displace::app::parse_command_line(args);
  } catch (const displace::app::AppError& error) {
    if (std::string_view(error.what()).empty()) __builtin_trap();
  }
  return 0;
}
