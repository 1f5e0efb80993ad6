// demos/cli/command.h - the `displace` command line as CLI11 subcommands, one file per command in
// demos/commands/ and one registration line in commands.def.
//
// A command registers its flags on its CLI11 subcommand and returns a Finish: called after CLI11
// parsed the arguments, it checks what goes together and returns the command's typed settings and
// how to run them. Exit status, one rule for every command: 2 (AppError of kind usage) when the
// command line alone is wrong and changing it fixes it (an unknown flag, a bad value, a value outside
// the flag's limits, flags that do not go together); 1 (kind runtime) when the problem lies outside
// it (a missing or malformed file, an output that cannot be written, no Vulkan device, not enough
// memory, work that fails).
#pragma once

#include <any>
#include <functional>
#include <iosfwd>
#include <span>
#include <string>
#include <string_view>

namespace CLI {
class App;  // CLI11's, included by the files that register flags (a third of a minute to compile under ASan)
}

namespace displace::app {

// What the command line asked for: the command, its typed settings (the tests read them) and how
// to run them. A --help request is a command too: its `run` prints the help.
struct ParsedCommand {
  std::string name;
  std::any settings;
  std::function<void(std::ostream& out)> run;
};

// Made by a command's registration once CLI11 has parsed; throws AppError.
using Finish = std::function<ParsedCommand()>;

// The registration functions, one per command (demos/commands/<name>.cpp).
#define DISPLACE_COMMAND(name, function, summary) Finish function(CLI::App& command);
#include "demos/commands/commands.def"
#undef DISPLACE_COMMAND

// `args` excludes the program name. Throws AppError (usage) for a command line that is wrong.
ParsedCommand parse_command_line(std::span<const std::string_view> args);

// `displace help`: the commands with their summaries (CLI11's own help of the root command).
std::string overview();

// Whether `word` names a command.
bool is_command(std::string_view word);

namespace cli {
// A library's message in the command line's words: each field a library names (View::tile,
// MethodSettings::steps, "MapSet::width x MapSet::height", ...) becomes the flag that sets it
// (--tile, --steps, --map-size). The libraries name their own fields (issue 30); this is the one
// table that maps them to flags.
std::string flag_words(std::string_view message);
}  // namespace cli

}  // namespace displace::app
