// pipeline/maps.cpp - the one map maker (maps.h): cone maps (whole, refined across frames or lagged),
// the relaxed layer, the dual max pyramid and the distance map, per slot, from one height field.
#include "pipeline/maps.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <optional>

#include "bake/lagged.h"

namespace displace::pipeline {
namespace {

constexpr int sector_counts[3] = {1, 4, 8};  // by render::cone_slot

}  // namespace

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

namespace {

// One slot's cone map of one sector count. `made_for` and `relaxed_for` name the heights they were
// made from (0: none); `served` is what the set hands over: `ratios`, or a lagged map's.
struct SlotCones {
  std::uint64_t made_for = 0, relaxed_for = 0;
  bake::Address address = bake::Address::wrap;
  std::vector<float> ratios, apex, relaxed;
  std::span<const float> served;
  std::uint64_t version = 0;
  bake::BakeStats stats;
};

// One slot's levels of detail (render::MapSet::levels): levels 1 .. count of the heights of version
// `made_for` (0: none), each with its bilinear cone map of `sectors`.
struct SlotLevels {
  std::uint64_t made_for = 0;
  int count = 0, sectors = 0;
  bake::Address address = bake::Address::wrap;
  std::array<std::vector<float>, bake::max_detail_levels> heights, ratios, apex, slopes;
  std::uint64_t version = 0;
};

// The maps of one frame in flight.
struct Slot {
  SlotLevels levels;
  std::array<SlotCones, 3> cones;  // by render::cone_slot
  std::uint64_t pyramid_for = 0;
  bake::Address pyramid_address = bake::Address::wrap;
  bake::DualMaxPyramid pyramid;
  std::uint64_t pyramid_version = 0;
  std::uint64_t distance_for = 0;
  bake::Address distance_address = bake::Address::wrap;
  DistanceMap distance;
  std::uint64_t distance_version = 0;
  render::MapSet set;
};

// The baker of one sector count, kept between frames with where it emitted last.
struct ConeBaker {
  std::optional<bake::BilinearBaker> baker;
  int width = 0, height = 0;
  bake::Address address = bake::Address::wrap;
  int last_slot = -1;        // the slot it emitted into last (refinement continues from its map)
  std::uint64_t held = 0;    // the heights version the baker holds (bake, update; 0: none, or lagged)
  bake::LaggedCones lagged;  // lagged maps (bake/lagged.h)
};

bool holds(std::uint64_t made_for, bake::Address address, const MapHeights& heights, bake::Address wanted) {
  return made_for == heights.version && address == wanted;
}

// Heights that changed only in their dirty rectangles since the heights version a baker holds: what
// it may update rather than bake whole (0: it holds none).
bool updates(std::uint64_t held, const MapHeights& heights) {
  return !heights.dirty.empty() && held != 0 && held == heights.dirty_since;
}

bool holds_levels(const SlotLevels& levels, const MapHeights& heights, const render::MapNeeds& needs) {
  return levels.made_for == heights.version && levels.sectors == needs.cone_sectors &&
         levels.address == needs.cone_address;
}

// The levels' cone bakers (one per level, for one sector count and size), kept between frames.
struct LevelBakers {
  std::array<std::optional<bake::BilinearBaker>, bake::max_detail_levels> bakers;
  int width = 0, height = 0, sectors = 0;
  bake::Address address = bake::Address::wrap;
  std::uint64_t held = 0;  // the heights version whose levels the bakers hold (0: none)
};

// What the levels' bakes may spend after the level-0 bake spent `spent` of the frame's budget; with
// nothing left each level gets its baker's first stage, which is always complete and conservative.
void spend(bake::Budget& budget, const bake::BakeStats& spent) {
  budget.milliseconds = std::max(0.0, budget.milliseconds - spent.milliseconds);
  if (budget.max_work >= 0) budget.max_work = std::max(0ll, budget.max_work - spent.work);
}

}  // namespace

struct MapMaker::State {
  int max_3d_side = distance_max_side;
  std::vector<Slot> slots;
  std::array<ConeBaker, 3> bakers;  // by render::cone_slot
  LevelBakers level_bakers;
  std::vector<float> slope_scratch;     // level 0's gradient moments while the levels are made
  std::vector<bake::Rect> level_rects;  // a level's dirty rectangles while the levels are updated

  // the one-off heights (slot 0)
  render::HeightField field;
  std::uint64_t heights_version = 0;
  std::uint64_t heights_dirty_since = 0;  // the version `heights_dirty` is relative to
  std::vector<bake::Rect> heights_dirty;
  bake::Budget cone_budget;

  ConeBaker& baker_for(const render::MapNeeds& needs, int width, int height);
  void copy_from_other_slots(int slot, const MapHeights& heights, const render::MapNeeds& needs);
  void make_cones(int slot, const MapHeights& heights, const render::MapNeeds& needs,
                  const ConeSchedule& schedule, MapStats& stats);
  void make_lagged(int slot, const MapHeights& heights, const render::MapNeeds& needs,
                   const ConeSchedule& schedule, MapStats& stats);
  // Returns whether the levels were updated in the heights' dirty rectangles (not made whole, not kept).
  bool make_levels(Slot& slot, const MapHeights& heights, const render::MapNeeds& needs, bake::Budget budget);
  void make_pyramid_and_distance(Slot& slot, const MapHeights& heights, const render::MapNeeds& needs);
  const render::MapSet& assemble(Slot& slot, const MapHeights& heights);
};

namespace {

bake::HeightView view_of(const MapHeights& heights) {
  return {heights.heights.data(), heights.width, heights.height};
}

}  // namespace

ConeBaker& MapMaker::State::baker_for(const render::MapNeeds& needs, int width, int height) {
  ConeBaker& k = bakers[std::size_t(render::cone_slot(needs.cone_sectors))];
  if (!k.baker || k.width != width || k.height != height || k.address != needs.cone_address) {
    k.baker.emplace(width, height, needs.cone_sectors, needs.cone_address);
    k.width = width;
    k.height = height;
    k.address = needs.cone_address;
    k.last_slot = -1;
    k.held = 0;
  }
  return k;
}

// Maps another slot made for the same heights (a static source's, two frames in flight): copied
// rather than baked again, the cone baker's progress with them.
void MapMaker::State::copy_from_other_slots(int index, const MapHeights& heights,
                                            const render::MapNeeds& needs) {
  Slot& slot = slots[std::size_t(index)];
  for (std::size_t other_index = 0; other_index < slots.size(); ++other_index) {
    if (int(other_index) == index) continue;
    const Slot& other = slots[other_index];
    if (needs.cone_sectors > 0) {
      const std::size_t cone_slot = std::size_t(render::cone_slot(needs.cone_sectors));
      SlotCones& cones = slot.cones[cone_slot];
      const SlotCones& theirs = other.cones[cone_slot];
      if (!holds(cones.made_for, cones.address, heights, needs.cone_address) &&
          holds(theirs.made_for, theirs.address, heights, needs.cone_address) &&
          theirs.served.data() == theirs.ratios.data()) {
        cones.ratios = theirs.ratios;
        cones.apex = theirs.apex;
        cones.served = cones.ratios;
        cones.relaxed = theirs.relaxed;
        cones.relaxed_for = theirs.relaxed_for;
        cones.made_for = theirs.made_for;
        cones.address = theirs.address;
        cones.version = theirs.version;
        cones.stats = theirs.stats;
      }
    }
    if (needs.levels && !holds_levels(slot.levels, heights, needs) &&
        holds_levels(other.levels, heights, needs))
      slot.levels = other.levels;
    if (needs.max_pyramid && !holds(slot.pyramid_for, slot.pyramid_address, heights, needs.address) &&
        holds(other.pyramid_for, other.pyramid_address, heights, needs.address)) {
      slot.pyramid = other.pyramid;
      slot.pyramid_for = other.pyramid_for;
      slot.pyramid_address = other.pyramid_address;
      slot.pyramid_version = other.pyramid_version;
    }
    if (needs.distance && !holds(slot.distance_for, slot.distance_address, heights, needs.address) &&
        holds(other.distance_for, other.distance_address, heights, needs.address)) {
      slot.distance = other.distance;
      slot.distance_for = other.distance_for;
      slot.distance_address = other.distance_address;
      slot.distance_version = other.distance_version;
    }
  }
}

// A lagged frame: the stage under way advances within the budget (a new one starts on this frame's
// heights when none is), and the map made last is served, raised (bake::LaggedCones).
void MapMaker::State::make_lagged(int index, const MapHeights& heights, const render::MapNeeds& needs,
                                  const ConeSchedule& schedule, MapStats& stats) {
  const int sectors = needs.cone_sectors;
  ConeBaker& k = baker_for(needs, heights.width, heights.height);
  SlotCones& cones = slots[std::size_t(index)].cones[std::size_t(render::cone_slot(sectors))];
  const bake::LaggedCones::Served served =
      k.lagged.advance(*k.baker, view_of(heights), sectors, schedule.budget, schedule.lag_frames,
                       schedule.frame_index, cones.apex);
  cones.served = served.ratios;
  cones.stats = served.stats;
  cones.made_for = heights.version;
  cones.address = needs.cone_address;
  cones.relaxed_for = 0;
  cones.version = next_map_version();
  k.last_slot = index;
  k.held = 0;  // the baker holds the heights of the map in progress
  stats.cone_lag = served.age;
  stats.cone_lift = served.lift;
}

void MapMaker::State::make_cones(int index, const MapHeights& heights, const render::MapNeeds& needs,
                                 const ConeSchedule& schedule, MapStats& stats) {
  const int width = heights.width, height = heights.height, sectors = needs.cone_sectors;
  const std::size_t texels = heights.heights.size();
  const std::size_t cone_slot = std::size_t(render::cone_slot(sectors));
  SlotCones& cones = slots[std::size_t(index)].cones[cone_slot];
  ConeBaker& k = baker_for(needs, width, height);
  if (schedule.lag_frames > 0) {
    make_lagged(index, heights, needs, schedule, stats);
  } else if (!holds(cones.made_for, cones.address, heights, needs.cone_address)) {
    // new heights: changed only in their dirty rectangles since the heights the baker holds, an
    // update (stage L again, and the searched ratios the change cannot have lowered kept); else a
    // whole bake. Either within the budget.
    cones.ratios.resize(texels * std::size_t(sectors));
    cones.apex.resize(texels);
    const bake::ConeView out{cones.ratios.data(), width, height, sectors};
    const bool patch = updates(k.held, heights);
    k.held = 0;  // until the bake returns (one that throws leaves no claim behind)
    cones.stats = patch ? k.baker->update(view_of(heights), heights.dirty, schedule.budget, out, cones.apex)
                        : k.baker->bake(view_of(heights), schedule.budget, out, cones.apex);
    k.held = heights.version;
    stats.cones_updated = patch;
    cones.served = cones.ratios;
    cones.made_for = heights.version;
    cones.address = needs.cone_address;
    cones.relaxed_for = 0;
    cones.version = next_map_version();
    k.last_slot = index;
  } else if (schedule.refine && k.baker->pending() > 0 && k.last_slot >= 0 &&
             slots[std::size_t(k.last_slot)].cones[cone_slot].made_for == heights.version) {
    // the same heights: refinement goes on where the baker stopped, from the map it emitted last
    if (k.last_slot != index) {
      const SlotCones& last = slots[std::size_t(k.last_slot)].cones[cone_slot];
      std::copy(last.ratios.begin(), last.ratios.end(), cones.ratios.begin());
      std::copy(last.apex.begin(), last.apex.end(), cones.apex.begin());
    }
    cones.stats = k.baker->refine(schedule.budget, {cones.ratios.data(), width, height, sectors}, cones.apex);
    cones.version = next_map_version();
    k.last_slot = index;
  }
  if (needs.relaxed && cones.relaxed_for != heights.version) {
    cones.relaxed.resize(texels);
    bake::bake_relaxed(view_of(heights), needs.cone_address, {cones.relaxed.data(), width, height, 1});
    cones.relaxed_for = heights.version;
    cones.version = next_map_version();
  }
  stats.cones = cones.stats;
  stats.pending = k.baker->pending();
}

// The levels of detail of new heights: each level the box mean of the one below
// (bake::downsample_heights), its cones baked by that level's BilinearBaker within what is left of
// the budget. Made whole when the heights change and kept (not refined) while they stay.
bool MapMaker::State::make_levels(Slot& slot, const MapHeights& heights, const render::MapNeeds& needs,
                                  bake::Budget budget) {
  SlotLevels& levels = slot.levels;
  if (holds_levels(levels, heights, needs)) return false;
  const int sectors = needs.cone_sectors;
  LevelBakers& k = level_bakers;
  if (k.width != heights.width || k.height != heights.height || k.sectors != sectors ||
      k.address != needs.cone_address) {
    for (auto& baker : k.bakers) baker.reset();
    k.held = 0;
    k.width = heights.width;
    k.height = heights.height;
    k.sectors = sectors;
    k.address = needs.cone_address;
  }
  levels.count = bake::detail_level_count(heights.width, heights.height);
  // heights changed only in their dirty rectangles since the levels the bakers hold: a level's
  // texel is the mean of a 2 x 2 block of the one below, so its rectangles are those below halved
  // (rounded outwards), and each level's cones are updated there
  const bool patch = updates(k.held, heights);
  std::vector<bake::Rect>& rects = level_rects;
  rects.assign(heights.dirty.begin(), heights.dirty.end());
  k.held = 0;  // until every level is made (a bake that throws leaves no claim behind)
  bake::HeightView below = view_of(heights);
  std::vector<float>& level0_slopes = slope_scratch;
  if (levels.count > 0) {
    level0_slopes.resize(std::size_t(heights.width) * std::size_t(heights.height) * 3);
    bake::gradient_moments(below, level0_slopes);
  }
  for (int level = 1; level <= levels.count; ++level) {
    const auto index = std::size_t(level - 1);
    const int width = heights.width >> level, height = heights.height >> level;
    const std::size_t texels = std::size_t(width) * std::size_t(height);
    levels.heights[index].resize(texels);
    bake::downsample_heights(below, levels.heights[index]);
    levels.slopes[index].resize(texels * 3);
    bake::downsample_moments(index == 0 ? std::span<const float>(level0_slopes) : levels.slopes[index - 1],
                             below.width, below.height, levels.slopes[index]);
    below = {levels.heights[index].data(), width, height};
    levels.ratios[index].resize(texels * std::size_t(sectors));
    levels.apex[index].resize(texels);
    if (!k.bakers[index]) k.bakers[index].emplace(width, height, sectors, needs.cone_address);
    for (bake::Rect& rect : rects) rect = {rect.x0 / 2, rect.y0 / 2, (rect.x1 + 1) / 2, (rect.y1 + 1) / 2};
    const bake::ConeView out{levels.ratios[index].data(), width, height, sectors};
    const bake::BakeStats stats = patch
                                      ? k.bakers[index]->update(below, rects, budget, out, levels.apex[index])
                                      : k.bakers[index]->bake(below, budget, out, levels.apex[index]);
    spend(budget, stats);
  }
  k.held = heights.version;
  levels.made_for = heights.version;
  levels.sectors = sectors;
  levels.address = needs.cone_address;
  levels.version = next_map_version();
  return patch && levels.count > 0;
}

void MapMaker::State::make_pyramid_and_distance(Slot& slot, const MapHeights& heights,
                                                const render::MapNeeds& needs) {
  if (needs.max_pyramid && !holds(slot.pyramid_for, slot.pyramid_address, heights, needs.address)) {
    slot.pyramid = bake::build_dual_max_pyramid(view_of(heights), needs.address);
    slot.pyramid_for = heights.version;
    slot.pyramid_address = needs.address;
    slot.pyramid_version = next_map_version();
  }
  if (needs.distance && !holds(slot.distance_for, slot.distance_address, heights, needs.address)) {
    bake_distance(view_of(heights), needs.address, max_3d_side, slot.distance);
    slot.distance_for = heights.version;
    slot.distance_address = needs.address;
    slot.distance_version = next_map_version();
  }
}

// The set: every map the slot holds for these heights.
const render::MapSet& MapMaker::State::assemble(Slot& slot, const MapHeights& heights) {
  render::MapSet& set = slot.set;
  set = render::MapSet{};
  set.width = heights.width;
  set.height = heights.height;
  set.heights = heights.heights;
  set.heights_version = heights.version;
  set.heights_dirty = heights.dirty;
  set.heights_dirty_since = heights.dirty_since;
  for (std::size_t cone_slot = 0; cone_slot < slot.cones.size(); ++cone_slot) {
    const SlotCones& c = slot.cones[cone_slot];
    if (c.made_for != heights.version) continue;
    render::ConeMapView& view = set.cones[cone_slot];
    view.sector_count = sector_counts[cone_slot];
    view.address = c.address;
    view.ratios = c.served;
    view.apex = c.apex;
    if (c.relaxed_for == heights.version) view.relaxed = c.relaxed;
    view.version = c.version;
  }
  if (slot.pyramid_for == heights.version) {
    set.max_pyramid = {&slot.pyramid, slot.pyramid_address, slot.pyramid_version};
  }
  if (slot.distance_for == heights.version) {
    set.distance = {slot.distance.width,   slot.distance.height, slot.distance.depth,
                    slot.distance_address, slot.distance.values, slot.distance_version};
  }
  const SlotLevels& levels = slot.levels;
  if (levels.made_for == heights.version && levels.count > 0) {
    set.level_count = levels.count;
    set.level_sectors = levels.sectors;
    set.level_address = levels.address;
    for (std::size_t index = 0; index < std::size_t(levels.count); ++index)
      set.levels[index] = {levels.heights[index], levels.ratios[index], levels.apex[index],
                           levels.slopes[index]};
    set.levels_version = levels.version;
  }
  if (!heights.foam.empty()) {
    set.foam = heights.foam;
    set.foam_version = heights.foam_version;
  }
  return set;
}

MapMaker::MapMaker(int max_3d_side, int frames_in_flight) : state_(std::make_unique<State>()) {
  state_->max_3d_side = std::max(1, max_3d_side);
  state_->slots.resize(std::size_t(std::max(1, frames_in_flight)));
}
MapMaker::~MapMaker() = default;
MapMaker::MapMaker(MapMaker&&) noexcept = default;
MapMaker& MapMaker::operator=(MapMaker&&) noexcept = default;

const render::MapSet& MapMaker::make(int slot, const MapHeights& heights, const render::MapNeeds& needs,
                                     const ConeSchedule& schedule, MapStats& stats) {
  State& s = *state_;
  stats = MapStats{};
  s.copy_from_other_slots(slot, heights, needs);
  if (needs.cone_sectors > 0) s.make_cones(slot, heights, needs, schedule, stats);
  Slot& made = s.slots[std::size_t(slot)];
  if (needs.levels && needs.cone_sectors > 0) {
    // what the level-0 cones left of the budget (a lagged frame's stage took its share: none)
    bake::Budget left = schedule.budget;
    if (schedule.lag_frames > 0) {
      left.milliseconds = 0.0;
      left.max_work = 0;
    } else {
      spend(left, stats.cones);
    }
    stats.levels_updated = s.make_levels(made, heights, needs, left);
  }
  s.make_pyramid_and_distance(made, heights, needs);
  return s.assemble(made, heights);
}

const render::MapSet& MapMaker::made(int slot) const { return state_->slots[std::size_t(slot)].set; }

void MapMaker::reserve(const render::MapNeeds& needs, int width, int height) {
  if (needs.cone_sectors > 0) state_->baker_for(needs, width, height);
}

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
  s.heights_dirty_since = s.heights_version;
  s.heights_version = next_map_version();
}

void MapMaker::set_cone_budget(const bake::Budget& budget) { state_->cone_budget = budget; }

const render::HeightField& MapMaker::heights() const { return state_->field; }

const bake::BakeStats& MapMaker::cone_stats(int sector_count) const {
  return state_->slots[0].cones[std::size_t(render::cone_slot(sector_count))].stats;
}

MapHeights map_heights(const render::HeightField& field, std::uint64_t version) {
  MapHeights heights;
  heights.heights = field.heights;
  heights.width = field.width;
  heights.height = field.height;
  heights.version = version;
  return heights;
}

const render::MapSet& MapMaker::maps(const render::MapNeeds& needs) {
  State& s = *state_;
  if (s.field.heights.empty()) throw bake::BakeError("maps: no heights were set");
  MapHeights heights = map_heights(s.field, s.heights_version);
  heights.dirty = s.heights_dirty;
  heights.dirty_since = s.heights_dirty_since;
  ConeSchedule schedule;
  schedule.budget = s.cone_budget;
  MapStats stats;
  return make(0, heights, needs, schedule, stats);
}

render::Frame render_with_maps(render::Renderer& renderer, MapMaker& maps, const render::View& view,
                               const render::MethodSettings& method, unsigned outputs) {
  renderer.set_maps(maps.maps_for(method.method, view));
  return renderer.render(view, method, outputs);
}

}  // namespace displace::pipeline
