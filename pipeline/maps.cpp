// pipeline/maps.cpp - the renderer's maps baked on demand from one height field (maps.h).
#include "pipeline/maps.h"

#include <algorithm>
#include <atomic>
#include <optional>

namespace displace::pipeline {
void bake_distance(bake::HeightView heights, bake::Address address, int max_3d_side, DistanceMap& out) {
  const int side = std::min(distance_max_side, max_3d_side);
  out.width = std::min(heights.width, side);
  out.height = std::min(heights.height, side);
  out.depth = std::min(distance_slices, max_3d_side);
  out.values.resize(std::size_t(out.width) * std::size_t(out.height) * std::size_t(out.depth));
  bake::bake_distance_map(heights, address, {out.values.data(), out.width, out.height, out.depth});
}

std::uint64_t next_map_version() {
  static std::atomic<std::uint64_t> counter{0};
  return ++counter;
}

struct MapMaker::State {
  int max_3d_side = distance_max_side;
  render::HeightField field;
  std::uint64_t heights_version = 0;
  std::uint64_t heights_dirty_since = 0;  // the version `heights_dirty` is relative to
  std::vector<bake::Rect> heights_dirty;
  bake::Budget cone_budget;

  struct Cones {
    bool made = false;
    bool relaxed_made = false;
    bake::Address address = bake::Address::wrap;
    std::vector<float> ratios, apex, relaxed;
    std::uint64_t version = 0;
    std::optional<bake::BilinearBaker> baker;  // kept while the map size and address stay
    int baker_width = 0, baker_height = 0;
    bake::BakeStats stats;
  };
  std::array<Cones, 3> cones;  // by render::cone_slot

  bool pyramid_made = false;
  bake::DualMaxPyramid pyramid;
  bake::Address pyramid_address = bake::Address::wrap;
  std::uint64_t pyramid_version = 0;

  bool distance_made = false;
  bake::Address distance_address = bake::Address::wrap;
  DistanceMap distance;
  std::uint64_t distance_version = 0;

  render::MapSet set;

  void heights_changed() {
    heights_dirty_since = heights_version;
    heights_version = next_map_version();
    for (Cones& c : cones) {
      c.made = false;
      c.relaxed_made = false;
    }
    pyramid_made = false;
    distance_made = false;
  }
  bake::HeightView view() const { return {field.heights.data(), field.width, field.height}; }
};

MapMaker::MapMaker(int max_3d_side) : state_(std::make_unique<State>()) {
  state_->max_3d_side = std::max(1, max_3d_side);
}
MapMaker::~MapMaker() = default;
MapMaker::MapMaker(MapMaker&&) noexcept = default;
MapMaker& MapMaker::operator=(MapMaker&&) noexcept = default;

void MapMaker::set_heights(const render::HeightField& field, std::span<const bake::Rect> dirty) {
  render::HeightField copy = field;
  set_heights(std::move(copy), dirty);
}

void MapMaker::set_heights(render::HeightField&& field, std::span<const bake::Rect> dirty) {
  bake::validate_heights({field.heights.data(), field.width, field.height}, "the renderer's maps");
  State& s = *state_;
  const bool same_size = field.width == s.field.width && field.height == s.field.height;
  s.field = std::move(field);
  s.heights_dirty.assign(dirty.begin(), dirty.end());
  if (!same_size) s.heights_dirty.clear();
  s.heights_changed();
}

void MapMaker::set_cone_budget(const bake::Budget& budget) { state_->cone_budget = budget; }

const render::HeightField& MapMaker::heights() const { return state_->field; }

const bake::BakeStats& MapMaker::cone_stats(int sector_count) const {
  return state_->cones[std::size_t(render::cone_slot(sector_count))].stats;
}

const render::MapSet& MapMaker::maps(const render::MapNeeds& needs) {
  State& s = *state_;
  if (s.field.heights.empty()) throw bake::BakeError("maps: no heights were set");
  const int width = s.field.width, height = s.field.height;
  const std::size_t texels = s.field.heights.size();

  // cones (and the relaxed layer)
  if (needs.cone_sectors > 0) {
    State::Cones& c = s.cones[std::size_t(render::cone_slot(needs.cone_sectors))];
    if (!c.made || c.address != needs.cone_address) {
      if (!c.baker || c.address != needs.cone_address || c.baker_width != width || c.baker_height != height) {
        c.baker.emplace(width, height, needs.cone_sectors, needs.cone_address);
        c.baker_width = width;
        c.baker_height = height;
      }
      c.ratios.resize(texels * std::size_t(needs.cone_sectors));
      c.apex.resize(texels);
      c.stats = c.baker->bake(s.view(), s.cone_budget, {c.ratios.data(), width, height, needs.cone_sectors},
                              c.apex);
      c.made = true;
      c.relaxed_made = false;
      c.address = needs.cone_address;
      c.version = next_map_version();
    }
    if (needs.relaxed && !c.relaxed_made) {
      c.relaxed.resize(texels);
      bake::bake_relaxed(s.view(), needs.cone_address, {c.relaxed.data(), width, height, 1});
      c.relaxed_made = true;
      c.version = next_map_version();
    }
  }

  // the dual max pyramid
  if (needs.max_pyramid && (!s.pyramid_made || s.pyramid_address != needs.address)) {
    s.pyramid = bake::build_dual_max_pyramid(s.view(), needs.address);
    s.pyramid_address = needs.address;
    s.pyramid_made = true;
    s.pyramid_version = next_map_version();
  }

  // the distance map
  if (needs.distance && (!s.distance_made || s.distance_address != needs.address)) {
    bake_distance(s.view(), needs.address, s.max_3d_side, s.distance);
    s.distance_address = needs.address;
    s.distance_made = true;
    s.distance_version = next_map_version();
  }

  // the set: every map made for these heights
  render::MapSet& set = s.set;
  set = render::MapSet{};
  set.width = width;
  set.height = height;
  set.heights = s.field.heights;
  set.heights_version = s.heights_version;
  set.heights_dirty = s.heights_dirty;
  set.heights_dirty_since = s.heights_dirty_since;
  const int sector_counts[3] = {1, 4, 8};
  for (std::size_t slot = 0; slot < s.cones.size(); ++slot) {
    const State::Cones& c = s.cones[slot];
    if (!c.made) continue;
    render::ConeMapView& view = set.cones[slot];
    view.sector_count = sector_counts[slot];
    view.address = c.address;
    view.ratios = c.ratios;
    view.apex = c.apex;
    if (c.relaxed_made) view.relaxed = c.relaxed;
    view.version = c.version;
  }
  if (s.pyramid_made) set.max_pyramid = {&s.pyramid, s.pyramid_address, s.pyramid_version};
  if (s.distance_made) {
    set.distance = {s.distance.width,   s.distance.height, s.distance.depth,
                    s.distance_address, s.distance.values, s.distance_version};
  }
  return set;
}

render::Frame render_with_maps(render::Renderer& renderer, MapMaker& maps, const render::View& view,
                               const render::MethodSettings& method, unsigned outputs) {
  renderer.set_maps(maps.maps_for(method.method, view));
  return renderer.render(view, method, outputs);
}

}  // namespace displace::pipeline
