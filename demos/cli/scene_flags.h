// demos/cli/scene_flags.h - a scene from the command line: --scene NAME|FILE.toml names a built-in
// scene or a TOML file (pipeline/scene.h, the one scene model), and every other scene flag sets one
// of its keys over it (--steps 16 is [render] steps = 16). The flags are written into a TOML table
// and applied with pipeline::apply_scene, so the command line and a scene file pass the same checks;
// docs/scenes.md (from `displace scene --keys`) maps each flag to its key.
#pragma once

#include <CLI/CLI.hpp>
#include <map>
#include <string>
#include <vector>

#include "pipeline/scene.h"

namespace displace::app::cli {

// Which keys a command takes from the command line.
enum SceneGroup : unsigned {
  scene_source = 1u << 0,  // [source], [ocean], [sinusoids] and --time
  scene_view = 1u << 1,    // [material], [camera], [render] but method, steps and refine
  scene_method = 1u << 2,  // [render] method, steps, refine
  scene_frames = 1u << 3,  // [time] fps, [budget]
  scene_all = scene_source | scene_view | scene_method | scene_frames,
};

// What CLI11 fills: the --scene word and each given flag's value, canonical text.
struct SceneFlags {
  std::string scene;
  std::map<std::string, std::string> values;  // flag -> value, for each flag with a value declared
  bool shadows = false, foam = false, invert = false;
  std::vector<std::string> switches;  // the switches declared
};

// Declares --scene (default `default_scene`) and the flags of `groups` on `app`.
void add_scene_flags(CLI::App& app, SceneFlags& flags, unsigned groups, const std::string& default_scene);
// The scene --scene names with the given flags over it. A bad flag value is a usage error; a scene
// file that cannot be read or is malformed is a runtime error.
pipeline::Scene finish_scene(const CLI::App& app, const SceneFlags& flags);
// --cone-lag given without a frame budget (it would do nothing): a usage error.
void check_cone_lag(const CLI::App& app, const pipeline::Scene& scene);
// A built-in scene or a TOML scene file (runtime error naming both when it is neither).
pipeline::Scene named_scene(const std::string& name_or_file);

// The flag -> key table, for docs/scenes.md: one row per flag.
struct SceneFlagRow {
  std::string flag, value, keys, limits, help;
};
std::vector<SceneFlagRow> scene_flag_rows();

}  // namespace displace::app::cli
