// demos/cli/flags.cpp - the validators, vocabularies and CLI11 plumbing of demos/cli/flags.h (the output
// and renderer flags: demos/cli/output_flags.cpp).
#include "demos/cli/flags.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "demos/cli/command.h"
#include "demos/error.h"

namespace displace::app::cli {

std::string in_quotes(std::string_view text) { return fmt::format("'{}'", text); }

namespace {

template <typename Number>
std::errc read_whole(std::string_view text, Number& value) {
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error == std::errc{} && end != text.data() + text.size()) return std::errc::invalid_argument;
  return error;
}

}  // namespace

std::errc read_number(std::string_view text, long long& value) { return read_whole(text, value); }
std::errc read_number(std::string_view text, unsigned long long& value) { return read_whole(text, value); }
std::errc read_number(std::string_view text, int& value) { return read_whole(text, value); }
std::errc read_number(std::string_view text, double& value) { return read_whole(text, value); }

// A finite number that fits a float; nothing otherwise.
std::optional<float> read_float(std::string_view text) {
  double value = 0.0;
  if (read_number(text, value) != std::errc{} || !std::isfinite(value) ||
      std::abs(value) > double(std::numeric_limits<float>::max())) {
    return std::nullopt;
  }
  return float(value);
}

// "WxH", each side in [1, render::max_image_side]
std::optional<std::pair<int, int>> read_image_size(std::string_view text) {
  const auto x = text.find('x');
  if (x == std::string_view::npos) return std::nullopt;
  int width = 0, height = 0;
  if (read_number(text.substr(0, x), width) != std::errc{} ||
      read_number(text.substr(x + 1), height) != std::errc{} || width < 1 || height < 1 ||
      width > render::max_image_side || height > render::max_image_side) {
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
std::optional<std::pair<float, float>> read_pair(std::string_view text) {
  const auto comma = text.find(',');
  if (comma == std::string_view::npos) return std::nullopt;
  const std::optional<float> low = read_float(text.substr(0, comma)),
                             high = read_float(text.substr(comma + 1));
  if (!low || !high || !(*high > *low) || !std::isfinite(*high - *low)) return std::nullopt;
  return std::pair{*low, *high};
}

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
        unsigned long long value = 0;
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

CLI::Validator text_check(std::function<std::string(const std::string&)> problem, std::string description) {
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

// An image size WxH, each side 1 .. render::max_image_side.
CLI::Validator image_size_check() {
  return text_check(
      [](const std::string& text) {
        return read_image_size(text)
                   ? std::string()
                   : fmt::format("expects WxH with each side an integer between 1 and {}, got {}",
                                 render::max_image_side, in_quotes(text));
      },
      fmt::format("[1, {}] each", render::max_image_side));
}

CLI::Validator vector_value() {
  return text_check([](const std::string& text) {
    return read_vector(text) ? std::string() : "expects X,Y,Z (finite numbers), got " + in_quotes(text);
  });
}

// A bake's time budget: milliseconds, or "unlimited".
CLI::Validator bake_budget_in(double maximum_ms) {
  const CLI::Validator milliseconds = number_in({0.0, maximum_ms, "ms"});
  return CLI::Validator(
      [milliseconds](std::string& text) -> std::string {
        if (text == "unlimited") return {};
        double value = 0.0;
        if (read_number(text, value) != std::errc{} || !std::isfinite(value))
          return "expects milliseconds or 'unlimited', got " + in_quotes(text);
        return milliseconds(text);
      },
      fmt::format("[0, {:g}] ms|unlimited", maximum_ms));
}

double bake_budget_value(const std::string& text) {
  return text == "unlimited" ? std::numeric_limits<double>::infinity() : std::stod(text);
}

// A baker's tolerance (bake::Budget::tolerance): a finite number in [0, bake::max_tolerance).
CLI::Validator tolerance_in_range() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        double value = 0.0;
        if (read_number(text, value) != std::errc{} || !std::isfinite(value)) {
          return "expects a finite number, got " + in_quotes(text);
        }
        if (!(value >= 0.0 && value < bake::max_tolerance))
          return fmt::format("must be in [0, {:g}), got {}", bake::max_tolerance, in_quotes(text));
        text = fmt::format("{}", value);
        return {};
      },
      fmt::format("[0, {:g})", bake::max_tolerance));
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

const Words<pipeline::SourceKind> source_words = {{"ocean", pipeline::SourceKind::ocean},
                                                  {"sinusoids", pipeline::SourceKind::sinusoids},
                                                  {"bricks", pipeline::SourceKind::bricks},
                                                  {"cliff", pipeline::SourceKind::cliff},
                                                  {"image", pipeline::SourceKind::image}};
const Words<sim::Spectrum> spectrum_words = [] {
  Words<sim::Spectrum> words;
  for (sim::Spectrum spectrum : pipeline::ocean_spectra())
    words.emplace_back(std::string(pipeline::spectrum_word(spectrum)), spectrum);
  return words;
}();
const Words<sim::Spreading> spreading_words = [] {
  Words<sim::Spreading> words;
  for (sim::Spreading model : pipeline::spreading_models())
    words.emplace_back(std::string(pipeline::spreading_word(model)), model);
  return words;
}();
const Words<bake::Address> address_words = {{"wrap", bake::Address::wrap}, {"clamp", bake::Address::clamp}};
const Words<render::Surface> surface_words = {{"plane", render::Surface::plane},
                                              {"sphere", render::Surface::sphere},
                                              {"cylinder", render::Surface::cylinder},
                                              {"cone", render::Surface::cone}};
const Words<render::Material> material_words = {
    {"grid", render::Material::grid}, {"albedo", render::Material::grid}, {"water", render::Material::water}};

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

CLI::Option* add_switch(CLI::App& app, const std::string& flag, bool& value, const std::string& description) {
  return app.add_flag(flag, value, description)
      ->disable_flag_override()
      ->multi_option_policy(CLI::MultiOptionPolicy::Throw);
}

// "displace render" for the subcommand render.
std::string command_name(const CLI::App& app) {
  return app.get_parent() ? "displace " + app.get_name() : app.get_name();
}

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
    return fmt::format("'{}' needs {}{}", command_name(app), name,
                       option ? " " + option->get_type_name() : "");
  }
  return text;
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
  throw usage_error(fmt::format("unknown flag {} for '{}'{}", in_quotes(flag), command_name(app),
                                map_size ? " (the height map's samples are --map-size N)" : ""));
}

// The settings every command's parser shares: unknown arguments are left for reject_extras(), each
// flag may be given once.
void set_up(CLI::App& app) {
  app.allow_extras();
  app.option_defaults()->multi_option_policy(CLI::MultiOptionPolicy::Throw);
  app.get_formatter()->column_width(36);
}

}  // namespace displace::app::cli

namespace displace::app::cli {

std::string flag_words(std::string_view message) {
  // longer names first, so that a phrase is replaced before the field names inside it
  static const std::pair<std::string_view, std::string_view> fields[] = {
      {"View::tile or MapSet::width x MapSet::height", "--tile or --map-size"},
      {"MapSet::width x MapSet::height", "--map-size"},
      {"Camera::width x Camera::height", "--size"},
      {"Camera::width and Camera::height", "--size"},
      {"Camera::fov_y_degrees", "--fov-y"},
      {"Camera::look_at", "--look-at"},
      {"Camera::eye", "--eye"},
      {"Camera::up", "--up"},
      {"View::depth_scale", "--depth-scale"},
      {"View::light_direction", "--light"},
      {"View::address", "--address"},
      {"View::surface", "--surface"},
      {"View::radius", "--radius"},
      {"View::tile", "--tile"},
      {"MethodSettings::method", "--method"},
      {"MethodSettings::steps", "--steps"},
      {"MethodSettings::refine", "--refine"},
      {"RendererOptions::validate", "--validate"},
      {"RendererOptions::device", "--device"},
      {"DeviceOptions::validate", "--validate"},  // the renderer's device (vulkan/context.h)
      {"DeviceOptions::device", "--device"},
      {"Budget::tolerance", "--tolerance"},
  };
  std::string text(message);
  for (const auto& [field, flag] : fields) {
    for (std::size_t at = text.find(field); at != std::string::npos;
         at = text.find(field, at + flag.size())) {
      text.replace(at, field.size(), flag);
    }
  }
  return text;
}

}  // namespace displace::app::cli
