// tests/pipeline/maps_test.cpp - the map maker's cone maps over heights that change in a patch
// (pipeline/maps.h): updated there rather than baked whole, and held to the contract of a whole bake
// by brute force; and an image sequence's frames saying where they changed (pipeline/height_source.h).
#include "pipeline/maps.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "pipeline/height_source.h"
#include "tests/bake/bake_checks.h"
#include "tests/test_maps.h"

namespace displace::pipeline {
namespace {

using bake::Address;
using test::Map;

constexpr int side = 128;

struct Made {
  bake::ConeMap cones;
  std::vector<float> apex;
  bake::BakeStats stats;
};

Made make(MapMaker& maps, const render::MapNeeds& needs) {
  const render::MapSet& set = maps.maps(needs);
  const render::ConeMapView& view = set.cones[std::size_t(render::cone_slot(needs.cone_sectors))];
  Made made;
  made.cones = {side, side, needs.cone_sectors, {view.ratios.begin(), view.ratios.end()}};
  made.apex.assign(view.apex.begin(), view.apex.end());
  made.stats = maps.cone_stats(needs.cone_sectors);
  return made;
}

render::HeightField field_of(const Map& map) { return {map.width, map.height, map.values}; }

bool operator==(const bake::Rect& a, const bake::Rect& b) {
  return a.x0 == b.x0 && a.y0 == b.y0 && a.x1 == b.x1 && a.y1 == b.y1;
}

// A patch raised and lowered in a checkerboard (a raise shrinks cones that see it, a lowering
// unblocks them).
Map with_patch(const Map& map, const bake::Rect& patch, float by) {
  Map changed = map;
  for (int i = patch.y0; i < patch.y1; ++i)
    for (int j = patch.x0; j < patch.x1; ++j)
      changed.at(i, j) = std::clamp(changed.at(i, j) + ((i + j) % 2 != 0 ? by : -by), 0.0f, 1.0f);
  return changed;
}

// Heights changed only inside their dirty rectangles since the heights the cone baker holds: the cone
// map is BilinearBaker::update's (bit for bit what the baker gives when called directly; its
// conservativeness is the baker's own test, UpdateChainsStayConservative), with a fraction of a
// whole bake's searches, and about the whole bake's mean ratio. Dirty rectangles relative to heights the
// baker does not hold get a whole bake; heights changed outside them get one clear error.
TEST(MapMaker, HeightsChangedInAPatchUpdateTheConesThere) {
  const Map map = test::make_ocean(side, side);
  const bake::Rect patch{40, 30, 46, 36};
  const Map changed = with_patch(map, patch, 0.1f);
  for (const int sectors : {1, 4, 8}) {
    const std::string at = std::to_string(sectors) + " sectors";
    render::MapNeeds needs;
    needs.cone_sectors = sectors;
    MapMaker maps;
    maps.set_heights(field_of(map));
    const Made whole = make(maps, needs);
    maps.set_heights(field_of(changed), std::span<const bake::Rect>(&patch, 1));
    const Made updated = make(maps, needs);

    bake::BilinearBaker baker(side, side, sectors, Address::wrap);
    bake::ConeMap direct = bake::make_cone_map(map, sectors);
    std::vector<float> apex(std::size_t(side) * side);
    baker.bake(bake::view_of(map), {}, direct.view(), apex);
    const bake::BakeStats stats =
        baker.update(bake::view_of(changed), std::span<const bake::Rect>(&patch, 1), {}, direct.view(), apex);
    EXPECT_EQ(updated.cones.ratios, direct.ratios) << at;
    EXPECT_EQ(updated.apex, apex) << at;
    EXPECT_EQ(updated.stats.work, stats.work) << at;
    // the searches the change cannot have touched are kept (the first stage, the whole map's, is
    // done again)
    EXPECT_LT(updated.stats.texels_refined, whole.stats.texels_refined / 2) << at;

    MapMaker fresh;
    fresh.set_heights(field_of(changed));
    const Made reference = make(fresh, needs);
    EXPECT_EQ(updated.apex, reference.apex) << at;
    EXPECT_GE(updated.stats.mean_ratio, 0.98 * reference.stats.mean_ratio) << at;

    // two new heights before the maps are made: the second's rectangles are relative to the first,
    // which the baker never held
    const bake::Rect other{2, 90, 8, 96};
    const Map first = with_patch(changed, other, 0.1f);
    maps.set_heights(field_of(first), std::span<const bake::Rect>(&other, 1));
    const Map second = with_patch(first, patch, 0.15f);
    maps.set_heights(field_of(second), std::span<const bake::Rect>(&patch, 1));
    const Made rebaked = make(maps, needs);
    MapMaker second_fresh;
    second_fresh.set_heights(field_of(second));
    const Made second_reference = make(second_fresh, needs);
    EXPECT_EQ(rebaked.cones.ratios, second_reference.cones.ratios) << at;
    EXPECT_EQ(rebaked.stats.work, second_reference.stats.work) << at;

    // a change outside the rectangles given
    const Map outside = with_patch(second, other, 0.05f);
    maps.set_heights(field_of(outside), std::span<const bake::Rect>(&patch, 1));
    EXPECT_THROW(maps.maps(needs), bake::BakeError) << at;
  }
}

// The levels of detail (an unbounded view's) of heights changed in a patch: each level's cones are
// updated in the rectangles of the level below halved (rounded outwards) - bit for bit what each
// level's baker gives when called directly on the levels of both heights - and a level's map keeps
// the contract (brute force on level 3). Rectangles relative to other heights: every level baked
// whole.
TEST(MapMaker, LevelsOfHeightsChangedInAPatchAreUpdatedThere) {
  const Map map = test::make_ocean(side, side);
  const bake::Rect patch{40, 30, 47, 37};
  const Map changed = with_patch(map, patch, 0.1f);
  const render::HeightField before = field_of(map), after = field_of(changed);
  render::MapNeeds needs;
  needs.cone_sectors = 4;
  needs.levels = true;
  MapMaker maps;
  MapStats stats;
  const std::uint64_t first = next_map_version();
  maps.make(0, map_heights(before, first), needs, {}, stats);
  EXPECT_FALSE(stats.levels_updated);
  MapHeights heights = map_heights(after, next_map_version());
  heights.dirty_since = first;
  heights.dirty = std::span<const bake::Rect>(&patch, 1);
  const render::MapSet& set = maps.make(0, heights, needs, {}, stats);
  EXPECT_TRUE(stats.cones_updated);
  EXPECT_TRUE(stats.levels_updated);
  ASSERT_EQ(set.level_count, bake::detail_level_count(side, side));

  std::vector<float> level_before = map.values, level_after = changed.values;
  bake::Rect rect = patch;
  for (int level = 1; level <= set.level_count; ++level) {
    const int w = side >> level;
    const std::string at = "level " + std::to_string(level);
    std::vector<float> coarse_before(std::size_t(w) * w), coarse_after(std::size_t(w) * w);
    bake::downsample_heights({level_before.data(), 2 * w, 2 * w}, coarse_before);
    bake::downsample_heights({level_after.data(), 2 * w, 2 * w}, coarse_after);
    level_before = std::move(coarse_before);
    level_after = std::move(coarse_after);
    rect = {rect.x0 / 2, rect.y0 / 2, (rect.x1 + 1) / 2, (rect.y1 + 1) / 2};
    bake::BilinearBaker baker(w, w, 4, Address::wrap);
    bake::ConeMap direct{w, w, 4, std::vector<float>(std::size_t(w) * w * 4)};
    std::vector<float> apex(std::size_t(w) * w);
    baker.bake({level_before.data(), w, w}, {}, direct.view(), apex);
    baker.update({level_after.data(), w, w}, std::span<const bake::Rect>(&rect, 1), {}, direct.view(), apex);
    const render::MapSet::Level& made = set.levels[std::size_t(level - 1)];
    ASSERT_TRUE(std::equal(made.heights.begin(), made.heights.end(), level_after.begin(), level_after.end()))
        << at;
    EXPECT_TRUE(
        std::equal(made.ratios.begin(), made.ratios.end(), direct.ratios.begin(), direct.ratios.end()))
        << at;
    EXPECT_TRUE(std::equal(made.apex.begin(), made.apex.end(), apex.begin(), apex.end())) << at;
    if (level == 3) {
      const Map level_map{"level-3", w, w, level_after};
      const bake::ConeMap cones{w, w, 4, {made.ratios.begin(), made.ratios.end()}};
      EXPECT_EQ(bake::check_bilinear(level_map, Address::wrap, cones, {made.apex.begin(), made.apex.end()})
                    .violations,
                0);
    }
  }
  // rectangles relative to heights the bakers never held
  MapHeights stale = map_heights(before, next_map_version());
  stale.dirty_since = first;
  stale.dirty = std::span<const bake::Rect>(&patch, 1);
  maps.make(0, stale, needs, {}, stats);
  EXPECT_FALSE(stats.cones_updated);
  EXPECT_FALSE(stats.levels_updated);
}

// An image sequence's frame against the one before (HeightSource): the rectangles, on a grid of 16
// texel squares, that hold every texel that changed, with the version they are relative to; the
// same content keeps its version; a frame changed in more than half of its squares, or of another
// size, says nothing (all of it).
TEST(HeightSource, ImageSequencesSayWhereAFrameChanged) {
  std::vector<Map> images;
  images.push_back(test::make_ocean(64, 48));
  images.push_back(with_patch(images[0], {20, 5, 27, 9}, 0.1f));  // in one square
  images.push_back(images[1]);                                    // the same again
  images.push_back(with_patch(images[2], {10, 18, 40, 30}, 0.1f));
  images.push_back(with_patch(with_patch(images[3], {0, 32, 20, 48}, 0.1f), {40, 0, 64, 10}, 0.1f));
  images.push_back(with_patch(images[4], {0, 0, 64, 48}, 0.05f));  // all of it
  images.push_back(test::make_ocean(32, 32));                      // another size
  const std::vector<std::vector<bake::Rect>> expected = {
      {}, {{16, 0, 32, 16}}, {}, {{0, 16, 48, 32}}, {{32, 0, 64, 16}, {0, 32, 32, 48}}, {}, {}};
  SourceSettings settings;
  settings.kind = SourceKind::image;
  settings.image = "terrain_#.png";
  const HeightLoader loader = [&](const std::filesystem::path& file) {
    return field_of(images[std::size_t(std::stoi(file.stem().string().substr(8)))]);
  };
  HeightSource source(settings, effect_heights, loader);
  std::array<HeightFrame, 2> frames;  // two in flight, as the frame pipeline keeps them
  std::uint64_t before = 0;
  for (int f = 0; f < int(images.size()); ++f) {
    HeightFrame& frame = frames[std::size_t(f % 2)];
    source.make(0.0, f, frame);
    const std::string at = "frame " + std::to_string(f);
    ASSERT_EQ(frame.dirty.size(), expected[std::size_t(f)].size()) << at;
    for (std::size_t r = 0; r < frame.dirty.size(); ++r)
      EXPECT_TRUE(frame.dirty[r] == expected[std::size_t(f)][r]) << at << " rectangle " << r;
    if (f == 2) {
      EXPECT_EQ(frame.version, before) << at;
    } else {
      EXPECT_NE(frame.version, before) << at;
    }
    EXPECT_EQ(frame.dirty_since, frame.dirty.empty() ? 0 : before) << at;
    // every texel that changed lies in a rectangle
    if (f > 0 && !frame.dirty.empty()) {
      const Map& now = images[std::size_t(f)];
      const Map& then = images[std::size_t(f - 1)];
      for (int i = 0; i < now.height; ++i)
        for (int j = 0; j < now.width; ++j) {
          const std::size_t t = std::size_t(i) * std::size_t(now.width) + std::size_t(j);
          if (now.values[t] == then.values[t]) continue;
          const bool inside = std::any_of(frame.dirty.begin(), frame.dirty.end(), [&](const bake::Rect& r) {
            return j >= r.x0 && j < r.x1 && i >= r.y0 && i < r.y1;
          });
          ASSERT_TRUE(inside) << at << " texel " << i << ", " << j;
        }
    }
    before = frame.version;
  }
}

}  // namespace
}  // namespace displace::pipeline
