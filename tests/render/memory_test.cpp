// tests/render/memory_test.cpp - the memory guards (render/memory.cpp).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <iterator>
#include <memory>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "render/map_pack.h"
#include "render/mesh.h"
#include "render/render.h"
#include "sim/sim.h"
#include "tests/render/render_checks.h"
#include "tests/render_fixtures.h"

namespace {

using namespace displace;
using namespace displace::testing;
using render::Frame;
using render::HeightField;
using render::Method;
using render::MethodInfo;
using render::View;

// ---------------------------------------------------------------------------------------------
// memory guards: estimates before anything is allocated, and refusals that say what to lower

std::uint64_t bytes_of(const std::vector<render::Allocation>& list, render::MemoryKind kind) {
  std::uint64_t bytes = 0;
  for (const render::Allocation& allocation : list) bytes += allocation.kind == kind ? allocation.bytes : 0;
  return bytes;
}

std::string refusal(const std::vector<render::Allocation>& list, const render::MemoryLimits& limits) {
  try {
    render::check_memory(list, limits);
  } catch (const render::RenderError& error) {
    return error.what();
  }
  return "(fits)";
}

// A frame's estimate is the renderer's formats byte for byte: targets RGBA8 + RGBA32F + RG32F + D32F,
// a readback per output read back, the Frame's vectors, and the reference's tessellation.
TEST(MemoryGuard, FrameMemoryCountsTargetsReadbackAndTessellation) {
  View view;
  view.camera.width = 100;
  view.camera.height = 50;
  const std::uint64_t pixels = 5000;
  const auto acm4 = render::frame_memory(view, {Method::acm4, 8, 0}, 64, 32);
  EXPECT_EQ(bytes_of(acm4, render::MemoryKind::device_local), pixels * (4 + 16 + 8 + 4));
  EXPECT_EQ(bytes_of(acm4, render::MemoryKind::host_visible), pixels * (4 + 16 + 8));
  EXPECT_EQ(bytes_of(acm4, render::MemoryKind::host), pixels * (4 + 12 + 4 + 4 + 4));
  const auto colour = render::frame_memory(view, {Method::acm4, 8, 0}, 64, 32, render::output_color);
  EXPECT_EQ(bytes_of(colour, render::MemoryKind::host_visible), pixels * 4);
  // the reference: (64 K + 2) x (32 K + 2) vertices of (u, v), two triangles per cell, on the CPU
  // and again in buffers
  view.tile = 3;
  const auto reference = render::frame_memory(view, {Method::reference, 1, 0}, 64, 32, render::output_color);
  const std::uint64_t vertices = (64 * 3 + 2) * (32 * 3 + 2), triangles = (64 * 3 + 1) * (32 * 3 + 1) * 2;
  EXPECT_EQ(bytes_of(reference, render::MemoryKind::host), pixels * 4 + vertices * 8 + triangles * 12);
  EXPECT_EQ(bytes_of(reference, render::MemoryKind::host_visible),
            pixels * 4 + vertices * 8 + triangles * 12);
  // compared with the reference: a second readback and Frame, and the tessellation
  view.tile = 1;
  const auto compared = render::frame_memory(view, {Method::acm4, 8, 0}, 64, 32, render::output_all, true);
  EXPECT_GT(bytes_of(compared, render::MemoryKind::host_visible), 2 * pixels * (4 + 16 + 8));
  // a tessellation beyond 32-bit indices cannot be made at all, whatever the memory
  view.tile = 64;
  try {
    render::frame_memory(view, {Method::reference, 1, 0}, 16384, 16384);
    ADD_FAILURE() << "a tessellation of 2^40 vertices was estimated";
  } catch (const render::RenderError& error) {
    EXPECT_NE(std::string(error.what()).find("32-bit indices"), std::string::npos) << error.what();
    EXPECT_NE(std::string(error.what()).find("View::tile"), std::string::npos) << error.what();
  }
}

// The check: one Vulkan allocation above the device's largest, or a sum above what there is, is
// refused with what needs how much, what there is, and what to lower; a CPU device's memory is the
// host's; what fits passes.
TEST(MemoryGuard, RefusesWhatDoesNotFitAndSaysWhatToLower) {
  View view;
  view.camera.width = view.camera.height = 4096;
  const auto frame = render::frame_memory(view, {Method::acm4, 8, 0}, 256, 256);  // 256 MB of hit target
  render::MemoryLimits gpu;
  gpu.device = "a GPU";
  gpu.host = 4'000'000'000ull;
  gpu.device_local = 8'000'000'000ull;
  gpu.host_visible = 8'000'000'000ull;
  gpu.max_allocation = 4'000'000'000ull;
  EXPECT_EQ(refusal(frame, gpu), "(fits)");
  render::MemoryLimits small_allocations = gpu;
  small_allocations.max_allocation = 200'000'000ull;
  const std::string one = refusal(frame, small_allocations);
  EXPECT_NE(one.find("the hit target of a 4096 x 4096 frame needs one allocation of 268 MB"),
            std::string::npos)
      << one;
  EXPECT_NE(one.find("at most 200 MB"), std::string::npos) << one;
  EXPECT_NE(one.find("lower Camera::width x Camera::height"), std::string::npos) << one;
  render::MemoryLimits small_device = gpu;
  small_device.device_local = 300'000'000ull;  // the targets need 537 MB
  const std::string device = refusal(frame, small_device);
  EXPECT_NE(device.find("of device memory; 300 MB is all a GPU has"), std::string::npos) << device;
  // a CPU device: the device's heaps are not used, everything counts against the host
  render::MemoryLimits cpu = gpu;
  cpu.device_is_host = true;
  cpu.device_local = cpu.host_visible = 1;
  EXPECT_EQ(refusal(frame, cpu), "(fits)");
  cpu.host = 1'000'000'000ull;  // the frame needs 1.5 GB in all
  cpu.limited_by = "DISPLACE_MEMORY_LIMIT_MB";
  const std::string host = refusal(frame, cpu);
  EXPECT_NE(host.find("with the rest) of host memory; 1.00 GB is available (DISPLACE_MEMORY_LIMIT_MB): lower "
                      "Camera::width x Camera::height"),
            std::string::npos)
      << host;
  // host work only (no device): a host limit
  const render::MemoryLimits host_only = render::host_memory_limits(1 << 20, "a test");
  EXPECT_EQ(host_only.host, std::uint64_t(1 << 20));
  EXPECT_NE(refusal(frame, host_only).find("(a test)"), std::string::npos);
  EXPECT_GT(render::host_memory_limits().host, 0u);
}

// A renderer held to a memory limit refuses a frame and maps that do not fit before it allocates
// anything (its allocation count does not move), and goes on rendering what does fit.
TEST(MemoryGuard, ARendererRefusesBeforeItAllocates) {
  render::RendererOptions options = headless_options(true);
  // 48 MiB: the 4096 x 4096 height map below (64 MiB) is over it by itself, on a device whose image and
  // staging count in one pool (lavapipe: the host's) and on one that counts them apart (a GPU's device
  // and host-visible heaps; at 64 MiB an H200 rightly took that map, each part exactly at the limit)
  options.memory_limit = 48ull << 20;
  options.memory_limit_source = "the test's limit";
  render::Renderer renderer(options);
  pipeline::MapMaker maps(renderer.device().max_image_dimension_3d);
  maps.set_heights(ramp_field(32));
  renderer.set_maps(maps.maps_for(Method::relief, oblique_view(8)));
  const long long before = renderer.memory_allocations();
  View large = oblique_view(2048);  // 2048 x 2048: about 370 MB of targets, readback and pixels
  try {
    renderer.render(large, {Method::relief, 8, 2});
    ADD_FAILURE() << "a 2048 x 2048 frame was rendered within 48 MiB";
  } catch (const render::RenderError& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find("2048 x 2048"), std::string::npos) << message;
    EXPECT_NE(message.find("lower Camera::width x Camera::height"), std::string::npos) << message;
  }
  EXPECT_EQ(renderer.memory_allocations(), before);
  // a 4096 x 4096 height map: a 67 MB image and its staging
  render::MapSet big;
  const std::vector<float> heights(std::size_t(4096) * 4096, 0.5f);
  big.width = big.height = 4096;
  big.heights = heights;
  big.heights_version = pipeline::next_map_version();
  EXPECT_THROW(renderer.set_maps(big), render::RenderError);
  EXPECT_EQ(renderer.memory_allocations(), before);
  // what fits still renders
  const Frame small = renderer.render(oblique_view(16), {Method::relief, 8, 2});
  EXPECT_EQ(small.color.size(), std::size_t(16 * 16 * 4));
  EXPECT_EQ(renderer.validation_messages(), 0);
}

}  // namespace
