// demos/options.cpp - parses `displace` argv into the typed settings of options.h with CLI11.
//
// The one fact to know: each flag is declared once with a validator that both words the error the
// project's way ("--steps must be an integer between 1 and 4096, got '0'") and shows the flag's
// limits in `--help` ("--steps INT:[1, 4096]"); CLI11's own errors are translated into the same
// words (translate()). Numbers are checked and rewritten in canonical form by these validators before
// CLI11 converts them, so "010" is ten and "0x10" is refused. Each flag but --aov and --scene may be
// given once; a flag that does not apply to the chosen source or mode is an error, not ignored.
#include "demos/options.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <functional>
#include <numbers>
#include <optional>
#include <sstream>
#include <string>
#include <utility>

#include "demos/memory.h"
#include "pipeline/scene.h"

namespace displace::app {
namespace {

// Bounds on numbers a user may reasonably mean (anything outside is a typo or an attack).
constexpr int max_wave_count = 4096;             // sinusoid waves
constexpr double max_budget_milliseconds = 1e9;  // about 11 days
constexpr int max_steps = 4096;                  // search steps per pixel
constexpr int max_ocean_size = 8192;             // the ocean's FFT grid (sim::OceanParams)
constexpr int max_refine = 64;                   // refinement steps per pixel
constexpr int max_tile = 64;                     // texture repeats over the plane
constexpr int max_repeat = 100;                  // sweep renders per row
constexpr int max_channel_index = 1 << 16;       // image channels
struct Range {
  double low, high;
  const char* unit;
};
constexpr Range time_range{-1e12, 1e12, "s"};         // phases w t are formed in double (sim.h)
constexpr Range patch_size_range{1e-2, 1e5, "m"};     // a centimetre to a hundred kilometres
constexpr Range wind_speed_range{0.1, 100.0, "m/s"};  // calm air to beyond a hurricane
constexpr Range fetch_range{0.1, 1e5, "km"};
constexpr Range spreading_range{0.0, 100.0, ""};  // exponent s of cos^(2s)
constexpr Range choppiness_range{0.0, 10.0, ""};
constexpr Range depth_scale_range{1e-4, 10.0, "world units"};
constexpr Range fov_range{0.01, 179.0, "degrees"};
constexpr Range radius_range{0.01, 10.0, "world units"};
constexpr Range budget_range{0.0, max_budget_milliseconds, "ms"};

std::string in_quotes(std::string_view text) { return fmt::format("'{}'", text); }

template <typename Number>
std::errc read_number(std::string_view text, Number& value) {
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error == std::errc{} && end != text.data() + text.size()) return std::errc::invalid_argument;
  return error;
}

// A finite number that fits a float; nothing otherwise.
std::optional<float> read_float(std::string_view text) {
  double value = 0.0;
  if (read_number(text, value) != std::errc{} || !std::isfinite(value) ||
      std::abs(value) > double(std::numeric_limits<float>::max())) {
    return std::nullopt;
  }
  return float(value);
}

// "WxH", each side in [1, max_image_side]
std::optional<std::pair<int, int>> read_image_size(std::string_view text) {
  const auto x = text.find('x');
  if (x == std::string_view::npos) return std::nullopt;
  int width = 0, height = 0;
  if (read_number(text.substr(0, x), width) != std::errc{} ||
      read_number(text.substr(x + 1), height) != std::errc{} || width < 1 || height < 1 ||
      width > max_image_side || height > max_image_side) {
    return std::nullopt;
  }
  return std::pair{width, height};
}

// "X,Y,Z"
std::optional<glm::vec3> read_vector(std::string_view text) {
  glm::vec3 value;
  std::string_view rest = text;
  for (int c = 0; c < 3; ++c) {
    const auto comma = rest.find(',');
    if ((c < 2) == (comma == std::string_view::npos)) return std::nullopt;
    const std::optional<float> component = read_float(rest.substr(0, comma));
    if (!component) return std::nullopt;
    value[c] = *component;
    rest = comma == std::string_view::npos ? std::string_view{} : rest.substr(comma + 1);
  }
  return value;
}

// "LOW,HIGH" with LOW < HIGH
std::optional<HeightRange> read_height_range(std::string_view text) {
  const auto comma = text.find(',');
  if (comma == std::string_view::npos) return std::nullopt;
  const std::optional<float> low = read_float(text.substr(0, comma)),
                             high = read_float(text.substr(comma + 1));
  if (!low || !high || !(*high > *low) || !std::isfinite(*high - *low)) return std::nullopt;
  return HeightRange{*low, *high};
}

// ---------------------------------------------------------------------------------------------
// validators: each returns what follows the flag's name in the error ("must be ..., got '0'") and
// rewrites a good value in the form CLI11 then converts

CLI::Validator integer_in(long long minimum, long long maximum) {
  return CLI::Validator(
      [=](std::string& text) -> std::string {
        long long value = 0;
        const std::errc error = read_number(text, value);
        if (error == std::errc::result_out_of_range ||
            (error == std::errc{} && (value < minimum || value > maximum))) {
          return fmt::format("must be an integer between {} and {}, got {}", minimum, maximum,
                             in_quotes(text));
        }
        if (error != std::errc{}) return "expects an integer, got " + in_quotes(text);
        text = std::to_string(value);
        return {};
      },
      fmt::format("[{}, {}]", minimum, maximum));
}

CLI::Validator seed_value() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        std::uint64_t value = 0;
        if (read_number(text, value) != std::errc{})
          return "expects a non-negative integer, got " + in_quotes(text);
        text = std::to_string(value);
        return {};
      },
      "[0, 2^64)");
}

CLI::Validator number_in(const Range& range) {
  const std::string bounds =
      fmt::format("{:g} and {:g}{}{}", range.low, range.high, range.unit[0] ? " " : "", range.unit);
  return CLI::Validator(
      [=](std::string& text) -> std::string {
        double value = 0.0;
        if (read_number(text, value) != std::errc{} || !std::isfinite(value)) {
          return "expects a finite number, got " + in_quotes(text);
        }
        if (!(value >= range.low && value <= range.high))
          return "must be between " + bounds + ", got " + in_quotes(text);
        text = fmt::format("{}", value);
        return {};
      },
      fmt::format("[{:g}, {:g}]{}{}", range.low, range.high, range.unit[0] ? " " : "", range.unit));
}

CLI::Validator finite_number() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        const std::optional<float> value = read_float(text);
        if (!value) return "expects a finite number, got " + in_quotes(text);
        text = fmt::format("{}", *value);
        return {};
      },
      "");
}

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

// A check of a text value that stays text: `problem` returns what is wrong, empty when nothing is.
CLI::Validator text_check(std::function<std::string(const std::string&)> problem,
                          std::string description = "") {
  return CLI::Validator([problem](std::string& text) { return problem(text); }, std::move(description));
}

CLI::Validator not_empty() {
  return text_check(
      [](const std::string& text) { return text.empty() ? std::string("needs a value") : std::string(); });
}

CLI::Validator output_file(std::vector<std::string> extensions) {
  return text_check([extensions](const std::string& text) -> std::string {
    const std::string extension = lower_extension(std::filesystem::path(text));
    if (!text.empty() && std::find(extensions.begin(), extensions.end(), extension) != extensions.end())
      return {};
    return fmt::format("must name a {} file, got {}", fmt::join(extensions, " or "), in_quotes(text));
  });
}

// An image size WxH, each side 1 .. max_image_side.
CLI::Validator image_size_check() {
  return text_check(
      [](const std::string& text) {
        return read_image_size(text)
                   ? std::string()
                   : fmt::format("expects WxH with each side an integer between 1 and {}, got {}",
                                 max_image_side, in_quotes(text));
      },
      fmt::format("[1, {}] each", max_image_side));
}

const Words<SourceKind> source_words = {{"ocean", SourceKind::ocean},
                                        {"sinusoids", SourceKind::sinusoids},
                                        {"bricks", SourceKind::bricks},
                                        {"cliff", SourceKind::cliff}};
const Words<sim::Spectrum> spectrum_words = {{"phillips", sim::Spectrum::phillips},
                                             {"jonswap", sim::Spectrum::jonswap}};
const Words<Baker> mode_words = {{"exact", Baker::exact},
                                 {"original", Baker::original},
                                 {"paper-adaptive", Baker::paper_adaptive},
                                 {"budgeted", Baker::budgeted},
                                 {"full", Baker::full}};
const Words<ConeKind> cone_kind_words = {{"center", ConeKind::center}, {"bilinear", ConeKind::bilinear}};
const Words<bake::Address> address_words = {{"wrap", bake::Address::wrap}, {"clamp", bake::Address::clamp}};
const Words<render::Surface> surface_words = {{"plane", render::Surface::plane},
                                              {"sphere", render::Surface::sphere},
                                              {"cylinder", render::Surface::cylinder},
                                              {"cone", render::Surface::cone}};
const Words<Aov> aov_words = {
    {"uv", Aov::uv}, {"depth", Aov::depth}, {"iterations", Aov::iterations}, {"fetches", Aov::fetches}};

Words<render::Method> method_words() {
  Words<render::Method> words;
  for (const render::MethodInfo& info : render::method_table()) words.emplace_back(info.name, info.method);
  return words;
}

std::vector<render::Method> all_methods_but_reference() {
  std::vector<render::Method> methods;
  for (const render::MethodInfo& info : render::method_table()) {
    if (info.family != render::MethodFamily::reference) methods.push_back(info.method);
  }
  return methods;
}

template <typename Enum>
Enum word_value(const Words<Enum>& words, std::string_view text) {
  for (const auto& [word, value] : words) {
    if (word == text) return value;
  }
  throw std::logic_error("unknown word " + in_quotes(text) + " passed its flag's validator");
}

// A file pattern: at least one '#' in its name, one of `extensions`.
CLI::Validator frame_pattern(std::vector<std::string> extensions) {
  return text_check([extensions](const std::string& text) -> std::string {
    if (std::filesystem::path(text).filename().string().find('#') == std::string::npos) {
      return "needs '#' in the file name for the frame number (name_####.png), got " + in_quotes(text);
    }
    return output_file(extensions)(text);
  });
}

// --aov NAME=FILE (render) or NAME=PATTERN (sequence, a '#' pattern): uv and depth to .exr,
// iterations and fetches to .exr (raw) or .png (heatmap).
void add_aov_option(CLI::App& app, std::vector<std::string>& aovs, const std::string& description,
                    bool patterns) {
  const std::string value = patterns ? "PATTERN" : "FILE";
  app.add_option("--aov", aovs, description)
      ->type_name("NAME=" + value)
      ->check(text_check([value, patterns](const std::string& text) -> std::string {
        const auto equals = text.find('=');
        if (equals == std::string::npos || equals + 1 == text.size()) {
          return "expects NAME=" + value + " (" + word_list(aov_words, ", ") + "), got " + in_quotes(text);
        }
        if (std::string problem = word_in(aov_words)(text.substr(0, equals)); !problem.empty())
          return problem;
        const Aov aov = word_value(aov_words, text.substr(0, equals));
        std::vector<std::string> extensions{".exr"};
        if (aov == Aov::iterations || aov == Aov::fetches) extensions.push_back(".png");
        const std::string file = text.substr(equals + 1);
        return patterns ? frame_pattern(extensions)(file) : output_file(extensions)(file);
      }))
      ->allow_extra_args(false)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
}

std::vector<AovOutput> aov_outputs(const std::vector<std::string>& aovs) {
  std::vector<AovOutput> outputs;
  for (const std::string& aov : aovs) {
    const auto equals = aov.find('=');
    outputs.push_back(
        {word_value(aov_words, aov.substr(0, equals)), std::filesystem::path(aov.substr(equals + 1))});
  }
  return outputs;
}

// ---------------------------------------------------------------------------------------------
// running CLI11

bool given(const CLI::App& app, const std::string& flag) {
  const CLI::Option* option = app.get_option_no_throw(flag);
  return option && option->count() > 0;
}

// CLI11's error in the project's words.
std::string translate(const CLI::App& app, const CLI::ParseError& error) {
  const std::string text = error.what();
  std::string name = text.substr(0, text.find_first_of(": "));
  if (!name.starts_with("-")) name = "--" + name;  // CLI11 names a flag without its dashes
  if (dynamic_cast<const CLI::ValidationError*>(&error)) {
    const auto colon = text.find(": ");
    return colon == std::string::npos ? text : text.substr(0, colon) + " " + text.substr(colon + 2);
  }
  if (dynamic_cast<const CLI::ArgumentMismatch*>(&error)) {
    if (text.find("At Most") != std::string::npos) return name + " is given twice";
    if (text.find("flag override") != std::string::npos) return name + " takes no value";
    return name + " needs a value";
  }
  if (dynamic_cast<const CLI::RequiredError*>(&error)) {
    const CLI::Option* option = app.get_option_no_throw(name);
    return fmt::format("'{}' needs {}{}", app.get_name(), name, option ? " " + option->get_type_name() : "");
  }
  return text;
}

// Runs CLI11 over `args`; the help text when --help was asked. Arguments it did not take are left
// in app.remaining().
std::optional<HelpSettings> parse_flags(CLI::App& app, std::span<const std::string_view> args) {
  std::vector<std::string> reversed(args.rbegin(), args.rend());  // CLI11 takes them last first
  try {
    app.parse(reversed);
  } catch (const CLI::CallForHelp&) {
    return HelpSettings{app.help()};
  } catch (const CLI::ParseError& error) {
    // CLI11 checks values before it looks at --help: asking for help wins over a bad value
    if (const CLI::Option* help = app.get_help_ptr(); help && help->count() > 0)
      return HelpSettings{app.help()};
    throw usage_error(translate(app, error));
  }
  return std::nullopt;
}

// The first argument no flag took, as an error.
void reject_extras(const CLI::App& app) {
  const std::vector<std::string> extras = app.remaining();
  if (extras.empty()) return;
  const std::string& extra = extras.front();
  if (!extra.starts_with("--") || extra == "--")
    throw usage_error("unexpected argument " + in_quotes(extra) + " (flags start with --)");
  const std::string flag = extra.substr(0, extra.find('='));
  const bool map_size = flag == "--size" && app.get_option_no_throw("--map-size");
  throw usage_error(fmt::format("unknown flag {} for '{}'{}", in_quotes(flag), app.get_name(),
                                map_size ? " (the height map's samples are --map-size N)" : ""));
}

// The settings every command's parser shares: unknown arguments are left for reject_extras(), each
// flag may be given once.
void set_up(CLI::App& app) {
  app.allow_extras();
  app.option_defaults()->multi_option_policy(CLI::MultiOptionPolicy::Throw);
  app.get_formatter()->column_width(36);
}

// A flag with a value: `type` names the value in --help, `validator` checks it (and rewrites it in
// the form CLI11 converts); the validator's description, if any, shows the limits next to `type`.
template <typename Value>
CLI::Option* add_value(CLI::App& app, const std::string& flag, Value& value, const std::string& description,
                       const std::string& type, CLI::Validator validator) {
  return app.add_option(flag, value, description)->type_name(type)->transform(std::move(validator));
}

// A flag without a value, given at most once.
CLI::Option* add_switch(CLI::App& app, const std::string& flag, bool& value, const std::string& description) {
  return app.add_flag(flag, value, description)
      ->disable_flag_override()
      ->multi_option_policy(CLI::MultiOptionPolicy::Throw);
}

// ---------------------------------------------------------------------------------------------
// the synthesis flags shared by `sim` and every --source

struct SourceDraft {
  SourceKind kind = SourceKind::ocean;
  int map_size = 0;
  double time = 0.0;
  std::uint64_t seed = 0;
  float patch_size = 0.0f, wind_speed = 0.0f, wind_direction_degrees = 0.0f, fetch = 0.0f, spreading = 0.0f,
        choppiness = 0.0f;
  sim::Spectrum spectrum = sim::Spectrum::phillips;
  int wave_count = 0;
};

// The flags that only a --source takes, in the order they are declared.
const std::vector<std::string> source_only_flags = {
    "--map-size", "--time",  "--seed",      "--patch-size", "--wind-direction", "--wind-speed",
    "--spectrum", "--fetch", "--spreading", "--choppiness", "--waves"};

void add_source_flags(CLI::App& app, SourceDraft& draft) {
  app.option_defaults()->group("Heights from a source");
  add_value(app, "--source", draft.kind, "what to synthesize", word_list(source_words),
            word_in(source_words));
  // a single texel (or a single row) has no relief to displace: at least 2 x 2
  add_value(app, "--map-size", draft.map_size,
            fmt::format("height map samples along u and v (ocean: even, at most {})", max_ocean_size), "INT",
            integer_in(2, max_image_side));
  add_value(app, "--time", draft.time, "seconds (ocean, sinusoids)", "T", number_in(time_range));
  add_value(app, "--seed", draft.seed, "random seed", "INT", seed_value());
  add_value(app, "--patch-size", draft.patch_size, "metres covered by the map (ocean 200, sinusoids 4)", "M",
            number_in(patch_size_range));
  add_value(app, "--wind-direction", draft.wind_direction_degrees,
            "azimuth of the wind / mean wave direction", "DEG", finite_number());
  add_value(app, "--wind-speed", draft.wind_speed, "ocean: m/s at 10 m (default 12)", "V",
            number_in(wind_speed_range));
  add_value(app, "--spectrum", draft.spectrum, "ocean (default phillips)", word_list(spectrum_words),
            word_in(spectrum_words));
  add_value(app, "--fetch", draft.fetch, "ocean, jonswap only: fetch in km (default 200)", "KM",
            number_in(fetch_range));
  add_value(app, "--spreading", draft.spreading, "ocean: directional spreading exponent (default 2)", "S",
            number_in(spreading_range));
  add_value(app, "--choppiness", draft.choppiness,
            "ocean: horizontal displacement scale, recorded only (default 1)", "L",
            number_in(choppiness_range));
  add_value(app, "--waves", draft.wave_count, "sinusoids: number of waves (default 12)", "INT",
            integer_in(1, max_wave_count));
}

SourceSettings finish_source(const CLI::App& app, const SourceDraft& draft) {
  SourceSettings source;
  source.kind = draft.kind;
  if (!given(app, "--map-size")) throw usage_error("--source needs --map-size N (samples along u and v)");
  source.size = draft.map_size;
  if (source.kind == SourceKind::ocean && (source.size % 2 != 0 || source.size > max_ocean_size)) {
    throw usage_error(
        fmt::format("--map-size for the ocean must be even and at most {} (its FFT grid), got {}",
                    max_ocean_size, source.size));
  }
  if (source.kind == SourceKind::bricks || source.kind == SourceKind::cliff) {
    // static procedural reliefs: only a seed
    for (const char* flag : {"--patch-size", "--wind-speed", "--wind-direction", "--fetch", "--spectrum",
                             "--spreading", "--choppiness", "--waves"}) {
      if (given(app, flag)) {
        throw usage_error(
            "--source bricks and --source cliff take only --map-size, --seed and --time (static)");
      }
    }
    if (given(app, "--seed")) source.seed = draft.seed;
    return source;
  }
  if (!given(app, "--time")) throw usage_error("--source needs --time T (seconds)");
  source.time = draft.time;
  const float degrees_to_radians = std::numbers::pi_v<float> / 180.0f;

  if (source.kind == SourceKind::ocean) {
    if (given(app, "--waves")) throw usage_error("--waves applies to --source sinusoids only");
    sim::OceanParams& ocean = source.ocean;
    ocean.size = source.size;
    if (given(app, "--seed")) ocean.seed = draft.seed;
    if (given(app, "--patch-size")) ocean.patch_size = draft.patch_size;
    if (given(app, "--wind-speed")) ocean.wind_speed = draft.wind_speed;
    if (given(app, "--wind-direction"))
      ocean.wind_direction = draft.wind_direction_degrees * degrees_to_radians;
    if (given(app, "--spectrum")) ocean.spectrum = draft.spectrum;
    if (given(app, "--fetch")) {
      if (ocean.spectrum != sim::Spectrum::jonswap)
        throw usage_error("--fetch applies to --spectrum jonswap only");
      ocean.fetch = draft.fetch;
    }
    if (given(app, "--spreading")) ocean.spreading = draft.spreading;
    if (given(app, "--choppiness")) ocean.choppiness = draft.choppiness;
  } else {
    for (const char* flag : {"--wind-speed", "--fetch", "--spectrum", "--spreading", "--choppiness"}) {
      if (given(app, flag)) throw usage_error(std::string(flag) + " applies to --source ocean only");
    }
    sim::SinusoidParams& sinusoids = source.sinusoids;
    if (given(app, "--seed")) sinusoids.seed = draft.seed;
    if (given(app, "--patch-size")) sinusoids.patch_size = draft.patch_size;
    if (given(app, "--wind-direction"))
      sinusoids.wind_direction = draft.wind_direction_degrees * degrees_to_radians;
    if (given(app, "--waves")) sinusoids.wave_count = draft.wave_count;
  }
  return source;
}

// ---------------------------------------------------------------------------------------------
// the heights every command that bakes reads: --input FILE with its load flags, or --source with
// the synthesis flags (never both)

struct InputDraft {
  SourceDraft source;
  std::string file;
  std::string channel;
  bool invert = false;
  std::string height_range;
};

void add_input_flags(CLI::App& app, InputDraft& draft) {
  app.option_defaults()->group("Heights from a file");
  app.add_option("--input", draft.file,
                 "a height image (8/16-bit: value / maximum; float: min..max or as `sim` wrote it)")
      ->type_name("FILE")
      ->check(not_empty());
  app.add_option("--channel", draft.channel,
                 "the channel: a name or an index (default `height`, or the only grey one)")
      ->type_name("NAME|INDEX")
      ->check(text_check([](const std::string& text) -> std::string {
        if (text.empty()) return "needs a value";
        if (!std::all_of(text.begin(), text.end(), [](char c) { return c >= '0' && c <= '9'; })) return {};
        std::string index = text;
        return integer_in(0, max_channel_index)(index);
      }));
  add_switch(app, "--invert", draft.invert, "the image stores depth (1 = deepest)");
  app.add_option("--height-range", draft.height_range, "float images: the raw values that map to 0 and 1")
      ->type_name("LOW,HIGH")
      ->check(text_check([](const std::string& text) -> std::string {
        if (text.find(',') == std::string::npos) return "expects LOW,HIGH, got " + in_quotes(text);
        if (!read_height_range(text)) return "needs finite LOW < HIGH, got " + in_quotes(text);
        return {};
      }));
  add_source_flags(app, draft.source);
}

std::variant<FileInput, SourceSettings> finish_input(const CLI::App& app, const InputDraft& draft) {
  const bool file = given(app, "--input"), source = given(app, "--source");
  if (file && source) throw usage_error("give either --input or --source, not both");
  if (file) {
    for (const CLI::Option* option : app.parse_order()) {
      const std::string flag = option->get_name();
      if (std::find(source_only_flags.begin(), source_only_flags.end(), flag) != source_only_flags.end()) {
        throw usage_error(flag + " applies to --source only, not --input");
      }
    }
    FileInput input{std::filesystem::path(draft.file), {}};
    if (given(app, "--channel")) {
      if (std::all_of(draft.channel.begin(), draft.channel.end(),
                      [](char c) { return c >= '0' && c <= '9'; })) {
        input.load.channel.index = std::stoi(draft.channel);
      } else {
        input.load.channel.name = draft.channel;
      }
    }
    input.load.invert = draft.invert;
    if (given(app, "--height-range")) input.load.range = read_height_range(draft.height_range);
    return input;
  }
  if (source) {
    if (given(app, "--channel") || given(app, "--invert") || given(app, "--height-range")) {
      throw usage_error("--channel, --invert and --height-range apply to --input only");
    }
    return finish_source(app, draft.source);
  }
  throw usage_error(
      fmt::format("'{}' needs --input FILE or --source {}", app.get_name(), word_list(source_words)));
}

// ---------------------------------------------------------------------------------------------
// the flags that describe a scene: the heights (file or source) and the view; shared by `render`
// and the scene files of `sweep`

struct SceneDraft {
  InputDraft input;
  render::View view;
  std::string size, eye, look_at, up, light, surface, albedo;
};

CLI::Validator vector_value() {
  return text_check([](const std::string& text) {
    return read_vector(text) ? std::string() : "expects X,Y,Z (finite numbers), got " + in_quotes(text);
  });
}

void add_scene_flags(CLI::App& app, SceneDraft& draft) {
  add_input_flags(app, draft.input);
  app.option_defaults()->group("View");
  render::View& view = draft.view;
  app.add_option("--size", draft.size, "the image in pixels (default 512x512)")
      ->type_name("WxH")
      ->check(text_check(
          [](const std::string& text) -> std::string {
            if (text.find('x') == std::string::npos) {
              return "expects WxH (pixels), got " + in_quotes(text) +
                     "; a --source's samples are --map-size N";
            }
            if (!read_image_size(text)) {
              return fmt::format("expects WxH with each side an integer between 1 and {}, got {}",
                                 max_image_side, in_quotes(text));
            }
            return {};
          },
          fmt::format("[1, {}] each", max_image_side)));
  add_value(app, "--address", view.address, "how the map continues past its edges (default wrap)",
            word_list(address_words), word_in(address_words));
  add_value(app, "--tile", view.tile, "texture repeats over the plane (above 1 needs --address wrap)", "INT",
            integer_in(1, max_tile));
  add_value(app, "--depth-scale", view.depth_scale, "world units between height 1 and height 0 (default 0.1)",
            "D", number_in(depth_scale_range));
  add_value(app, "--eye", draft.eye, "camera position", "X,Y,Z", vector_value());
  add_value(app, "--look-at", draft.look_at, "point the camera looks at", "X,Y,Z", vector_value());
  add_value(app, "--up", draft.up, "camera up (default 0,0,1)", "X,Y,Z", vector_value());
  add_value(app, "--fov-y", view.camera.fov_y_degrees, "full vertical angle (default 45)", "DEG",
            number_in(fov_range));
  add_value(app, "--light", draft.light, "direction towards the light", "X,Y,Z", vector_value());
  add_switch(app, "--shadows", view.shadows, "self-shadowing, traced towards the light with the same method");
  add_value(app, "--albedo", draft.albedo,
            "shade with an image (1-4 channels) instead of the procedural grid", "IMAGE", not_empty());
  app.add_option("--surface", draft.surface, "what the relief lies on (default plane)")
      ->type_name(word_list(surface_words) + "|mesh:FILE.obj")
      ->check(text_check([](const std::string& text) -> std::string {
        if (text == "mesh:") return "mesh:FILE.obj needs a file name after 'mesh:'";
        if (text.starts_with("mesh:")) return {};
        std::string word = text;
        return word_in(surface_words)(word);
      }));
  add_value(app, "--radius", view.radius, "the quadric's outer radius (default 0.25)", "R",
            number_in(radius_range));
}

SceneSettings finish_scene(const CLI::App& app, const SceneDraft& draft, const std::string& name) {
  SceneSettings scene{
      name, finish_input(app, draft.input), draft.view, std::filesystem::path(draft.albedo), {}};
  render::View& view = scene.view;
  if (given(app, "--size")) std::tie(view.camera.width, view.camera.height) = *read_image_size(draft.size);
  if (given(app, "--eye")) view.camera.eye = *read_vector(draft.eye);
  if (given(app, "--look-at")) view.camera.look_at = *read_vector(draft.look_at);
  if (given(app, "--up")) view.camera.up = *read_vector(draft.up);
  if (given(app, "--light")) {
    view.light_direction = *read_vector(draft.light);
    if (glm::length(view.light_direction) < 1e-6f)
      throw usage_error("--light must not be 0,0,0 (a direction towards the light)");
  }
  if (given(app, "--surface")) {
    if (draft.surface.starts_with("mesh:")) {
      view.surface = render::Surface::mesh;
      scene.mesh = std::filesystem::path(draft.surface.substr(5));
    } else {
      view.surface = word_value(surface_words, draft.surface);
    }
  }
  if (view.tile > 1 && view.address != bake::Address::wrap)
    throw usage_error("--tile above 1 needs --address wrap");
  try {
    view.camera.validate();
  } catch (const render::RenderError& error) {
    throw usage_error(error.what());
  }
  return scene;
}

// --device, --validate and --pipeline-cache, for every command that renders.
void add_renderer_flags(CLI::App& app, render::RendererOptions& options) {
  app.option_defaults()->group("Vulkan");
  add_value(app, "--device", options.device,
            "a device index or part of its name (default: the best GPU, else lavapipe)", "N|NAME",
            not_empty());
  add_switch(app, "--validate", options.validate, "Khronos validation layer; any message fails the command");
  app.add_option(
         "--pipeline-cache", options.pipeline_cache,
         "where compiled pipelines are kept (default $DISPLACE_PIPELINE_CACHE, else ~/.cache/displace)")
      ->type_name("DIR|off")
      ->check(text_check([](const std::string& text) {
        return text.empty() ? std::string("needs a directory or 'off'") : std::string();
      }));
}

// ---------------------------------------------------------------------------------------------
// the commands

CommandSettings parse_sim(std::span<const std::string_view> args) {
  CLI::App app(
      "Synthesize heights and write raw metres to channel `height`, with the source "
      "parameters and the [0, 1] mapping as EXR attributes.",
      "displace sim");
  set_up(app);
  SourceDraft source;
  std::string output;
  add_source_flags(app, source);
  app.get_option("--source")->required();
  app.option_defaults()->group("Options");
  add_value(app, "--output", output, "the heights", "FILE.exr", output_file({".exr"}))->required();
  if (auto help = parse_flags(app, args)) return *help;
  reject_extras(app);
  return SimSettings{finish_source(app, source), std::filesystem::path(output)};
}

// A baker's tolerance (bake::Budget::tolerance): a finite number in [0, 1).
CLI::Validator tolerance_in_range() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        double value = 0.0;
        if (read_number(text, value) != std::errc{} || !std::isfinite(value)) {
          return "expects a finite number, got " + in_quotes(text);
        }
        if (!(value >= 0.0 && value < 1.0)) return "must be in [0, 1), got " + in_quotes(text);
        text = fmt::format("{}", value);
        return {};
      },
      "[0, 1)");
}

// --bake-budget-ms and --bake-tolerance: the budget of the cone methods' maps (bake::BilinearBaker),
// into `budget` where given.
void add_cone_bake_flags(CLI::App& app, bake::Budget& budget) {
  add_value(app, "--bake-budget-ms", budget.milliseconds,
            "cone methods: bake their cone maps within this time (default unlimited; 0 allowed)", "MS",
            number_in(budget_range));
  app.add_option("--bake-tolerance", budget.tolerance,
                 "cone methods: refine while a ratio may be more than T below the best (default 0.25)")
      ->type_name("T")
      ->transform(tolerance_in_range());
}

CommandSettings parse_bake(std::span<const std::string_view> args) {
  CLI::App app("Bake a cone map from a height image or a source.", "displace bake");
  set_up(app);
  BakeSettings settings;
  InputDraft input;
  std::string output;
  Baker mode = Baker::exact;
  double budget = 0.0, tolerance = 0.0;
  bool relaxed = false;
  add_input_flags(app, input);
  app.option_defaults()->group("Cones");
  app.add_option("--sectors", settings.sector_count, "cone sectors per texel")
      ->type_name("1|4|8")
      ->transform(CLI::Validator(
          [](std::string& text) -> std::string {
            int value = 0;
            if (read_number(text, value) != std::errc{}) return "expects an integer, got " + in_quotes(text);
            if (!bake::is_valid_sector_count(value)) return "must be 1, 4 or 8, got " + std::to_string(value);
            text = std::to_string(value);
            return {};
          },
          ""))
      ->required();
  add_value(app, "--mode", mode, "the baker (bilinear cones: budgeted or full)", word_list(mode_words),
            word_in(mode_words));
  add_switch(app, "--relaxed", relaxed, "relaxed cones (sectors 1 or 4), its own baker");
  add_value(app, "--cones", settings.cones,
            "between texel centres, or the renderer's bilinear cones with apex heights",
            word_list(cone_kind_words), word_in(cone_kind_words));
  add_value(app, "--budget-ms", budget, "budgeted: refinement time (default unlimited; 0 allowed)", "MS",
            number_in(budget_range));
  app.add_option("--tolerance", tolerance,
                 "budgeted: refine while a ratio may be more than T below exact (default 0.25)")
      ->type_name("T")
      ->transform(tolerance_in_range());
  add_value(app, "--address", settings.address, "how the map continues past its edges (default wrap)",
            word_list(address_words), word_in(address_words));
  app.option_defaults()->group("Options");
  add_value(app, "--output", output, "the cone map (.png: heights quantized to 8 bits before baking)",
            "FILE.exr|FILE.png", output_file({".exr", ".png"}))
      ->required();
  add_switch(app, "--stats", settings.stats, "print one JSON line instead of the human line");
  if (auto help = parse_flags(app, args)) return *help;
  reject_extras(app);

  settings.input = finish_input(app, input);
  if (settings.cones == ConeKind::bilinear) {
    if (relaxed) throw usage_error("--cones bilinear bakes with --mode budgeted|full, not --relaxed");
    if (!given(app, "--mode"))
      throw usage_error("'displace bake --cones bilinear' needs --mode budgeted|full");
    if (mode != Baker::budgeted && mode != Baker::full) {
      throw usage_error(std::string("--cones bilinear bakes with --mode budgeted|full, not --mode ") +
                        baker_name(mode));
    }
    settings.baker = mode;
  } else if (relaxed) {
    if (settings.sector_count != 1 && settings.sector_count != 4) {
      throw usage_error("--relaxed supports --sectors 1 or 4, got " + std::to_string(settings.sector_count));
    }
    if (given(app, "--mode")) throw usage_error("--relaxed is its own baker; drop --mode");
    settings.baker = Baker::relaxed;
  } else {
    if (!given(app, "--mode")) {
      throw usage_error("'displace bake' needs --mode exact|original|paper-adaptive|budgeted (or --relaxed)");
    }
    if (mode == Baker::full) throw usage_error("--mode full bakes bilinear cones only: add --cones bilinear");
    settings.baker = mode;
  }
  if (given(app, "--budget-ms")) {
    if (settings.baker != Baker::budgeted) throw usage_error("--budget-ms applies to --mode budgeted only");
    settings.budget_milliseconds = budget;
  }
  if (given(app, "--tolerance")) {
    if (settings.baker != Baker::budgeted) throw usage_error("--tolerance applies to --mode budgeted only");
    settings.tolerance = float(tolerance);
  }
  settings.output = output;
  settings.output_format = lower_extension(settings.output) == ".png" ? ImageFormat::png : ImageFormat::exr;
  return settings;
}

CommandSettings parse_render(std::span<const std::string_view> args) {
  CLI::App app("Render the height field with one per-pixel method, baking the maps it needs.",
               "displace render");
  set_up(app);
  RenderSettings settings;
  SceneDraft scene;
  std::string output, compare;
  std::vector<std::string> aovs;
  add_scene_flags(app, scene);
  add_renderer_flags(app, settings.renderer);
  const Words<render::Method> methods = method_words();
  app.option_defaults()->group("Method");
  add_value(app, "--method", settings.method.method, "the per-pixel method", word_list(methods),
            word_in(methods))
      ->required();
  add_value(app, "--steps", settings.method.steps, "linear-search steps or maximum cone steps (default 32)",
            "INT", integer_in(1, max_steps));
  add_value(app, "--refine", settings.method.refine, "binary or secant steps (default 8)", "INT",
            integer_in(0, max_refine));
  add_cone_bake_flags(app, settings.cone_budget);
  app.option_defaults()->group("Options");
  add_value(app, "--output", output, "the picture", "FILE.png|FILE.exr", output_file({".png", ".exr"}))
      ->required();
  add_aov_option(app, aovs, "also write uv=F.exr, depth=F.exr, iterations=F.exr|F.png or fetches=F.exr|F.png",
                 false);
  app.add_option("--compare", compare, "also render the reference and print the error against it")
      ->type_name("reference")
      ->check(text_check([](const std::string& text) {
        return text == "reference" ? std::string() : "supports only 'reference', got " + in_quotes(text);
      }));
  if (auto help = parse_flags(app, args)) return *help;
  reject_extras(app);

  const SceneSettings parsed = finish_scene(app, scene, "render");
  settings.input = parsed.input;
  settings.view = parsed.view;
  settings.albedo = parsed.albedo;
  settings.mesh = parsed.mesh;
  const render::MethodInfo& info = render::method_info(settings.method.method);
  if (!render::supports_surface(info.method, settings.view.surface)) {
    throw usage_error(fmt::format("--method {} does not support --surface {}", info.name,
                                  render::surface_name(settings.view.surface)));
  }
  for (const char* flag : {"--bake-budget-ms", "--bake-tolerance"}) {
    if (!given(app, flag) || info.cone_sectors != 0) continue;
    std::vector<std::string> cone_methods;
    for (const render::MethodInfo& known : render::method_table()) {
      if (known.cone_sectors != 0) cone_methods.emplace_back(known.name);
    }
    throw usage_error(fmt::format("{} applies to the methods that read cone maps ({}), not --method {}", flag,
                                  fmt::join(cone_methods, ", "), info.name));
  }
  settings.aovs = aov_outputs(aovs);
  settings.compare_reference = given(app, "--compare");
  settings.output = output;
  return settings;
}

// A scene given as render flags (a built-in one, or a scene file's lines).
SceneSettings scene_from_args(const std::string& name, std::span<const std::string_view> args,
                              const std::string& where) {
  try {
    CLI::App app("", "displace sweep");
    set_up(app);
    app.set_help_flag();
    SceneDraft scene;
    add_scene_flags(app, scene);
    parse_flags(app, args);
    if (const std::vector<std::string> extras = app.remaining(); !extras.empty()) {
      throw usage_error(in_quotes(extras.front()) +
                        " does not describe a scene (only heights and view flags do)");
    }
    return finish_scene(app, scene, name);
  } catch (const AppError& error) {
    throw runtime_error(where + ": " + error.what());  // the flags come from a file, not the command line
  }
}

const std::vector<std::string> sweep_scene_names = {"bricks", "ocean", "cliff"};

CommandSettings parse_sweep(std::span<const std::string_view> args) {
  CLI::App app(
      "What accuracy costs: every method at every step count on each scene, against "
      "the reference. One CSV row per scene, method and steps.",
      "displace sweep");
  set_up(app);
  SweepSettings settings;
  std::vector<std::string> scenes;
  std::string methods, steps, size, output;
  app.add_option("--scene", scenes,
                 "a built-in scene or a file of render flags, one per line (default: all three)")
      ->type_name(fmt::format("{}|FILE", fmt::join(sweep_scene_names, "|")))
      ->check(not_empty())
      ->allow_extra_args(false)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  app.add_option("--methods", methods, "all (but the reference, the default) or a list")
      ->type_name("all|NAME,NAME...")
      ->check(text_check([](const std::string& text) -> std::string {
        if (text == "all") return {};
        std::string_view rest = text;
        while (true) {
          const auto comma = rest.find(',');
          const std::string_view word = rest.substr(0, comma);
          if (!render::find_method(word)) {
            return fmt::format("names an unknown method {} (methods: {})", in_quotes(word),
                               word_list(method_words(), ", "));
          }
          if (comma == std::string_view::npos) return {};
          rest = rest.substr(comma + 1);
        }
      }));
  app.add_option("--steps", steps, "the step counts (default 4,8,16,32,64)")
      ->type_name("S,S,...")
      ->check(text_check(
          [](const std::string& text) -> std::string {
            std::string_view rest = text;
            while (true) {
              const auto comma = rest.find(',');
              std::string one(rest.substr(0, comma));
              if (std::string problem = integer_in(1, max_steps)(one); !problem.empty()) return problem;
              if (comma == std::string_view::npos) return {};
              rest = rest.substr(comma + 1);
            }
          },
          fmt::format("[1, {}] each", max_steps)));
  add_value(app, "--refine", settings.refine, "binary or secant steps (default 8)", "INT",
            integer_in(0, max_refine));
  app.add_option("--repeat", settings.repeat,
                 "renders per row; the row reports the median device time (default 3)")
      ->type_name("INT")
      ->transform(integer_in(1, max_repeat));
  app.add_option("--size", size, "the image in pixels of every scene (default 512x512)")
      ->type_name("WxH")
      ->check(image_size_check());
  app.add_option("--output", output, "the table")
      ->type_name("FILE.csv")
      ->check(text_check([](const std::string& text) {
        return lower_extension(std::filesystem::path(text)) == ".csv"
                   ? std::string()
                   : std::string("of 'displace sweep' must end in .csv");
      }))
      ->required();
  add_cone_bake_flags(app, settings.cone_budget);
  add_renderer_flags(app, settings.renderer);
  if (auto help = parse_flags(app, args)) return *help;
  reject_extras(app);

  for (const std::string& scene : scenes) {
    const bool builtin =
        std::find(sweep_scene_names.begin(), sweep_scene_names.end(), scene) != sweep_scene_names.end();
    settings.scenes.push_back(builtin ? builtin_scene(scene) : read_scene_file(std::filesystem::path(scene)));
  }
  if (settings.scenes.empty()) {
    for (const std::string& name : sweep_scene_names) settings.scenes.push_back(builtin_scene(name));
  }
  if (methods.empty() || methods == "all") {
    settings.methods = all_methods_but_reference();
  } else {
    std::string_view rest = methods;
    while (true) {
      const auto comma = rest.find(',');
      settings.methods.push_back(render::find_method(rest.substr(0, comma))->method);
      if (comma == std::string_view::npos) break;
      rest = rest.substr(comma + 1);
    }
  }
  settings.steps = {4, 8, 16, 32, 64};
  if (given(app, "--steps")) {
    settings.steps.clear();
    std::istringstream list(steps);
    for (std::string one; std::getline(list, one, ',');) settings.steps.push_back(std::stoi(one));
  }
  if (given(app, "--size")) {
    for (SceneSettings& scene : settings.scenes) {
      std::tie(scene.view.camera.width, scene.view.camera.height) = *read_image_size(size);
    }
  }
  settings.output = output;
  return settings;
}

CommandSettings parse_demo(std::span<const std::string_view> args) {
  CLI::App app("The default ocean end to end: synthesize, bake, export, render and compare.",
               "displace demo");
  set_up(app);
  DemoSettings settings;
  std::string directory = settings.output_directory.string();
  add_value(app, "--map-size", settings.map_size, "ocean samples along u and v, even (default 512)", "INT",
            integer_in(2, max_ocean_size));
  add_value(app, "--output-dir", directory, "where the files go (default out)", "DIR", not_empty());
  if (auto help = parse_flags(app, args)) return *help;
  reject_extras(app);
  if (settings.map_size % 2 != 0) {
    throw usage_error(
        fmt::format("--map-size for the ocean must be even (its FFT grid), got {}", settings.map_size));
  }
  settings.output_directory = directory;
  return settings;
}

CommandSettings parse_scene(std::span<const std::string_view> args) {
  CLI::App app("Built-in scenes of the frame pipeline as TOML scene files.", "displace scene");
  set_up(app);
  PrintSceneSettings settings;
  const std::vector<std::string> names = pipeline::builtin_scene_names();
  app.add_option("--print", settings.name, "write the built-in scene NAME as TOML to stdout")
      ->type_name(fmt::format("{}", fmt::join(names, "|")))
      ->check(text_check([names](const std::string& text) -> std::string {
        if (std::find(names.begin(), names.end(), text) != names.end()) return {};
        return fmt::format("must name a built-in scene ({}), got {}", fmt::join(names, ", "),
                           in_quotes(text));
      }))
      ->required();
  if (auto help = parse_flags(app, args)) return *help;
  reject_extras(app);
  return settings;
}

// ---------------------------------------------------------------------------------------------
// the frame pipeline's commands: a scene (built-in or TOML file) with a few overrides

struct PipelineSceneDraft {
  std::string scene = "water";
  std::string size;
  int map_size = 0;
  render::Method method = render::Method::acm4;
  int steps = 0;
  double budget_ms = 0.0;
  long long bake_work = 0;
  int cone_lag = 0;
};

void add_pipeline_scene_flags(CLI::App& app, PipelineSceneDraft& draft) {
  app.option_defaults()->group("Scene");
  const std::vector<std::string> names = pipeline::builtin_scene_names();
  add_value(app, "--scene", draft.scene,
            fmt::format("a built-in scene ({}) or a TOML scene file (default water)", fmt::join(names, ", ")),
            "NAME|FILE.toml", not_empty());
  add_value(app, "--map-size", draft.map_size, "the height map's texels a side (default: the scene's)", "N",
            integer_in(2, 8192));
  app.add_option("--size", draft.size, "the image in pixels (default: the scene's)")
      ->type_name("WxH")
      ->check(image_size_check());
  const Words<render::Method> methods = method_words();
  add_value(app, "--method", draft.method, "the per-pixel method (default: the scene's)", word_list(methods),
            word_in(methods));
  add_value(app, "--steps", draft.steps, "search steps (default: the scene's)", "INT",
            integer_in(1, max_steps));
  add_value(app, "--budget-ms", draft.budget_ms,
            "the frame budget the bake's share comes from (default: the scene's)", "MS",
            number_in(budget_range));
  add_value(app, "--bake-work", draft.bake_work,
            "texels the cone bake may search a frame (default: the scene's)", "N", integer_in(0, 1ll << 40));
  add_value(
      app, "--cone-lag", draft.cone_lag,
      "with --budget-ms and moving heights: frames a cone map may take to make while the last one is served "
      "with raised apexes (default: the scene's; 0: every frame makes its own)",
      "N", integer_in(0, pipeline::max_cone_lag_frames));
}

pipeline::Scene finish_pipeline_scene(const CLI::App& app, const PipelineSceneDraft& draft) {
  pipeline::Scene scene;
  const std::vector<std::string> names = pipeline::builtin_scene_names();
  try {
    if (std::find(names.begin(), names.end(), draft.scene) != names.end()) {
      scene = pipeline::builtin_scene(draft.scene);
    } else {
      if (!std::filesystem::exists(draft.scene)) {
        throw runtime_error(fmt::format("--scene {} is neither a built-in scene ({}) nor a file",
                                        in_quotes(draft.scene), fmt::join(names, ", ")));
      }
      scene = pipeline::read_scene_file(draft.scene);
    }
  } catch (const pipeline::SceneError& error) {
    throw runtime_error(error.what());  // the file's content, not the command line
  }
  if (given(app, "--map-size")) {
    if (scene.source == pipeline::SourceKind::image) {
      throw usage_error("--map-size does not apply to an image scene (the map size is the image's)");
    }
    if (scene.source == pipeline::SourceKind::ocean && draft.map_size % 2 != 0) {
      throw usage_error("--map-size must be even for the ocean");
    }
    scene.map_size = draft.map_size;
  }
  if (given(app, "--size")) std::tie(scene.camera.width, scene.camera.height) = *read_image_size(draft.size);
  if (given(app, "--method")) scene.method = draft.method;
  if (given(app, "--steps")) scene.steps = draft.steps;
  if (given(app, "--budget-ms")) scene.frame_ms = draft.budget_ms;
  if (given(app, "--bake-work")) scene.bake_work = draft.bake_work;
  if (given(app, "--cone-lag")) {
    if (!std::isfinite(scene.frame_ms)) {
      throw usage_error(
          "--cone-lag needs a frame budget (--budget-ms, or the scene's [budget] frame_ms): without one "
          "every frame makes its own cone maps");
    }
    scene.cone_lag_frames = draft.cone_lag;
  }
  if (!render::supports_surface(scene.method, scene.surface)) {
    throw usage_error(fmt::format("--method {} does not support the scene's surface {}",
                                  render::method_info(scene.method).name,
                                  render::surface_name(scene.surface)));
  }
  return scene;
}

CommandSettings parse_sequence(std::span<const std::string_view> args) {
  CLI::App app(
      "Render frames A..B of a scene headless, each to its own file; deterministic, so any split "
      "into shards, any order and a resumed run give the same files.",
      "displace sequence");
  set_up(app);
  SequenceSettings settings;
  PipelineSceneDraft scene;
  std::string frames, output, shard, video;
  std::vector<std::string> aovs;
  add_pipeline_scene_flags(app, scene);
  add_renderer_flags(app, settings.renderer);
  app.option_defaults()->group("Frames");
  app.add_option("--frames", frames, "frames A to B inclusive, every STEP-th (frame n is at start + n / fps)")
      ->type_name("A:B[:STEP]")
      ->check(text_check([](const std::string& text) -> std::string {
        long long a = 0, b = 0, step = 1;
        char extra = 0;
        const int read = std::sscanf(text.c_str(), "%lld:%lld:%lld%c", &a, &b, &step, &extra);
        if ((read != 2 && read != 3) || a < 0 || b < a || step < 1 || b - a > 10000000) {
          return "expects A:B[:STEP] with 0 <= A <= B and STEP >= 1, got " + in_quotes(text);
        }
        return {};
      }))
      ->required();
  add_value(app, "--output", output, "the frames: '#' runs become the frame number", "DIR/name_####.png|.exr",
            frame_pattern({".png", ".exr"}))
      ->required();
  add_aov_option(app, aovs, "also write uv=DIR/uv_####.exr, depth=..., iterations=..., fetches=... per frame",
                 true);
  app.add_option("--shard", shard, "render shard I of N (round robin over the frames, I from 1)")
      ->type_name("I/N")
      ->check(text_check([](const std::string& text) -> std::string {
        int i = 0, n = 0;
        char extra = 0;
        if (std::sscanf(text.c_str(), "%d/%d%c", &i, &n, &extra) != 2 || n < 1 || n > 100000 || i < 1 ||
            i > n) {
          return "expects I/N with 1 <= I <= N, got " + in_quotes(text);
        }
        return {};
      }));
  add_switch(app, "--resume", settings.resume, "skip frames whose outputs all exist");
  add_value(app, "--video", video, "also encode the frames with ffmpeg (needs ffmpeg on the PATH)",
            "FILE.mp4|FILE.webm", output_file({".mp4", ".webm"}));
  std::string preview;
  add_value(app, "--preview", preview, "also an animated GIF of the frames (a preview)", "FILE.gif",
            output_file({".gif"}));
  if (auto help = parse_flags(app, args)) return *help;
  reject_extras(app);
  settings.scene = finish_pipeline_scene(app, scene);
  settings.preview = preview;
  long long step = 1;
  std::sscanf(frames.c_str(), "%lld:%lld:%lld", &settings.first, &settings.last, &step);
  settings.step = step;
  if (!shard.empty()) std::sscanf(shard.c_str(), "%d/%d", &settings.shard_index, &settings.shard_count);
  if (!settings.preview.empty() && settings.shard_count > 1) {
    throw usage_error("--preview shows one run's frames: not with --shard");
  }
  // shards and resumed runs give one run's files only when a frame depends on its index alone
  if (std::isfinite(settings.scene.frame_ms) && (settings.shard_count > 1 || settings.resume)) {
    throw usage_error(fmt::format(
        "--shard and --resume need frames that depend on their index only, and a wall-clock frame budget "
        "({:g} ms, from --budget-ms or the scene's [budget] frame_ms) makes them depend on timing: give a "
        "work "
        "budget instead (--bake-work N)",
        settings.scene.frame_ms));
  }
  settings.output = output;
  settings.aovs = aov_outputs(aovs);
  settings.video = video;
  if (!settings.video.empty() && settings.shard_count > 1) {
    throw usage_error("--video encodes one run's frames: not with --shard");
  }
  return settings;
}

// The keys of the play window, for `displace play --help` (demos/play.cpp acts on them).
constexpr const char* play_keys = R"(Keys:
  M / Shift+M      next / previous method (those the scene's surface supports)
  Up / Down        search steps x2 / /2
  Right / Left     frame budget up / down (unlimited, 100 .. 1 ms, 0: the bake's share is what is left);
                   a scene without a budget starts at 33 ms (with --frames: the scene's, deterministic)
  Space            pause / resume
  N                one frame forward (while paused)
  L / Shift+L      cone maps made over one frame more / fewer (lagged maps, 0 .. 64, with a budget;
                   the title shows their age and how far their apexes were raised)
  S                screenshot: play_NNNNNN.png (the frame index) in the working directory
  R                camera back to the scene's
  Esc / Q          quit
  mouse drag       orbit the camera around its look-at point; wheel: closer / farther)";

CommandSettings parse_play(std::span<const std::string_view> args) {
  CLI::App app(
      "The frame pipeline's scene animated in a window (GLFW, a Vulkan swapchain). The title and the "
      "terminal show the frame time, its split (sim, bake, upload, render), the bake budget and the "
      "texels left to refine. Needs a display: without one, run it under 'xvfb-run -a'.",
      "displace play");
  set_up(app);
  app.footer(play_keys);
  PlaySettings settings;
  std::string size, screenshot;
  const std::vector<std::string> names = pipeline::builtin_scene_names();
  app.add_option("--scene", settings.scene, "a built-in scene or a TOML scene file (default water)")
      ->type_name(fmt::format("{}|FILE.toml", fmt::join(names, "|")))
      ->check(text_check([names](const std::string& text) -> std::string {
        if (std::find(names.begin(), names.end(), text) != names.end() ||
            lower_extension(std::filesystem::path(text)) == ".toml") {
          return {};
        }
        return fmt::format("must name a built-in scene ({}) or a .toml file, got {}", fmt::join(names, ", "),
                           in_quotes(text));
      }));
  app.add_option("--size", size, "the window and image in pixels (default: the scene's, 512x512)")
      ->type_name("WxH")
      ->check(image_size_check());
  add_value(app, "--map-size", settings.map_size, "height map samples along u and v (default: the scene's)",
            "INT", integer_in(2, 8192));
  add_value(app, "--frames", settings.frames,
            "render exactly N fixed-step frames (scene time start + n / fps), then exit", "N",
            integer_in(1, 1000000000));
  add_value(
      app, "--cone-lag", settings.cone_lag,
      "frames a cone map may take to make while the last one is served with raised apexes (interactive: "
      "with a frame budget; default: the scene's)",
      "N", integer_in(0, pipeline::max_cone_lag_frames));
  add_value(app, "--screenshot", screenshot, "with --frames: write the last frame", "F.png",
            output_file({".png"}));
  add_switch(app, "--vsync", settings.vsync,
             "present at the display's rate (default: as fast as frames come)");
  add_switch(app, "--pin-threads", settings.pin_threads,
             "run TBB's threads and lavapipe's rasterizer threads one per CPU (Linux): steadier frame times");
  add_renderer_flags(app, settings.renderer);
  if (auto help = parse_flags(app, args)) return *help;
  reject_extras(app);
  if (given(app, "--size")) std::tie(settings.width, settings.height) = *read_image_size(size);
  if (given(app, "--cone-lag") && given(app, "--frames")) {
    throw usage_error("--cone-lag applies to real-time play, not --frames (its frames are deterministic)");
  }
  if (given(app, "--screenshot")) {
    if (!given(app, "--frames")) {
      throw usage_error("--screenshot needs --frames N (in the window, S writes a screenshot)");
    }
    settings.screenshot = screenshot;
  }
  return settings;
}

CommandSettings parse_bench_frame(std::span<const std::string_view> args) {
  CLI::App app(
      "Run the frame pipeline for F frames after a warm-up and print, per stage, the p50, p95 and "
      "p99 milliseconds, the frames within budget, FFTs per frame, the effects, and Vulkan allocations.",
      "displace bench-frame");
  set_up(app);
  BenchFrameSettings settings;
  PipelineSceneDraft scene;
  std::string json;
  add_pipeline_scene_flags(app, scene);
  add_renderer_flags(app, settings.renderer);
  app.option_defaults()->group("Benchmark");
  add_value(app, "--frames", settings.frames, "frames timed (default 120)", "F", integer_in(1, 1000000));
  add_value(app, "--warm-up", settings.warm_up, "frames run first, not timed (default 5)", "N",
            integer_in(2, 10000));
  add_switch(app, "--serial", settings.serial,
             "run the stages one after another, none overlapped: what each costs with the whole machine");
  add_switch(
      app, "--pin-threads", settings.pin_threads,
      "run TBB's threads and lavapipe's rasterizer threads one per CPU (Linux): frame times without the "
      "stalls of a woken thread queued on a busy CPU");
  add_value(app, "--json", json, "also write the table as JSON", "FILE.json", output_file({".json"}));
  if (auto help = parse_flags(app, args)) return *help;
  reject_extras(app);
  settings.scene = finish_pipeline_scene(app, scene);
  settings.json = json;
  return settings;
}

constexpr int max_report_image_side = 2048;  // --size of `displace report`

CommandSettings parse_report(std::span<const std::string_view> args) {
  CLI::App app(
      "What accuracy costs in time: every method's error against fetches and device milliseconds, "
      "grazing views, the bake's tightness and price, the frame loop's budget against its error, and "
      "iteration heatmaps; the CSV and JSON behind each figure, the figures (PNG, matplotlib) and a "
      "README.md that embeds them.",
      "displace report");
  set_up(app);
  ReportSettings settings;
  std::vector<std::string> scenes;
  bool invert = false;
  std::string output = settings.output.string();
  app.add_option("--scene", scenes,
                 "a built-in scene, a height image, or a .txt file of render flags (default: the three "
                 "built-in ones)")
      ->type_name(fmt::format("{}|IMAGE|FILE.txt", fmt::join(sweep_scene_names, "|")))
      ->check(not_empty())
      ->allow_extra_args(false)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  add_switch(app, "--invert", invert, "height images store depth (1 = deepest)");
  add_switch(app, "--quick", settings.quick,
             "fewer step counts, frames and budgets at 128 x 128 pixels (minutes, for CI)");
  add_value(app, "--size", settings.image_side,
            "the render figures' square images, pixels a side (default 256, --quick 128)", "N",
            integer_in(16, max_report_image_side));
  add_value(app, "--output", output, "the report's directory (default docs/report)", "DIR", not_empty());
  bool no_plots = false;
  add_switch(app, "--no-plots", no_plots, "write the data (CSV, JSON) without running the plotting script");
  add_renderer_flags(app, settings.renderer);
  if (auto help = parse_flags(app, args)) return *help;
  reject_extras(app);

  bool any_image = false;
  for (const std::string& scene : scenes) {
    if (std::find(sweep_scene_names.begin(), sweep_scene_names.end(), scene) != sweep_scene_names.end()) {
      settings.scenes.push_back(builtin_scene(scene));
    } else if (lower_extension(std::filesystem::path(scene)) == ".txt") {
      settings.scenes.push_back(read_scene_file(std::filesystem::path(scene)));
    } else {
      // a user's map: rarely a tile, so clamped at its edges
      SceneSettings image;
      image.name = std::filesystem::path(scene).stem().string();
      image.input = FileInput{std::filesystem::path(scene), HeightLoadSettings{{}, invert, std::nullopt}};
      image.view.address = bake::Address::clamp;
      settings.scenes.push_back(std::move(image));
      any_image = true;
    }
  }
  if (invert && !any_image) throw usage_error("--invert needs a height image in --scene");
  if (settings.scenes.empty()) {
    for (const std::string& name : sweep_scene_names) settings.scenes.push_back(builtin_scene(name));
  }
  settings.output = output;
  settings.plots = !no_plots;
  return settings;
}

struct Command {
  std::string_view name;
  CommandSettings (*parse)(std::span<const std::string_view> args);  // the arguments after the name
};
constexpr Command commands[] = {{"sim", parse_sim},           {"bake", parse_bake},
                                {"render", parse_render},     {"sweep", parse_sweep},
                                {"demo", parse_demo},         {"scene", parse_scene},
                                {"sequence", parse_sequence}, {"bench-frame", parse_bench_frame},
                                {"play", parse_play},         {"report", parse_report}};

}  // namespace

std::string lower_extension(const std::filesystem::path& path) {
  std::string extension = path.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  return extension;
}

bool is_command(std::string_view word) {
  return std::any_of(std::begin(commands), std::end(commands),
                     [&](const Command& c) { return c.name == word; });
}

CommandSettings parse_command_line(std::span<const std::string_view> args) {
  if (args.empty()) throw usage_error("no command given");
  const std::string_view word = args.front();
  if (word == "help" || word == "--help" || word == "-h") return HelpSettings{};
  for (const Command& command : commands) {
    if (command.name != word) continue;
    CommandSettings settings = command.parse(args.subspan(1));
    std::visit(
        [](auto& parsed) {
          if constexpr (requires { parsed.renderer.memory_limit; }) {
            parsed.renderer.memory_limit = memory_limit_from_environment();
            parsed.renderer.memory_limit_source = memory_limit_variable;
          }
        },
        settings);
    return settings;
  }
  std::vector<std::string_view> names;
  for (const Command& command : commands) names.push_back(command.name);
  throw usage_error(
      fmt::format("unknown command {} (commands: {}, help)", in_quotes(word), fmt::join(names, ", ")));
}

SceneSettings builtin_scene(std::string_view name) {
  if (std::find(sweep_scene_names.begin(), sweep_scene_names.end(), name) == sweep_scene_names.end()) {
    throw usage_error(
        fmt::format("unknown built-in scene {} ({})", in_quotes(name), fmt::join(sweep_scene_names, ", ")));
  }
  const std::vector<std::string_view> args = {"--source", name, "--map-size", "256", "--time", "0"};
  return scene_from_args(std::string(name), args, "scene " + std::string(name));
}

SceneSettings read_scene_file(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw runtime_error("cannot read scene file " + in_quotes(file.string()));
  std::vector<std::string> words;
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    const auto hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    std::istringstream tokens(line);
    std::string flag, value, extra;
    if (!(tokens >> flag)) continue;
    if (!flag.starts_with("--")) {
      throw runtime_error(fmt::format("scene file {} line {}: expected a --flag, got {}",
                                      in_quotes(file.string()), number, in_quotes(flag)));
    }
    words.push_back(flag);
    if (tokens >> value) words.push_back(value);
    if (tokens >> extra) {
      throw runtime_error(fmt::format("scene file {} line {}: one flag and at most one value per line",
                                      in_quotes(file.string()), number));
    }
  }
  const std::vector<std::string_view> args(words.begin(), words.end());
  return scene_from_args(file.stem().string(), args, "scene file " + in_quotes(file.string()));
}

}  // namespace displace::app
