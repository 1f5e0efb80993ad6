// demos/cli/scene_flags.cpp - the scene flags of demos/cli/scene_flags.h: one table of flag -> keys,
// each flag's value checked by its validator (the libraries' limits), then written as TOML.
#include "demos/cli/scene_flags.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <toml++/toml.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <sstream>

#include "demos/cli/flags.h"
#include "demos/cli/scene_keys.h"
#include "demos/error.h"

namespace displace::app::cli {
namespace {

bool* switch_of(SceneFlags& flags, const std::string& flag) {
  if (flag == "--shadows") return &flags.shadows;
  if (flag == "--foam") return &flags.foam;
  return &flags.invert;
}

// Whether the command declared `entry` as a scene flag (a command may have a flag of the same name of
// its own: bake's --budget-ms) and it was given.
bool set_by(const CLI::App& app, const SceneFlags& flags, const Entry& entry) {
  const bool declared = entry.kind == Kind::on ? std::find(flags.switches.begin(), flags.switches.end(),
                                                           entry.flag) != flags.switches.end()
                                               : flags.values.count(entry.flag) > 0;
  return declared && given(app, entry.flag);
}

// "section.key" -> the node of `root` it names, its section made when missing.
void set_key(toml::table& root, std::string_view key, toml::node&& value) {
  const auto dot = key.find('.');
  const std::string section(key.substr(0, dot));
  if (!root.contains(section)) root.insert(section, toml::table{});
  root[section].as_table()->insert_or_assign(std::string(key.substr(dot + 1)), std::move(value));
}

void set_value(toml::table& root, const Entry& entry, const std::string& text) {
  for (const char* key : entry.keys) {
    switch (entry.kind) {
      case Kind::integer: set_key(root, key, toml::value<std::int64_t>(std::stoll(text))); break;
      case Kind::number: set_key(root, key, toml::value<double>(std::stod(text))); break;
      case Kind::word:
      case Kind::path: set_key(root, key, toml::value<std::string>(text)); break;
      case Kind::on: set_key(root, key, toml::value<bool>(true)); break;
      case Kind::vector: {
        const glm::vec3 v = *read_vector(text);
        set_key(root, key, toml::array{double(v.x), double(v.y), double(v.z)});
        break;
      }
      case Kind::pair: {
        const auto [low, high] = *read_pair(text);
        set_key(root, key, toml::array{double(low), double(high)});
        break;
      }
      case Kind::size: {
        const auto [width, height] = *read_image_size(text);
        set_key(root, key, toml::array{std::int64_t(width), std::int64_t(height)});
        break;
      }
    }
  }
}

// The given flags as TOML keys, with what a flag implies: --input is kind image, --albedo the albedo
// material, --surface mesh:FILE the mesh surface.
toml::table flags_as_toml(const CLI::App& app, const SceneFlags& flags) {
  toml::table root;
  for (const Entry& entry : entries()) {
    if (!set_by(app, flags, entry)) continue;
    if (entry.kind == Kind::on) {
      set_value(root, entry, "");
      continue;
    }
    const std::string& text = flags.values.at(entry.flag);
    if (std::string_view(entry.flag) == "--surface" && text.starts_with("mesh:")) {
      set_key(root, "render.surface", toml::value<std::string>("mesh"));
      set_key(root, "render.mesh", toml::value<std::string>(text.substr(5)));
      continue;
    }
    set_value(root, entry, text);
    if (std::string_view(entry.flag) == "--input")
      set_key(root, "source.kind", toml::value<std::string>("image"));
    if (std::string_view(entry.flag) == "--albedo")
      set_key(root, "material.kind", toml::value<std::string>("albedo"));
  }
  return root;
}

constexpr const char* command_line = "the command line";

// A scene error of the command line's keys in its flags' words: "--tile: above 1 needs ...".
std::string flag_message(const std::string& message) {
  std::string text = message;
  if (text.starts_with(command_line)) {
    text = text.substr(std::string_view(command_line).size());
    if (text.starts_with(":")) text = text.substr(text.find(": ") + 2);  // the line
  }
  // the key it names first: the flag that sets it
  for (const Entry& entry : entries()) {
    for (std::string_view key : entry.keys) {
      if (text.starts_with(std::string(key) + ": ")) {
        return std::string(entry.flag) + " " + text.substr(key.size() + 2);
      }
    }
  }
  static const std::pair<std::string_view, std::string_view> implied[] = {
      {"render.mesh: ", "--surface mesh:FILE.obj: "},
      {"material.albedo: ", "--albedo: "},
      {"source.path: ", "--input: "},
      {"render.surface: ", "--surface: "}};
  for (const auto& [key, flag] : implied) {
    if (text.starts_with(key)) return std::string(flag) + text.substr(key.size());
  }
  return text;
}

// A flag of the ocean's, the sinusoids' or an image's keys given for another source is an error, not
// ignored (a scene file may carry every section; a command line says what it means).
void reject_what_does_not_apply(const CLI::App& app, const SceneFlags& flags, const pipeline::Scene& scene) {
  const std::string section = scene.source == pipeline::SourceKind::ocean       ? "ocean."
                              : scene.source == pipeline::SourceKind::sinusoids ? "sinusoids."
                                                                                : "source.";
  for (const Entry& entry : entries()) {
    if (!set_by(app, flags, entry)) continue;
    bool applies = false, source_keys = false;
    for (std::string_view key : entry.keys) {
      const bool own = key.starts_with("ocean.") || key.starts_with("sinusoids.");
      source_keys |= own;
      applies |= !own || key.starts_with(section);
    }
    if (source_keys && !applies) {
      throw usage_error(fmt::format("{} does not apply to --source {}", entry.flag,
                                    source_words[std::size_t(scene.source)].first));
    }
    const bool image_key = std::string_view(entry.keys.front()) == "source.channel" ||
                           std::string_view(entry.keys.front()) == "source.invert" ||
                           std::string_view(entry.keys.front()) == "source.height_range";
    if (image_key && scene.source != pipeline::SourceKind::image)
      throw usage_error(std::string(entry.flag) + " applies to a height image (--input) only");
    if (std::string_view(entry.flag) == "--map-size" && scene.source == pipeline::SourceKind::image)
      throw usage_error("--map-size does not apply to a height image (the map size is the image's)");
  }
}

}  // namespace

void add_scene_flags(CLI::App& app, SceneFlags& flags, unsigned groups, const std::string& default_scene) {
  app.option_defaults()->group("Scene");
  flags.scene = default_scene;
  const std::vector<std::string> names = pipeline::builtin_scene_names();
  add_value(app, "--scene", flags.scene,
            fmt::format("a built-in scene ({}) or a TOML scene file (default {})", fmt::join(names, ", "),
                        default_scene),
            "NAME|FILE.toml", not_empty());
  for (const Entry& entry : entries()) {
    if (!(entry.group & groups)) continue;
    app.option_defaults()->group(entry.group == scene_source   ? "Heights (scene keys)"
                                 : entry.group == scene_frames ? "Frames (scene keys)"
                                                               : "View (scene keys)");
    if (entry.kind == Kind::on) {
      add_switch(app, entry.flag, *switch_of(flags, entry.flag), entry.help);
      flags.switches.emplace_back(entry.flag);
      continue;
    }
    std::string& value = flags.values[entry.flag];
    app.add_option(entry.flag, value, entry.help)->type_name(entry.value)->transform(entry.validator());
  }
}

pipeline::Scene named_scene(const std::string& name_or_file) {
  const std::vector<std::string> names = pipeline::builtin_scene_names();
  try {
    if (std::find(names.begin(), names.end(), name_or_file) != names.end()) {
      return pipeline::builtin_scene(name_or_file);
    }
    if (!std::filesystem::exists(name_or_file)) {
      throw runtime_error(fmt::format("--scene {} is neither a built-in scene ({}) nor a file",
                                      in_quotes(name_or_file), fmt::join(names, ", ")));
    }
    return pipeline::read_scene_file(name_or_file);
  } catch (const pipeline::SceneError& error) {
    throw runtime_error("scene file " +
                        std::string(error.what()));  // the file's content, not the command line
  }
}

pipeline::Scene finish_scene(const CLI::App& app, const SceneFlags& flags) {
  const pipeline::Scene base = named_scene(flags.scene);
  const toml::table keys = flags_as_toml(app, flags);
  if (keys.empty()) return base;
  std::ostringstream text;
  text << keys;
  pipeline::Scene scene;
  try {
    scene = pipeline::apply_scene(base, text.str(), command_line);
  } catch (const pipeline::SceneError& error) {
    throw usage_error(flag_message(error.what()));
  }
  reject_what_does_not_apply(app, flags, scene);
  return scene;
}

void check_cone_lag(const CLI::App& app, const pipeline::Scene& scene) {
  if (given(app, "--cone-lag") && !std::isfinite(scene.frame_ms)) {
    throw usage_error(
        "--cone-lag needs a frame budget (--budget-ms, or the scene's [budget] frame_ms): without one "
        "every frame makes its own cone maps");
  }
}

std::vector<SceneFlagRow> scene_flag_rows() {
  std::vector<SceneFlagRow> rows;
  for (const Entry& entry : entries()) {
    std::string keys;
    for (std::string_view key : entry.keys) {
      const auto dot = key.find('.');
      keys += fmt::format("{}`[{}] {}`", keys.empty() ? "" : ", ", key.substr(0, dot), key.substr(dot + 1));
    }
    rows.push_back({entry.flag, entry.value, keys,
                    entry.validator ? entry.validator().get_description() : std::string(), entry.help});
  }
  return rows;
}

}  // namespace displace::app::cli
