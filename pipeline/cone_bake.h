// pipeline/cone_bake.h - one height map's cone map baked whole, by the baker a program names: centre
// cones (between texel centres) with one of bake/'s centre bakers, or the renderer's bilinear cones
// with their apex heights. What `displace bake` and the Python module's bake() run on the CPU.
//
//   pipeline::BakedCones baked = pipeline::bake_bilinear(heights, w, h, 4, pipeline::Baker::budgeted,
//                                                        bake::Address::wrap, /*budget_ms*/ 2.0);
//   // baked.ratios: w * h * 4 interleaved, baked.apex: w * h, baked.stats: what the bake did
//
// Heights in [0, 1], row-major. Throws std::invalid_argument for a baker that does not make that kind of
// cones, or a sector count it does not bake (as bake/ does for bad maps).
#pragma once

#include <optional>
#include <span>
#include <string_view>
#include <vector>

#include "bake/bake.h"

namespace displace::pipeline {

// Which baker makes a cone map: for centre cones the four conservative-ratio modes (bake_exact,
// bake_original, bake_paper_adaptive, bake_budgeted) and the relaxed baker; for bilinear cones budgeted
// (bake::BilinearBaker) or full (bake::bake_bilinear_cones).
enum class Baker { exact, original, paper_adaptive, budgeted, relaxed, full };
// "exact", "original", "paper-adaptive", "budgeted", "relaxed", "full"
const char* baker_name(Baker baker);
std::optional<Baker> baker_named(std::string_view name);  // none for an unknown name

struct BakedCones {
  std::vector<float> ratios;  // interleaved, width * height * sector_count
  std::vector<float> apex;    // bilinear cones: width * height apex heights; centre cones: empty
  bake::BakeStats stats;      // with width, height and sector_count set; milliseconds the wall time
};
// Centre cones with one of the centre bakers (not Baker::full); the relaxed baker takes 1 or 4
// sectors. `budget_milliseconds` and `tolerance` are the budgeted baker's; `progress` hears from the
// slow ones (exact, original, relaxed).
BakedCones bake_cones(std::span<const float> heights, int width, int height, int sector_count, Baker baker,
                      bake::Address address, double budget_milliseconds, float tolerance = 0.25f,
                      const bake::Progress& progress = {});
// Bilinear cones (bake::bake_bilinear_cones' contract) with their apex heights: Baker::full bakes them
// whole, Baker::budgeted with bake::BilinearBaker within the budget (0 allowed); `progress` goes to
// either.
BakedCones bake_bilinear(std::span<const float> heights, int width, int height, int sector_count, Baker baker,
                         bake::Address address, double budget_milliseconds, float tolerance = 0.25f,
                         const bake::Progress& progress = {});

}  // namespace displace::pipeline
