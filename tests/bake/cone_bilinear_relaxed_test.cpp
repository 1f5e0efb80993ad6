// bake_bilinear_relaxed_cones against its contract (bake/bake.h), checked ray by ray on the exact
// bilinear surface: from points all over each texel's square, at every height from the apex up, in
// directions across each sector (its edges too) and at slopes from steep to grazing, a ray that takes
// the relaxed step must land at or before the first point where it leaves the surface.
#include "tests/bake/bake_checks.h"

namespace displace::bake {
namespace {

// The largest of surface - ray over the ray's first `length` of horizontal uv travel, and its value
// there. The ray starts at (u, v, z), runs along the unit uv direction (du, dv) and descends 1 per
// `run` of horizontal travel. Along a line the bilinear surface is a quadratic on each cell, so the
// ray is cut where it crosses a cell edge and each piece's quadratic is fitted through three points.
struct RayRange {
  double highest = -1.0;  // > 0: the ray was below the surface somewhere
  double last = 0.0;      // < 0: the ray ends above it
};

RayRange ray_range(const Map& map, Address address, double u, double v, double z, double du, double dv,
                   double run, double length) {
  if (address == Address::clamp) {  // the surface ends at the map's edges: so does the check
    auto inside_for = [](double start, double step) {
      if (step > 0.0) return (1.0 - start) / step;
      if (step < 0.0) return -start / step;
      return std::numeric_limits<double>::infinity();
    };
    length = std::min({length, inside_for(u, du), inside_for(v, dv)});
  }
  auto gap = [&](double t) { return surface(map, address, u + t * du, v + t * dv) - (z - t / run); };
  std::vector<double> cuts = {0.0, length};
  auto add_cuts = [&](double start, double step, int texels) {  // texel coordinate start * texels - 0.5
    if (step == 0.0) return;
    const double from = start * texels - 0.5, to = (start + length * step) * texels - 0.5;
    for (double edge = std::ceil(std::min(from, to)); edge <= std::max(from, to); edge += 1.0) {
      const double t = ((edge + 0.5) / texels - start) / step;
      if (t > 0.0 && t < length) cuts.push_back(t);
    }
  };
  add_cuts(u, du, map.width);
  add_cuts(v, dv, map.height);
  std::sort(cuts.begin(), cuts.end());
  RayRange range;
  range.highest = gap(0.0);
  for (std::size_t n = 0; n + 1 < cuts.size(); ++n) {
    const double a = cuts[n], b = cuts[n + 1];
    if (b <= a) continue;
    const double q0 = gap(a), qm = gap(0.5 * (a + b)), q1 = gap(b);
    range.highest = std::max({range.highest, q0, qm, q1});
    const double curve = 2.0 * (q0 + q1 - 2.0 * qm),
                 slope = q1 - q0 - curve;  // q(f) = q0 + slope f + curve f^2
    if (curve < 0.0) {
      const double f = -slope / (2.0 * curve);
      if (f > 0.0 && f < 1.0) range.highest = std::max(range.highest, q0 + slope * f + curve * f * f);
    }
  }
  range.last = gap(length);
  return range;
}

struct RelaxedCheck {
  long long rays = 0, landed_below = 0, violations = 0;
};

// Every texel, sector and a spread of starts, heights, directions and slopes: the relaxed step of
// ratio ratio(i, j, k) * scale from apex apex(i, j).
RelaxedCheck check_relaxed(const Map& map, Address address, int sectors, const std::vector<float>& ratios,
                           const std::vector<float>& apex, double scale = 1.0) {
  RelaxedCheck check;
  std::uint64_t state = 0x9e3779b97f4a7c15ull;
  auto uniform = [&] {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return double(state >> 11) * 0x1.0p-53;
  };
  constexpr double runs[] = {0.05, 0.3, 1.0, 3.0, 20.0, 300.0};  // horizontal uv per unit of descent
  for (int i = 0; i < map.height; ++i)
    for (int j = 0; j < map.width; ++j) {
      const std::size_t t = std::size_t(i) * map.width + j;
      const double top = apex[t];
      for (int k = 0; k < sectors; ++k) {
        const double ratio = std::min(1.0, double(ratios[t * sectors + k]) * scale);
        for (int sample = 0; sample < 24; ++sample) {
          // the square's corners and centre first, then anywhere in it
          const double fu = sample < 4 ? double(sample & 1) : sample == 4 ? 0.5 : uniform();
          const double fv = sample < 4 ? double(sample >> 1) : sample == 4 ? 0.5 : uniform();
          const double u = (j + fu) / map.width, v = (i + fv) / map.height;
          const double edge = sample % 3 == 0 ? 0.0 : sample % 3 == 1 ? 1.0 : uniform();
          const double angle = 2.0 * std::numbers::pi * (k + edge) / sectors;
          const double du = std::cos(angle), dv = std::sin(angle);
          const double z = sample % 4 == 0 ? top : sample % 4 == 1 ? 1.0 : top + (1.0 - top) * uniform();
          if (z < top) continue;
          for (const double run : runs) {
            const double length = (z - top) * run * ratio / (ratio + run);
            const RayRange range = ray_range(map, address, u, v, z, du, dv, run, length);
            ++check.rays;
            if (range.last > 1e-6) ++check.landed_below;
            if (range.highest > 1e-6 && range.last < -1e-6) ++check.violations;
          }
        }
      }
    }
  return check;
}

std::vector<Map> relaxed_maps() {
  std::vector<Map> maps = hard_maps();
  for (const Map& map : bilinear_maps()) maps.push_back(map);
  maps.push_back(test::make_bricks(32, 32));
  maps.push_back(test::make_ocean(16, 16));
  return maps;
}

struct Baked {
  std::vector<float> ratios, apex;
};

Baked bake_with(BakeStats (*baker)(HeightView, Address, ConeView, std::span<float>,
                                   const BilinearConeSettings&),
                const Map& map, Address address, int sectors) {
  Baked baked{std::vector<float>(std::size_t(map.width) * map.height * sectors),
              std::vector<float>(std::size_t(map.width) * map.height)};
  baker(view_of(map), address, {baked.ratios.data(), map.width, map.height, sectors}, baked.apex, {});
  return baked;
}

TEST(BilinearRelaxedCones, NoRayLeavesTheSurfaceBeforeItsStepLands) {
  for (const Map& map : relaxed_maps())
    for (const Address address : {Address::wrap, Address::clamp})
      for (const int sectors : {1, 4, 8}) {
        const Baked relaxed = bake_with(bake_bilinear_relaxed_cones, map, address, sectors);
        const RelaxedCheck check = check_relaxed(map, address, sectors, relaxed.ratios, relaxed.apex);
        EXPECT_EQ(check.violations, 0) << map.name << " " << address_name(address) << " " << sectors
                                       << " sectors, of " << check.rays << " rays";
      }
}

// The same check catches ratios a quarter too wide (so it can fail), and the conservative cones of
// bake_bilinear_cones, which no ray crosses, land below the surface on no ray.
TEST(BilinearRelaxedCones, TheCheckCatchesRatiosAQuarterTooWide) {
  long long caught = 0;
  for (const Map& map :
       {test::make_bricks(32, 32), test::make_fractal_cliff(32, 32), make_single_spike(7, 5)}) {
    const Baked relaxed = bake_with(bake_bilinear_relaxed_cones, map, Address::wrap, 4);
    caught += check_relaxed(map, Address::wrap, 4, relaxed.ratios, relaxed.apex, 1.25).violations;
    const Baked conservative = bake_with(bake_bilinear_cones, map, Address::wrap, 4);
    EXPECT_EQ(check_relaxed(map, Address::wrap, 4, conservative.ratios, conservative.apex).landed_below, 0)
        << map.name;
  }
  EXPECT_GT(caught, 0);
}

// Never narrower than the conservative cones (the same apexes; the relaxed ratio bounds a subset of
// the surface's points), and wider where the surface only rises along a sector's directions: on a
// clamped ramp that rises along +u, 1 in the sector of +u and +v, where the conservative cones meet
// the ramp. How much wider on the built-in kinds of map is printed: little, as grazing rays can clip
// any corner of a brick or crest of a wave and leave it again (docs/design/bakers.md).
TEST(BilinearRelaxedCones, NeverNarrowerThanTheConservativeConesWiderWhereNothingFalls) {
  for (const Map& map : relaxed_maps())
    for (const Address address : {Address::wrap, Address::clamp}) {
      const Baked relaxed = bake_with(bake_bilinear_relaxed_cones, map, address, 4);
      const Baked conservative = bake_with(bake_bilinear_cones, map, address, 4);
      EXPECT_EQ(relaxed.apex, conservative.apex) << map.name;
      long long narrower = 0;
      for (std::size_t n = 0; n < relaxed.ratios.size(); ++n)
        narrower += relaxed.ratios[n] < conservative.ratios[n];
      EXPECT_EQ(narrower, 0) << map.name << " " << address_name(address);
    }
  const Map ramp = make_ramp(16, 8);
  const Baked relaxed = bake_with(bake_bilinear_relaxed_cones, ramp, Address::clamp, 4);
  const Baked conservative = bake_with(bake_bilinear_cones, ramp, Address::clamp, 4);
  for (std::size_t t = 0; t + 1 < relaxed.apex.size(); ++t) {
    if (t % 16 == 15) continue;  // the top of the ramp: nothing rises beyond it
    EXPECT_EQ(relaxed.ratios[t * 4], 1.0f) << t;
    EXPECT_LT(conservative.ratios[t * 4], 0.95f) << t;
  }
  for (const Map& map :
       {test::make_bricks(64, 64), test::make_fractal_cliff(64, 64), test::make_ocean(64, 64)})
    for (const int sectors : {4, 8}) {
      const Baked wide = bake_with(bake_bilinear_relaxed_cones, map, Address::wrap, sectors);
      const Baked narrow = bake_with(bake_bilinear_cones, map, Address::wrap, sectors);
      const double count = double(wide.ratios.size());
      std::printf("%s 64 x 64, %d sectors: mean relaxed ratio %.4f, conservative %.4f\n", map.name.c_str(),
                  sectors, std::accumulate(wide.ratios.begin(), wide.ratios.end(), 0.0) / count,
                  std::accumulate(narrow.ratios.begin(), narrow.ratios.end(), 0.0) / count);
    }
}

}  // namespace
}  // namespace displace::bake
