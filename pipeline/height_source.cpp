// pipeline/height_source.cpp - the one source switch (height_source.h): the ocean (heights, choppy
// crests resampled onto the grid, foam from the Jacobian), sinusoids, bricks, cliff and height images.
#include "pipeline/height_source.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>

#include "pipeline/maps.h"

namespace displace::pipeline {
namespace {

// resample_displaced's Newton steps: at most 8, a block of texels stopping once every residual is
// within 3e-4 texel (0.003 leaves heights 2.5e-4 of their range off where J is small; this, 2.5e-5).
// On the water scene's ocean (choppiness 1.5) a block measures its residual 2.5 times on average.
constexpr int choppy_iterations = 8;
constexpr float choppy_settle = 3e-4f;  // texels

void check_map_size(const SourceSettings& settings) {
  const int n = settings.map_size;
  if (settings.kind != SourceKind::image && (n < min_map_size || n > max_map_size)) {
    throw SceneError("source.map_size must be between " + std::to_string(min_map_size) + " and " +
                     std::to_string(max_map_size));
  }
}

}  // namespace

unsigned scene_effects(const Scene& scene) {
  unsigned effects = effect_heights;
  if (scene.source == SourceKind::ocean && scene.ocean.choppiness > 0.0f) effects |= effect_choppy;
  if (scene.source == SourceKind::ocean && scene.foam && scene.material == render::Material::water) {
    effects |= effect_foam;
  }
  return effects;
}

SourceSettings source_settings(const Scene& scene) {
  SourceSettings settings;
  settings.kind = scene.source;
  settings.map_size = scene.map_size;
  settings.seed = scene.seed;
  settings.image = scene.image;
  settings.ocean = scene.ocean;
  settings.sinusoids = scene.sinusoids;
  settings.foam_start = scene.foam_coverage;
  return settings;
}

unsigned source_effects(SourceKind kind, unsigned effects) {
  return effect_heights | (kind == SourceKind::ocean ? effects : 0u);
}

struct HeightSource::State {
  SourceSettings settings;
  unsigned effects = effect_heights;
  HeightLoader loader;
  bool is_static = false;
  std::uint64_t static_version = 0;  // a static source's heights, drawn at the first make()
  sim::HeightMapping mapping{1.0f, 0.0f};
  std::optional<sim::Ocean> ocean;
  std::vector<sim::Wave> waves;

  // an image sequence's last frame and its version, to find what the next one changed
  std::vector<float> last_image;
  int last_width = 0, last_height = 0;
  std::uint64_t last_version = 0;

  void make_ocean(double time, HeightFrame& out);
  void make_image(long long frame_index, HeightFrame& out);
  void compare_with_last(HeightFrame& out);
};

HeightSource::HeightSource(const SourceSettings& settings, unsigned effects, HeightLoader loader)
    : state_(std::make_unique<State>()) {
  State& s = *state_;
  s.settings = settings;
  s.effects = source_effects(settings.kind, effects);
  s.loader = std::move(loader);
  check_map_size(settings);
  const int n = settings.map_size;
  try {
    switch (settings.kind) {
      case SourceKind::ocean: {
        sim::OceanParams params = settings.ocean;
        params.size = n;
        s.ocean.emplace(params);
        s.mapping = s.ocean->mapping();
        break;
      }
      case SourceKind::sinusoids:
        s.waves = sim::make_sinusoid_waves(settings.sinusoids);
        s.mapping = sim::sinusoid_mapping(s.waves);
        break;
      case SourceKind::bricks:
      case SourceKind::cliff: s.is_static = true; break;
      case SourceKind::image:
        if (!s.loader)
          throw SceneError("an image scene needs a height loader (the application's image reader)");
        s.is_static = !is_image_sequence(settings.image);
        break;
    }
  } catch (const std::invalid_argument& error) {
    throw SceneError(std::string("the scene's source: ") + error.what());
  }
}

HeightSource::~HeightSource() = default;
HeightSource::HeightSource(HeightSource&&) noexcept = default;
HeightSource& HeightSource::operator=(HeightSource&&) noexcept = default;

bool HeightSource::is_static() const { return state_->is_static; }
unsigned HeightSource::effects() const { return state_->effects; }
sim::HeightMapping HeightSource::mapping() const { return state_->mapping; }
double HeightSource::loop_error() const { return state_->ocean ? state_->ocean->loop_error() : 0.0; }

double source_time(const SourceSettings& settings, double time) {
  const double loop = settings.kind == SourceKind::ocean ? settings.ocean.loop_seconds : 0.0;
  return loop > 0.0 ? time - loop * std::floor(time / loop) : time;
}

void HeightSource::State::make_image(long long frame_index, HeightFrame& out) {
  out.field = loader(is_static ? settings.image : image_for_frame(settings.image, frame_index));
  out.raw = out.field.heights;
  out.clamped = 0;
}

namespace {

constexpr int change_tile = 16;  // texels a side of the squares an image's changes are found in

// The rectangles, on a grid of change_tile squares, that hold every texel where `now` differs from
// `before` (both W x H): each tile row's runs of changed squares, merged with the run above where it
// spans the same columns. Empty where nothing changed (`any` false) or more than half of the squares
// did (a whole bake is as cheap).
std::vector<bake::Rect> changed_rects(std::span<const float> before, std::span<const float> now, int W, int H,
                                      bool& any) {
  const int tiles_u = (W + change_tile - 1) / change_tile, tiles_v = (H + change_tile - 1) / change_tile;
  std::vector<std::uint8_t> changed(std::size_t(tiles_u) * std::size_t(tiles_v), 0);
  long long count = 0;
  for (int i = 0; i < H; ++i) {
    const std::size_t row = std::size_t(i) * std::size_t(W);
    for (int j = 0; j < W; ++j) {
      // bit for bit: -0 against 0 or one NaN against another is a change too
      if (std::bit_cast<std::uint32_t>(before[row + std::size_t(j)]) ==
          std::bit_cast<std::uint32_t>(now[row + std::size_t(j)]))
        continue;
      std::uint8_t& tile =
          changed[std::size_t(i / change_tile) * std::size_t(tiles_u) + std::size_t(j / change_tile)];
      count += tile == 0;
      tile = 1;
    }
  }
  any = count > 0;
  std::vector<bake::Rect> rects;
  if (count == 0 || 2 * count > static_cast<long long>(changed.size())) return rects;
  // the rectangles the tile row above reached (their runs in column order) and this row's
  std::vector<std::size_t> above, reached;
  for (int tv = 0; tv < tiles_v; ++tv) {
    const int y0 = tv * change_tile, y1 = std::min(H, y0 + change_tile);
    const std::uint8_t* row = changed.data() + std::size_t(tv) * std::size_t(tiles_u);
    reached.clear();
    std::size_t next_above = 0;
    for (int tu = 0; tu < tiles_u;) {
      if (!row[tu]) {
        ++tu;
        continue;
      }
      int end = tu;
      while (end < tiles_u && row[end]) ++end;
      const int x0 = tu * change_tile, x1 = std::min(W, end * change_tile);
      while (next_above < above.size() && rects[above[next_above]].x0 < x0) ++next_above;
      if (next_above < above.size() && rects[above[next_above]].x0 == x0 &&
          rects[above[next_above]].x1 == x1) {
        rects[above[next_above]].y1 = y1;  // the same columns as the run above: one rectangle
        reached.push_back(above[next_above]);
      } else {
        reached.push_back(rects.size());
        rects.push_back({x0, y0, x1, y1});
      }
      tu = end;
    }
    std::swap(above, reached);
  }
  return rects;
}

}  // namespace

// An image sequence's frame against the one before: the same content keeps its version; a change in
// places gets the rectangles that hold it.
void HeightSource::State::compare_with_last(HeightFrame& out) {
  const int W = out.field.width, H = out.field.height;
  out.dirty.clear();
  out.dirty_since = 0;
  bool any = true;
  if (last_version != 0 && W == last_width && H == last_height) {
    out.dirty = changed_rects(last_image, out.field.heights, W, H, any);
    if (!any) {
      out.version = last_version;
      return;
    }
    if (!out.dirty.empty()) out.dirty_since = last_version;
  }
  out.version = next_map_version();
  last_image.assign(out.field.heights.begin(), out.field.heights.end());
  last_width = W;
  last_height = H;
  last_version = out.version;
}

void HeightSource::State::make_ocean(double time, HeightFrame& out) {
  const int n = settings.map_size;
  const long long ffts = ocean->fft_count();
  const bool choppy = (effects & effect_choppy) != 0;
  const bool foam = (effects & effect_foam) != 0;
  ocean->evaluate(
      time, sim::ocean_heights | (choppy ? sim::ocean_displacement : 0u) | (foam ? sim::ocean_foam : 0u),
      out.ocean);
  out.ffts = ocean->fft_count() - ffts;
  if (foam) out.jacobian.resize(out.field.heights.size());
  if (choppy) {
    // the choppy crests: heights resampled where the displaced surface lands on the grid
    out.choppy_residual =
        sim::resample_displaced(n, ocean->patch_size(), out.ocean.height, out.ocean.displacement_x,
                                out.ocean.displacement_y, choppy_iterations, out.raw_values,
                                foam ? std::span<const float>(out.ocean.jacobian) : std::span<const float>{},
                                foam ? std::span<float>(out.jacobian) : std::span<float>{}, choppy_settle);
    out.raw = out.raw_values;
  } else {
    if (foam) out.jacobian = out.ocean.jacobian;
    out.raw = out.ocean.height;
  }
  out.clamped = sim::apply_mapping(mapping, out.raw, out.field.heights);
  if (foam) {
    out.foam.resize(out.jacobian.size());
    for (std::size_t t = 0; t < out.foam.size(); ++t) {
      out.foam[t] = std::clamp((settings.foam_start - out.jacobian[t]) / foam_width, 0.0f, 1.0f);
    }
    out.foam_version = next_map_version();
  }
}

bool simulates_on_device(SourceKind kind) {
  return kind == SourceKind::ocean || kind == SourceKind::sinusoids;
}

std::unique_ptr<sim::DeviceSim> make_device_sim(render::Renderer& renderer, const SourceSettings& settings,
                                                unsigned effects, DeviceSimInfo* info) {
  if (!simulates_on_device(settings.kind))
    throw SceneError("the device path simulates the ocean and sinusoids only");
  check_map_size(settings);
  try {
    if (settings.kind == SourceKind::sinusoids) {
      const std::vector<sim::Wave> waves = sim::make_sinusoid_waves(settings.sinusoids);
      const sim::HeightMapping mapping = sim::sinusoid_mapping(waves);
      if (info) *info = {mapping, 0.0};
      std::vector<float> values;
      for (const sim::Wave& wave : waves)
        values.insert(values.end(), {wave.kx, wave.ky, wave.amplitude, wave.omega, wave.phase});
      sim::SinusoidWavesView view;
      view.size = settings.map_size;
      view.patch_size = settings.sinusoids.patch_size;
      view.waves = values;
      view.scale = mapping.scale;
      view.bias = mapping.bias;
      return std::make_unique<sim::DeviceSim>(renderer.frames(), view);
    }
    sim::OceanParams params = settings.ocean;
    params.size = settings.map_size;
    const sim::Ocean ocean(params);
    const sim::Ocean::HalfSpectrum spectrum = ocean.half_spectrum();
    const sim::HeightMapping mapping = ocean.mapping();
    if (info) *info = {mapping, ocean.loop_error()};
    sim::OceanSpectrumView view;
    view.size = params.size;
    view.patch_size = params.patch_size;
    view.choppiness = params.choppiness;
    view.coefficients = spectrum.coefficients;
    view.omega = spectrum.omega;
    view.scale = mapping.scale;
    view.bias = mapping.bias;
    view.foam_start = settings.foam_start;
    view.foam_full = settings.foam_start - foam_width;
    const unsigned device_effects =
        ((effects & effect_choppy) && params.choppiness > 0.0f ? sim::device_choppy : 0u) |
        ((effects & effect_foam) ? sim::device_foam : 0u);
    return std::make_unique<sim::DeviceSim>(renderer.frames(), view, device_effects);
  } catch (const std::invalid_argument& error) {
    throw SceneError(std::string("the scene's source: ") + error.what());
  }
}

void HeightSource::make(double time, long long frame_index, HeightFrame& out) {
  State& s = *state_;
  if (s.is_static && s.static_version != 0 && out.version == s.static_version) return;  // made already
  out.ffts = 0;
  out.choppy_residual = 0.0;
  if (s.settings.kind == SourceKind::image) {
    s.make_image(frame_index, out);
  } else {
    const int n = s.settings.map_size;
    const std::size_t texels = std::size_t(n) * std::size_t(n);
    out.field.width = out.field.height = n;
    out.field.heights.resize(texels);
    out.raw_values.resize(texels);
    switch (s.settings.kind) {
      case SourceKind::ocean: s.make_ocean(time, out); break;
      case SourceKind::sinusoids:
        sim::sinusoid_heights(s.waves, s.settings.sinusoids.patch_size, time, n, n, out.raw_values);
        break;
      case SourceKind::bricks: sim::brick_heights(n, n, s.settings.seed, out.raw_values); break;
      case SourceKind::cliff: sim::cliff_heights(n, n, s.settings.seed, out.raw_values); break;
      case SourceKind::image: break;
    }
    if (s.settings.kind != SourceKind::ocean) {
      out.raw = out.raw_values;
      out.clamped = sim::apply_mapping(s.mapping, out.raw, out.field.heights);
    }
  }
  if (s.is_static) {
    if (s.static_version == 0) s.static_version = next_map_version();
    out.version = s.static_version;
  } else if (s.settings.kind == SourceKind::image) {
    s.compare_with_last(out);
  } else {
    out.version = next_map_version();
  }
}

}  // namespace displace::pipeline
