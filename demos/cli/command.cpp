// demos/cli/command.cpp - the root of the `displace` command line: every command of commands.def as
// a CLI11 subcommand, the chosen one parsed and finished into a ParsedCommand.
#include "demos/cli/command.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <iterator>
#include <ostream>
#include <vector>

#include "demos/cli/flags.h"
#include "demos/error.h"

namespace displace::app {
namespace {

struct Registration {
  const char* name;
  Finish (*add)(CLI::App& command);
  const char* summary;
};

constexpr Registration registrations[] = {
#define DISPLACE_COMMAND(name, function, summary) {name, function, summary},
#include "demos/commands/commands.def"
#undef DISPLACE_COMMAND
};

constexpr const char* footer =
    "Run 'displace COMMAND --help' for a command's flags and their limits (docs/cli.md has them all).\n"
    "Scenes: docs/scenes.md. Exit status: 0 success; 2 a wrong command line; 1 anything else (a missing\n"
    "or malformed file, no Vulkan device, not enough memory). DISPLACE_MEMORY_LIMIT_MB=N holds the\n"
    "memory guards to N megabytes.";

// A registered command: its CLI11 subcommand, its Finish and its own help's description (the root's
// list shows the one-line summary).
struct Registered {
  CLI::App* command;
  Finish finish;
  std::string description;
};

// The root command with every command registered, or only the one named `only`: a command line is
// parsed with its own command alone (a word that names another command is an argument like any
// other, and the parse does not build every command's flags: a tenth of the time).
std::unique_ptr<CLI::App> make_root(std::vector<Registered>& registered, std::string_view only = {}) {
  auto root = std::make_unique<CLI::App>(
      "displace - dynamic height fields rendered with per-pixel displacement mapping, and their cone maps",
      "displace");
  root->footer(footer);
  root->get_formatter()->column_width(16);
  for (const Registration& registration : registrations) {
    if (!only.empty() && registration.name != only) continue;
    CLI::App* command = root->add_subcommand(registration.name, registration.summary);
    cli::set_up(*command);
    Finish finish = registration.add(*command);
    registered.push_back({command, std::move(finish), command->get_description()});
    command->description(registration.summary);
  }
  return root;
}

ParsedCommand help_of(std::string name, std::string text) {
  return ParsedCommand{"help", std::move(name), [text](std::ostream& out) { out << text; }};
}

// A command's own help, with its full description.
std::string command_help(const Registered& registered) {
  registered.command->description(registered.description);
  return registered.command->help("displace");
}

}  // namespace

bool is_command(std::string_view word) {
  return std::any_of(std::begin(registrations), std::end(registrations),
                     [&](const Registration& r) { return r.name == word; });
}

std::string overview() {
  std::vector<Registered> registered;
  return make_root(registered)->help();
}

ParsedCommand parse_command_line(std::span<const std::string_view> args) {
  if (args.empty()) throw usage_error("no command given");
  const std::string_view word = args.front();
  if (word == "help" || word == "--help" || word == "-h") return help_of("", overview());
  if (!is_command(word)) {
    std::vector<std::string_view> names;
    for (const Registration& registration : registrations) names.push_back(registration.name);
    throw usage_error(
        fmt::format("unknown command {} (commands: {}, help)", cli::in_quotes(word), fmt::join(names, ", ")));
  }
  std::vector<Registered> registered;
  const std::unique_ptr<CLI::App> root = make_root(registered, word);
  const Registered& chosen = registered.front();
  CLI::App& command = *chosen.command;
  std::vector<std::string> reversed(args.rbegin(), args.rend());  // CLI11 takes them last first
  try {
    root->parse(reversed);
  } catch (const CLI::CallForHelp&) {
    return help_of(std::string(word), command_help(chosen));
  } catch (const CLI::ParseError& error) {
    // CLI11 checks values before it looks at --help: asking for help wins over a bad value
    if (const CLI::Option* help = command.get_help_ptr(); help && help->count() > 0)
      return help_of(std::string(word), command_help(chosen));
    throw usage_error(cli::translate(command, error));
  }
  cli::reject_extras(command);
  return chosen.finish();
}

}  // namespace displace::app
