// demos/commands/scene.cpp - `displace scene`: a built-in scene as the TOML file that reads back to it
// (--print), and the table of the scene flags and the keys they set (--keys, docs/scenes.md's table).
#include "pipeline/scene.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <ostream>

#include "demos/cli/command.h"
#include "demos/cli/flags.h"
#include "demos/cli/scene_flags.h"
#include "demos/error.h"

namespace displace::app {
namespace {

struct SceneCommand {
  std::string print;
  bool keys = false;
};

// A table cell: a '|' would end it.
std::string cell(const std::string& text) {
  std::string escaped;
  for (const char c : text) {
    if (c == '|') escaped += '\\';
    escaped += c;
  }
  return escaped;
}

void print_keys(std::ostream& out) {
  out << "| flag | value | scene key | limits | what it sets |\n|---|---|---|---|---|\n";
  for (const cli::SceneFlagRow& row : cli::scene_flag_rows()) {
    out << fmt::format("| `{}` | {} | {} | {} | {} |\n", row.flag,
                       row.value.empty() ? "" : "`" + cell(row.value) + "`", row.keys, cell(row.limits),
                       cell(row.help));
  }
}

}  // namespace

Finish add_scene_command(CLI::App& command) {
  command.description(
      "Built-in scenes as TOML scene files (--print NAME), and the scene flags of every command with the "
      "keys they set (--keys, a Markdown table).");
  auto draft = std::make_shared<SceneCommand>();
  const std::vector<std::string> names = pipeline::builtin_scene_names();
  command.add_option("--print", draft->print, "write the built-in scene NAME as TOML to stdout")
      ->type_name(fmt::format("{}", fmt::join(names, "|")))
      ->check(cli::text_check([names](const std::string& text) -> std::string {
        if (std::find(names.begin(), names.end(), text) != names.end()) return {};
        return fmt::format("must name a built-in scene ({}), got {}", fmt::join(names, ", "),
                           cli::in_quotes(text));
      }));
  cli::add_switch(command, "--keys", draft->keys, "write the scene flags and the keys they set (Markdown)");
  return [&command, draft] {
    const bool print = cli::given(command, "--print");
    if (print == draft->keys)
      throw usage_error("'displace scene' needs --print NAME or --keys (one of them)");
    const SceneCommand parsed = *draft;
    return ParsedCommand{"scene", parsed, [parsed](std::ostream& out) {
                           if (parsed.keys) {
                             print_keys(out);
                           } else {
                             out << pipeline::scene_toml(pipeline::builtin_scene(parsed.print));
                           }
                         }};
  };
}

}  // namespace displace::app
