// tests/render/renderer_test.cpp - the Vulkan renderer on lavapipe (or whatever device the loader offers),
// validation on: every method against the exact CPU intersection, numerical stability at hard rays.
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

Frame render_frame(const HeightField& field, const View& view, Method method, int steps, int refine) {
  shared_maps().set_heights(field);
  return draw(view, {method, steps, refine});
}

struct HitError {
  double max_texels = 0.0;        // worst |uv - truth| over pixels both hit, in texels
  long long over_half_texel = 0;  // pixels whose hit is more than half a texel from the truth
  long long compared = 0;
  long long hit_mismatch = 0;  // pixels where exactly one of GPU and CPU hit the patch
};

HitError hit_error(const Frame& frame, const HeightField& field, const View& view) {
  HitError error;
  for (int py = 0; py < frame.height; ++py) {
    for (int px = 0; px < frame.width; ++px) {
      const std::size_t p = std::size_t(py) * frame.width + px;
      const render::CpuHit truth = render::cpu_trace(field, view, px + 0.5, py + 0.5);
      const bool gpu_hit = frame.uv[p * 3 + 2] > 0.5f;
      if (gpu_hit != truth.hit) {
        ++error.hit_mismatch;
        continue;
      }
      if (!truth.hit) continue;
      const double du = (frame.uv[p * 3 + 0] - truth.texture.x) * field.width;
      const double dv = (frame.uv[p * 3 + 1] - truth.texture.y) * field.height;
      const double texels = std::hypot(du, dv);
      error.max_texels = std::max(error.max_texels, texels);
      if (texels > 0.5) {
        ++error.over_half_texel;
        if (std::getenv("DISPLACE_DEBUG_HITS") && error.over_half_texel < 6)
          std::printf("  pixel %d,%d gpu %.5f,%.5f truth %.5f,%.5f,%.5f\n", px, py, frame.uv[p * 3],
                      frame.uv[p * 3 + 1], truth.texture.x, truth.texture.y, truth.texture.z);
      }
      ++error.compared;
    }
  }
  return error;
}

TEST(Renderer, ReportsItsDevice) {
  const render::DeviceInfo& device = shared_renderer().device();
  EXPECT_FALSE(device.name.empty());
  EXPECT_GE(device.sub_texel_precision_bits, 4);  // Vulkan's least
  std::printf("device: %s (%s), %d sub-texel bits\n", device.name.c_str(), device.type.c_str(),
              device.sub_texel_precision_bits);
}

// The bakers and the exact traces define the surface as the texels' bilinear interpolation with exact
// weights; a linear sampler's weights are fixed point on GPUs (8 bits on NVIDIA), and reads through it
// let rays end past the first crossing on an H200 (render/shaders/height_fetch.inc.glsl). lavapipe
// filters float images exactly, so no picture made here can show such a read: the shaders are read
// instead. Every height read is a gather (bilinear_height_of, the cell walks) or a texel fetch.
TEST(Renderer, ShadersReadHeightsOnlyWithExactWeights) {
  const std::filesystem::path shaders = std::filesystem::path(DISPLACE_SOURCE_DIR) / "render" / "shaders";
  int files = 0, gathers = 0;
  for (const auto& entry : std::filesystem::directory_iterator(shaders)) {
    if (entry.path().extension() != ".glsl") continue;
    ++files;
    std::ifstream in(entry.path());
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    for (const char* filtered :
         {"texture(height_map", "textureLod(height_map", "textureGrad(height_map", "textureProj(height_map",
          "textureOffset(height_map", "textureLodOffset(height_map"}) {
      EXPECT_EQ(text.find(filtered), std::string::npos)
          << entry.path().filename() << " reads " << filtered << ")";
    }
    for (std::size_t at = text.find("textureGather("); at != std::string::npos;
         at = text.find("textureGather(", at + 1)) {
      ++gathers;
    }
  }
  EXPECT_GT(files, 10);
  EXPECT_GE(gathers, 3);  // bilinear_height_of, the cell step, the pyramid's cell corners
}

TEST(Renderer, ExactClassMethodsHitWithinHalfATexelOfTheTruth) {
  const int size = 32;
  const std::vector<std::pair<std::string, HeightField>> fields = {{"constant", constant_field(size, 0.4f)},
                                                                   {"ramp", ramp_field(size)},
                                                                   {"step", step_field(size)},
                                                                   {"spikes", spike_field(size)}};
  const View view = oblique_view(48);
  for (const auto& [name, field] : fields) {
    for (const MethodInfo& info : render::method_table()) {
      if (!info.exact_class) continue;
      const Frame frame = render_frame(field, view, info.method, 256, 16);
      const HitError error = hit_error(frame, field, view);
      SCOPED_TRACE(name + " / " + info.name);
      std::printf("%-9s %-13s max %.3f texels, %lld over half a texel, %lld hit mismatches, of %lld\n",
                  name.c_str(), info.name, error.max_texels, error.over_half_texel, error.hit_mismatch,
                  error.compared);
      ASSERT_GT(error.compared, 1000);
      // A pixel whose ray grazes an edge may land on either side of it; allow 1% of pixels there.
      EXPECT_LE(error.over_half_texel + error.hit_mismatch, error.compared / 100)
          << "max " << error.max_texels << " texels, " << error.over_half_texel << " over half a texel, "
          << error.hit_mismatch << " hit mismatches of " << error.compared;
      if (name == "constant" || name == "ramp") {
        EXPECT_LE(error.max_texels, 0.5);
      }
    }
  }
  EXPECT_EQ(shared_renderer().validation_messages(), 0);
}

TEST(Renderer, ParallaxFamilyMatchesItsFormulaOnConstantHeight) {
  const int size = 16;
  const float h0 = 0.3f;
  const HeightField field = constant_field(size, h0);
  const View view = oblique_view(40);
  const Frame parallax = render_frame(field, view, Method::parallax, 1, 0);
  const Frame limited = render_frame(field, view, Method::parallax_limited, 1, 0);
  const Frame bump = render_frame(field, view, Method::bump, 1, 0);
  const int slope_iterations = 4;
  const Frame slope = render_frame(field, view, Method::parallax_slope, slope_iterations, 0);
  int checked = 0;
  for (int py = 0; py < view.camera.height; ++py) {
    for (int px = 0; px < view.camera.width; ++px) {
      const std::size_t p = std::size_t(py) * view.camera.width + px;
      const render::Ray ray = view.camera.pixel_ray(px + 0.5, py + 0.5);
      const double t = -ray.origin.z / ray.direction.z;
      const glm::dvec3 entry = ray.origin + t * ray.direction;
      if (entry.x < 0.02 || entry.x > 0.98 || entry.y < 0.02 || entry.y > 0.98) continue;
      // parallax: the ray meets the plane h = h0 (exact on constant height)
      const double descent = (1.0 - h0) * view.depth_scale;  // world depth below the polygon
      const double s_world = descent / -ray.direction.z;
      const glm::dvec3 parallax_point = entry + s_world * ray.direction;
      if (parallax_point.x < 0.0 || parallax_point.x > 1.0 || parallax_point.y < 0.0 ||
          parallax_point.y > 1.0) {
        continue;  // the offset leaves the patch: discarded, like a ray leaving through a side
      }
      EXPECT_NEAR(parallax.uv[p * 3 + 0], parallax_point.x, 1e-4);
      EXPECT_NEAR(parallax.uv[p * 3 + 1], parallax_point.y, 1e-4);
      // offset limiting: the same offset scaled by cos(view angle)
      const double cos_view = -ray.direction.z;
      EXPECT_NEAR(limited.uv[p * 3 + 0], entry.x + (parallax_point.x - entry.x) * cos_view, 1e-4);
      EXPECT_NEAR(limited.uv[p * 3 + 1], entry.y + (parallax_point.y - entry.y) * cos_view, 1e-4);
      // iterative parallax with slope information (Premecz): on a flat surface N' = (0, 0, 1), so each
      // iteration moves the descent s by gap * cos_view, gap = (1 - s) - h0: after n iterations
      // s = (1 - h0) * (1 - (1 - cos_view)^n), a world distance s * D / cos_view along the ray
      const double slope_descent = (1.0 - h0) * (1.0 - std::pow(1.0 - cos_view, slope_iterations));
      const glm::dvec3 slope_point = entry + (slope_descent * view.depth_scale / cos_view) * ray.direction;
      EXPECT_NEAR(slope.uv[p * 3 + 0], slope_point.x, 1e-4);
      EXPECT_NEAR(slope.uv[p * 3 + 1], slope_point.y, 1e-4);
      // bump: no displacement at all
      EXPECT_NEAR(bump.uv[p * 3 + 0], entry.x, 1e-4);
      EXPECT_NEAR(bump.uv[p * 3 + 1], entry.y, 1e-4);
      ++checked;
    }
  }
  EXPECT_GT(checked, 500);
  EXPECT_EQ(shared_renderer().validation_messages(), 0);
}

// Interval mapping's claim (Risser et al., sec. 4): its secant refinement reaches the hit with fewer
// texture reads than relief mapping's binary search. Each method gets the cheapest (steps, refine)
// of a grid that reaches the accuracy, and the secant-refined ones must need fewer reads per pixel
// than relief. On the ramp the gap is linear along every ray, so the secant of any bracket holding
// the single crossing is exact, even the first one; the waves check the claim on a curved surface.
TEST(Renderer, SecantRefinedMethodsNeedFewerFetchesThanReliefForTheSameAccuracy) {
  const double target_texels = 0.01;  // texels: worst hit error allowed, over pixels both hit
  const int size = 32;
  const std::vector<std::pair<std::string, HeightField>> fields = {{"ramp", ramp_field(size)},
                                                                   {"waves", waves_field(size)}};
  const View view = oblique_view(48);
  struct Cheapest {
    double fetches = 1e30;  // mean reads per pixel hit
    int steps = 0, refine = 0;
    double max_texels = 0.0;
  };
  for (const auto& named_field : fields) {  // (no structured binding: clang 14 lambdas capture none)
    const std::string& name = named_field.first;
    const HeightField& field = named_field.second;
    std::vector<render::CpuHit> truth;
    for (int py = 0; py < view.camera.height; ++py)
      for (int px = 0; px < view.camera.width; ++px)
        truth.push_back(render::cpu_trace(field, view, px + 0.5, py + 0.5));
    shared_maps().set_heights(field);
    auto cheapest = [&](Method method) {
      Cheapest best;
      for (int steps : {1, 2, 4, 8, 16, 32}) {
        for (int refine : {0, 1, 2, 4, 6, 8, 12}) {
          const Frame frame = draw(view, {method, steps, refine});
          double fetches = 0.0, max_texels = 0.0;
          long long hits = 0, mismatches = 0;
          for (std::size_t p = 0; p < truth.size(); ++p) {
            const bool gpu_hit = frame.uv[p * 3 + 2] > 0.5f;
            if (gpu_hit != truth[p].hit) ++mismatches;
            if (!gpu_hit || !truth[p].hit) continue;
            const double du = (frame.uv[p * 3 + 0] - truth[p].texture.x) * field.width;
            const double dv = (frame.uv[p * 3 + 1] - truth[p].texture.y) * field.height;
            max_texels = std::max(max_texels, std::hypot(du, dv));
            fetches += frame.fetches[p];
            ++hits;
          }
          if (hits == 0 || mismatches > 0 || max_texels > target_texels) continue;
          if (fetches / double(hits) < best.fetches)
            best = {fetches / double(hits), steps, refine, max_texels};
        }
      }
      return best;
    };
    const Cheapest relief = cheapest(Method::relief);
    for (const Method method : {Method::relief, Method::interval, Method::acm4_interval}) {
      const Cheapest best = method == Method::relief ? relief : cheapest(method);
      const char* method_name = render::method_info(method).name;
      std::printf("%-6s %-13s %6.2f fetches per pixel at steps %2d, refine %2d (max %.4f texels)\n",
                  name.c_str(), method_name, best.fetches, best.steps, best.refine, best.max_texels);
      ASSERT_GT(best.steps, 0) << name << " / " << method_name << " never reached " << target_texels
                               << " texels";
      if (method != Method::relief) {
        EXPECT_LT(best.fetches, relief.fetches) << name << " / " << method_name;
      }
    }
  }
  EXPECT_EQ(shared_renderer().validation_messages(), 0);
}

// Views whose centre pixel (odd image sizes put a pixel centre on the axis) sees the plane along a
// chosen direction: exactly vertical, 0.01 degrees above grazing, along an axis, along a sector
// boundary of the 8-sector map.
std::vector<std::pair<std::string, View>> hard_views() {
  std::vector<std::pair<std::string, View>> views;
  auto aimed = [](double azimuth_degrees, double elevation_degrees, double distance) {
    View view;
    const double a = glm::radians(azimuth_degrees), e = glm::radians(elevation_degrees);
    const glm::dvec3 target(0.5, 0.5, 0.0);
    const glm::dvec3 eye =
        target - distance * glm::dvec3(std::cos(e) * std::cos(a), std::cos(e) * std::sin(a), -std::sin(e));
    view.camera.eye = glm::vec3(eye);
    view.camera.look_at = glm::vec3(target);
    view.camera.up = elevation_degrees >= 89.999 ? glm::vec3(0, 1, 0) : glm::vec3(0, 0, 1);
    view.camera.width = 33;
    view.camera.height = 33;
    view.camera.fov_y_degrees = 20.0f;
    return view;
  };
  views.emplace_back("vertical", aimed(0.0, 90.0, 1.0));
  views.emplace_back("grazing", aimed(30.0, 0.01, 0.6));
  views.emplace_back("along-u", aimed(0.0, 35.0, 1.0));
  views.emplace_back("along-v", aimed(90.0, 35.0, 1.0));
  views.emplace_back("against-u", aimed(180.0, 35.0, 1.0));
  for (int k = 0; k < 8; ++k)
    views.emplace_back("sector-boundary-" + std::to_string(k * 45), aimed(k * 45.0, 20.0, 1.0));
  return views;
}

TEST(Renderer, NoNanOrInfOnHardRaysAndFlatMaps) {
  const std::vector<std::pair<std::string, HeightField>> fields = {{"all-zero", constant_field(16, 0.0f)},
                                                                   {"all-one", constant_field(16, 1.0f)},
                                                                   {"flat-half", constant_field(16, 0.5f)},
                                                                   {"step", step_field(16)}};
  const auto views = hard_views();
  for (const auto& [field_name, field] : fields) {
    shared_maps().set_heights(field);
    for (const auto& [view_name, view] : views) {
      for (const MethodInfo& info : render::method_table()) {
        const Frame frame = draw(view, {info.method, 16, 6});
        EXPECT_TRUE(all_finite(frame)) << field_name << " / " << view_name << " / " << info.name;
      }
    }
    // shadow rays from hard light directions: vertical, grazing, along an axis and a diagonal,
    // below the horizon (the counters include the shadow trace's reads)
    for (const glm::vec3 light : {glm::vec3(0, 0, 1), glm::vec3(1, 0, 1e-4f), glm::vec3(0, -1, 0.3f),
                                  glm::vec3(1, 1, 0.2f), glm::vec3(0.2f, 0, -1)}) {
      View view = oblique_view(24);
      view.shadows = true;
      view.light_direction = light;
      for (const MethodInfo& info : render::method_table()) {
        const Frame frame = draw(view, {info.method, 16, 6});
        EXPECT_TRUE(all_finite(frame)) << field_name << " / shadows / " << info.name;
      }
    }
  }
  EXPECT_EQ(shared_renderer().validation_messages(), 0);
}

TEST(Renderer, RejectsBadViewsWithAClearError) {
  shared_maps().set_heights(constant_field(4, 0.5f));
  View view = oblique_view(8);
  view.camera.look_at = view.camera.eye;
  EXPECT_THROW(draw(view, {Method::pom, 8, 0}), render::RenderError);
  view = oblique_view(8);
  view.depth_scale = std::nanf("");
  EXPECT_THROW(draw(view, {Method::pom, 8, 0}), render::RenderError);
  view = oblique_view(8);
  view.tile = 2;
  view.address = bake::Address::clamp;
  EXPECT_THROW(draw(view, {Method::pom, 8, 0}), render::RenderError);
  EXPECT_THROW(draw(oblique_view(8), {Method::pom, 0, 0}), render::RenderError);
  HeightField bad = constant_field(4, 0.5f);
  bad.heights[3] = std::nanf("");
  EXPECT_THROW(shared_maps().set_heights(bad), bake::BakeError);
  // the renderer checks heights handed to it directly as well
  render::MapSet maps;
  maps.width = maps.height = 4;
  maps.heights = bad.heights;
  maps.heights_version = ~std::uint64_t(0);
  EXPECT_THROW(shared_renderer().set_maps(maps), render::RenderError);
  maps.width = 5;
  EXPECT_THROW(shared_renderer().set_maps(maps), render::RenderError);
}

// maxmip and qdm with unlimited steps against the exact CPU trace, pixel by pixel, on the brick and
// cliff reliefs (sharp edges, single-texel spikes): power-of-two and odd non-square maps, wrap with
// tiling (rays cross tile boundaries) and clamp (rays leave through the patch sides).
TEST(Renderer, MaxPyramidMethodsMatchTheExactTraceWithUnlimitedSteps) {
  struct Scene {
    std::string name;
    HeightField field;
    View view;
  };
  auto relief = [](bool bricks, int width, int height) {
    HeightField field{width, height, std::vector<float>(std::size_t(width) * height)};
    if (bricks) {
      displace::sim::brick_heights(width, height, 1, field.heights);
    } else {
      displace::sim::cliff_heights(width, height, 1, field.heights);
    }
    return field;
  };
  std::vector<Scene> scenes;
  scenes.push_back({"bricks-64-wrap", relief(true, 64, 64), oblique_view(96)});
  scenes.push_back({"cliff-64-clamp", relief(false, 64, 64), oblique_view(96)});
  scenes.back().view.address = bake::Address::clamp;
  View tiled = oblique_view(96);
  tiled.tile = 3;
  tiled.camera.eye = {-0.2f, -0.3f, 0.35f};
  tiled.camera.look_at = {0.6f, 0.5f, -0.05f};
  scenes.push_back({"bricks-48x40-wrap-tile3", relief(true, 48, 40), tiled});
  View low = oblique_view(96);
  low.camera.eye = {0.5f, -0.6f, 0.25f};
  low.address = bake::Address::clamp;
  scenes.push_back({"cliff-37x29-clamp", relief(false, 37, 29), low});
  for (const Scene& scene : scenes) {
    const HeightField& field = scene.field;
    const View& view = scene.view;
    for (Method method : {Method::maxmip, Method::qdm}) {
      const Frame frame = render_frame(field, view, method, 4096, 0);
      long long compared = 0, wrong = 0;
      double max_texels = 0.0;
      for (int py = 0; py < frame.height; ++py) {
        for (int px = 0; px < frame.width; ++px) {
          const std::size_t p = std::size_t(py) * frame.width + px;
          const bool gpu_hit = frame.uv[p * 3 + 2] > 0.5f;
          auto texels_off = [&](const render::CpuHit& truth) {
            if (gpu_hit != truth.hit) return 1e30;
            if (!truth.hit) return 0.0;
            return std::hypot((frame.uv[p * 3 + 0] - truth.texture.x) * field.width,
                              (frame.uv[p * 3 + 1] - truth.texture.y) * field.height);
          };
          const double texels = texels_off(render::cpu_trace(field, view, px + 0.5, py + 0.5));
          if (texels > 0.5) ++wrong;
          if (gpu_hit) {
            ++compared;
            if (texels < 1e29) max_texels = std::max(max_texels, texels);
          }
        }
      }
      const float most_iterations = *std::max_element(frame.iterations.begin(), frame.iterations.end());
      std::printf(
          "%-24s %-7s max %.5f texels, %lld pixels off by more than half a texel or hit mismatched, of %lld, "
          "at most %.0f iterations\n",
          scene.name.c_str(), render::method_info(method).name, max_texels, wrong, compared, most_iterations);
      ASSERT_GT(compared, 3000) << scene.name;
      // no ray ran out of steps: the traversal never cycles
      EXPECT_LT(most_iterations, 4096.0f) << scene.name;
      EXPECT_EQ(wrong, 0) << scene.name << " / " << render::method_info(method).name;
    }
  }
  EXPECT_EQ(shared_renderer().validation_messages(), 0);
}

// The reference (tessellation + snap to the bilinear surface) against the exact CPU trace on the
// brick relief, whose sharp edges are where a tessellation and the bilinear surface disagree most.
TEST(Renderer, ReferenceAndReliefMatchTheExactTraceOnBricks) {
  HeightField field{64, 64, std::vector<float>(64 * 64)};
  displace::sim::brick_heights(64, 64, 1, field.heights);
  const View view = oblique_view(96);
  for (Method method : {Method::reference, Method::relief}) {
    const Frame frame = render_frame(field, view, method, 256, 16);
    const HitError error = hit_error(frame, field, view);
    std::printf("bricks %-10s max %.3f texels, %lld over half a texel, %lld hit mismatches, of %lld\n",
                render::method_info(method).name, error.max_texels, error.over_half_texel, error.hit_mismatch,
                error.compared);
    EXPECT_LE(error.over_half_texel + error.hit_mismatch, error.compared / 100);
  }
}

// With enough steps every exact-class method lands within RMSE 1.0 (8-bit units) of the reference
// on a brick relief and an ocean frame. Relaxed cone stepping included: as published it plateaued
// (bricks: rmse 2.87 at 4096 steps in the 512 x 512 sweep), since relaxed cones promise one crossing
// only for rays through the texel centre's apex and a relaxed step could jump over a brick edge; its
// steps are now verified with the bilinear cones (relaxed_march.inc.glsl).
TEST(Renderer, ExactClassMethodsConvergeToTheReference) {
  const auto scenes = bricks_and_ocean(128);
  View view;
  view.camera.width = 256;
  view.camera.height = 256;
  for (const auto& [name, field] : scenes) {
    shared_maps().set_heights(field);
    const Frame reference = draw(view, {Method::reference, 1, 0});
    for (const MethodInfo& info : render::method_table()) {
      if (!info.exact_class || info.family == render::MethodFamily::reference) continue;
      const int steps = info.family == render::MethodFamily::linear_search ? 4096 : 512;
      const Frame frame = draw(view, {info.method, steps, 16});
      const render::ImageError error = render::compare(frame, reference);
      std::printf("%-7s %-14s %4d steps: rmse %.3f, %lld of %lld pixels off by more than 10\n", name.c_str(),
                  info.name, steps, error.rmse, (long long)(error.fraction_over_10 * error.pixels + 0.5),
                  error.pixels);
      EXPECT_LE(error.rmse, 1.0) << name << " / " << info.name;
    }
  }
  EXPECT_EQ(shared_renderer().validation_messages(), 0);
}

// Error against the reference does not grow as steps grow, for every exact-class method, on a
// small ocean frame and a small brick relief.
TEST(Renderer, ErrorDoesNotGrowWithSteps) {
  constexpr double noise = 0.25;  // 8-bit rmse units: pixels that flip at a grid line between runs
  const auto scenes = bricks_and_ocean(64);
  View view;
  view.camera.width = 96;
  view.camera.height = 96;
  for (const auto& [name, field] : scenes) {
    shared_maps().set_heights(field);
    const Frame reference = draw(view, {Method::reference, 1, 0});
    for (const MethodInfo& info : render::method_table()) {
      if (!info.exact_class || info.family == render::MethodFamily::reference) continue;
      std::string line;
      double previous = 1e30;
      for (int steps : {4, 8, 16, 32, 64}) {
        const double rmse = render::compare(draw(view, {info.method, steps, 8}), reference).rmse;
        char entry[32];
        std::snprintf(entry, sizeof entry, " %d:%.3f", steps, rmse);
        line += entry;
        EXPECT_LE(rmse, previous + noise) << name << " / " << info.name << " at " << steps << " steps";
        previous = rmse;
      }
      std::printf("%-7s %-14s rmse by steps%s\n", name.c_str(), info.name, line.c_str());
    }
  }
  EXPECT_EQ(shared_renderer().validation_messages(), 0);
}

View top_down_view(int pixels) {
  View view;
  view.camera.eye = {0.5f, 0.5f, 2.0f};
  view.camera.look_at = {0.5f, 0.5f, 0.0f};
  view.camera.up = {0.0f, 1.0f, 0.0f};
  view.camera.fov_y_degrees = 30.0f;
  view.camera.width = pixels;
  view.camera.height = pixels;
  view.address = bake::Address::clamp;
  return view;
}

bool colour_differs(const Frame& a, const Frame& b, std::size_t pixel) {
  for (int c = 0; c < 3; ++c) {
    if (std::abs(int(a.color[pixel * 4 + c]) - int(b.color[pixel * 4 + c])) > 8) return true;
  }
  return false;
}

// A step casts the shadow its height and the light's elevation put on the floor, for the reference
// and every exact-class method; a flat map casts none (no self-shadowing acne).
TEST(Renderer, ShadowsFallWhereTheStepHeightPutsThem) {
  const int size = 64;
  const HeightField step = step_field(size);  // 0.2 for u < 0.5, 0.8 beyond, a one-texel ramp between
  const HeightField flat = constant_field(size, 0.4f);
  View view = top_down_view(128);
  view.light_direction = {1.0f, 0.0f, 0.25f};    // from +u, low: the plateau shades the floor below it
  const double slope = 0.25 / view.depth_scale;  // heights gained per uv along the light ray
  const double ramp_start = (size / 2 - 0.5) / size, ramp_end = (size / 2 + 0.5) / size;
  const double shadow_start =
      ramp_end - 0.6 / slope;  // the floor point whose light ray grazes the ramp's top
  const double texel = 1.0 / size;
  for (const MethodInfo& info : render::method_table()) {
    if (!info.exact_class) continue;
    SCOPED_TRACE(info.name);
    View lit_view = view;
    View shadow_view = view;
    shadow_view.shadows = true;
    const Frame lit = render_frame(step, lit_view, info.method, 256, 16);
    const Frame shaded = render_frame(step, shadow_view, info.method, 256, 16);
    long long shadowed = 0, wrong = 0, floor_pixels = 0;
    for (std::size_t p = 0; p < std::size_t(128 * 128); ++p) {
      if (shaded.uv[p * 3 + 2] == 0.0f) continue;
      const double u = shaded.uv[p * 3 + 0];
      const bool differs = colour_differs(lit, shaded, p);
      if (u < shadow_start - 1.5 * texel || u > ramp_end + texel) {
        wrong += differs;  // lit floor far from the step, and the plateau
      } else if (u > shadow_start + 1.5 * texel && u < ramp_start - texel) {
        ++floor_pixels;
        shadowed += differs;
        wrong += !differs;
      }
    }
    EXPECT_GT(floor_pixels, 200);
    EXPECT_EQ(wrong, 0) << shadowed << " of " << floor_pixels << " floor pixels in the shadow band are dark";
    const Frame flat_lit = render_frame(flat, lit_view, info.method, 256, 16);
    const Frame flat_shaded = render_frame(flat, shadow_view, info.method, 256, 16);
    long long acne = 0;
    for (std::size_t p = 0; p < std::size_t(128 * 128); ++p) acne += colour_differs(flat_lit, flat_shaded, p);
    EXPECT_EQ(acne, 0);
  }
  EXPECT_EQ(shared_renderer().validation_messages(), 0);
}

// Sphere tracing (render/shaders/sphere_trace.inc.glsl) never passes the first crossing of the ray
// with the bilinear surface and never ends below the surface, at any step budget: its sphere steps
// read a conservative distance map and its cell walk solves each cell exactly. Checked per pixel
// against the exact CPU trace, with several tile counts K, depth scales D and both address modes
// (the map is in texture units, so the ray's step is r / |descent| whatever K and D are). With
// enough steps every hit lies on the surface and within half a texel of the CPU's hit.
TEST(Renderer, SphereTracingNeverStepsPastTheSurface) {
  constexpr double world_tolerance = 1e-5;  // world units: float rounding of the root and of the depth AOV
  HeightField bricks{64, 64, std::vector<float>(64 * 64)};
  displace::sim::brick_heights(64, 64, 1, bricks.heights);
  const std::vector<std::pair<std::string, HeightField>> fields = {{"spikes", spike_field(32)},
                                                                   {"bricks", std::move(bricks)}};
  struct Case {
    const char* name;
    int tile;
    float depth_scale;
    bake::Address address;
  };
  const Case cases[] = {{"K1 D0.1 wrap", 1, 0.1f, bake::Address::wrap},
                        {"K2 D0.3 wrap", 2, 0.3f, bake::Address::wrap},
                        {"K3 D0.02 wrap", 3, 0.02f, bake::Address::wrap},
                        {"K1 D0.5 clamp", 1, 0.5f, bake::Address::clamp}};
  for (const auto& [field_name, field] : fields) {
    shared_maps().set_heights(field);
    for (const Case& c : cases) {
      View view = oblique_view(48);
      view.tile = c.tile;
      view.depth_scale = c.depth_scale;
      view.address = c.address;
      std::vector<render::CpuHit> truth;
      for (int py = 0; py < view.camera.height; ++py)
        for (int px = 0; px < view.camera.width; ++px)
          truth.push_back(render::cpu_trace(field, view, px + 0.5, py + 0.5));
      const double tolerance = world_tolerance / view.depth_scale;  // in height units
      for (int steps : {4, 16, 256}) {
        const Frame frame = draw(view, {Method::sphere, steps, 0});
        long long compared = 0, past = 0, below = 0, above = 0, mismatches = 0, over_half_texel = 0;
        double worst_past = 0.0, worst_below = 0.0;
        for (int py = 0; py < frame.height; ++py) {
          for (int px = 0; px < frame.width; ++px) {
            const std::size_t p = std::size_t(py) * frame.width + px;
            const bool gpu_hit = frame.uv[p * 3 + 2] > 0.5f;
            if (gpu_hit != truth[p].hit) ++mismatches;
            if (!gpu_hit || !truth[p].hit) continue;
            ++compared;
            // the descent s = 1 - h of the GPU's hit, from its distance along the pixel's ray
            const render::Ray ray = view.camera.pixel_ray(px + 0.5, py + 0.5);
            const double h = 1.0 + (ray.origin.z + frame.depth[p] * ray.direction.z) / view.depth_scale;
            const double gap =
                h - render::bilinear_height(field, view.address, frame.uv[p * 3], frame.uv[p * 3 + 1]);
            const double beyond = truth[p].texture.z - h;  // > 0: further down the ray than the first hit
            if (beyond > tolerance) ++past;
            if (gap < -tolerance) ++below;
            if (gap > tolerance) ++above;
            worst_past = std::max(worst_past, beyond);
            worst_below = std::max(worst_below, -gap);
            const double texels = std::hypot((frame.uv[p * 3] - truth[p].texture.x) * field.width,
                                             (frame.uv[p * 3 + 1] - truth[p].texture.y) * field.height);
            if (texels > 0.5) ++over_half_texel;
          }
        }
        std::printf(
            "%-6s %-13s %3d steps: %lld compared, past the first hit %lld (worst %.1e), below %lld (worst "
            "%.1e), above %lld, over half a texel %lld, hit mismatches %lld\n",
            field_name.c_str(), c.name, steps, compared, past, worst_past, below, worst_below, above,
            over_half_texel, mismatches);
        SCOPED_TRACE(field_name + " / " + c.name + " / " + std::to_string(steps) + " steps");
        ASSERT_GT(compared, 500);
        EXPECT_EQ(past, 0);
        EXPECT_EQ(below, 0);
        if (steps == 256) {
          EXPECT_EQ(above, 0);
          // a ray that grazes an edge may land on either side of it; allow 1% of pixels there
          EXPECT_LE(over_half_texel + mismatches, compared / 100);
        }
      }
    }
  }
  EXPECT_EQ(shared_renderer().validation_messages(), 0);
}

// An albedo image replaces the procedural grid: a red albedo on a flat map gives red times the
// Lambert term plus the (white, small) highlight, and clearing it brings the grid back.
TEST(Renderer, AlbedoImageShadesTheHit) {
  const HeightField flat = constant_field(16, 0.5f);
  View view = top_down_view(32);
  view.light_direction = {1.0f, 0.0f, 1.0f};
  render::Renderer& renderer = shared_renderer();
  shared_maps().set_heights(flat);
  renderer.set_albedo({2, 2, std::vector<std::uint8_t>(16, 0)});  // all black first: replaced below
  renderer.set_albedo({2, 2, {255, 0, 0, 255, 255, 0, 0, 255, 255, 0, 0, 255, 255, 0, 0, 255}});
  const Frame red = draw(view, {Method::relief, 32, 8});
  renderer.clear_albedo();
  const Frame grid = draw(view, {Method::relief, 32, 8});
  const double lambert = 0.15 + 0.85 * std::sqrt(0.5);
  long long checked = 0, grid_differs = 0;
  for (std::size_t p = 0; p < std::size_t(32 * 32); ++p) {
    if (red.uv[p * 3 + 2] == 0.0f) continue;
    ++checked;
    const int highlight = red.color[p * 4 + 1];
    EXPECT_NEAR(red.color[p * 4 + 0] - highlight, 255.0 * lambert, 2.0);
    EXPECT_EQ(red.color[p * 4 + 2], highlight);
    EXPECT_LE(highlight, 20);  // the highlight at its peak would be 0.25 * 255
    grid_differs += colour_differs(red, grid, p);
  }
  EXPECT_GT(checked, 500);
  EXPECT_EQ(grid_differs, checked);
  EXPECT_THROW(renderer.set_albedo({2, 2, std::vector<std::uint8_t>(15, 0)}), render::RenderError);
  EXPECT_THROW(renderer.set_albedo({0, 0, {}}), render::RenderError);
  EXPECT_EQ(renderer.validation_messages(), 0);
}

// Sphere tracing against relief mapping on smooth fields: each method gets the cheapest setting of a
// grid (steps, and refine for relief) that reaches the accuracy on every pixel, and sphere tracing
// must need fewer reads per pixel than relief (a textureGather of one cell counts as one read, like
// a bilinear read does).
TEST(Renderer, SphereTracingNeedsFewerFetchesThanReliefOnSmoothFields) {
  const double target_texels = 0.01;  // texels: worst hit error allowed, over pixels both hit
  const int size = 32;
  const std::vector<std::pair<std::string, HeightField>> fields = {{"ramp", ramp_field(size)},
                                                                   {"waves", waves_field(size)}};
  const View view = oblique_view(48);
  for (const auto& named_field : fields) {  // (no structured binding: clang 14 lambdas capture none)
    const std::string& name = named_field.first;
    const HeightField& field = named_field.second;
    std::vector<render::CpuHit> truth;
    for (int py = 0; py < view.camera.height; ++py)
      for (int px = 0; px < view.camera.width; ++px)
        truth.push_back(render::cpu_trace(field, view, px + 0.5, py + 0.5));
    shared_maps().set_heights(field);
    // mean reads per pixel hit of the cheapest setting that reaches the target, and that setting
    auto cheapest = [&](Method method, std::initializer_list<int> refines) {
      double best = 1e30;
      int best_steps = 0, best_refine = 0;
      for (int steps : {1, 2, 4, 8, 16, 32, 64}) {
        for (int refine : refines) {
          const Frame frame = draw(view, {method, steps, refine});
          double fetches = 0.0, max_texels = 0.0;
          long long hits = 0, mismatches = 0;
          for (std::size_t p = 0; p < truth.size(); ++p) {
            const bool gpu_hit = frame.uv[p * 3 + 2] > 0.5f;
            if (gpu_hit != truth[p].hit) ++mismatches;
            if (!gpu_hit || !truth[p].hit) continue;
            max_texels =
                std::max(max_texels, std::hypot((frame.uv[p * 3] - truth[p].texture.x) * field.width,
                                                (frame.uv[p * 3 + 1] - truth[p].texture.y) * field.height));
            fetches += frame.fetches[p];
            ++hits;
          }
          if (hits == 0 || mismatches > 0 || max_texels > target_texels) continue;
          if (fetches / double(hits) < best)
            std::tie(best, best_steps, best_refine) = std::tuple(fetches / double(hits), steps, refine);
        }
      }
      std::printf("%-6s %-7s %6.2f fetches per pixel at steps %2d, refine %2d\n", name.c_str(),
                  render::method_info(method).name, best, best_steps, best_refine);
      return best;
    };
    const double relief = cheapest(Method::relief, {0, 1, 2, 4, 6, 8, 12, 16});
    const double sphere = cheapest(Method::sphere, {0});
    ASSERT_LT(relief, 1e30) << name << ": relief never reached " << target_texels << " texels";
    ASSERT_LT(sphere, 1e30) << name << ": sphere never reached " << target_texels << " texels";
    EXPECT_LT(sphere, relief) << name;
  }
  EXPECT_EQ(shared_renderer().validation_messages(), 0);
}

// Over 1..64 steps of each of `methods`, on sharp and smooth fields with wrap and clamp, the rays
// that end beyond their exact first crossing (render::cpu_trace), with the cone maps baked within
// `cone_budget`: none may.
void expect_no_ray_past_the_first_crossing(std::initializer_list<Method> methods,
                                           const bake::Budget& cone_budget, const char* label) {
  constexpr double tolerance = 1e-4;  // world units (a texel here is 0.03): float rounding of the march
  HeightField bricks{32, 32, std::vector<float>(32 * 32)};
  displace::sim::brick_heights(32, 32, 1, bricks.heights);
  const std::vector<std::pair<std::string, HeightField>> fields = {
      {"spikes", spike_field(32)},
      {"step", step_field(32)},
      {"bricks", bricks},
      {"waves", waves_field(32)},
      {"noise",
       field_of(24, 20, [](int i, int j) { return 0.5 + 0.5 * std::sin(12.9898 * i + 78.233 * j * j); })}};
  for (const bake::Address address : {bake::Address::wrap, bake::Address::clamp}) {
    View view = oblique_view(48);
    view.address = address;
    for (const auto& [name, field] : fields) {
      std::vector<render::CpuHit> truth;
      for (int py = 0; py < view.camera.height; ++py)
        for (int px = 0; px < view.camera.width; ++px)
          truth.push_back(render::cpu_trace(field, view, px + 0.5, py + 0.5));
      shared_maps().set_cone_budget(cone_budget);
      shared_maps().set_heights(field);
      for (const Method method : methods) {
        long long compared = 0, beyond = 0;
        double worst = 0.0;
        for (int steps : {1, 2, 3, 5, 8, 16, 64}) {
          const Frame frame = draw(view, {method, steps, 0});
          for (std::size_t p = 0; p < truth.size(); ++p) {
            if (!truth[p].hit || frame.uv[p * 3 + 2] < 0.5f) continue;
            ++compared;
            const double past = frame.depth[p] - truth[p].distance;
            worst = std::max(worst, past);
            if (past > tolerance) ++beyond;
          }
        }
        std::printf("%s: %-6s %-5s %-7s %lld rays, %lld beyond the first crossing, worst %.2g\n", label,
                    name.c_str(), address == bake::Address::wrap ? "wrap" : "clamp",
                    render::method_info(method).name, compared, beyond, worst);
        EXPECT_GT(compared, 5000);
        EXPECT_EQ(beyond, 0) << label << " " << name << " / " << render::method_info(method).name;
      }
    }
  }
  shared_maps().set_cone_budget({});
  EXPECT_EQ(shared_renderer().validation_messages(), 0);
}

// The cone methods' steps are safe for the bilinear surface from wherever the ray is (cone maps
// baked for it, bake_bilinear_cones' contract): with any number of steps, however few, a ray never
// ends beyond its exact first crossing, on wrap and clamp, sharp and smooth fields. Relaxed cone
// steps too: each is verified with the bilinear cones from both of its ends, and one that lands
// below the surface is searched with conservative and exact cell steps. (Accepting every relaxed
// step that lands above the surface, unverified, ends 51 rays beyond it on the spikes, by up to
// 0.16, and 2 on the noise.)
TEST(Renderer, ConeStepsNeverPassTheFirstCrossing) {
  expect_no_ray_past_the_first_crossing({Method::csm, Method::acm4, Method::acm8, Method::relaxed}, {},
                                        "unlimited");
}

// The same with the cone maps baked at budget 0 (0 ms and no work past the baker's first stage):
// a starved bake is looser, never unsafe.
TEST(Renderer, ConeStepsOnMapsBakedAtBudgetZeroNeverPassTheFirstCrossing) {
  bake::Budget starved;
  starved.milliseconds = 0.0;
  starved.max_work = 0;
  expect_no_ray_past_the_first_crossing({Method::csm, Method::acm4, Method::acm8}, starved, "budget 0");
}

}  // namespace
