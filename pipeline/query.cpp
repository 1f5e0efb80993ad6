// pipeline/query.cpp - height queries (query.h): the bilinear surface of the heights the renderer
// samples, evaluated where asked. The one fact to know: texel (i, j) sits at the centre
// u = (j + 1/2) / W, v = (i + 1/2) / H, so a point's cell starts at floor(u W - 1/2).
#include "pipeline/query.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace displace::pipeline {
namespace {

constexpr std::size_t points_per_task = 1 << 14;  // queries per TBB task

// The four texels around a point and its place between them, along one axis.
struct Axis {
  int first, second;
  double fraction;
};
Axis axis_at(double texel_coordinate, int size, bool wrap) {
  const double floor_value = std::floor(texel_coordinate);
  const double fraction = texel_coordinate - floor_value;
  if (wrap) {
    const double wrapped = floor_value - double(size) * std::floor(floor_value / double(size));
    int first = int(wrapped);
    if (first >= size) first -= size;  // the division's rounding at the upper end
    return {first, first + 1 == size ? 0 : first + 1, fraction};
  }
  // clamp: the edge texels extended over the half-texel border and beyond
  if (floor_value < 0.0) return {0, 0, 0.0};
  if (floor_value >= double(size - 1)) return {size - 1, size - 1, 0.0};
  const int first = int(floor_value);
  return {first, first + 1, fraction};
}

}  // namespace

struct HeightQuery::State {
  Scene scene;
  HeightSource source;
  HeightFrame frame;
  bool made = false;
  double made_time = 0.0;
  long long heights_made = 0;
  bool choppy = false;
  double patch = 1.0;                                 // metres a patch covers
  std::vector<float> displacement_x, displacement_y;  // choppy: resampled through the same p
  State(const Scene& s, HeightLoader loader)
      : scene(s), source(source_settings(s), scene_effects(s) & ~unsigned(effect_foam), std::move(loader)) {}
  void make(double time);
};

void HeightQuery::State::make(double time) {
  if (made && (source.is_static() || made_time == time)) return;
  source.make(source_time(source_settings(scene), time), 0, frame);
  ++heights_made;
  made = true;
  made_time = time;
  if (choppy) {
    // the displacement of the water at each grid position x: D(p) with p + D(p) = x, resampled as the
    // heights were (pipeline/height_source.cpp's settings)
    const int n = frame.field.width;
    const std::size_t texels = std::size_t(n) * std::size_t(n);
    displacement_x.resize(texels);
    displacement_y.resize(texels);
    std::vector<float>& scratch = frame.raw_values;  // resampled heights again: the same as raw
    for (int axis = 0; axis < 2; ++axis) {
      const std::vector<float>& field = axis == 0 ? frame.ocean.displacement_x : frame.ocean.displacement_y;
      std::vector<float>& out = axis == 0 ? displacement_x : displacement_y;
      sim::resample_displaced(n, scene.ocean.patch_size, frame.ocean.height, frame.ocean.displacement_x,
                              frame.ocean.displacement_y, 8, scratch, field, out, 3e-4f);
    }
  }
}

HeightQuery::HeightQuery(const Scene& scene, HeightLoader loader)
    : state_(std::make_unique<State>(scene, std::move(loader))) {
  State& s = *state_;
  s.choppy = (s.source.effects() & effect_choppy) != 0;
  s.patch = scene.source == SourceKind::ocean       ? double(scene.ocean.patch_size)
            : scene.source == SourceKind::sinusoids ? double(scene.sinusoids.patch_size)
                                                    : 1.0;
}

HeightQuery::~HeightQuery() = default;
HeightQuery::HeightQuery(HeightQuery&&) noexcept = default;
HeightQuery& HeightQuery::operator=(HeightQuery&&) noexcept = default;

double HeightQuery::patch_metres() const { return state_->patch; }
long long HeightQuery::heights_made() const { return state_->heights_made; }

void HeightQuery::query(std::span<const QueryPoint> points, double time, QueryResult& out) {
  State& s = *state_;
  if (!std::isfinite(time)) throw SceneError("a height query's time must be finite");
  s.make(time);
  const int width = s.frame.field.width, height = s.frame.field.height;
  const float* h = s.frame.field.heights.data();
  const bool wrap = s.scene.address == bake::Address::wrap;
  const sim::HeightMapping mapping = s.source.mapping();
  const double depth = s.scene.depth_scale, tile = s.scene.tile;
  const std::size_t count = points.size();
  out.height_m.resize(count);
  out.z.resize(count);
  out.normal.resize(count);
  out.displacement.resize(count);
  const float* dx = s.choppy ? s.displacement_x.data() : nullptr;
  const float* dy = s.choppy ? s.displacement_y.data() : nullptr;
  auto one = [&](std::size_t n) {
    const QueryPoint& p = points[n];
    const double u = p.x / s.patch, v = p.y / s.patch;
    if (!std::isfinite(u) || !std::isfinite(v)) {
      out.height_m[n] = out.z[n] = std::numeric_limits<float>::quiet_NaN();
      out.normal[n] = glm::vec3(std::numeric_limits<float>::quiet_NaN());
      out.displacement[n] = glm::vec2(std::numeric_limits<float>::quiet_NaN());
      return;
    }
    const Axis ax = axis_at(u * width - 0.5, width, wrap), ay = axis_at(v * height - 0.5, height, wrap);
    const std::size_t r0 = std::size_t(ay.first) * std::size_t(width),
                      r1 = std::size_t(ay.second) * std::size_t(width);
    const double a = h[r0 + std::size_t(ax.first)], b = h[r0 + std::size_t(ax.second)];
    const double c = h[r1 + std::size_t(ax.first)], d = h[r1 + std::size_t(ax.second)];
    const double top = a + (b - a) * ax.fraction, bottom = c + (d - c) * ax.fraction;
    const double value = top + (bottom - top) * ay.fraction;
    // the bilinear patch's slopes per uv unit (0 across a clamped border)
    const double along_u =
        (ax.first == ax.second ? 0.0 : ((b - a) + ((d - c) - (b - a)) * ay.fraction)) * width;
    const double along_v = (ay.first == ay.second ? 0.0 : (bottom - top)) * height;
    out.height_m[n] = float((value - double(mapping.bias)) / double(mapping.scale));
    out.z[n] = float(depth * (value - 1.0));
    // world: x = u / tile, z = D (h - 1), so dz/dx = D tile dh/du
    out.normal[n] =
        glm::vec3(glm::normalize(glm::dvec3(-depth * tile * along_u, -depth * tile * along_v, 1.0)));
    if (dx) {
      auto sample = [&](const float* field) {
        const double fa = field[r0 + std::size_t(ax.first)], fb = field[r0 + std::size_t(ax.second)];
        const double fc = field[r1 + std::size_t(ax.first)], fd = field[r1 + std::size_t(ax.second)];
        const double ft = fa + (fb - fa) * ax.fraction, fbm = fc + (fd - fc) * ax.fraction;
        return float(ft + (fbm - ft) * ay.fraction);
      };
      out.displacement[n] = glm::vec2(sample(dx), sample(dy));
    } else {
      out.displacement[n] = glm::vec2(0.0f);
    }
  };
  if (count < points_per_task) {
    for (std::size_t n = 0; n < count; ++n) one(n);
  } else {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, count, points_per_task),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                        for (std::size_t n = range.begin(); n != range.end(); ++n) one(n);
                      });
  }
}

}  // namespace displace::pipeline
