// pipeline/scene.cpp - scenes: built-ins, TOML files (toml++), and the camera over time.
#include "pipeline/scene.h"

#include <toml++/toml.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <initializer_list>
#include <numbers>
#include <sstream>

#include "render/render.h"

namespace displace::pipeline {
namespace {

const char* source_word(SourceKind kind) {
  switch (kind) {
    case SourceKind::ocean: return "ocean";
    case SourceKind::sinusoids: return "sinusoids";
    case SourceKind::bricks: return "bricks";
    case SourceKind::cliff: return "cliff";
    case SourceKind::image: return "image";
  }
  return "ocean";
}

}  // namespace

const char* backend_word(Backend backend) {
  switch (backend) {
    case Backend::automatic: return "auto";
    case Backend::cpu: return "cpu";
    case Backend::device: return "device";
  }
  return "auto";
}

namespace {

constexpr std::pair<sim::Spectrum, std::string_view> spectrum_names[] = {
    {sim::Spectrum::phillips, "phillips"},
    {sim::Spectrum::pierson_moskowitz, "pierson-moskowitz"},
    {sim::Spectrum::jonswap, "jonswap"},
    {sim::Spectrum::tma, "tma"}};
constexpr std::pair<sim::Spreading, std::string_view> spreading_names[] = {
    {sim::Spreading::cos2s, "cos2s"},
    {sim::Spreading::mitsuyasu, "mitsuyasu"},
    {sim::Spreading::hasselmann, "hasselmann"},
    {sim::Spreading::donelan_banner, "donelan-banner"}};

}  // namespace

std::vector<sim::Spectrum> ocean_spectra() {
  std::vector<sim::Spectrum> values;
  for (const auto& [value, name] : spectrum_names) values.push_back(value);
  return values;
}
std::vector<sim::Spreading> spreading_models() {
  std::vector<sim::Spreading> values;
  for (const auto& [value, name] : spreading_names) values.push_back(value);
  return values;
}
std::string_view spectrum_word(sim::Spectrum spectrum) {
  for (const auto& [value, name] : spectrum_names) {
    if (value == spectrum) return name;
  }
  return "phillips";
}
std::string_view spreading_word(sim::Spreading model) {
  for (const auto& [value, name] : spreading_names) {
    if (value == model) return name;
  }
  return "cos2s";
}

bool runs_on_device(Backend backend, const vulkan::DeviceInfo& device) {
  return backend == Backend::device || (backend == Backend::automatic && device.type != "cpu");
}

bool runs_on_default_device(Backend backend) {
  if (backend != Backend::automatic) return backend == Backend::device;
  // asked of Vulkan once a process (an instance each time otherwise: a program that resolves its sim
  // and its bake would make two)
  static const std::optional<vulkan::DeviceInfo> device = []() -> std::optional<vulkan::DeviceInfo> {
    try {
      return render::default_device();
    } catch (const render::RenderError&) {
      return std::nullopt;
    }
  }();
  return device && runs_on_device(backend, *device);
}

namespace {

Backend backend_of(const std::string& word) {
  return word == "cpu" ? Backend::cpu : word == "device" ? Backend::device : Backend::automatic;
}

template <typename Words>
std::string join(const Words& words) {
  std::string out;
  for (std::string_view word : words) out += (out.empty() ? "" : ", ") + std::string(word);
  return out;
}

// Reads typed values out of one parsed file, naming file, line and key in every error.
class Reader {
 public:
  explicit Reader(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void fail(const toml::node* node, const std::string& key, const std::string& what) const {
    std::string where = file_;
    if (node && node->source().begin.line > 0) where += ":" + std::to_string(node->source().begin.line);
    throw SceneError(where + ": " + key + ": " + what);
  }

  void known_keys(const toml::table& table, const std::string& section,
                  std::initializer_list<std::string_view> known) const {
    for (auto&& [key, node] : table) {
      if (std::find(known.begin(), known.end(), key.str()) == known.end()) {
        fail(&node, qualified(section, key.str()),
             "unknown key (known in " + (section.empty() ? std::string("the file") : "[" + section + "]") +
                 ": " + join(known) + ")");
      }
    }
  }

  const toml::table* section(const toml::table& root, const std::string& name) const {
    const toml::node* node = root.get(name);
    if (!node) return nullptr;
    if (!node->is_table()) fail(node, name, "must be a table ([" + name + "])");
    return node->as_table();
  }

  double number(const toml::table* table, const std::string& section, const std::string& key, double value,
                double lo, double hi) const {
    const toml::node* node = table ? table->get(key) : nullptr;
    if (!node) return value;
    std::optional<double> read = node->value<double>();
    if (!read || !(node->is_number())) fail(node, qualified(section, key), "must be a number");
    if (!(*read >= lo && *read <= hi)) {
      fail(node, qualified(section, key),
           "must be in [" + format_number(lo) + ", " + format_number(hi) + "]");
    }
    return *read;
  }

  long long integer(const toml::table* table, const std::string& section, const std::string& key,
                    long long value, long long lo, long long hi) const {
    const toml::node* node = table ? table->get(key) : nullptr;
    if (!node) return value;
    if (!node->is_integer()) fail(node, qualified(section, key), "must be an integer");
    const long long read = node->as_integer()->get();
    if (read < lo || read > hi) {
      fail(node, qualified(section, key),
           "must be in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
    }
    return read;
  }

  bool boolean(const toml::table* table, const std::string& section, const std::string& key,
               bool value) const {
    const toml::node* node = table ? table->get(key) : nullptr;
    if (!node) return value;
    if (!node->is_boolean()) fail(node, qualified(section, key), "must be true or false");
    return node->as_boolean()->get();
  }

  std::string word(const toml::table* table, const std::string& section, const std::string& key,
                   const std::string& value, std::initializer_list<std::string_view> allowed) const {
    return word_of(table, section, key, value, allowed);
  }
  std::string word(const toml::table* table, const std::string& section, const std::string& key,
                   const std::string& value, const std::vector<std::string_view>& allowed) const {
    return word_of(table, section, key, value, allowed);
  }

  glm::vec3 vector3(const toml::node* node, const std::string& key, glm::vec3 value) const {
    if (!node) return value;
    const toml::array* array = node->as_array();
    if (!array || array->size() != 3) fail(node, key, "must be an array of 3 numbers [x, y, z]");
    glm::vec3 out;
    for (int i = 0; i < 3; ++i) {
      const std::optional<double> v = (*array)[std::size_t(i)].value<double>();
      if (!v || !std::isfinite(*v) || std::abs(*v) > 1e6)
        fail(node, key, "must be an array of 3 finite numbers");
      out[i] = float(*v);
    }
    return out;
  }

 private:
  template <typename Words>
  std::string word_of(const toml::table* table, const std::string& section, const std::string& key,
                      const std::string& value, const Words& allowed) const {
    const toml::node* node = table ? table->get(key) : nullptr;
    if (!node) return value;
    if (!node->is_string()) {
      fail(node, qualified(section, key),
           allowed.size() == 0 ? std::string("must be a string")
                               : "must be a string (one of " + join(allowed) + ")");
    }
    const std::string read = node->as_string()->get();
    if (allowed.size() > 0 && std::find(allowed.begin(), allowed.end(), read) == allowed.end()) {
      fail(node, qualified(section, key), "'" + read + "' is not one of " + join(allowed));
    }
    return read;
  }
  static std::string qualified(const std::string& section, std::string_view key) {
    return section.empty() ? std::string(key) : section + "." + std::string(key);
  }
  static std::string format_number(double value) {
    std::ostringstream out;
    out << value;
    return out.str();
  }
  std::string file_;
};

}  // namespace

bool is_image_sequence(const std::filesystem::path& pattern) {
  return pattern.filename().string().find('#') != std::string::npos;
}

std::filesystem::path image_for_frame(const std::filesystem::path& pattern, long long frame_index) {
  std::string name = pattern.filename().string();
  std::string out;
  for (std::size_t i = 0; i < name.size();) {
    if (name[i] != '#') {
      out += name[i++];
      continue;
    }
    std::size_t run = 0;
    while (i + run < name.size() && name[i + run] == '#') ++run;
    std::string digits = std::to_string(frame_index);
    if (digits.size() < run) digits.insert(0, run - digits.size(), '0');
    out += digits;
    i += run;
  }
  return pattern.parent_path() / out;
}

long long loop_frames(const Scene& scene) {
  if (scene.source != SourceKind::ocean || !(scene.ocean.loop_seconds > 0.0)) return 0;
  const double frames = scene.ocean.loop_seconds * scene.fps;
  const double whole = std::round(frames);
  return whole >= 1.0 && std::abs(frames - whole) <= 1e-9 * whole ? (long long)whole : 0;
}

double frame_time(const Scene& scene, long long frame_index) {
  const long long loop = loop_frames(scene);
  if (loop > 0) frame_index = ((frame_index % loop) + loop) % loop;
  return scene.start + double(frame_index) / scene.fps;
}

render::View scene_view(const Scene& scene, double time) {
  render::View view;
  view.camera = scene.camera;
  view.material = scene.material;
  view.unbounded = scene.unbounded;
  view.foam_color = scene.foam_color;
  view.foam_intensity = scene.foam_intensity;
  view.surface = scene.surface;
  view.shadows = scene.shadows;
  view.light_direction = scene.light;
  view.depth_scale = scene.depth_scale;
  view.tile = scene.tile;
  view.address = scene.address;
  view.radius = scene.radius;
  const std::vector<CameraKey>& keys = scene.keyframes;
  if (keys.empty()) return view;
  if (time <= keys.front().time || keys.size() == 1) {
    view.camera.eye = keys.front().eye;
    view.camera.look_at = keys.front().look_at;
    return view;
  }
  if (time >= keys.back().time) {
    view.camera.eye = keys.back().eye;
    view.camera.look_at = keys.back().look_at;
    return view;
  }
  std::size_t i = 0;
  while (keys[i + 1].time < time) ++i;
  const CameraKey& a = keys[i];
  const CameraKey& b = keys[i + 1];
  const double span = b.time - a.time;
  const double s = (time - a.time) / span;
  // tangents (per unit of s) from the neighbours: one-sided at the ends
  auto tangent = [&](std::size_t k, auto get) {
    const std::size_t lo = k == 0 ? 0 : k - 1, hi = std::min(k + 1, keys.size() - 1);
    return (get(keys[hi]) - get(keys[lo])) / (keys[hi].time - keys[lo].time) * span;
  };
  auto hermite = [&](auto get) {
    const glm::dvec3 p0 = get(a), p1 = get(b);
    const glm::dvec3 m0 = tangent(i, get), m1 = tangent(i + 1, get);
    const double s2 = s * s, s3 = s2 * s;
    return (2 * s3 - 3 * s2 + 1) * p0 + (s3 - 2 * s2 + s) * m0 + (-2 * s3 + 3 * s2) * p1 + (s3 - s2) * m1;
  };
  view.camera.eye = glm::vec3(hermite([](const CameraKey& k) { return glm::dvec3(k.eye); }));
  view.camera.look_at = glm::vec3(hermite([](const CameraKey& k) { return glm::dvec3(k.look_at); }));
  return view;
}

std::vector<std::string> builtin_scene_names() {
  return {"water", "calm", "storm", "harbour", "ripples", "ocean", "bricks", "cliff"};
}

Scene builtin_scene(std::string_view name) {
  Scene scene;
  scene.name = std::string(name);
  scene.camera.width = scene.camera.height = 512;
  if (name == "water" || name == "calm" || name == "storm" || name == "harbour") {
    scene.source = SourceKind::ocean;
    scene.material = render::Material::water;
    scene.light = {0.0f, 1.0f, 0.3f};  // a low sun ahead: its glint path runs towards the eye
    scene.camera.eye = {0.5f, -0.25f, 0.22f};
    scene.camera.look_at = {0.5f, 0.6f, -0.02f};
    scene.unbounded = true;
    sim::OceanParams& ocean = scene.ocean;
    if (name == "water" || name == "calm") {
      // a fully developed sea in an 11 m/s wind (Hs 2.7 m, peak wavelength 106 m), on the 200 m patch
      ocean.spectrum = sim::Spectrum::pierson_moskowitz;
      ocean.wind_speed = 11.0f;
      ocean.choppiness = name == "calm" ? 0.0f : 1.0f;
      scene.foam = name == "water";
      scene.depth_scale = 0.04f;  // 8 m of relief over the 200 m patch (6 sigma, 4.1 m, drawn twice as tall)
    } else if (name == "storm") {
      // Beaufort 9 (22.6 m/s), fully developed in deep water: Hs 11.4 m, peak wavelength 446 m
      ocean.spectrum = sim::Spectrum::pierson_moskowitz;
      ocean.wind_speed = sim::beaufort_wind_speed(9);
      ocean.patch_size = 1200.0f;
      ocean.choppiness = 1.0f;
      scene.map_size = 512;
      scene.foam = true;
      scene.foam_coverage = 1.0f;
      scene.depth_scale = 0.03f;  // 36 m of relief over the 1200 m patch (6 sigma, 17 m, drawn twice as tall)
      scene.camera.eye = {0.5f, -0.1f, 0.1f};
      scene.camera.look_at = {0.5f, 0.35f, -0.02f};
    } else {
      // a harbour 6 m deep: a short-fetch local sea (10 m/s over 5 km, TMA) and a swell from the entrance
      ocean.spectrum = sim::Spectrum::tma;
      ocean.wind_speed = 10.0f;
      ocean.fetch = 5.0f;
      ocean.depth = 6.0f;
      ocean.patch_size = 350.0f;
      ocean.swell = {0.8f, 9.0f, float(std::numbers::pi / 6.0), 40.0f};
      ocean.choppiness = 0.5f;
      scene.depth_scale =
          0.008f;  // 2.8 m of relief over the 350 m patch (6 sigma, 1.3 m, drawn twice as tall)
      scene.camera.eye = {0.5f, -0.05f, 0.045f};
      scene.camera.look_at = {0.5f, 0.25f, -0.01f};
    }
  } else if (name == "ripples") {
    scene.source = SourceKind::sinusoids;
    scene.material = render::Material::water;
    scene.light = {0.0f, 1.0f, 0.3f};
    scene.unbounded = true;
  } else if (name == "ocean") {
    scene.source = SourceKind::ocean;  // the default ocean on the grid, seen from above: the method sweeps'
  } else if (name == "bricks" || name == "cliff") {
    scene.source = name == "bricks" ? SourceKind::bricks : SourceKind::cliff;
  } else {
    std::string names;
    for (const std::string& known : builtin_scene_names()) names += (names.empty() ? "" : ", ") + known;
    throw SceneError("unknown scene '" + std::string(name) + "' (built-in scenes: " + names + ")");
  }
  return scene;
}

namespace {

// The renderer's message in the scene file's words: the fields it names become their keys.
std::string key_words(std::string text) {
  static const std::pair<std::string_view, std::string_view> fields[] = {
      {"Camera::width and Camera::height", "render.size"},
      {"Camera::fov_y_degrees", "camera.fov_y"},
      {"Camera::look_at", "camera.look_at"},
      {"Camera::eye", "camera.eye"},
      {"Camera::up", "camera.up"}};
  for (const auto& [field, key] : fields) {
    for (std::size_t at = text.find(field); at != std::string::npos; at = text.find(field, at + key.size())) {
      text.replace(at, field.size(), key);
    }
  }
  return text;
}

// A scene's sections, one reader each (apply_scene calls them in this order). Each reads the keys
// its table holds over what `scene` holds already: a file over the defaults, the command line's
// keys over a built-in scene or a file. A relative path is taken from the scene file's directory.

std::filesystem::path beside(const std::string& source_name, const std::string& path) {
  std::filesystem::path file(path);
  if (file.is_relative() && source_name.find('/') != std::string::npos) {
    file = std::filesystem::path(source_name).parent_path() / file;
  }
  return file;
}

const toml::node* key_node(const toml::table* table, std::string_view key) {
  return table ? table->get(key) : nullptr;
}

void read_source(const Reader& read, const toml::table& root, const std::string& source_name, Scene& scene) {
  const toml::table* source = read.section(root, "source");
  if (source) {
    read.known_keys(*source, "source",
                    {"kind", "map_size", "seed", "path", "channel", "invert", "height_range"});
  }
  const std::string kind = read.word(source, "source", "kind", source_word(scene.source),
                                     {"ocean", "sinusoids", "bricks", "cliff", "image"});
  scene.source = kind == "ocean"       ? SourceKind::ocean
                 : kind == "sinusoids" ? SourceKind::sinusoids
                 : kind == "bricks"    ? SourceKind::bricks
                 : kind == "cliff"     ? SourceKind::cliff
                                       : SourceKind::image;
  const std::string path = read.word(source, "source", "path", "", {});
  if (!path.empty()) {
    if (scene.source != SourceKind::image)
      read.fail(key_node(source, "path"), "source.path", "only kind = \"image\" reads a file");
    scene.image = beside(source_name, path);
  }
  if (scene.source != SourceKind::image) scene.image.clear();
  if (scene.source == SourceKind::image && scene.image.empty())
    read.fail(key_node(source, "kind"), "source.path", "kind = \"image\" needs a path");
  // how the image is read
  ImageRead& image = scene.image_read;
  image.channel = read.word(source, "source", "channel", image.channel, {});
  image.invert = read.boolean(source, "source", "invert", image.invert);
  if (const toml::node* range = key_node(source, "height_range")) {
    const toml::array* pair = range->as_array();
    const std::optional<double> low = pair && pair->size() == 2 ? (*pair)[0].value<double>() : std::nullopt;
    const std::optional<double> high = pair && pair->size() == 2 ? (*pair)[1].value<double>() : std::nullopt;
    if (!low || !high || !std::isfinite(*low) || !std::isfinite(*high) || !(*high > *low))
      read.fail(range, "source.height_range", "must be [low, high], finite numbers with low < high");
    image.height_range = std::array<float, 2>{float(*low), float(*high)};
  }
  if (scene.source != SourceKind::image &&
      (key_node(source, "channel") || key_node(source, "invert") || key_node(source, "height_range"))) {
    read.fail(source, "source", "channel, invert and height_range apply to kind = \"image\" only");
  }
  scene.map_size =
      int(read.integer(source, "source", "map_size", scene.map_size, min_map_size, max_map_size));
  if (scene.source == SourceKind::ocean && scene.map_size % 2 != 0) {
    read.fail(key_node(source, "map_size"), "source.map_size", "must be even for the ocean");
  }
  scene.seed = std::uint64_t(read.integer(source, "source", "seed", std::int64_t(scene.seed), 0,
                                          std::numeric_limits<std::int64_t>::max()));
}

template <typename Enum, std::size_t count>
std::vector<std::string_view> words_in(const std::pair<Enum, std::string_view> (&names)[count]) {
  std::vector<std::string_view> words;
  for (const auto& [value, name] : names) words.push_back(name);
  return words;
}
template <typename Enum, std::size_t count>
Enum value_of(const std::pair<Enum, std::string_view> (&names)[count], std::string_view word) {
  for (const auto& [known, name] : names) {
    if (name == word) return known;
  }
  return names[0].first;
}

double degrees(float radians) { return double(radians) * 180.0 / std::numbers::pi; }
float radians(double degrees) { return float(degrees * std::numbers::pi / 180.0); }

// [ocean]: the ocean's spectrum; [ocean] size is the ocean's grid, the same as [source] map_size
// (either may be given; not both, differing). The sea state comes one way in a table: by the wind
// (wind_speed, fetch), by the Beaufort force (its wind, fully developed) or by hs and tp.
void read_ocean(const Reader& read, const toml::table& root, Scene& scene) {
  const toml::table* source = read.section(root, "source");
  const toml::table* ocean = read.section(root, "ocean");
  if (ocean) {
    read.known_keys(
        *ocean, "ocean",
        {"size", "patch_size", "spectrum", "wind_speed", "wind_direction", "fetch", "beaufort", "hs", "tp",
         "depth", "spreading", "spreading_model", "choppiness", "seed", "loop_seconds"});
  }
  sim::OceanParams& params = scene.ocean;
  if (const toml::node* size = key_node(ocean, "size")) {
    const int ocean_size =
        int(read.integer(ocean, "ocean", "size", scene.map_size, sim::min_ocean_size, sim::max_ocean_size));
    if (ocean_size % 2 != 0) read.fail(size, "ocean.size", "must be even");
    if (key_node(source, "map_size") && ocean_size != scene.map_size) {
      read.fail(size, "ocean.size", "differs from source.map_size (" + std::to_string(scene.map_size) + ")");
    }
    scene.map_size = ocean_size;
  }
  params.patch_size = float(
      read.number(ocean, "ocean", "patch_size", params.patch_size, sim::min_patch_size, sim::max_patch_size));
  params.spectrum = value_of(
      spectrum_names, read.word(ocean, "ocean", "spectrum", std::string(spectrum_word(params.spectrum)),
                                words_in(spectrum_names)));
  const bool fetch_limited =
      params.spectrum == sim::Spectrum::jonswap || params.spectrum == sim::Spectrum::tma;

  // the sea state, one way
  const toml::node* wind = key_node(ocean, "wind_speed");
  const toml::node* fetch = key_node(ocean, "fetch");
  const toml::node* beaufort = key_node(ocean, "beaufort");
  const toml::node* hs = key_node(ocean, "hs");
  const toml::node* tp = key_node(ocean, "tp");
  if (beaufort && (wind || fetch)) {
    read.fail(beaufort, "ocean.beaufort",
              "gives the wind speed and a fully developed sea: not with wind_speed or fetch");
  }
  if ((hs || tp) && (wind || fetch || beaufort)) {
    read.fail(hs ? hs : tp, hs ? "ocean.hs" : "ocean.tp",
              "hs and tp give the sea state: not with wind_speed, fetch or beaufort");
  }
  params.wind_speed = float(
      read.number(ocean, "ocean", "wind_speed", params.wind_speed, sim::min_wind_speed, sim::max_wind_speed));
  params.fetch = float(read.number(ocean, "ocean", "fetch", params.fetch, sim::min_fetch, sim::max_fetch));
  if (fetch && !fetch_limited)
    read.fail(fetch, "ocean.fetch", "applies to spectrum = \"jonswap\" or \"tma\" only");
  if (beaufort) {
    const int force = int(read.integer(ocean, "ocean", "beaufort", 0, 0, sim::max_beaufort));
    params.wind_speed = sim::beaufort_wind_speed(force);
    params.fetch = sim::max_fetch;  // as far as the growth goes: fully developed
  }
  if (wind || fetch || beaufort) params.significant_height = params.peak_period = 0.0f;
  params.significant_height = float(read.number(ocean, "ocean", "hs", params.significant_height,
                                                sim::min_significant_height, sim::max_significant_height));
  params.peak_period = float(
      read.number(ocean, "ocean", "tp", params.peak_period, sim::min_peak_period, sim::max_peak_period));
  if ((params.significant_height > 0.0f) != (params.peak_period > 0.0f)) {
    read.fail(hs ? hs : tp, hs ? "ocean.hs" : "ocean.tp",
              "hs and tp go together: the significant height (metres) and the peak period (seconds)");
  }
  if (params.significant_height > 0.0f && params.spectrum == sim::Spectrum::phillips) {
    const toml::node* where = hs ? hs : tp ? tp : key_node(ocean, "spectrum");
    read.fail(where, hs || tp ? (hs ? "ocean.hs" : "ocean.tp") : "ocean.spectrum",
              "hs and tp make a pierson-moskowitz, jonswap or tma sea, not phillips");
  }

  params.wind_direction =
      radians(read.number(ocean, "ocean", "wind_direction", degrees(params.wind_direction),
                          -max_direction_degrees, max_direction_degrees));
  if (key_node(ocean, "depth"))
    params.depth = float(read.number(ocean, "ocean", "depth", 0.0, sim::min_depth, sim::max_depth));
  params.spreading_model =
      value_of(spreading_names,
               read.word(ocean, "ocean", "spreading_model",
                         std::string(spreading_word(params.spreading_model)), words_in(spreading_names)));
  params.spreading =
      float(read.number(ocean, "ocean", "spreading", params.spreading, 0.0, sim::max_spreading));
  if (key_node(ocean, "spreading") && params.spreading_model != sim::Spreading::cos2s) {
    read.fail(key_node(ocean, "spreading"), "ocean.spreading",
              "the exponent of spreading_model = \"cos2s\"; " +
                  std::string(spreading_word(params.spreading_model)) + " sets its own");
  }
  params.choppiness =
      float(read.number(ocean, "ocean", "choppiness", params.choppiness, 0.0, sim::max_choppiness));
  params.seed = std::uint64_t(read.integer(ocean, "ocean", "seed", std::int64_t(params.seed), 0,
                                           std::numeric_limits<std::int64_t>::max()));
  params.loop_seconds =
      read.number(ocean, "ocean", "loop_seconds", params.loop_seconds, 0.0, sim::max_loop_seconds);
  if (params.loop_seconds > 0.0 && params.loop_seconds < sim::min_loop_seconds) {
    read.fail(key_node(ocean, "loop_seconds"), "ocean.loop_seconds",
              "must be 0 (no loop) or at least " + std::to_string(sim::min_loop_seconds).substr(0, 3) + " s");
  }
}

// [swell]: a swell from elsewhere over the ocean's sea (hs 0: none)
void read_swell(const Reader& read, const toml::table& root, Scene& scene) {
  const toml::table* table = read.section(root, "swell");
  if (!table) return;
  read.known_keys(*table, "swell", {"hs", "tp", "direction", "spreading"});
  sim::SwellParams& swell = scene.ocean.swell;
  swell.significant_height =
      float(read.number(table, "swell", "hs", swell.significant_height, 0.0, sim::max_significant_height));
  if (swell.significant_height > 0.0f && swell.significant_height < sim::min_significant_height) {
    std::ostringstream least;
    least << sim::min_significant_height;
    read.fail(key_node(table, "hs"), "swell.hs",
              "must be 0 (no swell) or at least " + least.str() + " metres");
  }
  swell.peak_period =
      float(read.number(table, "swell", "tp", swell.peak_period, sim::min_peak_period, sim::max_peak_period));
  swell.direction = radians(read.number(table, "swell", "direction", degrees(swell.direction),
                                        -max_direction_degrees, max_direction_degrees));
  swell.spreading = float(read.number(table, "swell", "spreading", swell.spreading, 0.0, sim::max_spreading));
  if (swell.significant_height == 0.0f && !key_node(table, "hs"))
    read.fail(table, "swell.hs", "a swell needs its significant height (hs, metres)");
}

void read_sinusoids(const Reader& read, const toml::table& root, Scene& scene) {
  const toml::table* waves = read.section(root, "sinusoids");
  if (waves) {
    read.known_keys(*waves, "sinusoids", {"wave_count", "patch_size", "steepness", "wind_direction", "seed"});
  }
  sim::SinusoidParams& params = scene.sinusoids;
  params.wave_count =
      int(read.integer(waves, "sinusoids", "wave_count", params.wave_count, 1, sim::max_wave_count));
  params.patch_size = float(read.number(waves, "sinusoids", "patch_size", params.patch_size,
                                        sim::min_patch_size, sim::max_patch_size));
  params.steepness = float(
      read.number(waves, "sinusoids", "steepness", params.steepness, min_steepness, sim::max_steepness));
  params.wind_direction = float(read.number(waves, "sinusoids", "wind_direction",
                                            double(params.wind_direction) * 180.0 / std::numbers::pi,
                                            -max_direction_degrees, max_direction_degrees) *
                                std::numbers::pi / 180.0);
  params.seed = std::uint64_t(read.integer(waves, "sinusoids", "seed", std::int64_t(params.seed), 0,
                                           std::numeric_limits<std::int64_t>::max()));
}

void read_material(const Reader& read, const toml::table& root, const std::string& source_name,
                   Scene& scene) {
  const toml::table* material = read.section(root, "material");
  if (material) {
    read.known_keys(*material, "material",
                    {"kind", "foam", "albedo", "foam_coverage", "foam_color", "foam_intensity"});
  }
  const std::string current = scene.material == render::Material::water ? "water"
                              : !scene.albedo.empty()                   ? "albedo"
                                                                        : "grid";
  const std::string material_kind =
      read.word(material, "material", "kind", current, {"grid", "albedo", "water"});
  scene.material = material_kind == "water" ? render::Material::water : render::Material::grid;
  const std::string albedo = read.word(material, "material", "albedo", "", {});
  if (!albedo.empty()) {
    if (material_kind != "albedo")
      read.fail(key_node(material, "albedo"), "material.albedo", "only kind = \"albedo\" reads an image");
    scene.albedo = beside(source_name, albedo);
  }
  if (material_kind != "albedo") scene.albedo.clear();
  if (material_kind == "albedo" && scene.albedo.empty())
    read.fail(key_node(material, "kind"), "material.albedo", "kind = \"albedo\" needs an albedo image");
  // foam follows the water: a scene that leaves water or the ocean drops it unless it asks again
  if (scene.material != render::Material::water || scene.source != SourceKind::ocean) scene.foam = false;
  scene.foam = read.boolean(material, "material", "foam", scene.foam);
  if (scene.foam && (scene.material != render::Material::water || scene.source != SourceKind::ocean)) {
    read.fail(key_node(material, "foam"), "material.foam",
              "foam needs kind = \"water\" and the ocean source");
  }
  scene.foam_coverage =
      float(read.number(material, "material", "foam_coverage", scene.foam_coverage, 0.0, max_foam_coverage));
  scene.foam_intensity =
      float(read.number(material, "material", "foam_intensity", scene.foam_intensity, 0.0, 1.0));
  scene.foam_color = read.vector3(key_node(material, "foam_color"), "material.foam_color", scene.foam_color);
  const glm::vec3 colour = scene.foam_color;
  if (!(glm::all(glm::greaterThanEqual(colour, glm::vec3(0.0f))) &&
        glm::all(glm::lessThanEqual(colour, glm::vec3(1.0f)))))
    read.fail(key_node(material, "foam_color"), "material.foam_color", "each channel must be in [0, 1]");
}

// [camera]; returns the section (the camera's own check runs after every section is read)
const toml::table* read_camera(const Reader& read, const toml::table& root, Scene& scene) {
  const toml::table* camera = read.section(root, "camera");
  if (camera) read.known_keys(*camera, "camera", {"eye", "look_at", "up", "fov_y", "keyframes"});
  scene.camera.eye = read.vector3(key_node(camera, "eye"), "camera.eye", scene.camera.eye);
  scene.camera.look_at = read.vector3(key_node(camera, "look_at"), "camera.look_at", scene.camera.look_at);
  scene.camera.up = read.vector3(key_node(camera, "up"), "camera.up", scene.camera.up);
  scene.camera.fov_y_degrees = float(read.number(camera, "camera", "fov_y", scene.camera.fov_y_degrees,
                                                 render::min_fov_y_degrees, render::max_fov_y_degrees));
  // keyframes move the camera; a scene that sets an eye or a look-at without them holds it still
  if (key_node(camera, "eye") || key_node(camera, "look_at")) scene.keyframes.clear();
  if (const toml::node* keys = key_node(camera, "keyframes")) {
    const toml::array* array = keys->as_array();
    if (!array || !array->is_array_of_tables()) {
      read.fail(keys, "camera.keyframes", "must be an array of tables {time, eye, look_at}");
    }
    scene.keyframes.clear();
    for (const toml::node& key : *array) {
      const toml::table& table = *key.as_table();
      read.known_keys(table, "camera.keyframes", {"time", "eye", "look_at"});
      if (!table.get("time") || !table.get("eye") || !table.get("look_at")) {
        read.fail(&key, "camera.keyframes", "every keyframe needs time, eye and look_at");
      }
      CameraKey k;
      k.time = read.number(&table, "camera.keyframes", "time", 0.0, -max_abs_time, max_abs_time);
      k.eye = read.vector3(table.get("eye"), "camera.keyframes.eye", {});
      k.look_at = read.vector3(table.get("look_at"), "camera.keyframes.look_at", {});
      if (!scene.keyframes.empty() && !(k.time > scene.keyframes.back().time)) {
        read.fail(&key, "camera.keyframes", "times must increase from one keyframe to the next");
      }
      scene.keyframes.push_back(k);
    }
  }
  return camera;
}

const char* surface_word(render::Surface surface) {
  switch (surface) {
    case render::Surface::sphere: return "sphere";
    case render::Surface::cylinder: return "cylinder";
    case render::Surface::cone: return "cone";
    case render::Surface::mesh: return "mesh";
    case render::Surface::plane: break;
  }
  return "plane";
}

// [render] method, steps, refine, size
void read_render_method(const Reader& read, const toml::table* render_table, Scene& scene) {
  if (const toml::node* method = key_node(render_table, "method")) {
    const std::optional<std::string> name = method->value<std::string>();
    const render::MethodInfo* info = name ? render::find_method(*name) : nullptr;
    if (!info) {
      std::string names;
      for (const render::MethodInfo& known : render::method_table())
        names += (names.empty() ? "" : ", ") + std::string(known.name);
      read.fail(method, "render.method", "must be one of " + names);
    }
    scene.method = info->method;
  }
  scene.steps = int(read.integer(render_table, "render", "steps", scene.steps, 1, render::max_steps));
  scene.refine = int(read.integer(render_table, "render", "refine", scene.refine, 0, render::max_refine));
  if (const toml::node* size = key_node(render_table, "size")) {
    const toml::array* array = size->as_array();
    if (!array || array->size() != 2 || !(*array)[0].is_integer() || !(*array)[1].is_integer()) {
      read.fail(size, "render.size", "must be [width, height] in pixels");
    }
    const long long w = (*array)[0].as_integer()->get(), h = (*array)[1].as_integer()->get();
    if (w < 1 || h < 1 || w > render::max_image_side || h > render::max_image_side) {
      read.fail(size, "render.size",
                "must be between [1, 1] and [" + std::to_string(render::max_image_side) + ", " +
                    std::to_string(render::max_image_side) + "]");
    }
    scene.camera.width = int(w);
    scene.camera.height = int(h);
  }
}

// [render] surface, mesh, radius, address, tile, shadows, light, depth_scale
void read_render(const Reader& read, const toml::table& root, const std::string& source_name, Scene& scene) {
  const toml::table* render_table = read.section(root, "render");
  if (render_table) {
    read.known_keys(*render_table, "render",
                    {"method", "steps", "refine", "size", "surface", "mesh", "radius", "address", "shadows",
                     "light", "depth_scale", "tile", "extent"});
  }
  read_render_method(read, render_table, scene);
  const std::string surface = read.word(render_table, "render", "surface", surface_word(scene.surface),
                                        {"plane", "sphere", "cylinder", "cone", "mesh"});
  scene.surface = surface == "sphere"     ? render::Surface::sphere
                  : surface == "cylinder" ? render::Surface::cylinder
                  : surface == "cone"     ? render::Surface::cone
                  : surface == "mesh"     ? render::Surface::mesh
                                          : render::Surface::plane;
  const std::string mesh = read.word(render_table, "render", "mesh", "", {});
  if (!mesh.empty()) {
    if (scene.surface != render::Surface::mesh)
      read.fail(key_node(render_table, "mesh"), "render.mesh", "only surface = \"mesh\" reads a mesh");
    scene.mesh = beside(source_name, mesh);
  }
  if (scene.surface != render::Surface::mesh) scene.mesh.clear();
  if (scene.surface == render::Surface::mesh && scene.mesh.empty())
    read.fail(key_node(render_table, "surface"), "render.mesh",
              "surface = \"mesh\" needs a mesh (an OBJ file)");
  scene.radius = float(
      read.number(render_table, "render", "radius", scene.radius, render::min_radius, render::max_radius));
  scene.address =
      read.word(render_table, "render", "address", scene.address == bake::Address::clamp ? "clamp" : "wrap",
                {"wrap", "clamp"}) == "clamp"
          ? bake::Address::clamp
          : bake::Address::wrap;
  scene.shadows = read.boolean(render_table, "render", "shadows", scene.shadows);
  scene.light = read.vector3(key_node(render_table, "light"), "render.light", scene.light);
  if (glm::length(scene.light) < 1e-6f)
    read.fail(key_node(render_table, "light"), "render.light", "must not be zero");
  scene.depth_scale = float(read.number(render_table, "render", "depth_scale", scene.depth_scale,
                                        render::min_depth_scale, render::max_depth_scale));
  scene.tile = int(read.integer(render_table, "render", "tile", scene.tile, 1, render::max_tile));
  if (scene.tile > 1 && scene.address != bake::Address::wrap)
    read.fail(key_node(render_table, "tile"), "render.tile", "above 1 needs address = \"wrap\"");
  scene.unbounded = read.word(render_table, "render", "extent", scene.unbounded ? "unbounded" : "patch",
                              {"patch", "unbounded"}) == "unbounded";
  if (scene.unbounded && (scene.surface != render::Surface::plane || scene.address != bake::Address::wrap ||
                          scene.method == render::Method::reference)) {
    const toml::node* where =
        key_node(render_table, "extent") ? key_node(render_table, "extent") : render_table;
    read.fail(where, "render.extent",
              "\"unbounded\" tiles the plane with address = \"wrap\" and a method other than the reference "
              "(extent = \"patch\" for the others)");
  }
  if (!render::supports_surface(scene.method, scene.surface)) {
    read.fail(key_node(render_table, "surface"), "render.surface",
              std::string("render.method ") + render::method_info(scene.method).name +
                  " does not render on " + surface);
  }
}

void read_time_and_budget(const Reader& read, const toml::table& root, Scene& scene) {
  const toml::table* time = read.section(root, "time");
  if (time) read.known_keys(*time, "time", {"start", "fps"});
  scene.start = read.number(time, "time", "start", scene.start, -max_abs_time, max_abs_time);
  scene.fps = read.number(time, "time", "fps", scene.fps, 1e-3, max_fps);
  const toml::table* budget = read.section(root, "budget");
  if (budget)
    read.known_keys(*budget, "budget",
                    {"frame_ms", "bake_work", "tolerance", "cone_lag_frames", "cone_ahead"});
  scene.frame_ms = read.number(budget, "budget", "frame_ms", scene.frame_ms, 0.0, max_frame_ms);
  scene.bake_work = read.integer(budget, "budget", "bake_work", scene.bake_work, -1, max_bake_work);
  scene.tolerance =
      float(read.number(budget, "budget", "tolerance", scene.tolerance, 0.0, bake::max_tolerance));
  if (!(scene.tolerance < bake::max_tolerance))
    read.fail(key_node(budget, "tolerance"), "budget.tolerance", "must be below 1");
  scene.cone_lag_frames =
      int(read.integer(budget, "budget", "cone_lag_frames", scene.cone_lag_frames, 0, max_cone_lag_frames));
  scene.cone_ahead = read.boolean(budget, "budget", "cone_ahead", scene.cone_ahead);
}

void read_backend(const Reader& read, const toml::table& root, Scene& scene) {
  const toml::table* backend = read.section(root, "backend");
  if (backend)
    read.known_keys(*backend, "backend", {"sim", "bake", "device_rings", "device_window", "device_group"});
  scene.sim_backend = backend_of(
      read.word(backend, "backend", "sim", backend_word(scene.sim_backend), {"auto", "cpu", "device"}));
  scene.bake_backend = backend_of(
      read.word(backend, "backend", "bake", backend_word(scene.bake_backend), {"auto", "cpu", "device"}));
  bake::DeviceFirstPass& first_pass = scene.device_first_pass;
  first_pass.ring_radius = int(read.integer(backend, "backend", "device_rings", first_pass.ring_radius, 0,
                                            bake::max_first_pass_rings));
  first_pass.window_radius = int(read.integer(backend, "backend", "device_window", first_pass.window_radius,
                                              1, bake::max_first_pass_window));
  first_pass.group = read.boolean(backend, "backend", "device_group", first_pass.group);
  // the group's first pass replaces the rings': turned on without a ring radius, it takes none
  if (backend && first_pass.group && backend->contains("device_group") && !backend->contains("device_rings"))
    first_pass.ring_radius = 0;
}

}  // namespace

Scene apply_scene(const Scene& base, std::string_view text, const std::string& source_name) {
  toml::table root;
  try {
    root = toml::parse(text, source_name);
  } catch (const toml::parse_error& error) {
    throw SceneError(source_name + ":" + std::to_string(error.source().begin.line) + ": " +
                     std::string(error.description()));
  }
  const Reader read(source_name);
  read.known_keys(root, "",
                  {"name", "source", "ocean", "swell", "sinusoids", "material", "camera", "render", "time",
                   "budget", "backend"});
  Scene scene = base;
  scene.name = read.word(&root, "", "name", scene.name, {});
  read_source(read, root, source_name, scene);
  read_ocean(read, root, scene);
  read_swell(read, root, scene);
  read_sinusoids(read, root, scene);
  read_material(read, root, source_name, scene);
  const toml::table* camera = read_camera(read, root, scene);
  read_render(read, root, source_name, scene);
  read_time_and_budget(read, root, scene);
  read_backend(read, root, scene);
  try {
    scene_view(scene, scene.start).camera.validate();
  } catch (const render::RenderError& error) {
    read.fail(camera, "camera", key_words(error.what()));
  }
  return scene;
}

Scene parse_scene(std::string_view text, const std::string& source_name) {
  return apply_scene(Scene{}, text, source_name);
}

Scene read_scene_file(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw SceneError(file.string() + ": cannot open the scene file");
  std::ostringstream text;
  text << in.rdbuf();
  Scene base;
  base.name = file.stem().string();  // a file without a name key is named after itself
  return apply_scene(base, text.str(), file.string());
}

namespace {

// A float as the double with the shortest decimal that reads back to it (0.22f prints as 0.22).
double tidy(float value) {
  char text[32];
  const auto end = std::to_chars(text, text + sizeof text, value).ptr;
  return std::strtod(std::string(text, end).c_str(), nullptr);
}

}  // namespace

std::string scene_toml(const Scene& scene) {
  auto vec = [](glm::vec3 v) { return toml::array{tidy(v.x), tidy(v.y), tidy(v.z)}; };
  toml::table root;
  root.insert("name", scene.name);
  toml::table source{
      {"kind", source_word(scene.source)}, {"map_size", scene.map_size}, {"seed", std::int64_t(scene.seed)}};
  if (scene.source == SourceKind::image) {
    source.insert("path", scene.image.string());
    if (!scene.image_read.channel.empty()) source.insert("channel", scene.image_read.channel);
    source.insert("invert", scene.image_read.invert);
    if (const auto& range = scene.image_read.height_range)
      source.insert("height_range", toml::array{double(tidy((*range)[0])), double(tidy((*range)[1]))});
  }
  root.insert("source", source);
  const sim::OceanParams& ocean = scene.ocean;
  toml::table ocean_table{{"patch_size", tidy(ocean.patch_size)},
                          {"spectrum", spectrum_word(ocean.spectrum)}};
  if (ocean.significant_height > 0.0f) {
    ocean_table.insert("hs", tidy(ocean.significant_height));
    ocean_table.insert("tp", tidy(ocean.peak_period));
  } else {
    ocean_table.insert("wind_speed", tidy(ocean.wind_speed));
    if (ocean.spectrum == sim::Spectrum::jonswap || ocean.spectrum == sim::Spectrum::tma)
      ocean_table.insert("fetch", tidy(ocean.fetch));
  }
  ocean_table.insert("wind_direction", tidy(float(degrees(ocean.wind_direction))));
  if (std::isfinite(ocean.depth)) ocean_table.insert("depth", tidy(ocean.depth));
  if (ocean.spreading_model == sim::Spreading::cos2s) {
    ocean_table.insert("spreading", tidy(ocean.spreading));
  } else {
    ocean_table.insert("spreading_model", spreading_word(ocean.spreading_model));
  }
  ocean_table.insert("choppiness", tidy(ocean.choppiness));
  ocean_table.insert("seed", std::int64_t(ocean.seed));
  ocean_table.insert("loop_seconds", ocean.loop_seconds);
  root.insert("ocean", ocean_table);
  if (ocean.swell.significant_height > 0.0f) {
    root.insert("swell", toml::table{{"hs", tidy(ocean.swell.significant_height)},
                                     {"tp", tidy(ocean.swell.peak_period)},
                                     {"direction", tidy(float(degrees(ocean.swell.direction)))},
                                     {"spreading", tidy(ocean.swell.spreading)}});
  }
  root.insert("sinusoids", toml::table{{"wave_count", scene.sinusoids.wave_count},
                                       {"patch_size", tidy(scene.sinusoids.patch_size)},
                                       {"steepness", tidy(scene.sinusoids.steepness)},
                                       {"wind_direction", tidy(float(double(scene.sinusoids.wind_direction) *
                                                                     180.0 / std::numbers::pi))},
                                       {"seed", std::int64_t(scene.sinusoids.seed)}});
  toml::table material{{"kind", scene.material == render::Material::water ? "water"
                                : !scene.albedo.empty()                   ? "albedo"
                                                                          : "grid"},
                       {"foam", scene.foam},
                       {"foam_coverage", tidy(scene.foam_coverage)},
                       {"foam_color", vec(scene.foam_color)},
                       {"foam_intensity", tidy(scene.foam_intensity)}};
  if (!scene.albedo.empty()) material.insert("albedo", scene.albedo.string());
  root.insert("material", material);
  toml::table camera{{"eye", vec(scene.camera.eye)},
                     {"look_at", vec(scene.camera.look_at)},
                     {"up", vec(scene.camera.up)},
                     {"fov_y", tidy(scene.camera.fov_y_degrees)}};
  if (!scene.keyframes.empty()) {
    toml::array keys;
    for (const CameraKey& key : scene.keyframes) {
      keys.push_back(toml::table{{"time", key.time}, {"eye", vec(key.eye)}, {"look_at", vec(key.look_at)}});
    }
    camera.insert("keyframes", keys);
  }
  root.insert("camera", camera);
  toml::table render_table{{"method", render::method_info(scene.method).name},
                           {"steps", scene.steps},
                           {"refine", scene.refine},
                           {"size", toml::array{scene.camera.width, scene.camera.height}},
                           {"surface", surface_word(scene.surface)},
                           {"radius", tidy(scene.radius)},
                           {"address", scene.address == bake::Address::clamp ? "clamp" : "wrap"},
                           {"shadows", scene.shadows},
                           {"light", vec(scene.light)},
                           {"depth_scale", tidy(scene.depth_scale)},
                           {"tile", scene.tile},
                           {"extent", scene.unbounded ? "unbounded" : "patch"}};
  if (scene.surface == render::Surface::mesh) render_table.insert("mesh", scene.mesh.string());
  root.insert("render", render_table);
  root.insert("time", toml::table{{"start", scene.start}, {"fps", scene.fps}});
  toml::table budget{{"bake_work", std::int64_t(scene.bake_work)},
                     {"tolerance", tidy(scene.tolerance)},
                     {"cone_lag_frames", std::int64_t(scene.cone_lag_frames)},
                     {"cone_ahead", scene.cone_ahead}};
  if (std::isfinite(scene.frame_ms)) budget.insert("frame_ms", scene.frame_ms);
  root.insert("budget", budget);
  root.insert("backend", toml::table{{"sim", backend_word(scene.sim_backend)},
                                     {"bake", backend_word(scene.bake_backend)},
                                     {"device_rings", std::int64_t(scene.device_first_pass.ring_radius)},
                                     {"device_window", std::int64_t(scene.device_first_pass.window_radius)},
                                     {"device_group", scene.device_first_pass.group}});
  std::ostringstream out;
  out << "# displace scene (pipeline/scene.h documents every key)\n" << root << "\n";
  return out.str();
}

}  // namespace displace::pipeline
