// demos/options.cpp - parses `displace` argv into the typed settings of options.h.
//
// Flags take their value as the next argument or after '=' (--size 512, --size=512). Each flag may
// be given once; a flag that does not apply to the chosen source or mode is an error, not ignored.
#include "demos/options.h"

#include <cstdio>
#include <fstream>
#include <sstream>
#include <algorithm>
#include <charconv>
#include <cmath>
#include <numbers>
#include <optional>
#include <tuple>
#include <set>
#include <string>

namespace displace::app {
namespace {

// Bounds on numbers a user may reasonably mean (anything outside is a typo or an attack).
constexpr int max_wave_count = 4096;             // sinusoid waves
constexpr double max_budget_milliseconds = 1e9;  // about 11 days
struct Range {
  double low, high;
  const char* unit;
};
constexpr Range time_range{-1e6, 1e6, "s"};          // beyond, float phases w t lose the wave shape
constexpr Range patch_size_range{1e-2, 1e5, "m"};    // a centimetre to a hundred kilometres
constexpr Range wind_speed_range{0.1, 100.0, "m/s"};  // calm air to beyond a hurricane
constexpr Range fetch_range{0.1, 1e5, "km"};
constexpr Range spreading_range{0.0, 100.0, ""};      // exponent s of cos^(2s)
constexpr Range choppiness_range{0.0, 10.0, ""};

std::string quoted(std::string_view text) {
  std::string result(1, '\'');
  result.append(text);
  result.push_back('\'');
  return result;
}


// Walks argv one flag at a time.
class FlagReader {
 public:
  explicit FlagReader(std::span<const std::string_view> args) : args_(args) {}

  bool done() const { return position_ >= args_.size(); }

  // The next flag's name; throws unless it looks like --name. Rejects repeated flags.
  std::string_view next_flag() {
    std::string_view argument = args_[position_++];
    inline_value_.reset();
    if (argument.size() < 3 || argument.substr(0, 2) != "--") {
      throw usage_error("unexpected argument " + quoted(argument) + " (flags start with --)");
    }
    if (const auto equals = argument.find('='); equals != std::string_view::npos) {
      inline_value_ = argument.substr(equals + 1);
      argument = argument.substr(0, equals);
    }
    flag_ = argument;
    if (flag_ != "--aov" && !seen_.insert(std::string(flag_)).second) {  // --aov may repeat
      throw usage_error(std::string(flag_) + " is given twice");
    }
    return flag_;
  }

  // The current flag's value.
  std::string_view value() {
    if (inline_value_) {
      if (inline_value_->empty()) throw usage_error(std::string(flag_) + " needs a value");
      return *inline_value_;
    }
    if (done() || args_[position_].starts_with("--"))
      throw usage_error(std::string(flag_) + " needs a value");
    return args_[position_++];
  }

  // The current flag is a switch and must not carry a value.
  void no_value() const {
    if (inline_value_) throw usage_error(std::string(flag_) + " takes no value");
  }

 private:
  std::span<const std::string_view> args_;
  std::size_t position_ = 0;
  std::string_view flag_;
  std::optional<std::string_view> inline_value_;
  std::set<std::string> seen_;
};

// numbers
template <typename Integer>
Integer parse_integer(std::string_view flag, std::string_view text, Integer minimum, Integer maximum,
                      const char* what) {
  Integer value{};
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error == std::errc::result_out_of_range ||
      (error == std::errc{} && end == text.data() + text.size() && (value < minimum || value > maximum))) {
    throw usage_error(std::string(flag) + " must be " + what + " between " + std::to_string(minimum) +
                      " and " + std::to_string(maximum) + ", got " + quoted(text));
  }
  if (error != std::errc{} || end != text.data() + text.size()) {
    throw usage_error(std::string(flag) + " expects " + what + ", got " + quoted(text));
  }
  return value;
}

int parse_int(std::string_view flag, std::string_view text, int minimum, int maximum) {
  return parse_integer<int>(flag, text, minimum, maximum, "an integer");
}

// "WxH" in pixels
std::pair<int, int> parse_image_size(std::string_view flag, std::string_view text, int maximum) {
  const auto x = text.find('x');
  if (x == std::string_view::npos) {
    throw usage_error(std::string(flag) + " expects WxH (pixels), got " + quoted(text) +
                      "; a --source's samples are --map-size N");
  }
  return {parse_integer<int>(flag, text.substr(0, x), 1, maximum, "an integer"),
          parse_integer<int>(flag, text.substr(x + 1), 1, maximum, "an integer")};
}

std::uint64_t parse_seed(std::string_view flag, std::string_view text) {
  return parse_integer<std::uint64_t>(flag, text, 0, std::numeric_limits<std::uint64_t>::max(),
                                      "a non-negative integer");
}

double parse_number(std::string_view flag, std::string_view text) {
  double value = 0.0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error != std::errc{} || end != text.data() + text.size() || !std::isfinite(value)) {
    throw usage_error(std::string(flag) + " expects a finite number, got " + quoted(text));
  }
  return value;
}

float parse_float(std::string_view flag, std::string_view text) {
  const double value = parse_number(flag, text);
  if (std::abs(value) > double(std::numeric_limits<float>::max())) {
    throw usage_error(std::string(flag) + " is out of range, got " + quoted(text));
  }
  return float(value);
}

float parse_float_in(std::string_view flag, std::string_view text, const Range& range) {
  const double value = parse_number(flag, text);
  if (!(value >= range.low && value <= range.high)) {
    char bounds[96];
    std::snprintf(bounds, sizeof bounds, "%g and %g%s%s", range.low, range.high, range.unit[0] ? " " : "", range.unit);
    throw usage_error(std::string(flag) + " must be between " + bounds + ", got " + quoted(text));
  }
  return float(value);
}

// words
template <typename Enum, std::size_t count>
Enum parse_word(std::string_view flag, std::string_view text,
                const std::pair<std::string_view, Enum> (&table)[count]) {
  std::string choices;
  for (const auto& [word, value] : table) {
    if (word == text) return value;
    if (!choices.empty()) choices += '|';
    choices += word;
  }
  throw usage_error(std::string(flag) + " must be one of " + choices + ", got " + quoted(text));
}

constexpr std::pair<std::string_view, SourceKind> source_words[] = {{"ocean", SourceKind::ocean},
                                                                    {"sinusoids", SourceKind::sinusoids},
                                                                    {"bricks", SourceKind::bricks},
                                                                    {"cliff", SourceKind::cliff}};
constexpr std::pair<std::string_view, sim::Spectrum> spectrum_words[] = {
    {"phillips", sim::Spectrum::phillips}, {"jonswap", sim::Spectrum::jonswap}};
constexpr std::pair<std::string_view, Baker> mode_words[] = {{"exact", Baker::exact},
                                                             {"original", Baker::original},
                                                             {"paper-adaptive", Baker::paper_adaptive},
                                                             {"budgeted", Baker::budgeted},
                                                             {"full", Baker::full}};
constexpr std::pair<std::string_view, ConeKind> cone_kind_words[] = {{"center", ConeKind::center},
                                                                     {"bilinear", ConeKind::bilinear}};
constexpr std::pair<std::string_view, bake::Address> address_words[] = {{"wrap", bake::Address::wrap},
                                                                        {"clamp", bake::Address::clamp}};

}  // namespace

std::string lower_extension(const std::filesystem::path& path) {
  std::string extension = path.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  return extension;
}

namespace {

std::filesystem::path parse_output(std::string_view flag, std::string_view text, ImageFormat& format,
                                   bool png_allowed) {
  std::filesystem::path path{std::string(text)};
  const std::string extension = lower_extension(path);
  if (extension == ".exr") {
    format = ImageFormat::exr;
  } else if (extension == ".png" && png_allowed) {
    format = ImageFormat::png;
  } else {
    throw usage_error(std::string(flag) + " must name a " + (png_allowed ? ".exr or .png" : ".exr") +
                      " file, got " + quoted(text));
  }
  return path;
}

// The synthesis flags shared by `sim` and `bake --source`, collected before they are checked
// against the source they apply to.
struct SourceDraft {
  std::optional<SourceKind> kind;
  std::optional<int> size;
  std::optional<float> time;
  std::optional<std::uint64_t> seed;
  std::optional<float> patch_size, wind_speed, wind_direction_degrees, fetch, spreading, choppiness;
  std::optional<sim::Spectrum> spectrum;
  std::optional<int> wave_count;
  std::string first_flag;  // the first synthesis flag given, for error messages

  bool any_besides_kind() const {
    return size || time || seed || patch_size || wind_speed || wind_direction_degrees || fetch || spreading ||
           choppiness || spectrum || wave_count;
  }
};

// Takes `flag` if it is a synthesis flag; false otherwise.
bool take_source_flag(std::string_view flag, FlagReader& reader, SourceDraft& draft) {
  const bool was_empty = !draft.any_besides_kind();
  if (flag == "--source") {
    draft.kind = parse_word(flag, reader.value(), source_words);
    return true;
  } else if (flag == "--size" || flag == "--map-size") {
    // a single texel (or a single row) has no relief to displace: at least 2 x 2
    draft.size = parse_int(flag, reader.value(), 2, max_image_side);
  } else if (flag == "--time") {
    draft.time = parse_float_in(flag, reader.value(), time_range);
  } else if (flag == "--seed") {
    draft.seed = parse_seed(flag, reader.value());
  } else if (flag == "--patch-size") {
    draft.patch_size = parse_float_in(flag, reader.value(), patch_size_range);
  } else if (flag == "--wind-speed") {
    draft.wind_speed = parse_float_in(flag, reader.value(), wind_speed_range);
  } else if (flag == "--wind-direction") {
    draft.wind_direction_degrees = parse_float(flag, reader.value());
  } else if (flag == "--fetch") {
    draft.fetch = parse_float_in(flag, reader.value(), fetch_range);
  } else if (flag == "--spectrum") {
    draft.spectrum = parse_word(flag, reader.value(), spectrum_words);
  } else if (flag == "--spreading") {
    draft.spreading = parse_float_in(flag, reader.value(), spreading_range);
  } else if (flag == "--choppiness") {
    draft.choppiness = parse_float_in(flag, reader.value(), choppiness_range);
  } else if (flag == "--waves") {
    draft.wave_count = parse_int(flag, reader.value(), 1, max_wave_count);
  } else {
    return false;
  }
  if (was_empty) draft.first_flag = std::string(flag);
  return true;
}

SourceSettings finish_source(const SourceDraft& draft) {
  SourceSettings source;
  source.kind = *draft.kind;
  if (!draft.size) throw usage_error("--source needs --size N (samples along u and v)");
  source.size = *draft.size;
  if (source.kind == SourceKind::bricks || source.kind == SourceKind::cliff) {
    // static procedural reliefs: only a seed
    if (draft.patch_size || draft.wind_speed || draft.wind_direction_degrees || draft.fetch ||
        draft.spectrum || draft.spreading || draft.choppiness || draft.wave_count) {
      throw usage_error("--source bricks and --source cliff take only --size, --seed and --time (static)");
    }
    if (draft.seed) source.seed = *draft.seed;
    return source;
  }
  if (!draft.time) throw usage_error("--source needs --time T (seconds)");
  source.time = *draft.time;
  const float degrees_to_radians = std::numbers::pi_v<float> / 180.0f;

  if (source.kind == SourceKind::ocean) {
    if (draft.wave_count) throw usage_error("--waves applies to --source sinusoids only");
    if (source.size < 2) throw usage_error("--source ocean needs --size of at least 2");
    sim::OceanParams& ocean = source.ocean;
    ocean.size = source.size;
    if (draft.seed) ocean.seed = *draft.seed;
    if (draft.patch_size) ocean.patch_size = *draft.patch_size;
    if (draft.wind_speed) ocean.wind_speed = *draft.wind_speed;
    if (draft.wind_direction_degrees)
      ocean.wind_direction = *draft.wind_direction_degrees * degrees_to_radians;
    if (draft.spectrum) ocean.spectrum = *draft.spectrum;
    if (draft.fetch) {
      if (ocean.spectrum != sim::Spectrum::jonswap)
        throw usage_error("--fetch applies to --spectrum jonswap only");
      ocean.fetch = *draft.fetch;
    }
    if (draft.spreading) ocean.spreading = *draft.spreading;
    if (draft.choppiness) ocean.choppiness = *draft.choppiness;
  } else {
    for (const auto& [given, name] :
         {std::pair{bool(draft.wind_speed), "--wind-speed"}, std::pair{bool(draft.fetch), "--fetch"},
          std::pair{bool(draft.spectrum), "--spectrum"}, std::pair{bool(draft.spreading), "--spreading"},
          std::pair{bool(draft.choppiness), "--choppiness"}}) {
      if (given) throw usage_error(std::string(name) + " applies to --source ocean only");
    }
    sim::SinusoidParams& sinusoids = source.sinusoids;
    if (draft.seed) sinusoids.seed = *draft.seed;
    if (draft.patch_size) sinusoids.patch_size = *draft.patch_size;
    if (draft.wind_direction_degrees)
      sinusoids.wind_direction = *draft.wind_direction_degrees * degrees_to_radians;
    if (draft.wave_count) sinusoids.wave_count = *draft.wave_count;
  }
  return source;
}

bool is_help_flag(std::string_view argument) {
  return argument == "--help" || argument == "-h" || argument == "help";
}

SimSettings parse_sim(std::span<const std::string_view> args) {
  FlagReader reader(args);
  SourceDraft draft;
  std::optional<std::filesystem::path> output;
  while (!reader.done()) {
    const std::string_view flag = reader.next_flag();
    if (take_source_flag(flag, reader, draft)) continue;
    if (flag == "--output") {
      ImageFormat format{};
      output = parse_output(flag, reader.value(), format, false);
    } else {
      throw usage_error("unknown flag " + quoted(flag) + " for 'displace sim'");
    }
  }
  if (!draft.kind) throw usage_error("'displace sim' needs --source ocean|sinusoids");
  if (!output) throw usage_error("'displace sim' needs --output FILE.exr");
  return {finish_source(draft), *output};
}

// The height input every command that bakes reads: --input FILE with its load flags, or --source with
// the sim flags (never both).
struct InputDraft {
  SourceDraft source;
  std::optional<std::filesystem::path> file;
  HeightLoadSettings load;
  bool load_flag_given = false;
};

bool take_input_flag(std::string_view flag, FlagReader& reader, InputDraft& draft) {
  if (take_source_flag(flag, reader, draft.source)) return true;
  if (flag == "--input") {
    draft.file = std::filesystem::path(std::string(reader.value()));
  } else if (flag == "--channel") {
    const std::string_view text = reader.value();
    if (std::all_of(text.begin(), text.end(), [](char c) { return c >= '0' && c <= '9'; })) {
      draft.load.channel.index = parse_int(flag, text, 0, 1 << 16);
    } else {
      draft.load.channel.name = std::string(text);
    }
    draft.load_flag_given = true;
  } else if (flag == "--invert") {
    reader.no_value();
    draft.load.invert = true;
    draft.load_flag_given = true;
  } else if (flag == "--height-range") {
    const std::string_view text = reader.value();
    const auto comma = text.find(',');
    if (comma == std::string_view::npos) throw usage_error("--height-range expects LOW,HIGH, got " + quoted(text));
    const float low = parse_float(flag, text.substr(0, comma));
    const float high = parse_float(flag, text.substr(comma + 1));
    if (!(high > low) || !std::isfinite(high - low)) {
      throw usage_error("--height-range needs LOW < HIGH, got " + quoted(text));
    }
    draft.load.range = HeightRange{low, high};
    draft.load_flag_given = true;
  } else {
    return false;
  }
  return true;
}

std::variant<FileInput, SourceSettings> finish_input(const InputDraft& draft, const std::string& command) {
  if (draft.file && draft.source.kind) throw usage_error("give either --input or --source, not both");
  if (draft.file) {
    if (draft.source.any_besides_kind())
      throw usage_error(draft.source.first_flag + " applies to --source only, not --input");
    return FileInput{*draft.file, draft.load};
  }
  if (draft.source.kind) {
    if (draft.load_flag_given) throw usage_error("--channel, --invert and --height-range apply to --input only");
    return finish_source(draft.source);
  }
  throw usage_error("'displace " + command + "' needs --input FILE or --source ocean|sinusoids");
}

// --budget-ms and --bake-budget-ms: milliseconds, 0 allowed
double parse_budget(std::string_view flag, std::string_view text) {
  const double value = parse_number(flag, text);
  if (value < 0.0 || value > max_budget_milliseconds) {
    throw usage_error(std::string(flag) + " must be between 0 and " +
                      std::to_string(max_budget_milliseconds) + ", got " + std::to_string(value));
  }
  return value;
}

BakeSettings parse_bake(std::span<const std::string_view> args) {
  FlagReader reader(args);
  BakeSettings settings;
  InputDraft input;
  std::optional<std::filesystem::path> output;
  std::optional<int> sectors;
  std::optional<Baker> mode;
  std::optional<double> budget;
  std::optional<double> tolerance;
  bool relaxed = false;

  while (!reader.done()) {
    const std::string_view flag = reader.next_flag();
    if (take_input_flag(flag, reader, input)) continue;
    if (flag == "--sectors") {
      const int value =
          parse_int(flag, reader.value(), std::numeric_limits<int>::min(), std::numeric_limits<int>::max());
      if (!bake::is_valid_sector_count(value)) {
        throw usage_error("--sectors must be 1, 4 or 8, got " + std::to_string(value));
      }
      sectors = value;
    } else if (flag == "--mode") {
      mode = parse_word(flag, reader.value(), mode_words);
    } else if (flag == "--cones") {
      settings.cones = parse_word(flag, reader.value(), cone_kind_words);
    } else if (flag == "--budget-ms") {
      budget = parse_budget(flag, reader.value());
    } else if (flag == "--tolerance") {
      const double value = parse_number(flag, reader.value());
      if (!(value >= 0.0 && value < 1.0)) {
        throw usage_error("--tolerance must be in [0, 1), got " + std::to_string(value));
      }
      tolerance = value;
    } else if (flag == "--address") {
      settings.address = parse_word(flag, reader.value(), address_words);
    } else if (flag == "--relaxed") {
      reader.no_value();
      relaxed = true;
    } else if (flag == "--output") {
      output = parse_output(flag, reader.value(), settings.output_format, true);
    } else if (flag == "--stats") {
      reader.no_value();
      settings.stats = true;
    } else {
      throw usage_error("unknown flag " + quoted(flag) + " for 'displace bake'");
    }
  }

  settings.input = finish_input(input, "bake");

  // the baker
  if (!sectors) throw usage_error("'displace bake' needs --sectors 1|4|8");
  settings.sector_count = *sectors;
  if (settings.cones == ConeKind::bilinear) {
    if (relaxed) throw usage_error("--cones bilinear bakes with --mode budgeted|full, not --relaxed");
    if (!mode) throw usage_error("'displace bake --cones bilinear' needs --mode budgeted|full");
    if (*mode != Baker::budgeted && *mode != Baker::full) {
      throw usage_error(std::string("--cones bilinear bakes with --mode budgeted|full, not --mode ") +
                        baker_name(*mode));
    }
    settings.baker = *mode;
  } else if (relaxed) {
    if (settings.sector_count != 1 && settings.sector_count != 4) {
      throw usage_error("--relaxed supports --sectors 1 or 4, got " + std::to_string(settings.sector_count));
    }
    if (mode) throw usage_error("--relaxed is its own baker; drop --mode");
    settings.baker = Baker::relaxed;
  } else {
    if (!mode)
      throw usage_error("'displace bake' needs --mode exact|original|paper-adaptive|budgeted (or --relaxed)");
    if (*mode == Baker::full)
      throw usage_error("--mode full bakes bilinear cones only: add --cones bilinear");
    settings.baker = *mode;
  }
  if (budget) {
    if (settings.baker != Baker::budgeted) throw usage_error("--budget-ms applies to --mode budgeted only");
    settings.budget_milliseconds = *budget;
  }
  if (tolerance) {
    if (settings.baker != Baker::budgeted) throw usage_error("--tolerance applies to --mode budgeted only");
    settings.tolerance = float(*tolerance);
  }
  if (!output) throw usage_error("'displace bake' needs --output FILE.exr|FILE.png");
  settings.output = *output;
  return settings;
}

// "x,y,z"
glm::vec3 parse_vector(std::string_view flag, std::string_view text) {
  glm::vec3 value;
  std::string_view rest = text;
  for (int c = 0; c < 3; ++c) {
    const auto comma = rest.find(',');
    if ((c < 2) == (comma == std::string_view::npos)) throw usage_error(std::string(flag) + " expects X,Y,Z, got " + quoted(text));
    value[c] = parse_float(flag, rest.substr(0, comma));
    rest = comma == std::string_view::npos ? std::string_view{} : rest.substr(comma + 1);
  }
  return value;
}

constexpr std::pair<std::string_view, render::Surface> surface_words[] = {
    {"plane", render::Surface::plane},
    {"sphere", render::Surface::sphere},
    {"cylinder", render::Surface::cylinder},
    {"cone", render::Surface::cone}};

constexpr std::pair<std::string_view, Aov> aov_words[] = {
    {"uv", Aov::uv}, {"depth", Aov::depth}, {"iterations", Aov::iterations}, {"fetches", Aov::fetches}};

// The flags that describe a scene: the heights (file or source) and the view. Shared by
// `displace render` and the scene files of `displace sweep`.
struct SceneDraft {
  InputDraft input;
  render::View view;
  std::filesystem::path albedo;
  std::filesystem::path mesh;
};

bool take_scene_flag(std::string_view flag, FlagReader& reader, SceneDraft& draft) {
  render::Camera& camera = draft.view.camera;
  if (flag == "--size") {  // the image; the map of a --source takes --map-size
    std::tie(camera.width, camera.height) = parse_image_size(flag, reader.value(), max_image_side);
  } else if (take_input_flag(flag, reader, draft.input)) {
  } else if (flag == "--address") {
    draft.view.address = parse_word(flag, reader.value(), address_words);
  } else if (flag == "--tile") {
    draft.view.tile = parse_int(flag, reader.value(), 1, 64);
  } else if (flag == "--depth-scale") {
    draft.view.depth_scale = parse_float_in(flag, reader.value(), Range{1e-4, 10.0, "world units"});
  } else if (flag == "--eye") {
    camera.eye = parse_vector(flag, reader.value());
  } else if (flag == "--look-at") {
    camera.look_at = parse_vector(flag, reader.value());
  } else if (flag == "--up") {
    camera.up = parse_vector(flag, reader.value());
  } else if (flag == "--light") {
    draft.view.light_direction = parse_vector(flag, reader.value());
  } else if (flag == "--fov-y") {
    camera.fov_y_degrees = parse_float_in(flag, reader.value(), Range{0.01, 179.0, "degrees"});
  } else if (flag == "--shadows") {
    reader.no_value();
    draft.view.shadows = true;
  } else if (flag == "--albedo") {
    draft.albedo = std::filesystem::path(reader.value());
  } else if (flag == "--surface") {
    const std::string_view text = reader.value();
    if (text.rfind("mesh:", 0) == 0) {
      if (text.size() == 5) throw usage_error("--surface mesh:FILE.obj needs a file name after 'mesh:'");
      draft.view.surface = render::Surface::mesh;
      draft.mesh = std::filesystem::path(text.substr(5));
    } else {
      draft.view.surface = parse_word(flag, text, surface_words);
    }
  } else if (flag == "--radius") {
    draft.view.radius = parse_float_in(flag, reader.value(), Range{0.01, 10.0, "world units"});
  } else {
    return false;
  }
  return true;
}

SceneSettings finish_scene(const SceneDraft& draft, const std::string& name, const std::string& command) {
  SceneSettings scene{name, finish_input(draft.input, command), draft.view, draft.albedo, draft.mesh};
  if (scene.view.tile > 1 && scene.view.address != bake::Address::wrap) {
    throw usage_error("--tile above 1 needs --address wrap");
  }
  try {
    scene.view.camera.validate();
  } catch (const render::RenderError& error) {
    throw usage_error(error.what());
  }
  return scene;
}

// --device, --validate and --pipeline-cache, for every command that renders.
bool take_renderer_flag(std::string_view flag, FlagReader& reader, render::RendererOptions& options) {
  if (flag == "--device") {
    options.device = std::string(reader.value());
  } else if (flag == "--pipeline-cache") {
    options.pipeline_cache = std::string(reader.value());
    if (options.pipeline_cache.empty()) throw usage_error("--pipeline-cache needs a directory or 'off'");
  } else if (flag == "--validate") {
    reader.no_value();
    options.validate = true;
  } else {
    return false;
  }
  return true;
}

std::string method_names(const char* separator) {
  std::string names;
  for (const render::MethodInfo& known : render::method_table()) {
    if (!names.empty()) names += separator;
    names += known.name;
  }
  return names;
}

std::vector<render::Method> all_methods_but_reference() {
  std::vector<render::Method> methods;
  for (const render::MethodInfo& info : render::method_table()) {
    if (info.family != render::MethodFamily::reference) methods.push_back(info.method);
  }
  return methods;
}

RenderSettings parse_render(std::span<const std::string_view> args) {
  FlagReader reader(args);
  RenderSettings settings;
  SceneDraft scene;
  std::optional<std::filesystem::path> output;
  std::optional<render::Method> method;
  std::optional<double> bake_budget;
  while (!reader.done()) {
    const std::string_view flag = reader.next_flag();
    if (take_scene_flag(flag, reader, scene) || take_renderer_flag(flag, reader, settings.renderer)) continue;
    if (flag == "--method") {
      const std::string_view text = reader.value();
      const render::MethodInfo* info = render::find_method(text);
      if (!info) throw usage_error("--method must be one of " + method_names("|") + ", got " + quoted(text));
      method = info->method;
    } else if (flag == "--steps") {
      settings.method.steps = parse_int(flag, reader.value(), 1, 4096);
    } else if (flag == "--refine") {
      settings.method.refine = parse_int(flag, reader.value(), 0, 64);
    } else if (flag == "--output") {
      ImageFormat format{};
      output = parse_output(flag, reader.value(), format, true);
    } else if (flag == "--aov") {
      const std::string_view text = reader.value();
      const auto equals = text.find('=');
      if (equals == std::string_view::npos || equals + 1 == text.size()) {
        throw usage_error("--aov expects NAME=FILE (uv, depth, iterations, fetches), got " + quoted(text));
      }
      AovOutput aov{parse_word(flag, text.substr(0, equals), aov_words),
                    std::filesystem::path(std::string(text.substr(equals + 1)))};
      ImageFormat format{};
      parse_output(flag, text.substr(equals + 1), format, aov.aov == Aov::iterations || aov.aov == Aov::fetches);
      settings.aovs.push_back(aov);
    } else if (flag == "--compare") {
      const std::string_view text = reader.value();
      if (text != "reference") throw usage_error("--compare supports only 'reference', got " + quoted(text));
      settings.compare_reference = true;
    } else if (flag == "--bake-budget-ms") {
      bake_budget = parse_budget(flag, reader.value());
    } else {
      throw usage_error("unknown flag " + quoted(flag) + " for 'displace render'");
    }
  }
  const SceneSettings parsed = finish_scene(scene, "render", "render");
  settings.input = parsed.input;
  settings.view = parsed.view;
  settings.albedo = parsed.albedo;
  settings.mesh = parsed.mesh;
  if (!method) throw usage_error("'displace render' needs --method NAME");
  settings.method.method = *method;
  if (!render::supports_surface(*method, settings.view.surface)) {
    throw usage_error(std::string("--method ") + render::method_info(*method).name + " does not support --surface " +
                      render::surface_name(settings.view.surface));
  }
  if (bake_budget) {
    if (render::method_info(*method).cone_sectors == 0) {
      std::string cone_methods;
      for (const render::MethodInfo& info : render::method_table()) {
        if (info.cone_sectors == 0) continue;
        if (!cone_methods.empty()) cone_methods += ", ";
        cone_methods += info.name;
      }
      throw usage_error("--bake-budget-ms applies to the methods that read cone maps (" + cone_methods +
                        "), not --method " + render::method_info(*method).name);
    }
    settings.bake_budget_milliseconds = *bake_budget;
  }
  if (!output) throw usage_error("'displace render' needs --output FILE.png|FILE.exr");
  settings.output = *output;
  return settings;
}

std::vector<int> parse_int_list(std::string_view flag, std::string_view text, int minimum, int maximum) {
  std::vector<int> values;
  while (true) {
    const auto comma = text.find(',');
    values.push_back(parse_int(flag, text.substr(0, comma), minimum, maximum));
    if (comma == std::string_view::npos) break;
    text = text.substr(comma + 1);
  }
  return values;
}

// A scene given as render flags (a built-in one, or a scene file's lines).
SceneSettings scene_from_args(const std::string& name, std::span<const std::string_view> args,
                              const std::string& where) {
  try {
    FlagReader reader(args);
    SceneDraft scene;
    while (!reader.done()) {
      const std::string_view flag = reader.next_flag();
      if (!take_scene_flag(flag, reader, scene)) {
        throw usage_error(quoted(flag) + " does not describe a scene (only heights and view flags do)");
      }
    }
    return finish_scene(scene, name, "sweep");
  } catch (const AppError& error) {
    throw usage_error(where + ": " + error.what());
  }
}

SweepSettings parse_sweep(std::span<const std::string_view> args) {
  FlagReader reader(args);
  SweepSettings settings;
  std::optional<std::filesystem::path> output;
  std::optional<std::pair<int, int>> size;
  while (!reader.done()) {
    const std::string_view flag = reader.next_flag();
    if (flag == "--scene") {
      const std::string_view text = reader.value();
      if (text == "bricks" || text == "ocean" || text == "cliff") {
        settings.scenes.push_back(builtin_scene(text));
      } else {
        settings.scenes.push_back(read_scene_file(std::filesystem::path(std::string(text))));
      }
    } else if (flag == "--methods") {
      std::string_view text = reader.value();
      if (text == "all") {
        settings.methods = all_methods_but_reference();
        continue;
      }
      while (true) {
        const auto comma = text.find(',');
        const std::string_view word = text.substr(0, comma);
        const render::MethodInfo* info = render::find_method(word);
        if (!info) throw usage_error("--methods: unknown method " + quoted(word));
        settings.methods.push_back(info->method);
        if (comma == std::string_view::npos) break;
        text = text.substr(comma + 1);
      }
    } else if (flag == "--steps") {
      settings.steps = parse_int_list(flag, reader.value(), 1, 4096);
    } else if (flag == "--refine") {
      settings.refine = parse_int(flag, reader.value(), 0, 64);
    } else if (flag == "--repeat") {
      settings.repeat = parse_int(flag, reader.value(), 1, 100);
    } else if (flag == "--size") {
      size = parse_image_size(flag, reader.value(), max_image_side);
    } else if (flag == "--output") {
      const std::filesystem::path path{std::string(reader.value())};
      if (lower_extension(path) != ".csv") throw usage_error("--output of 'displace sweep' must end in .csv");
      output = path;
    } else if (take_renderer_flag(flag, reader, settings.renderer)) {
    } else {
      throw usage_error("unknown flag " + quoted(flag) + " for 'displace sweep'");
    }
  }
  if (settings.scenes.empty()) {
    for (std::string_view name : {"bricks", "ocean", "cliff"}) settings.scenes.push_back(builtin_scene(name));
  }
  if (settings.methods.empty()) settings.methods = all_methods_but_reference();
  if (settings.steps.empty()) settings.steps = {4, 8, 16, 32, 64};
  if (size) {
    for (SceneSettings& scene : settings.scenes) std::tie(scene.view.camera.width, scene.view.camera.height) = *size;
  }
  if (!output) throw usage_error("'displace sweep' needs --output FILE.csv");
  settings.output = *output;
  return settings;
}

DemoSettings parse_demo(std::span<const std::string_view> args) {
  FlagReader reader(args);
  DemoSettings settings;
  while (!reader.done()) {
    const std::string_view flag = reader.next_flag();
    if (flag == "--size") {
      settings.size = parse_int(flag, reader.value(), 2, max_image_side);
    } else if (flag == "--output-dir") {
      settings.output_directory = std::filesystem::path(std::string(reader.value()));
    } else {
      throw usage_error("unknown flag " + quoted(flag) + " for 'displace demo'");
    }
  }
  return settings;
}

}  // namespace

CommandSettings parse_command_line(std::span<const std::string_view> args) {
  if (args.empty()) throw usage_error("no command given");
  const std::string_view command = args.front();
  const auto rest = args.subspan(1);
  if (is_help_flag(command) ||
      std::any_of(rest.begin(), rest.end(), [](std::string_view a) { return a == "--help" || a == "-h"; })) {
    return HelpSettings{};
  }
  if (command == "sim") return parse_sim(rest);
  if (command == "bake") return parse_bake(rest);
  if (command == "demo") return parse_demo(rest);
  if (command == "render") return parse_render(rest);
  if (command == "sweep") return parse_sweep(rest);
  throw usage_error("unknown command " + quoted(command) + " (commands: sim, bake, render, sweep, demo, help)");
}

SceneSettings builtin_scene(std::string_view name) {
  const std::string source = name == "ocean" ? "ocean" : name == "bricks" ? "bricks" : "cliff";
  if (name != "ocean" && name != "bricks" && name != "cliff") {
    throw usage_error("unknown built-in scene " + app::quoted(name) + " (bricks, ocean, cliff)");
  }
  const std::vector<std::string_view> args = {"--source", source, "--map-size", "256", "--time", "0"};
  return scene_from_args(std::string(name), args, "scene " + std::string(name));
}

SceneSettings read_scene_file(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw usage_error("cannot read scene file " + app::quoted(file.string()));
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
    if (flag.rfind("--", 0) != 0) {
      throw usage_error("scene file " + app::quoted(file.string()) + " line " + std::to_string(number) +
                        ": expected a --flag, got " + app::quoted(flag));
    }
    words.push_back(flag);
    if (tokens >> value) words.push_back(value);
    if (tokens >> extra) {
      throw usage_error("scene file " + app::quoted(file.string()) + " line " + std::to_string(number) +
                        ": one flag and at most one value per line");
    }
  }
  const std::vector<std::string_view> args(words.begin(), words.end());
  return scene_from_args(file.stem().string(), args, "scene file " + app::quoted(file.string()));
}

}  // namespace displace::app
