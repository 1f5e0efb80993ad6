// demos/cone_bake.h - one cone map baked whole for `displace bake` and `displace demo`: on the CPU
// pipeline/cone_bake.h's bakers, on a device the renderer's bilinear cones; and the --stats line.
#pragma once

#include <span>
#include <string>
#include <vector>

#include "bake/bake.h"
#include "bake/device/device_cones.h"
#include "demos/cone_export.h"
#include "pipeline/cone_bake.h"
#include "render/render.h"
#include "sim/device/device_sim.h"

namespace displace::app {

using pipeline::bake_bilinear;
using pipeline::bake_cones;
using pipeline::BakedCones;

// Bilinear cones on `renderer`'s device (bake::DeviceCones, the same contract), with the frame
// pipeline's rule (bake::device_refine_limit): Baker::full and a budgeted bake without a budget
// search every texel to the cells, a budgeted bake with a budget (a dispatch cannot stop when it runs
// out) makes the first pass only, of the shape `first_pass` says. Stats: DeviceCones::read_back's,
// with mode bilinear and the wall milliseconds.
BakedCones bake_bilinear_on_device(render::Renderer& renderer, std::span<const float> heights, int width,
                                   int height, int sector_count, Baker baker, bake::Address address,
                                   double budget_milliseconds, const bake::DeviceFirstPass& first_pass = {});
// The --stats JSON line (no trailing newline).
std::string stats_json(const bake::BakeStats& stats, Baker baker, bake::Address address,
                       ConeKind kind = ConeKind::center);

}  // namespace displace::app
