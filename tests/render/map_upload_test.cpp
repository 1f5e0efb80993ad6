// tests/render/map_upload_test.cpp - maps kept between frames (render/map_upload.cpp, render/frame.cpp):
// dirty uploads, no allocation when warm, flat resident memory, refusals.
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

// ---- Maps handed over from outside (pipeline::MapMaker bakes; the renderer uploads and never bakes)

// Ocean heights at `size` for scene time t (the sweep's ocean, mapped into [0, 1]).
HeightField ocean_at(sim::Ocean& ocean, float t) {
  sim::OceanFrame frame;
  ocean.evaluate(t, sim::ocean_heights, frame);
  HeightField field{ocean.params().size, ocean.params().size, std::vector<float>(frame.height.size())};
  sim::apply_mapping(ocean.mapping(), frame.height, field.heights);
  return field;
}

sim::Ocean small_ocean(int size) {
  sim::OceanParams params;
  params.size = size;
  return sim::Ocean(params);
}

// The methods that read each kind of map: heights only, 4-sector cones, relaxed cones, the max
// pyramid, the distance map, and the tessellated reference.
const Method kept_methods[] = {Method::relief, Method::acm4,   Method::relaxed,
                               Method::qdm,    Method::sphere, Method::reference};

// Versions of hand-made map sets, far from pipeline::MapMaker's counter.
constexpr std::uint64_t hand_made = std::uint64_t(1) << 62;

bool same_frame(const Frame& a, const Frame& b) {
  return a.color == b.color && a.uv == b.uv && a.depth == b.depth && a.iterations == b.iterations &&
         a.fetches == b.fetches;
}

// A renderer kept over 20 successive ocean frames (new heights and maps each frame, uploaded into
// the images it already has, a method of every map kind drawn each frame) renders every frame bit
// for bit like a fresh renderer given the same maps. The fresh renderer of frame n draws one of the
// methods (n modulo their count: each is compared on 3 or 4 frames), as a fresh device compiles
// every pipeline again (about 0.15 s each here).
// The fresh one copies every map through the staging ring (host_written_maps off), the kept one on
// the CPU device writes them into linear images: the fast path against the slow one.
TEST(Maps, AKeptRendererMatchesAFreshOneOnEveryFrame) {
  sim::Ocean ocean = small_ocean(32);
  const View view = oblique_view(24);
  render::Renderer& kept = shared_renderer();
  render::RendererOptions staged = displace::testing::headless_options(false, "off");
  staged.host_written_maps = false;
  pipeline::MapMaker maps(kept.device().max_image_dimension_3d);
  Frame frame;
  constexpr int method_count = int(std::size(kept_methods));
  for (int n = 0; n < 20; ++n) {
    maps.set_heights(ocean_at(ocean, float(n) / 30.0f));
    for (int m = 0; m < method_count; ++m) {
      const Method method = kept_methods[m];
      kept.set_maps(maps.maps_for(method, view));
      kept.render(view, {method, 24, 6}, frame);
      if (m != n % method_count) continue;
      render::Renderer fresh(staged);
      fresh.set_maps(maps.maps_for(method, view));
      EXPECT_FALSE(fresh.host_written_maps());
      if (kept.device().type == "cpu") {
        EXPECT_TRUE(kept.host_written_maps());
      }
      const Frame expected = fresh.render(view, {method, 24, 6});
      EXPECT_TRUE(same_frame(frame, expected)) << "frame " << n << " " << render::method_info(method).name;
    }
  }
  EXPECT_EQ(kept.validation_messages(), 0);
}

// Heights and cones changed in a rectangle: the renderer that gets only the rectangles (dirty_since
// its version) draws what the one that gets whole maps draws; and it does copy only the rectangles
// (a rectangle too small leaves a different picture).
TEST(Maps, DirtyRectangleUploadsMatchWholeUploads) {
  const int size = 32;
  HeightField before = waves_field(size);
  HeightField after = before;
  const bake::Rect changed{5, 9, 17, 20};
  for (int i = changed.y0; i < changed.y1; ++i)
    for (int j = changed.x0; j < changed.x1; ++j) after.heights[std::size_t(i) * size + j] = 0.95f;
  auto bake_cones = [&](const HeightField& field, std::vector<float>& ratios, std::vector<float>& apex) {
    ratios.resize(field.heights.size() * 4);
    apex.resize(field.heights.size());
    bake::BilinearBaker baker(size, size, 4, bake::Address::wrap);
    baker.bake({field.heights.data(), size, size}, {}, {ratios.data(), size, size, 4}, apex);
  };
  std::vector<float> ratios_before, apex_before, ratios_after, apex_after;
  bake_cones(before, ratios_before, apex_before);
  bake_cones(after, ratios_after, apex_after);
  // the cone map changes further out than the heights: its rectangle is where any value changed
  bake::Rect cone_rect{size, size, 0, 0};
  for (int i = 0; i < size; ++i)
    for (int j = 0; j < size; ++j) {
      const std::size_t t = std::size_t(i) * size + j;
      bool differs = apex_before[t] != apex_after[t];
      for (int k = 0; k < 4; ++k) differs |= ratios_before[t * 4 + k] != ratios_after[t * 4 + k];
      if (!differs) continue;
      cone_rect = {std::min(cone_rect.x0, j), std::min(cone_rect.y0, i), std::max(cone_rect.x1, j + 1),
                   std::max(cone_rect.y1, i + 1)};
    }
  ASSERT_LT(cone_rect.x0, cone_rect.x1);

  auto map_set = [&](const HeightField& field, const std::vector<float>& ratios,
                     const std::vector<float>& apex, std::uint64_t version) {
    render::MapSet set;
    set.width = set.height = size;
    set.heights = field.heights;
    set.heights_version = version;
    set.cones[std::size_t(render::cone_slot(4))] = {4, bake::Address::wrap, ratios, apex, {}, version, 0, {}};
    return set;
  };
  const View view = oblique_view(48);
  const render::MethodSettings settings{Method::acm4, 32, 6};
  // maps written by the host (the shared renderer on the CPU device), then through the staging ring
  render::RendererOptions staged_options = displace::testing::headless_options(true, "off");
  staged_options.host_written_maps = false;
  render::Renderer staged(staged_options);
  for (render::Renderer* each : {&shared_renderer(), &staged}) {
    render::Renderer& renderer = *each;
    auto render_partial = [&](const bake::Rect& height_rect, const bake::Rect& cones_rect) {
      renderer.set_maps(map_set(before, ratios_before, apex_before, hand_made + 1001));
      renderer.render(view, settings);
      render::MapSet set = map_set(after, ratios_after, apex_after, hand_made + 1002);
      set.heights_dirty_since = hand_made + 1001;
      set.heights_dirty = std::span<const bake::Rect>(&height_rect, 1);
      set.cones[1].dirty_since = hand_made + 1001;
      set.cones[1].dirty = std::span<const bake::Rect>(&cones_rect, 1);
      renderer.set_maps(set);
      return renderer.render(view, settings);
    };
    const Frame partial = render_partial(changed, cone_rect);
    renderer.set_maps(map_set(after, ratios_after, apex_after, hand_made + 1003));  // whole maps
    const Frame whole = renderer.render(view, settings);
    EXPECT_TRUE(same_frame(partial, whole));
    const bake::Rect too_small{changed.x0, changed.y0, changed.x0 + 2, changed.y0 + 2};
    const Frame stale = render_partial(too_small, too_small);
    EXPECT_FALSE(same_frame(stale, whole));
    EXPECT_EQ(renderer.validation_messages(), 0);
    EXPECT_EQ(renderer.host_written_maps(), each != &staged && renderer.device().type == "cpu");
  }
}

// After two warm-up frames of the same sizes, a frame with new heights and new maps allocates no
// Vulkan memory - with frames read back and frames left in flight - and validation stays silent.
TEST(Maps, AWarmFrameAllocatesNothing) {
  sim::Ocean ocean = small_ocean(64);
  const View view = oblique_view(40);
  render::Renderer& renderer = shared_renderer();
  pipeline::MapMaker maps(renderer.device().max_image_dimension_3d);
  Frame frame;
  long long after_warm_up = 0;
  for (int n = 0; n < 8; ++n) {
    maps.set_heights(ocean_at(ocean, float(n) / 60.0f));
    for (const Method method : {Method::acm4, Method::qdm}) {
      renderer.set_maps(maps.maps_for(method, view));
      renderer.render(view, {method, 16, 4}, frame, n % 2 == 0 ? render::output_all : render::output_none);
    }
    if (n == 1) after_warm_up = renderer.memory_allocations();
  }
  renderer.wait_idle();
  EXPECT_GT(after_warm_up, 0);
  EXPECT_EQ(renderer.memory_allocations(), after_warm_up);
  EXPECT_EQ(renderer.validation_messages(), 0);
}

// The process's resident memory (VmRSS of /proc/self/status) in KiB, -1 where it cannot be read.
long resident_kib() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("VmRSS:", 0) == 0) return std::stol(line.substr(6));
  }
  return -1;
}

// After warm-up, a long frame loop keeps resident memory flat: neither the renderer nor the driver
// keeps anything per frame. While the frame block was a uniform buffer, lavapipe (Mesa 22.3)
// compiled and kept a shader variant every frame (render/shaders/frame_block.inc.glsl): these 300
// frames then grew by 394 MiB. Without it they grow by 0 KiB (five runs, alone and after the other
// renderer tests); the bound catches any leak of 30 KiB a frame or more.
TEST(Maps, AFrameLoopKeepsResidentMemoryFlat) {
  if (resident_kib() < 0) GTEST_SKIP() << "no /proc/self/status";
#if defined(DISPLACE_ADDRESS_SANITIZER)
  GTEST_SKIP() << "AddressSanitizer keeps freed memory resident (its quarantine)";
#endif
  shared_maps().set_heights(waves_field(32));
  const View view = oblique_view(24);
  render::Renderer& renderer = shared_renderer();
  const std::array<render::MethodSettings, 3> methods = {
      {{Method::relief, 16, 4}, {Method::acm4, 16, 4}, {Method::bump, 1, 0}}};
  Frame frame;
  auto frames = [&](int count) {
    for (int n = 0; n < count; ++n) {
      const render::MethodSettings& method = methods[std::size_t(n) % methods.size()];
      renderer.set_maps(shared_maps().maps_for(method.method, view));
      renderer.render(view, method, frame, n % 2 == 0 ? render::output_all : render::output_none);
    }
    renderer.wait_idle();
  };
  frames(30);
  const long warm = resident_kib();
  frames(300);
  EXPECT_LT(resident_kib() - warm, 9 * 1024) << "KiB more after 300 frames";
  EXPECT_EQ(renderer.validation_messages(), 0);
}

// Only the outputs asked for are read back; the rest stay empty, and what is read is the same.
TEST(Maps, ReadsBackOnlyWhatIsAskedFor) {
  shared_maps().set_heights(waves_field(16));
  const View view = oblique_view(16);
  const Frame all = draw(view, {Method::relief, 16, 4});
  const Frame color = draw(view, {Method::relief, 16, 4}, render::output_color | render::output_fetches);
  EXPECT_EQ(color.color, all.color);
  EXPECT_EQ(color.fetches, all.fetches);
  EXPECT_TRUE(color.uv.empty() && color.depth.empty() && color.iterations.empty());
  const Frame none = draw(view, {Method::relief, 16, 4}, render::output_none);
  EXPECT_TRUE(none.color.empty() && none.uv.empty());
  shared_renderer().wait_idle();
}

// A method whose maps were not given is refused with one error naming the map; the renderer never
// bakes it.
TEST(Maps, AMethodWithoutItsMapsIsRefusedNamingTheMap) {
  const HeightField field = waves_field(16);
  render::MapSet set;
  set.width = set.height = 16;
  set.heights = field.heights;
  set.heights_version = hand_made + 2001;
  render::Renderer& renderer = shared_renderer();
  renderer.set_maps(set);
  const View view = oblique_view(8);
  auto error_of = [&](Method method, const View& v) {
    try {
      renderer.render(v, {method, 8, 2});
    } catch (const render::RenderError& error) {
      return std::string(error.what());
    }
    return std::string("(rendered)");
  };
  EXPECT_EQ(error_of(Method::relief, view), "(rendered)");  // heights are enough
  EXPECT_NE(error_of(Method::acm4, view).find("4-sector cone map"), std::string::npos)
      << error_of(Method::acm4, view);
  EXPECT_NE(error_of(Method::csm, view).find("1-sector cone map"), std::string::npos);
  EXPECT_NE(error_of(Method::maxmip, view).find("max pyramid"), std::string::npos);
  EXPECT_NE(error_of(Method::sphere, view).find("distance map"), std::string::npos);
  // cones without the relaxed layer, and cones baked for the other address mode
  std::vector<float> ratios(field.heights.size() * 4, 0.0f), apex(field.heights.size(), 1.0f);
  set.cones[1] = {4, bake::Address::wrap, ratios, apex, {}, hand_made + 2002, 0, {}};
  renderer.set_maps(set);
  EXPECT_EQ(error_of(Method::acm4, view), "(rendered)");
  EXPECT_NE(error_of(Method::relaxed, view).find("relaxed ratios"), std::string::npos);
  View clamped = view;
  clamped.address = bake::Address::clamp;
  EXPECT_NE(error_of(Method::acm4, clamped).find("baked with address clamp"), std::string::npos)
      << error_of(Method::acm4, clamped);
  // a NaN ratio is refused when it is handed over
  ratios[7] = std::nanf("");
  set.cones[1].version = hand_made + 2003;
  EXPECT_THROW(renderer.set_maps(set), render::RenderError);
  EXPECT_EQ(renderer.validation_messages(), 0);
}

// Every bad value is refused wherever it sits - in the four-texel blocks that are packed together
// and in a row's tail (7 columns), in each sector of the 4- and 8-sector maps, the apexes, the
// relaxed layers and the heights - and the same maps with the value put back are taken.
TEST(Maps, EveryBadValueIsRefusedWhereverItSits) {
  const int width = 7, height = 3;
  const std::size_t texels = std::size_t(width) * height;
  std::vector<float> heights(texels), ratios(texels * 4), apex(texels), relaxed(texels);
  std::vector<float> ratios8(texels * 8), apex8(texels), relaxed8(texels);
  for (std::size_t t = 0; t < texels; ++t) {
    heights[t] = 0.5f + 0.01f * float(t % 5);
    apex[t] = apex8[t] = heights[t] + 0.1f;
    relaxed[t] = relaxed8[t] = 0.3f;
    for (int k = 0; k < 4; ++k) ratios[t * 4 + k] = 0.1f * float(k + 1);
    for (int k = 0; k < 8; ++k) ratios8[t * 8 + k] = 0.05f * float(k + 1);
  }
  render::Renderer& renderer = shared_renderer();
  std::uint64_t version = hand_made + 3000;
  auto hand_over = [&] {
    render::MapSet set;
    set.width = width;
    set.height = height;
    set.heights = heights;
    set.heights_version = ++version;
    set.cones[1] = {4, bake::Address::wrap, ratios, apex, relaxed, version, 0, {}};
    set.cones[2] = {8, bake::Address::wrap, ratios8, apex8, relaxed8, version, 0, {}};
    renderer.set_maps(set);
  };
  ASSERT_NO_THROW(hand_over());
  long long taken = 0, refused = 0;
  auto try_bad = [&](float& value, float bad) {
    const float good = value;
    value = bad;
    try {
      hand_over();
      ++taken;
    } catch (const render::RenderError&) {
      ++refused;
    }
    value = good;
  };
  const float nan = std::nanf(""), inf = std::numeric_limits<float>::infinity();
  for (std::size_t t = 0; t < texels; ++t) {
    for (int k = 0; k < 4; ++k)
      for (float bad : {nan, -0.25f, inf}) try_bad(ratios[t * 4 + k], bad);
    for (float bad : {nan, -0.25f, 1.5f}) try_bad(apex[t], bad);
    for (float bad : {nan, -0.25f, inf}) try_bad(relaxed[t], bad);
    for (float bad : {nan, -0.25f, 1.5f}) try_bad(heights[t], bad);
    for (int k = 0; k < 8; ++k)
      for (float bad : {nan, -0.25f, inf}) try_bad(ratios8[t * 8 + k], bad);
    for (float bad : {nan, -0.25f, 1.5f}) try_bad(apex8[t], bad);
    for (float bad : {nan, -0.25f, inf}) try_bad(relaxed8[t], bad);
  }
  EXPECT_EQ(taken, 0);
  EXPECT_EQ(refused, static_cast<long long>(texels) * 3 * (4 + 1 + 1 + 1 + 8 + 1 + 1));
  EXPECT_NO_THROW(hand_over());
  EXPECT_EQ(renderer.validation_messages(), 0);
}

}  // namespace
