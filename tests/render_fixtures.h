// tests/render_fixtures.h - what the renderer tests share: one renderer for the whole test program
// (device and pipelines made once, validation on, as in the app) and the maps of its methods, plus
// the height fields of tests/height_fields.h. A test file that includes this header makes a Vulkan
// instance: tests/CMakeLists.txt runs every such file in one process (lavapipe compiles each
// pipeline again in every process).
#pragma once

#include <memory>
#include <string>
#include <utility>

#include "pipeline/maps.h"
#include "render/render.h"
#include "tests/height_fields.h"

namespace displace::testing {

// Headless renderer options: the best device, validation on or off, the pipeline cache directory.
inline render::RendererOptions headless_options(bool validate, std::string pipeline_cache = {}) {
  render::RendererOptions options;
  options.validate = validate;
  options.pipeline_cache = std::move(pipeline_cache);
  return options;
}

inline render::Renderer& shared_renderer() {
  static std::unique_ptr<render::Renderer> renderer =
      std::make_unique<render::Renderer>(headless_options(true));
  return *renderer;
}

// The maps of the shared renderer's methods, baked on demand from the heights last set.
inline pipeline::MapMaker& shared_maps() {
  static pipeline::MapMaker maps(shared_renderer().device().max_image_dimension_3d);
  return maps;
}

// Renders with the shared renderer, from the maps the method needs (baked on first use).
inline render::Frame draw(const render::View& view, const render::MethodSettings& method,
                          unsigned outputs = render::output_all) {
  return pipeline::render_with_maps(shared_renderer(), shared_maps(), view, method, outputs);
}

}  // namespace displace::testing
