// pipeline/python/module.cpp - `import displace`: scenes, heights, cone maps, height queries and frames
// as numpy arrays, over the installed libraries' public headers only (pipeline/, bake/, render/).
//
//   scene = displace.Scene.builtin("water"); scene["ocean.wind_speed"] = 15.0
//   h = displace.heights(scene, 2.0)                        # float32 (H, W), metres
//   cones, apex, stats = displace.bake(displace.heights(scene, 2.0, normalized=True))
//   displace.query(scene, 2.0, [[10.0, 20.0]])["height_m"]  # float32 (N,)
//   image = displace.Pipeline(scene, size=(320, 180)).frame(0)  # uint8 (180, 320, 4)
//
// Each function is the command of the same name without its files: the same numbers, bit for bit
// (tests/python/test_module.py). The heavy calls release the GIL. Bad input raises TypeError (an array
// numpy cannot make float of), KeyError (an unknown scene key) or ValueError (everything else the
// command line refuses), with the command's one line. Names and units: docs/python.md.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <toml++/toml.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <sstream>
#include <string>
#include <vector>

#include "bake/bake.h"
#include "pipeline/cone_bake.h"
#include "pipeline/frame_pipeline.h"
#include "pipeline/height_source.h"
#include "pipeline/query.h"
#include "pipeline/scene.h"
#include "render/render.h"

namespace py = pybind11;
using namespace displace;

namespace {

// ---- scenes --------------------------------------------------------------------------------------

// A Python value as the TOML value a scene file would hold.
std::unique_ptr<toml::node> toml_value(const py::handle& value, const std::string& key) {
  if (py::isinstance<py::bool_>(value)) return std::make_unique<toml::value<bool>>(value.cast<bool>());
  if (py::isinstance<py::int_>(value))
    return std::make_unique<toml::value<std::int64_t>>(value.cast<std::int64_t>());
  if (py::isinstance<py::float_>(value)) return std::make_unique<toml::value<double>>(value.cast<double>());
  if (py::isinstance<py::str>(value))
    return std::make_unique<toml::value<std::string>>(value.cast<std::string>());
  if (py::isinstance<py::sequence>(value)) {
    auto array = std::make_unique<toml::array>();
    for (const py::handle item : value.cast<py::sequence>()) {
      std::unique_ptr<toml::node> element = toml_value(item, key);
      element->visit([&](auto& node) { array->push_back(node); });
    }
    return array;
  }
  // numpy scalars and anything else that says it is a number
  if (py::hasattr(value, "__float__")) return std::make_unique<toml::value<double>>(value.cast<double>());
  throw py::type_error("scene key '" + key + "': a bool, number, string or list, not " +
                       std::string(py::str(value.get_type().attr("__name__"))));
}

py::object python_value(const toml::node& node) {
  if (const auto* value = node.as_boolean()) return py::bool_(value->get());
  if (const auto* value = node.as_integer()) return py::int_(value->get());
  if (const auto* value = node.as_floating_point()) return py::float_(value->get());
  if (const auto* value = node.as_string()) return py::str(value->get());
  if (const auto* array = node.as_array()) {
    py::list list;
    for (const toml::node& item : *array) list.append(python_value(item));
    return list;
  }
  py::dict dict;
  for (const auto& [name, item] : *node.as_table())
    dict[py::str(std::string(name.str()))] = python_value(item);
  return dict;
}

struct Scene {
  pipeline::Scene scene;

  // "ocean.wind_speed" -> its value in the scene's TOML; KeyError for a key the scene does not hold
  py::object get(const std::string& key) const {
    const toml::table table = toml::parse(pipeline::scene_toml(scene));
    const toml::node_view<const toml::node> node = table.at_path(key);
    if (!node)
      throw py::key_error("scene key '" + key +
                          "' is not set in this scene (scene.to_toml() lists its keys)");
    return python_value(*node.node());
  }
  // the key through the scene reader's checks, as a file or a flag would set it
  void set(const std::string& key, const py::handle& value) {
    toml::table root;
    toml::table* section = &root;
    std::string::size_type begin = 0;
    for (std::string::size_type dot; (dot = key.find('.', begin)) != std::string::npos; begin = dot + 1) {
      const std::string name = key.substr(begin, dot - begin);
      section = section->insert(name, toml::table{}).first->second.as_table();
    }
    std::unique_ptr<toml::node> node = toml_value(value, key);
    node->visit([&](auto& typed) { section->insert(key.substr(begin), typed); });
    std::ostringstream text;
    text << root;
    try {
      scene = pipeline::apply_scene(scene, text.str(), "scene[\"" + key + "\"]");
    } catch (const pipeline::SceneError& error) {
      const std::string message = error.what();
      if (message.find("unknown key") != std::string::npos) throw py::key_error(message);
      throw py::value_error(message);
    }
  }
};

Scene scene_or_value_error(const std::function<pipeline::Scene()>& make) {
  try {
    return Scene{make()};
  } catch (const pipeline::SceneError& error) {
    throw py::value_error(error.what());
  }
}

// What the module cannot make: files only the application reads (height and albedo images, meshes).
void require_no_files(const pipeline::Scene& scene, const char* what) {
  std::string needs;
  if (scene.source == pipeline::SourceKind::image) needs = "a height image ([source] kind = \"image\")";
  if (scene.surface == render::Surface::mesh) needs = "a mesh (surface = \"mesh\")";
  if (!scene.albedo.empty()) needs = "an albedo image (material kind = \"albedo\")";
  if (!needs.empty())
    throw py::value_error(std::string(what) + ": scene '" + scene.name + "' reads " + needs +
                          ", which the module does not read: load the image with your own reader and "
                          "pass its heights to displace.bake, or use the displace command");
}

double time_or_start(const pipeline::Scene& scene, std::optional<double> time) {
  const double t = time.value_or(scene.start);
  if (!std::isfinite(t) || std::abs(t) > pipeline::max_abs_time)
    throw py::value_error("time must be finite and within +-1e12 s, got " + std::to_string(t));
  return t;
}

// ---- heights -------------------------------------------------------------------------------------

py::array_t<float> image_array(std::vector<float>&& values, std::vector<py::ssize_t> shape) {
  auto* owned = new std::vector<float>(std::move(values));
  py::capsule free_when_done(owned, [](void* p) { delete static_cast<std::vector<float>*>(p); });
  return py::array_t<float>(shape, owned->data(), free_when_done);
}

py::array_t<float> heights(const Scene& s, std::optional<double> time, bool normalized) {
  const pipeline::Scene& scene = s.scene;
  require_no_files(scene, "heights");
  const double t = time_or_start(scene, time);
  std::vector<float> values;
  int width = 0, height = 0;
  std::string error;
  {
    py::gil_scoped_release release;
    try {
      // what `displace sim` writes: the effects the renderer samples (choppy crests resampled onto the
      // grid), no foam
      pipeline::HeightSource source(pipeline::source_settings(scene),
                                    pipeline::scene_effects(scene) & ~unsigned(pipeline::effect_foam));
      pipeline::HeightFrame frame;
      source.make(t, 0, frame);
      width = frame.field.width;
      height = frame.field.height;
      if (normalized) {
        values = frame.field.heights;
      } else {
        values.assign(frame.raw.begin(), frame.raw.end());
      }
    } catch (const pipeline::SceneError& e) {
      error = e.what();
    } catch (const std::invalid_argument& e) {
      error = std::string("bad source parameters: ") + e.what();
    }
  }
  if (!error.empty()) throw py::value_error(error);
  if (!std::all_of(values.begin(), values.end(), [](float h) { return std::isfinite(h); }))
    throw py::value_error("the scene's source produced a non-finite height");
  return image_array(std::move(values), {height, width});
}

// ---- cone maps -----------------------------------------------------------------------------------

// A 2-D float32 C-contiguous copy of anything numpy can make float of (TypeError otherwise).
py::array_t<float, py::array::c_style | py::array::forcecast> float_array(const py::handle& object,
                                                                          const char* name) {
  py::array_t<float, py::array::c_style | py::array::forcecast> array;
  try {
    array = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(object);
  } catch (const py::error_already_set&) {
  }
  if (!array) {
    PyErr_Clear();
    throw py::type_error(std::string(name) + ": expects an array of numbers, got " +
                         std::string(py::str(object.get_type().attr("__name__"))));
  }
  return array;
}

bake::Address address_named(const std::string& address) {
  if (address == "wrap") return bake::Address::wrap;
  if (address == "clamp") return bake::Address::clamp;
  throw py::value_error("address: 'wrap' or 'clamp', not '" + address + "'");
}

py::tuple bake_map(const py::handle& heights_object, int sectors, const std::string& cones,
                   const std::string& mode, std::optional<double> budget_ms, const std::string& address_word,
                   float tolerance) {
  const auto heights = float_array(heights_object, "bake");
  if (heights.ndim() != 2)
    throw py::value_error("bake: heights must be a 2-D array (H, W), got " + std::to_string(heights.ndim()) +
                          " dimensions");
  const int height = int(heights.shape(0)), width = int(heights.shape(1));
  if (width < pipeline::min_map_size || height < pipeline::min_map_size)
    throw py::value_error("bake: heights must be at least 2 x 2, got " + std::to_string(height) + " x " +
                          std::to_string(width));
  const std::span<const float> values(heights.data(), std::size_t(width) * std::size_t(height));
  for (const float h : values) {
    if (!(h >= 0.0f && h <= 1.0f))
      throw py::value_error(std::isnan(h) ? std::string("bake: heights hold NaN")
                                          : "bake: heights must lie in [0, 1] (displace.heights(scene, t, "
                                            "normalized=True)), found " +
                                                std::to_string(h));
  }
  if (sectors != 1 && sectors != 4 && sectors != 8)
    throw py::value_error("bake: sectors 1, 4 or 8, not " + std::to_string(sectors));
  if (cones != "bilinear" && cones != "center")
    throw py::value_error("bake: cones 'bilinear' or 'center', not '" + cones + "'");
  const std::optional<pipeline::Baker> baker = pipeline::baker_named(mode);
  if (!baker) throw py::value_error("bake: unknown mode '" + mode + "'");
  if (budget_ms && *baker != pipeline::Baker::budgeted)
    throw py::value_error("bake: budget_ms applies to mode 'budgeted' only");
  const double budget = budget_ms.value_or(std::numeric_limits<double>::infinity());
  if (!(budget >= 0.0)) throw py::value_error("bake: budget_ms must be 0 or more");
  if (!(tolerance >= 0.0f && tolerance <= 1.0f)) throw py::value_error("bake: tolerance must lie in [0, 1]");
  const bake::Address address = address_named(address_word);
  const bool bilinear = cones == "bilinear";

  pipeline::BakedCones baked;
  std::string error;
  {
    py::gil_scoped_release release;
    try {
      baked =
          bilinear
              ? pipeline::bake_bilinear(values, width, height, sectors, *baker, address, budget, tolerance)
              : pipeline::bake_cones(values, width, height, sectors, *baker, address, budget, tolerance);
    } catch (const std::invalid_argument& e) {
      error = std::string("bake: ") + e.what();
    }
  }
  if (!error.empty()) throw py::value_error(error);
  // the keys of `displace bake --stats`
  const auto finite = [](double value) { return std::isfinite(value) ? value : 0.0; };
  py::dict stats;
  stats["mode"] = pipeline::baker_name(*baker);
  stats["cones"] = cones;
  stats["width"] = baked.stats.width;
  stats["height"] = baked.stats.height;
  stats["sectors"] = baked.stats.sector_count;
  stats["address"] = address_word;
  stats["bake_ms"] = finite(baked.stats.milliseconds);
  stats["texels_refined"] = baked.stats.texels_refined;
  stats["texels_fallback"] = baked.stats.texels_fallback;
  stats["blocker_tests"] = baked.stats.work;
  stats["mean_ratio"] = finite(baked.stats.mean_ratio);
  py::object apex = py::none();
  if (bilinear) apex = image_array(std::move(baked.apex), {height, width});
  return py::make_tuple(image_array(std::move(baked.ratios), {height, width, sectors}), apex, stats);
}

// ---- queries -------------------------------------------------------------------------------------

py::dict query(const Scene& s, double time, const py::handle& points_object) {
  const pipeline::Scene& scene = s.scene;
  require_no_files(scene, "query");
  const double t = time_or_start(scene, time);
  const auto array = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(points_object);
  if (!array) {
    PyErr_Clear();
    throw py::type_error("query: points must be an (N, 2) array of numbers");
  }
  if (array.ndim() != 2 || array.shape(1) != 2)
    throw py::value_error("query: points must be an (N, 2) array (x, y in metres)");
  const std::size_t count = std::size_t(array.shape(0));
  std::vector<pipeline::QueryPoint> points(count);
  for (std::size_t n = 0; n < count; ++n) {
    points[n] = {array.data()[2 * n], array.data()[2 * n + 1]};
    if (!std::isfinite(points[n].x) || !std::isfinite(points[n].y))
      throw py::value_error("query: point " + std::to_string(n) + " is not two finite numbers");
  }
  pipeline::QueryResult result;
  std::string error;
  {
    py::gil_scoped_release release;
    try {
      pipeline::HeightQuery height_query(scene);
      height_query.query(points, t, result);
    } catch (const pipeline::SceneError& e) {
      error = e.what();
    }
  }
  if (!error.empty()) throw py::value_error(error);
  const py::ssize_t n = py::ssize_t(count);
  py::array_t<float> normal({n, py::ssize_t(3)}), displacement({n, py::ssize_t(2)});
  std::memcpy(normal.mutable_data(), result.normal.data(), count * sizeof(glm::vec3));
  std::memcpy(displacement.mutable_data(), result.displacement.data(), count * sizeof(glm::vec2));
  py::dict out;
  out["height_m"] = image_array(std::move(result.height_m), {n});
  out["z"] = image_array(std::move(result.z), {n});
  out["normal"] = normal;
  out["displacement"] = displacement;
  return out;
}

// ---- frames --------------------------------------------------------------------------------------

pipeline::Backend backend_named(const std::string& word) {
  for (const pipeline::Backend backend :
       {pipeline::Backend::automatic, pipeline::Backend::cpu, pipeline::Backend::device}) {
    if (word == pipeline::backend_word(backend)) return backend;
  }
  throw py::value_error("backend: 'auto', 'cpu' or 'device', not '" + word + "'");
}

// Frames Pipeline.stats summarizes: the last ones, so that a long loop keeps its memory.
constexpr long long stats_window = 1000;

// bench-frame's percentile: the nearest rank.
double percentile(std::vector<double> values, double fraction) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  return values[std::min(values.size() - 1, std::size_t(std::ceil(fraction * double(values.size())) - 1))];
}

const char* placement_word(bool on_device) { return on_device ? "device" : "cpu"; }

// A frame pipeline and the renderer it draws with, as `displace sequence` runs them.
class Pipeline {
 public:
  Pipeline(const Scene& s, std::optional<std::pair<int, int>> size, const std::string& backend)
      : scene_(s.scene) {
    require_no_files(scene_, "Pipeline");
    if (size) {
      scene_.camera.width = size->first;
      scene_.camera.height = size->second;
    }
    scene_.sim_backend = scene_.bake_backend = backend_named(backend);
    std::string error;
    {
      py::gil_scoped_release release;
      try {
        scene_.camera.validate();
        renderer_ = std::make_unique<render::Renderer>(render::RendererOptions{});
        pipeline_ = std::make_unique<pipeline::FramePipeline>(scene_, *renderer_);
      } catch (const pipeline::SceneError& e) {
        error = e.what();
      } catch (const render::RenderError& e) {
        error = e.what();
      }
    }
    if (!error.empty()) throw py::value_error(error);
  }

  py::array_t<std::uint8_t> frame(long long index) {
    if (index < 0) throw py::value_error("frame: the index must be 0 or more");
    Sample sample;
    {
      py::gil_scoped_release release;
      const auto start = std::chrono::steady_clock::now();
      sample.record = pipeline_->run(index, frame_);
      sample.wall_ms =
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    }
    if (frames_ == 0) allocations_after_first_ = renderer_->memory_allocations();
    samples_[std::size_t(frames_ % stats_window)] = sample;
    ++frames_;
    const int width = scene_.camera.width, height = scene_.camera.height;
    py::array_t<std::uint8_t> image({py::ssize_t(height), py::ssize_t(width), py::ssize_t(4)});
    std::memcpy(image.mutable_data(), frame_.color.data(), frame_.color.size());
    return image;
  }

  // bench-frame's --json keys over the last frames (up to stats_window), and the last frame's record
  py::dict stats() const {
    const std::size_t count = std::size_t(std::min<long long>(frames_, stats_window));
    const auto values = [&](auto field) {
      std::vector<double> out;
      for (std::size_t n = 0; n < count; ++n) out.push_back(field(samples_[n]));
      return out;
    };
    using R = const Sample&;
    struct Stage {
      const char* name;
      std::vector<double> host, device;
      bool on_device;
    };
    const Stage stages[] = {{"sim", values([](R s) { return s.record.sim_ms; }),
                             values([](R s) { return s.record.sim_device_ms; }), true},
                            {"bake", values([](R s) { return s.record.bake_ms; }),
                             values([](R s) { return s.record.bake_device_ms; }), true},
                            {"upload", values([](R s) { return s.record.upload_ms; }), {}, false},
                            {"render", values([](R s) { return s.record.render_ms; }),
                             values([](R s) { return s.record.render_device_ms; }), true},
                            {"frame", values([](R s) { return s.wall_ms; }), {}, false},
                            {"latency", values([](R s) { return s.record.frame_ms; }), {}, false}};
    py::dict stage_table;
    for (const Stage& stage : stages) {
      py::dict row;
      row["p50_ms"] = percentile(stage.host, 0.50);
      row["p95_ms"] = percentile(stage.host, 0.95);
      row["p99_ms"] = percentile(stage.host, 0.99);
      if (stage.on_device) {
        const double device = percentile(stage.device, 0.50);
        row["device_p50_ms"] = device > 0.0 ? py::object(py::float_(device)) : py::none();
      }
      stage_table[stage.name] = row;
    }
    long long within = 0, ffts = 0;
    unsigned effects = 0;
    bool cones = false;
    for (std::size_t n = 0; n < count; ++n) {
      const Sample& sample = samples_[n];
      within += std::isfinite(scene_.frame_ms) ? sample.wall_ms <= scene_.frame_ms : 1;
      ffts += sample.record.ffts;
      effects |= sample.record.effects;
      cones = cones || sample.record.cones.sector_count > 0;
    }
    const auto p50_and_max = [&](const std::vector<double>& v) -> py::object {
      if (!cones) return py::none();
      return py::dict(py::arg("p50") = percentile(v, 0.50), py::arg("max") = percentile(v, 1.0));
    };
    py::list effect_names;
    if (effects & pipeline::effect_heights) effect_names.append("heights");
    if (effects & pipeline::effect_choppy) effect_names.append("choppy");
    if (effects & pipeline::effect_foam) effect_names.append("foam");
    const double frames = std::max(double(count), 1.0);
    py::dict out;
    out["frames"] = count;
    out["backend"] = py::dict(py::arg("sim") = placement_word(pipeline_->placement().sim_on_device),
                              py::arg("bake") = placement_word(pipeline_->placement().cones_on_device));
    out["budget_ms"] = std::isfinite(scene_.frame_ms) ? py::object(py::float_(scene_.frame_ms)) : py::none();
    out["stages"] = stage_table;
    out["within_budget"] = double(within) / frames;
    out["ffts_per_frame"] = double(ffts) / frames;
    out["effects"] = effect_names;
    out["vulkan_allocations_after_warmup"] =
        frames_ > 0 ? renderer_->memory_allocations() - allocations_after_first_ : 0;
    out["frames_rendered"] = frames_;
    out["cone_lag_frames"] = p50_and_max(values([](R s) { return double(s.record.cone_lag); }));
    out["cone_lift"] = p50_and_max(values([](R s) { return double(s.record.cone_lift); }));
    out["overlapped"] = false;
    out["pinned_threads"] = 0;
    out["rss_kb"] = py::none();
    out["scene"] = scene_.name;
    out["device"] = renderer_->device().name;
    py::dict record;
    if (frames_ > 0) {
      const pipeline::FrameRecord& last = samples_[std::size_t((frames_ - 1) % stats_window)].record;
      record["frame"] = last.index;
      record["time_s"] = last.time;
      record["sim_ms"] = last.sim_ms;
      record["bake_ms"] = last.bake_ms;
      record["upload_ms"] = last.upload_ms;
      record["render_ms"] = last.render_ms;
      record["frame_ms"] = last.frame_ms;
      record["ffts"] = last.ffts;
      record["texels_refined"] = last.cones.texels_refined;
      record["pending"] = last.pending;
      record["cone_lag_frames"] = last.cone_lag;
      record["cone_lift"] = last.cone_lift;
      record["cones_updated"] = last.cones_updated;
    }
    out["last"] = record;
    return out;
  }

  const pipeline::Scene& scene() const { return scene_; }

 private:
  pipeline::Scene scene_;
  std::unique_ptr<render::Renderer> renderer_;
  std::unique_ptr<pipeline::FramePipeline> pipeline_;
  render::Frame frame_;
  struct Sample {
    pipeline::FrameRecord record;
    double wall_ms = 0.0;  // the call's, with the copy out
  };
  std::vector<Sample> samples_ = std::vector<Sample>(stats_window);  // the last frames, a ring
  long long frames_ = 0;
  long long allocations_after_first_ = 0;
};

}  // namespace

PYBIND11_MODULE(_displace, m) {
  m.doc() = "displace: dynamic height fields, cone maps, height queries and frames as numpy arrays";

  py::class_<Scene>(m, "Scene", "A scene: its keys read and set by their TOML names, checked as files are")
      .def_static(
          "builtin",
          [](const std::string& name) {
            return scene_or_value_error([&] { return pipeline::builtin_scene(name); });
          },
          py::arg("name"),
          "A built-in scene: 'water', 'calm', 'storm', 'harbour', 'ripples', 'ocean', 'bricks', 'cliff'")
      .def_static("builtin_names", &pipeline::builtin_scene_names, "The built-in scenes' names")
      .def_static(
          "load",
          [](const std::string& path) {
            return scene_or_value_error([&] { return pipeline::read_scene_file(path); });
          },
          py::arg("path"), "A scene file (TOML); relative paths in it are relative to the file")
      .def_static(
          "from_toml",
          [](const std::string& text, const std::string& name) {
            return scene_or_value_error([&] { return pipeline::parse_scene(text, name); });
          },
          py::arg("text"), py::arg("name") = "python", "A scene from TOML text; `name` names it in errors")
      .def(
          "to_toml", [](const Scene& s) { return pipeline::scene_toml(s.scene); },
          "The scene as a TOML file that Scene.from_toml reads back to the same scene")
      .def("__getitem__", &Scene::get, py::arg("key"),
           "A key by its TOML name: scene['ocean.wind_speed'] (m/s)")
      .def("__setitem__", &Scene::set, py::arg("key"), py::arg("value"),
           "Sets a key by its TOML name with the scene reader's checks (KeyError: unknown; ValueError: bad "
           "value)")
      .def(
          "copy", [](const Scene& s) { return Scene{s.scene}; }, "An independent copy")
      .def_property_readonly("name", [](const Scene& s) { return s.scene.name; })
      .def("__repr__", [](const Scene& s) { return "<displace.Scene '" + s.scene.name + "'>"; });

  m.def("heights", &heights, py::arg("scene"), py::arg("time") = py::none(), py::kw_only(),
        py::arg("normalized") = false,
        "The scene's heights at `time` seconds (default: its [time] start) as float32 (H, W): metres, as "
        "`displace sim` writes them, or with normalized=True the [0, 1] heights the renderer and the bakers "
        "take. Row 0 is y = 0.");
  m.def("bake", &bake_map, py::arg("heights"), py::arg("sectors") = 4, py::arg("cones") = "bilinear",
        py::arg("mode") = "budgeted", py::arg("budget_ms") = py::none(), py::arg("address") = "wrap",
        py::arg("tolerance") = 0.25f,
        "A cone map of [0, 1] heights (H, W) as `displace bake` makes it: returns (cones, apex, stats) - "
        "cones float32 (H, W, sectors) ratios, apex float32 (H, W) apex heights in [0, 1] for bilinear "
        "cones (None for centre cones), stats a dict with the keys of `bake --stats` (bake_ms in "
        "milliseconds). budget_ms: None is unlimited (mode 'budgeted' only).");
  m.def("query", &query, py::arg("scene"), py::arg("time"), py::arg("points"),
        "Heights at (N, 2) points (x, y in metres; patch widths for sources without metres) at `time` "
        "seconds, as `displace query`: a dict of float32 arrays height_m (N,) metres, z (N,) and normal "
        "(N, 3) in the renderer's world, displacement (N, 2) metres (choppy water; else 0).");

  py::class_<Pipeline>(m, "Pipeline", "The per-frame pipeline of a scene, as `displace sequence` runs it")
      .def(py::init<const Scene&, std::optional<std::pair<int, int>>, const std::string&>(), py::arg("scene"),
           py::arg("size") = py::none(), py::arg("backend") = "auto",
           "size: (width, height) pixels (default: the scene's camera); backend: where the sim and the "
           "bake run, 'auto', 'cpu' or 'device'")
      .def("frame", &Pipeline::frame, py::arg("n"),
           "Frame n (scene time start + n / fps) as uint8 (height, width, 4) RGBA, row 0 at the top")
      .def_property_readonly(
          "stats", &Pipeline::stats,
          "bench-frame --json's keys over the last frames (up to 1,000; milliseconds), and "
          "under 'last' the last frame's record")
      .def_property_readonly("scene", [](const Pipeline& p) { return Scene{p.scene()}; });
}
