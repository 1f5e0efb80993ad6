// demos/cli/flags.h - the pieces every command's flags are made of (CLI11): number and word
// validators that word errors the project's way ("--steps must be an integer between 1 and 4096,
// got '0'") and show a flag's limits in --help ("--steps INT:[1, 4096]"), the vocabularies of the
// enums, and CLI11's own errors translated into the same words.
//
// Numbers are checked and rewritten in canonical form by these validators before CLI11 converts
// them, so "010" is ten and "0x10" is refused. Limits come from the libraries' headers (sim.h,
// bake.h, render.h, pipeline/scene.h): one constexpr per limit, shared with the scene reader.
#pragma once

#include <CLI/CLI.hpp>
#include <filesystem>
#include <functional>
#include <glm/glm.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include "bake/bake.h"
#include "demos/frame_output.h"
#include "pipeline/scene.h"
#include "render/render.h"
#include "sim/sim.h"

namespace displace::app::cli {

inline constexpr double max_budget_milliseconds = 1e9;  // about 11 days
inline constexpr int max_channel_index = 1 << 16;       // image channels

// A closed range of a number flag, its unit shown in --help and in errors.
struct Range {
  double low, high;
  const char* unit;
};

std::string in_quotes(std::string_view text);

// Parsing: a whole text as one number; nothing otherwise.
std::errc read_number(std::string_view text, long long& value);
std::errc read_number(std::string_view text, unsigned long long& value);
std::errc read_number(std::string_view text, int& value);
std::errc read_number(std::string_view text, double& value);
std::optional<float> read_float(std::string_view text);                     // finite, fits a float
std::optional<std::pair<int, int>> read_image_size(std::string_view text);  // "WxH"
std::optional<glm::vec3> read_vector(std::string_view text);                // "X,Y,Z"
std::optional<std::pair<float, float>> read_pair(std::string_view text);    // "LOW,HIGH", LOW < HIGH

// Validators: each returns what follows the flag's name in the error ("must be ..., got '0'") and
// rewrites a good value in the form CLI11 then converts.
CLI::Validator integer_in(long long minimum, long long maximum);
CLI::Validator seed_value();
CLI::Validator number_in(const Range& range);
CLI::Validator finite_number();
CLI::Validator text_check(std::function<std::string(const std::string&)> problem,
                          std::string description = "");
CLI::Validator not_empty();
CLI::Validator output_file(std::vector<std::string> extensions);
CLI::Validator image_size_check();
CLI::Validator vector_value();
// A bake's time budget: milliseconds in [0, maximum_ms], or "unlimited"; bake_budget_value reads
// what it let through (infinity for "unlimited").
CLI::Validator bake_budget_in(double maximum_ms);
double bake_budget_value(const std::string& text);
CLI::Validator tolerance_in_range();                                // [0, bake::max_tolerance)
CLI::Validator frame_pattern(std::vector<std::string> extensions);  // a '#' in the name

// The words of an enum's values (the --mode, --cones, ... vocabulary).
template <typename Enum>
using Words = std::vector<std::pair<std::string, Enum>>;

template <typename Enum>
std::string word_list(const Words<Enum>& words, std::string_view separator = "|") {
  std::string list;
  for (const auto& [word, value] : words) list += (list.empty() ? "" : std::string(separator)) + word;
  return list;
}

// One of `words`, rewritten to its enum value's number (which CLI11 converts to the enum).
template <typename Enum>
CLI::Validator word_in(const Words<Enum>& words) {
  return CLI::Validator(
      [=](std::string& text) -> std::string {
        for (const auto& [word, value] : words) {
          if (word == text) {
            text = std::to_string(static_cast<std::underlying_type_t<Enum>>(value));
            return {};
          }
        }
        return "must be one of " + word_list(words) + ", got " + in_quotes(text);
      },
      "");
}

template <typename Enum>
Enum word_value(const Words<Enum>& words, std::string_view text) {
  for (const auto& [word, value] : words) {
    if (word == text) return value;
  }
  throw std::logic_error("unknown word " + in_quotes(text) + " passed its flag's validator");
}

extern const Words<pipeline::SourceKind> source_words;
extern const Words<sim::Spectrum> spectrum_words;
extern const Words<sim::Spreading> spreading_words;
extern const Words<bake::Address> address_words;
extern const Words<render::Surface> surface_words;  // the quadrics and the plane (meshes: mesh:FILE.obj)
extern const Words<render::Material> material_words;
Words<render::Method> method_words();
std::vector<render::Method> all_methods_but_reference();

// A flag with a value: `type` names the value in --help, `validator` checks it (and rewrites it in
// the form CLI11 converts); the validator's description, if any, shows the limits next to `type`.
template <typename Value>
CLI::Option* add_value(CLI::App& app, const std::string& flag, Value& value, const std::string& description,
                       const std::string& type, CLI::Validator validator) {
  return app.add_option(flag, value, description)->type_name(type)->transform(std::move(validator));
}
// A flag without a value, given at most once.
CLI::Option* add_switch(CLI::App& app, const std::string& flag, bool& value, const std::string& description);

// Whether `flag` was given to `app`.
bool given(const CLI::App& app, const std::string& flag);

// The settings every command shares: unknown arguments are left for reject_extras(), each flag may
// be given once, help columns 36 wide.
void set_up(CLI::App& app);
// CLI11's error in the project's words.
std::string translate(const CLI::App& app, const CLI::ParseError& error);
// The first argument no flag took, as a usage error.
void reject_extras(const CLI::App& app);

}  // namespace displace::app::cli

namespace displace::app::cli {

// --aov NAME=FILE (render) or NAME=PATTERN (sequence: '#' runs become the frame number), repeatable.
void add_aov_option(CLI::App& app, std::vector<std::string>& aovs, const std::string& description,
                    bool patterns);
std::vector<AovOutput> aov_outputs(const std::vector<std::string>& aovs);
// --device, --validate and --pipeline-cache, for every command that renders; finish_renderer adds the
// memory limit of the environment (DISPLACE_MEMORY_LIMIT_MB).
void add_renderer_flags(CLI::App& app, render::RendererOptions& options);
void finish_renderer(render::RendererOptions& options);

}  // namespace displace::app::cli
