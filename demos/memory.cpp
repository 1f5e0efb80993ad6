// demos/memory.cpp - the memory a command needs, estimated before it starts (demos/memory.h).
#include "demos/memory.h"

#include <fmt/format.h>

#include <algorithm>
#include <charconv>
#include <cstdlib>
#include <string>
#include <string_view>

#include "demos/error.h"
#include "pipeline/maps.h"
#include "pipeline/scene.h"

namespace displace::app {
namespace {

// Host bytes per texel, measured as the growth of peak resident memory per texel from 1024 x 1024
// to 2048 x 2048 (512 to 1024 where a run takes minutes), rounded up by about a fifth.
constexpr std::uint64_t ocean_texel_bytes = 40;  // the spectrum, FFT plans and one frame (36 measured)
constexpr std::uint64_t synthesis_texel_bytes =
    10;                                          // sinusoids, bricks, cliff: heights and their mapping (8)
constexpr std::uint64_t bake_texel_bytes = 16;   // a centre-to-centre bake and its export, plus per sector:
constexpr std::uint64_t bake_sector_bytes = 13;  //   59 at 4 sectors, 108 at 8 (exact, budgeted, original)
constexpr std::uint64_t bilinear_texel_bytes =
    100;  // a bilinear bake (BilinearBaker, full) with its outputs,
constexpr std::uint64_t bilinear_sector_bytes = 10;  //   plus per sector: 104 at 4 sectors, 133 at 8
constexpr std::uint64_t pipeline_texel_bytes =
    480;                                   // the frame pipeline's loop (477 on water, 299 on bricks)
constexpr std::uint64_t height_bytes = 4;  // one float per texel
constexpr std::uint64_t mebibyte = 1ull << 20;

std::string map_text(int width, int height) { return fmt::format("a {} x {} map", width, height); }

std::uint64_t texels_of(int width, int height) { return std::uint64_t(width) * std::uint64_t(height); }

// The cone bake a method's maps need (pipeline::MapMaker bakes bilinear cones, plus relaxed ones).
void add_cone_bake(std::vector<render::Allocation>& list, const render::MapNeeds& needs, int width,
                   int height) {
  const std::uint64_t texels = texels_of(width, height);
  if (needs.cone_sectors > 0) {
    list.push_back(
        {fmt::format("baking the {}-sector cone maps of {}", needs.cone_sectors, map_text(width, height)),
         texels * (bilinear_texel_bytes + bilinear_sector_bytes * std::uint64_t(needs.cone_sectors)),
         render::MemoryKind::host, render::lower_map_size});
  }
  if (needs.relaxed) {
    list.push_back({"baking the relaxed cones of " + map_text(width, height),
                    texels * (bake_texel_bytes + bake_sector_bytes), render::MemoryKind::host,
                    render::lower_map_size});
  }
}

// The maps pipeline::MapMaker hands to the renderer for a method's needs.
render::MapShape map_shape(const render::MapNeeds& needs, int width, int height, bool foam) {
  render::MapShape shape;
  shape.width = width;
  shape.height = height;
  shape.cone_sectors = needs.cone_sectors;
  shape.relaxed = needs.relaxed;
  shape.foam = foam;
  if (needs.max_pyramid) {
    // the dual grid's (W + 1) x (H + 1) nodes, and a third more for the levels above
    shape.max_pyramid_values = texels_of(width + 1, height + 1) * 4 / 3 + 64;
  }
  if (needs.distance) {
    shape.distance_width = std::min(width, pipeline::distance_max_side);
    shape.distance_height = std::min(height, pipeline::distance_max_side);
    shape.distance_depth = pipeline::distance_slices;
  }
  return shape;
}

void append(std::vector<render::Allocation>& list, std::vector<render::Allocation> more) {
  list.insert(list.end(), std::make_move_iterator(more.begin()), std::make_move_iterator(more.end()));
}

}  // namespace

std::uint64_t memory_limit_from_environment() {
  const char* value = std::getenv(memory_limit_variable);
  if (!value || !*value) return 0;
  const std::string_view text(value);
  std::uint64_t megabytes = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), megabytes);
  if (error != std::errc{} || end != text.data() + text.size() || megabytes == 0 ||
      megabytes > (~0ull) / mebibyte) {
    throw usage_error(
        fmt::format("{} must be a whole number of megabytes above 0, got '{}'", memory_limit_variable, text));
  }
  return megabytes * mebibyte;
}

render::MemoryLimits host_limits() {
  return render::host_memory_limits(memory_limit_from_environment(), memory_limit_variable);
}

std::vector<render::Allocation> synthesis_memory(const pipeline::Scene& scene) {
  if (scene.source == pipeline::SourceKind::image) return {};
  const std::uint64_t texels = texels_of(scene.map_size, scene.map_size);
  const bool ocean = scene.source == pipeline::SourceKind::ocean;
  return {{"synthesizing the heights of " + map_text(scene.map_size, scene.map_size),
           texels * (ocean ? ocean_texel_bytes : synthesis_texel_bytes), render::MemoryKind::host,
           render::lower_map_size}};
}

std::vector<render::Allocation> bake_memory(int width, int height, int sector_count, Baker baker,
                                            ConeKind cones) {
  const std::uint64_t texels = texels_of(width, height), sectors = std::uint64_t(sector_count);
  const bool bilinear = cones == ConeKind::bilinear;
  const std::uint64_t per_texel = bilinear ? bilinear_texel_bytes + bilinear_sector_bytes * sectors
                                           : bake_texel_bytes + bake_sector_bytes * sectors;
  return {{fmt::format("baking {}-sector {} cones ({}) of {}", sector_count, bilinear ? "bilinear" : "centre",
                       baker_name(baker), map_text(width, height)),
           texels * per_texel, render::MemoryKind::host, render::lower_map_size}};
}

std::vector<render::Allocation> render_memory(const pipeline::Scene& scene, int width, int height,
                                              unsigned outputs, bool compare_reference) {
  std::vector<render::Allocation> list = synthesis_memory(scene);
  list.push_back({"the heights of " + map_text(width, height), texels_of(width, height) * height_bytes * 2,
                  render::MemoryKind::host, render::lower_map_size});
  const render::View view = pipeline::scene_view(scene, scene.start);
  const render::MapNeeds needs = render::map_needs(scene.method, view);
  add_cone_bake(list, needs, width, height);
  append(list, render::map_memory(map_shape(needs, width, height, scene.foam)));
  append(list, render::frame_memory(view, {scene.method, scene.steps, scene.refine}, width, height, outputs,
                                    compare_reference));
  return list;
}

std::vector<render::Allocation> pipeline_memory(const pipeline::Scene& scene) {
  std::vector<render::Allocation> list;
  if (scene.source == pipeline::SourceKind::image) return list;
  const int size = scene.map_size;
  list.push_back({"the frame pipeline's buffers and bakes for " + map_text(size, size),
                  texels_of(size, size) * pipeline_texel_bytes, render::MemoryKind::host,
                  render::lower_map_size});
  // the image size and what the method reads do not change over the frames: frame 0's view will do
  const render::View view = pipeline::scene_view(scene, pipeline::frame_time(scene, 0));
  const render::MapNeeds needs = render::map_needs(scene.method, view);
  append(list, render::map_memory(map_shape(needs, size, size, scene.foam)));
  append(list, render::frame_memory(view, {scene.method, scene.steps, scene.refine}, size, size,
                                    render::output_color));
  return list;
}

void require_memory(std::span<const render::Allocation> allocations, const render::MemoryLimits& limits) {
  try {
    render::check_memory(allocations, limits);
  } catch (const render::RenderError& error) {
    throw runtime_error(error.what());
  }
}

}  // namespace displace::app
