// demos/cli/scene_keys.cpp - the scene flags' table (demos/cli/scene_keys.h).
#include "demos/cli/scene_keys.h"

#include <algorithm>

#include "demos/cli/flags.h"
#include "demos/cli/scene_flags.h"

namespace displace::app::cli {
namespace {

Range range(double low, double high, const char* unit) { return Range{low, high, unit}; }

CLI::Validator surface_value() {
  return text_check([](const std::string& text) -> std::string {
    if (text == "mesh:") return "mesh:FILE.obj needs a file name after 'mesh:'";
    if (text.starts_with("mesh:")) return {};
    std::string word = text;
    return word_in(surface_words)(word);
  });
}

CLI::Validator pair_value() {
  return text_check([](const std::string& text) -> std::string {
    if (text.find(',') == std::string::npos) return "expects LOW,HIGH, got " + in_quotes(text);
    if (!read_pair(text)) return "needs finite LOW < HIGH, got " + in_quotes(text);
    return {};
  });
}

CLI::Validator channel_value() {
  return text_check([](const std::string& text) -> std::string {
    if (text.empty()) return "needs a value";
    if (!std::all_of(text.begin(), text.end(), [](char c) { return c >= '0' && c <= '9'; })) return {};
    std::string index = text;
    return integer_in(0, max_channel_index)(index);
  });
}

// A word flag keeps its word (the TOML value), checked against `words`.
template <typename Enum>
std::function<CLI::Validator()> words_of(const Words<Enum>& words) {
  return [&words] {
    return text_check([&words](const std::string& text) -> std::string {
      std::string copy = text;
      return word_in(words)(copy);
    });
  };
}

std::function<CLI::Validator()> method_value() {
  return [] {
    return text_check([](const std::string& text) -> std::string {
      std::string copy = text;
      return word_in(method_words())(copy);
    });
  };
}

}  // namespace

const std::vector<Entry>& entries() {
  static const std::vector<Entry> table = {
      // [source]
      {"--source",
       scene_source,
       {"source.kind"},
       Kind::word,
       "ocean|sinusoids|bricks|cliff|image",
       "what makes the heights",
       words_of(source_words)},
      {"--input",
       scene_source,
       {"source.path"},
       Kind::path,
       "FILE",
       "a height image (kind image; 8/16-bit: value / maximum; float: min..max or as `sim` wrote it)",
       [] { return not_empty(); }},
      {"--channel",
       scene_source,
       {"source.channel"},
       Kind::word,
       "NAME|INDEX",
       "the image's channel (default `height`, or the only grey one)",
       [] { return channel_value(); }},
      {"--invert", scene_source, {"source.invert"}, Kind::on, "", "the image stores depth (1 = deepest)", {}},
      {"--height-range",
       scene_source,
       {"source.height_range"},
       Kind::pair,
       "LOW,HIGH",
       "float images: the raw values that map to 0 and 1",
       [] { return pair_value(); }},
      {"--map-size",
       scene_source,
       {"source.map_size"},
       Kind::integer,
       "N",
       "height map texels a side (even for the ocean)",
       [] { return integer_in(pipeline::min_map_size, pipeline::max_map_size); }},
      {"--seed",
       scene_source,
       {"source.seed", "ocean.seed", "sinusoids.seed"},
       Kind::integer,
       "INT",
       "the source's random seed",
       [] { return seed_value(); }},
      {"--time",
       scene_source,
       {"time.start"},
       Kind::number,
       "T",
       "seconds: the time of frame 0",
       [] { return number_in(range(-pipeline::max_abs_time, pipeline::max_abs_time, "s")); }},
      // [ocean], [sinusoids]
      {"--patch-size",
       scene_source,
       {"ocean.patch_size", "sinusoids.patch_size"},
       Kind::number,
       "M",
       "metres the map covers (ocean 200, sinusoids 4)",
       [] { return number_in(range(sim::min_patch_size, sim::max_patch_size, "m")); }},
      {"--wind-direction",
       scene_source,
       {"ocean.wind_direction", "sinusoids.wind_direction"},
       Kind::number,
       "DEG",
       "azimuth of the wind / mean wave direction",
       [] {
         return number_in(
             range(-pipeline::max_direction_degrees, pipeline::max_direction_degrees, "degrees"));
       }},
      {"--wind-speed",
       scene_source,
       {"ocean.wind_speed"},
       Kind::number,
       "V",
       "ocean: m/s at 10 m",
       [] { return number_in(range(sim::min_wind_speed, sim::max_wind_speed, "m/s")); }},
      {"--spectrum",
       scene_source,
       {"ocean.spectrum"},
       Kind::word,
       "phillips|pierson-moskowitz|jonswap|tma",
       "ocean: the spectrum (Tessendorf's; the fully developed sea; fetch-limited; fetch-limited in finite "
       "depth)",
       words_of(spectrum_words)},
      {"--fetch",
       scene_source,
       {"ocean.fetch"},
       Kind::number,
       "KM",
       "ocean, jonswap and tma: fetch (growth stops where the sea is fully developed)",
       [] { return number_in(range(sim::min_fetch, sim::max_fetch, "km")); }},
      {"--beaufort",
       scene_source,
       {"ocean.beaufort"},
       Kind::integer,
       "B",
       "ocean: the wind of Beaufort force B and a fully developed sea (instead of --wind-speed, --fetch)",
       [] { return integer_in(0, sim::max_beaufort); }},
      {"--hs",
       scene_source,
       {"ocean.hs"},
       Kind::number,
       "M",
       "ocean: the sea's significant height, with --tp (instead of --wind-speed, --fetch; not phillips)",
       [] { return number_in(range(sim::min_significant_height, sim::max_significant_height, "m")); }},
      {"--tp",
       scene_source,
       {"ocean.tp"},
       Kind::number,
       "S",
       "ocean: the sea's peak period in seconds, with --hs",
       [] { return number_in(range(sim::min_peak_period, sim::max_peak_period, "s")); }},
      {"--depth",
       scene_source,
       {"ocean.depth"},
       Kind::number,
       "M",
       "ocean: water depth (default deep water): w^2 = g k tanh(k h); tma takes its energy from it too",
       [] { return number_in(range(sim::min_depth, sim::max_depth, "m")); }},
      {"--spreading",
       scene_source,
       {"ocean.spreading"},
       Kind::number,
       "S",
       "ocean: directional spreading exponent of cos2s",
       [] { return number_in(range(0.0, sim::max_spreading, "")); }},
      {"--spreading-model",
       scene_source,
       {"ocean.spreading_model"},
       Kind::word,
       "cos2s|mitsuyasu|hasselmann|donelan-banner",
       "ocean: directional spreading, fixed (cos2s) or following the frequency and the wave age",
       words_of(spreading_words)},
      {"--swell-hs",
       scene_source,
       {"swell.hs"},
       Kind::number,
       "M",
       "a swell over the ocean's sea: its significant height (0: none)",
       [] { return number_in(range(0.0, sim::max_significant_height, "m")); }},
      {"--swell-tp",
       scene_source,
       {"swell.tp"},
       Kind::number,
       "S",
       "the swell's peak period",
       [] { return number_in(range(sim::min_peak_period, sim::max_peak_period, "s")); }},
      {"--swell-direction",
       scene_source,
       {"swell.direction"},
       Kind::number,
       "DEG",
       "the azimuth the swell travels towards",
       [] {
         return number_in(
             range(-pipeline::max_direction_degrees, pipeline::max_direction_degrees, "degrees"));
       }},
      {"--swell-spreading",
       scene_source,
       {"swell.spreading"},
       Kind::number,
       "S",
       "the swell's cos2s spreading exponent (narrow: 20 and more)",
       [] { return number_in(range(0.0, sim::max_spreading, "")); }},
      {"--choppiness",
       scene_source,
       {"ocean.choppiness"},
       Kind::number,
       "L",
       "ocean: choppy crests, resampled onto the grid (0: none)",
       [] { return number_in(range(0.0, sim::max_choppiness, "")); }},
      {"--loop-seconds",
       scene_source,
       {"ocean.loop_seconds"},
       Kind::number,
       "T",
       "ocean: a seamless loop of T seconds (wave frequencies rounded to multiples of 2 pi / T; 0: none)",
       [] { return number_in(range(0.0, sim::max_loop_seconds, "s")); }},
      {"--wave-count",
       scene_source,
       {"sinusoids.wave_count"},
       Kind::integer,
       "INT",
       "sinusoids: waves",
       [] { return integer_in(1, sim::max_wave_count); }},
      {"--steepness",
       scene_source,
       {"sinusoids.steepness"},
       Kind::number,
       "S",
       "sinusoids: the sum of amplitude x wave number",
       [] { return number_in(range(pipeline::min_steepness, sim::max_steepness, "")); }},
      // [material]
      {"--material",
       scene_view,
       {"material.kind"},
       Kind::word,
       "grid|water",
       "how the hit is shaded",
       [] {
         return text_check([](const std::string& text) -> std::string {
           return text == "grid" || text == "water"
                      ? std::string()
                      : "must be one of grid|water (an image: --albedo), got " + in_quotes(text);
         });
       }},
      {"--foam",
       scene_view,
       {"material.foam"},
       Kind::on,
       "",
       "water on the ocean: foam where crests fold",
       {}},
      {"--foam-coverage",
       scene_view,
       {"material.foam_coverage"},
       Kind::number,
       "J",
       "foam where the choppy surface's Jacobian is below J (0.85: the most compressed crests; higher: more)",
       [] { return number_in(range(0.0, pipeline::max_foam_coverage, "")); }},
      {"--foam-color",
       scene_view,
       {"material.foam_color"},
       Kind::vector,
       "R,G,B",
       "the foam's colour, linear RGB in [0, 1]",
       [] { return vector_value(); }},
      {"--foam-intensity",
       scene_view,
       {"material.foam_intensity"},
       Kind::number,
       "I",
       "how much of the foam colour covers fully foamed water (0: foam hidden)",
       [] { return number_in(range(0.0, 1.0, "")); }},
      {"--albedo",
       scene_view,
       {"material.albedo"},
       Kind::path,
       "IMAGE",
       "shade with an image (1-4 channels) instead of the grid",
       [] { return not_empty(); }},
      // [camera]
      {"--eye",
       scene_view,
       {"camera.eye"},
       Kind::vector,
       "X,Y,Z",
       "camera position",
       [] { return vector_value(); }},
      {"--look-at",
       scene_view,
       {"camera.look_at"},
       Kind::vector,
       "X,Y,Z",
       "point the camera looks at",
       [] { return vector_value(); }},
      {"--up", scene_view, {"camera.up"}, Kind::vector, "X,Y,Z", "camera up", [] { return vector_value(); }},
      {"--fov-y",
       scene_view,
       {"camera.fov_y"},
       Kind::number,
       "DEG",
       "full vertical angle",
       [] { return number_in(range(render::min_fov_y_degrees, render::max_fov_y_degrees, "degrees")); }},
      // [render]
      {"--method",
       scene_method,
       {"render.method"},
       Kind::word,
       "NAME",
       "the per-pixel method",
       method_value()},
      {"--steps",
       scene_method,
       {"render.steps"},
       Kind::integer,
       "INT",
       "linear-search steps or maximum cone steps",
       [] { return integer_in(1, render::max_steps); }},
      {"--refine",
       scene_method,
       {"render.refine"},
       Kind::integer,
       "INT",
       "binary or secant steps",
       [] { return integer_in(0, render::max_refine); }},
      {"--size",
       scene_view,
       {"render.size"},
       Kind::size,
       "WxH",
       "the image in pixels",
       [] { return image_size_check(); }},
      {"--surface",
       scene_view,
       {"render.surface"},
       Kind::word,
       "plane|sphere|cylinder|cone|mesh:FILE.obj",
       "what the relief lies on",
       [] { return surface_value(); }},
      {"--radius",
       scene_view,
       {"render.radius"},
       Kind::number,
       "R",
       "the quadric's outer radius",
       [] { return number_in(range(render::min_radius, render::max_radius, "world units")); }},
      {"--address",
       scene_view,
       {"render.address"},
       Kind::word,
       "wrap|clamp",
       "how the map continues past its edges",
       words_of(address_words)},
      {"--tile",
       scene_view,
       {"render.tile"},
       Kind::integer,
       "INT",
       "texture repeats over the plane (above 1 needs --address wrap)",
       [] { return integer_in(1, render::max_tile); }},
      {"--depth-scale",
       scene_view,
       {"render.depth_scale"},
       Kind::number,
       "D",
       "world units between height 1 and height 0",
       [] { return number_in(range(render::min_depth_scale, render::max_depth_scale, "world units")); }},
      {"--light",
       scene_view,
       {"render.light"},
       Kind::vector,
       "X,Y,Z",
       "direction towards the light",
       [] { return vector_value(); }},
      {"--extent",
       scene_view,
       {"render.extent"},
       Kind::word,
       "patch|unbounded",
       "the one patch, or the plane tiled to the horizon under the sky (the water scenes)",
       [] {
         return text_check([](const std::string& text) -> std::string {
           return text == "patch" || text == "unbounded"
                      ? std::string()
                      : "must be patch or unbounded, got " + in_quotes(text);
         });
       }},
      {"--shadows",
       scene_view,
       {"render.shadows"},
       Kind::on,
       "",
       "self-shadowing, traced towards the light with the same method",
       {}},
      // [time], [budget]
      {"--fps",
       scene_frames,
       {"time.fps"},
       Kind::number,
       "F",
       "frames per second of scene time",
       [] { return number_in(range(1e-3, pipeline::max_fps, "")); }},
      {"--budget-ms",
       scene_frames,
       {"budget.frame_ms"},
       Kind::number,
       "MS",
       "the frame budget the cone bake's share comes from (default unlimited; 0 allowed)",
       [] { return number_in(range(0.0, pipeline::max_frame_ms, "ms")); }},
      {"--bake-work",
       scene_frames,
       {"budget.bake_work"},
       Kind::integer,
       "N",
       "texels the cone bake may search a frame (reproducible frames)",
       [] { return integer_in(0, pipeline::max_bake_work); }},
      {"--tolerance",
       scene_frames,
       {"budget.tolerance"},
       Kind::number,
       "T",
       "the cone bake refines while a ratio may be more than T below the best",
       [] { return tolerance_in_range(); }},
      {"--backend",
       scene_source,
       {"backend.sim", "backend.bake"},
       Kind::word,
       "auto|cpu|device",
       "where the ocean's sim and the cone bake run: the device (compute shaders on the renderer's GPU), "
       "the CPU, or auto (the device on a GPU, the CPU on lavapipe)",
       [] {
         return text_check([](const std::string& text) -> std::string {
           return text == "auto" || text == "cpu" || text == "device"
                      ? std::string()
                      : "must be auto, cpu or device, got " + in_quotes(text);
         });
       }},
      {"--device-rings",
       scene_source,
       {"backend.device_rings"},
       Kind::integer,
       "R",
       "the device cone bake's first pass: 0 searches the pyramid, R > 0 bounds the nodes more than R "
       "nodes from each texel's, level by level, the same for every texel (default 2)",
       [] { return integer_in(0, bake::max_first_pass_rings); }},
      {"--device-group",
       scene_source,
       {"backend.device_group"},
       Kind::on,
       "",
       "the device cone bake's first pass by 8 x 8 texel groups: each group bounds the cells far from it "
       "once, its texels the cells near it by rings of blocks (no --device-rings)",
       {}},
      {"--device-window",
       scene_source,
       {"backend.device_window"},
       Kind::integer,
       "CELLS",
       "the device cone bake's first pass: cells around each texel bounded by the surface's slopes",
       [] { return integer_in(1, bake::max_first_pass_window); }},
      {"--cone-lag",
       scene_frames,
       {"budget.cone_lag_frames"},
       Kind::integer,
       "N",
       "with a frame budget and moving heights: frames a cone map may take to make while the last one is "
       "served with raised apexes (0: every frame makes its own)",
       [] { return integer_in(0, pipeline::max_cone_lag_frames); }},
      {"--cone-ahead",
       scene_frames,
       {"budget.cone_ahead"},
       Kind::on,
       "",
       "with --cone-lag 1 and the sim and bake on the device: each frame bakes the next frame's cone map "
       "from the next frame's heights beside its draw",
       {}},
  };
  return table;
}

}  // namespace displace::app::cli
