// demos/cli/scene_keys.h - the table behind demos/cli/scene_flags.h: each scene flag, the keys it sets,
// how its text becomes a TOML value and the validator of its limits (the libraries' constants).
#pragma once

#include <CLI/CLI.hpp>
#include <functional>
#include <vector>

namespace displace::app::cli {

// How a flag's text becomes a TOML value.
enum class Kind { integer, number, word, vector, size, pair, path, on };

struct Entry {
  const char* flag;
  unsigned group;
  std::vector<const char*> keys;  // "section.key" set to the value (several: the same value each)
  Kind kind;
  const char* value;  // the value's name in --help
  const char* help;
  std::function<CLI::Validator()> validator;  // none for switches (Kind::on)
};

// Every scene flag, in the order --help and docs/scenes.md list them.
const std::vector<Entry>& entries();

}  // namespace displace::app::cli
