// demos/memory.h - the memory a command needs, estimated before it starts, against what the machine
// has (render.h's memory guards), so that a command that cannot fit is refused with one line and
// exit status 1 before it synthesizes, bakes or renders anything, instead of running out mid-way.
//
// The one fact to know: the renderer's own allocations are counted byte for byte (render::map_memory,
// render::frame_memory); what sim/ and bake/ hold while they work is an estimate per texel, measured
// (peak resident memory of the commands at 1024 and 2048 texels a side), rounded up.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "demos/cone_export.h"
#include "pipeline/scene.h"
#include "render/render.h"

namespace displace::app {

// The environment variable that lowers the memory the guards count on (megabytes; for a shared
// machine, a container whose limit /proc/meminfo does not show, or to try the guards).
inline constexpr const char* memory_limit_variable = "DISPLACE_MEMORY_LIMIT_MB";
// Its value in bytes; 0 when it is unset or empty. Throws a usage AppError when it is not a positive
// whole number of megabytes.
std::uint64_t memory_limit_from_environment();
// The host's memory with that limit applied (commands that use no device: sim, bake).
render::MemoryLimits host_limits();

// Synthesizing the heights of `scene` (none for an image scene: its size is the image's).
std::vector<render::Allocation> synthesis_memory(const pipeline::Scene& scene);
// Baking a width x height map to a cone map: heights, the baker's working memory, the export.
std::vector<render::Allocation> bake_memory(int width, int height, int sector_count, Baker baker,
                                            ConeKind cones);
// Rendering `scene`'s method on a width x height map: the heights, the maps it bakes
// (pipeline::MapMaker), their device copies and the frame with `outputs` (and the reference's when
// it compares).
std::vector<render::Allocation> render_memory(const pipeline::Scene& scene, int width, int height,
                                              unsigned outputs, bool compare_reference);
// The frame pipeline's loop on a synthesized scene: two frames of buffers, the bake, the maps on the
// device and the frame. Empty for an image scene (its size is the images').
std::vector<render::Allocation> pipeline_memory(const pipeline::Scene& scene);

// Throws a runtime AppError (render::check_memory's line) when `allocations` do not fit `limits`.
void require_memory(std::span<const render::Allocation> allocations, const render::MemoryLimits& limits);

}  // namespace displace::app
