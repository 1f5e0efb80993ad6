// embed: displace used as a library. Runs the built-in `water` scene for ten frames, asks the
// surface's height at a few points (a buoy, say) at the last frame's time, and writes that frame.
//   embed OUT.png
#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <cstdio>
#include <exception>
#include <span>
#include <vector>

#include "pipeline/frame_pipeline.h"
#include "pipeline/scene.h"
#include "render/files.h"
#include "render/render.h"

namespace pipeline = displace::pipeline;
namespace render = displace::render;

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: embed OUT.png\n");
    return 2;
  }
  try {
    // a scene: a built-in, or pipeline::read_scene_file("my.toml")
    pipeline::Scene scene = pipeline::builtin_scene("water");
    scene.camera.width = 320;
    scene.camera.height = 180;
    scene.frame_ms = 33.3;  // the frame budget: the cone bake gets what the other stages leave of it

    // a renderer on the best Vulkan device (lavapipe on a machine without a GPU)
    render::Renderer renderer;
    pipeline::FramePipeline frames(scene, renderer);

    // ten frames: sim -> bake -> upload -> render, each read back into `frame`
    render::Frame frame;
    pipeline::FrameRecord record;
    for (long long index = 0; index < 10; ++index) {
      record = frames.run(index, frame);
      std::printf(
          "frame %lld at %.3f s: sim %.2f ms, bake %.2f ms (%lld texels left to refine), render %.2f ms\n",
          record.index, record.time, record.sim_ms, record.bake_ms, record.pending, record.render_ms);
    }

    // heights of the surface the renderer drew, at the last frame's time (metres)
    const std::vector<pipeline::QueryPoint> buoys = {{0.0, 0.0}, {12.5, -40.0}, {150.0, 75.25}};
    pipeline::QueryResult heights;
    frames.query(buoys, record.time, heights);
    for (std::size_t i = 0; i < buoys.size(); ++i) {
      std::printf("height at (%g, %g) m: %.4f m, normal (%.3f, %.3f, %.3f)\n", buoys[i].x, buoys[i].y,
                  heights.height_m[i], heights.normal[i].x, heights.normal[i].y, heights.normal[i].z);
    }

    // the last frame, RGBA8: encoded in memory, then written whole or not at all (render/files.h)
    auto output = OIIO::ImageOutput::create(argv[1]);
    const OIIO::ImageSpec spec(frame.width, frame.height, 4, OIIO::TypeDesc::UINT8);
    std::vector<unsigned char> encoded;
    OIIO::Filesystem::IOVecOutput memory(encoded);
    if (!output || !output->set_ioproxy(&memory) || !output->open(argv[1], spec) ||
        !output->write_image(OIIO::TypeDesc::UINT8, frame.color.data()) || !output->close()) {
      std::fprintf(stderr, "embed: cannot encode %s\n", argv[1]);
      return 1;
    }
    displace::files::write_file(argv[1], std::as_bytes(std::span(encoded)));
    std::printf("wrote %s (%d x %d)\n", argv[1], frame.width, frame.height);
    return 0;
  } catch (const std::exception& error) {
    // pipeline::SceneError, render::RenderError and files::WriteError say what went wrong (no device,
    // a bad scene, a full disk)
    std::fprintf(stderr, "embed: %s\n", error.what());
    return 1;
  }
}
