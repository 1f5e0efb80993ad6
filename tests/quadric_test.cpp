// tests/quadric_test.cpp - inverse displacement mapping on the quadrics (sphere, cylinder, cone) with
// the validation layer on: silhouettes and hits of constant-height spheres against the analytic
// sphere, every quadric method against the exact CPU trace, no NaN and no holes on rays through the
// poles, along the axes and through the apex region, and clear errors for what is not supported.
#include "render/quadric.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <numbers>
#include <string>
#include <vector>

#include "render/render.h"

namespace {

using namespace displace;
using render::Frame;
using render::HeightField;
using render::Method;
using render::Surface;
using render::View;

render::Renderer& quadric_renderer() {
  static std::unique_ptr<render::Renderer> renderer =
      std::make_unique<render::Renderer>(render::RendererOptions{"", true});
  return *renderer;
}

HeightField field_of(int width, int height, auto&& height_at) {
  HeightField field{width, height, std::vector<float>(std::size_t(width) * height)};
  for (int i = 0; i < height; ++i)
    for (int j = 0; j < width; ++j) field.heights[std::size_t(i) * width + j] = float(height_at(i, j));
  return field;
}
HeightField constant_field(int size, double value) {
  return field_of(size, size, [&](int, int) { return value; });
}
HeightField waves_field(int size) {  // periodic: 3 waves around u, 2 along v
  return field_of(size, size, [&](int i, int j) {
    return 0.5 + 0.4 * std::sin(6.0 * std::numbers::pi * (j + 0.5) / size) *
                     std::cos(4.0 * std::numbers::pi * (i + 0.5) / size);
  });
}
HeightField spike_field(int size) {
  return field_of(size, size, [&](int i, int j) { return (i % 8 == 3 && j % 8 == 5) ? 1.0 : 0.1; });
}
HeightField ramp_u_field(int size) {  // a cliff at the seam u = 0 = 1 when u wraps
  return field_of(size, size, [&](int i, int j) {
    return 0.1 + 0.8 * (j + 0.5) / size * (0.5 + 0.5 * (i + 0.5) / size);
  });
}

const std::vector<Method>& quadric_methods() {
  static const std::vector<Method> methods = [] {
    std::vector<Method> list;
    for (const render::MethodInfo& info : render::method_table()) {
      if (render::supports_surface(info.method, Surface::sphere)) list.push_back(info.method);
    }
    return list;
  }();
  return methods;
}

View looking_at(Surface surface, glm::vec3 eye, glm::vec3 target, int pixels, float fov) {
  View view;
  view.surface = surface;
  view.radius = 0.25f;
  view.depth_scale = 0.1f;
  view.camera.eye = eye;
  view.camera.look_at = target;
  const glm::vec3 forward = glm::normalize(target - eye);
  view.camera.up = std::abs(forward.z) > 0.999f ? glm::vec3(0, 1, 0) : glm::vec3(0, 0, 1);
  view.camera.width = pixels;
  view.camera.height = pixels;
  view.camera.fov_y_degrees = fov;
  return view;
}

Frame render_frame(const HeightField& field, const View& view, Method method, int steps, int refine) {
  quadric_renderer().set_height_field(field);
  return quadric_renderer().render(view, {method, steps, refine});
}

bool hit_at(const Frame& frame, std::size_t p) { return frame.uv[p * 3 + 2] > 0.5f; }

bool all_finite(const Frame& frame) {
  auto finite = [](const std::vector<float>& values) {
    return std::all_of(values.begin(), values.end(), [](float v) { return std::isfinite(v); });
  };
  return finite(frame.uv) && finite(frame.depth) && finite(frame.iterations) && finite(frame.fetches);
}

// Acceptance: a sphere whose height is constant c is the sphere of radius r_c = R - (1 - c) D. A
// pixel is hit exactly when its centre ray passes within r_c of the centre (pixels whose closest
// approach lies within a quarter of a pixel's footprint of r_c may go either way), and the hit lies
// on that sphere (the depth AOV against the analytic ray / sphere distance, measured radially).
// 128 steps: rays that cross the polar cap need more cone steps than elsewhere (the (u, v) speed
// grows as 1 / distance from the axis there); at 64 the cone methods leave 2 such pixels short.
TEST(Quadric, ConstantHeightSphereHasItsSilhouetteWhereTheRadiusPutsIt) {
  const glm::dvec3 centre(0.5, 0.5, 0.0);
  const int map_size = 64;
  View view = looking_at(Surface::sphere, {0.5f, -0.45f, 0.55f}, {0.5f, 0.5f, 0.0f}, 128, 30.0f);
  const double pixel_angle =
      2.0 * std::tan(glm::radians(double(view.camera.fov_y_degrees)) / 2.0) / view.camera.height;
  const std::vector<Method> methods = {Method::reference, Method::relief,       Method::interval,
                                       Method::csm,       Method::acm4,         Method::pom,
                                       Method::acm8,      Method::acm4_interval};
  for (double c : {0.0, 0.45, 1.0}) {
    const double radius = view.radius - (1.0 - c) * view.depth_scale;
    quadric_renderer().set_height_field(constant_field(map_size, c));
    for (Method method : methods) {
      const Frame frame = quadric_renderer().render(view, {method, 128, 8});
      // the reference's facets lie inside the sphere by at most the sagitta of a texel's diagonal
      const double half_diagonal =
          0.5 * std::hypot(2.0 * std::numbers::pi / map_size, std::numbers::pi / map_size);
      const double radial_tolerance =
          method == Method::reference ? radius * (1.0 - std::cos(half_diagonal)) + 1e-5 : 1e-4;
      long long mask_errors = 0, depth_errors = 0, hits = 0, undecided = 0;
      double worst_radial = 0.0;
      for (int py = 0; py < frame.height; ++py) {
        for (int px = 0; px < frame.width; ++px) {
          const std::size_t p = std::size_t(py) * frame.width + px;
          const render::Ray ray = view.camera.pixel_ray(px + 0.5, py + 0.5);
          const double along = glm::dot(centre - ray.origin, ray.direction);
          const double closest = glm::length(ray.origin + along * ray.direction - centre);
          const double footprint = pixel_angle * along;
          if (std::abs(closest - radius) < 0.25 * footprint) {
            ++undecided;
            continue;
          }
          const bool expected = closest < radius;
          if (hit_at(frame, p) != expected) {
            ++mask_errors;
            continue;
          }
          if (!expected) continue;
          ++hits;
          const double analytic = along - std::sqrt(radius * radius - closest * closest);
          const glm::dvec3 point = ray.origin + double(frame.depth[p]) * ray.direction;
          const double radial = std::abs(glm::length(point - centre) - radius);
          worst_radial = std::max(worst_radial, radial);
          // radially: a depth error of x moves the point by x times the cosine of incidence
          if (radial > radial_tolerance || frame.depth[p] < analytic - 1e-4) ++depth_errors;
        }
      }
      const char* name = render::method_info(method).name;
      std::printf(
          "c %.2f %-13s %lld hits, %lld mask errors, %lld off the sphere (worst %.2e), %lld undecided\n", c,
          name, hits, mask_errors, depth_errors, worst_radial, undecided);
      EXPECT_GT(hits, 1500) << name;
      EXPECT_EQ(mask_errors, 0) << "c " << c << " / " << name;
      EXPECT_EQ(depth_errors, 0) << "c " << c << " / " << name << ": worst radial error " << worst_radial;
    }
  }
  EXPECT_EQ(quadric_renderer().validation_messages(), 0);
}

struct HitError {
  double max_texels = 0.0;
  long long over_half_texel = 0, hit_mismatch = 0, compared = 0;
};

HitError hit_error(const Frame& frame, const HeightField& field, const View& view,
                   const std::vector<render::CpuHit>& truth) {
  HitError error;
  for (std::size_t p = 0; p < truth.size(); ++p) {
    const bool gpu_hit = hit_at(frame, p);
    if (gpu_hit != truth[p].hit) {
      ++error.hit_mismatch;
      continue;
    }
    if (!gpu_hit) continue;
    const double tile = view.tile;
    const double du =
        std::remainder(frame.uv[p * 3 + 0] - truth[p].texture.x, tile) * field.width;  // u wraps
    const double dv = (frame.uv[p * 3 + 1] - truth[p].texture.y) * field.height;
    const double texels = std::hypot(du, dv);
    error.max_texels = std::max(error.max_texels, texels);
    if (texels > 0.5) ++error.over_half_texel;
    ++error.compared;
  }
  return error;
}

std::vector<render::CpuHit> exact_hits(const HeightField& field, const View& view) {
  std::vector<render::CpuHit> truth;
  for (int py = 0; py < view.camera.height; ++py)
    for (int px = 0; px < view.camera.width; ++px)
      truth.push_back(render::cpu_trace_quadric(field, view, px + 0.5, py + 0.5));
  return truth;
}

// Every quadric method converges to the exact CPU trace: with enough steps, all but 1% of the pixels
// land within half a texel of it (as the plane's exact-class methods must). Cone steps that were not
// conservative under the parameterisation's distortion would pass through the spikes.
TEST(Quadric, MethodsHitWithinHalfATexelOfTheExactTrace) {
  const int size = 32;
  struct Case {
    std::string name;
    Surface surface;
    HeightField field;
    int tile = 1;
    bake::Address address = bake::Address::wrap;
  };
  const std::vector<Case> cases = {
      {"sphere/waves", Surface::sphere, waves_field(size)},
      {"sphere/spikes", Surface::sphere, spike_field(size)},
      {"sphere/ramp-u clamp", Surface::sphere, ramp_u_field(size), 1, bake::Address::clamp},
      {"cylinder/waves", Surface::cylinder, waves_field(size)},
      {"cylinder/spikes tile 2", Surface::cylinder, spike_field(size), 2},
      {"cone/waves", Surface::cone, waves_field(size)},
      {"cone/spikes", Surface::cone, spike_field(size)},
  };
  for (const Case& test : cases) {
    View view = looking_at(test.surface, {0.5f, -0.4f, 0.45f}, {0.5f, 0.5f, 0.0f}, 56, 30.0f);
    view.tile = test.tile;
    view.address = test.address;
    const std::vector<render::CpuHit> truth = exact_hits(test.field, view);
    const long long truth_hits =
        std::count_if(truth.begin(), truth.end(), [](const render::CpuHit& h) { return h.hit; });
    for (Method method : quadric_methods()) {
      if (method == Method::bump) continue;       // no displacement
      if (method == Method::reference) continue;  // the tessellated surface: tested on its own below
      const Frame frame = render_frame(test.field, view, method, 256, 16);
      const HitError error = hit_error(frame, test.field, view, truth);
      const char* name = render::method_info(method).name;
      std::printf(
          "%-24s %-13s max %.3f texels, %lld over half a texel, %lld hit mismatches, of %lld (exact hits "
          "%lld)\n",
          test.name.c_str(), name, error.max_texels, error.over_half_texel, error.hit_mismatch,
          error.compared, truth_hits);
      EXPECT_GT(error.compared, 600) << test.name << " / " << name;
      EXPECT_LE(error.over_half_texel + error.hit_mismatch, error.compared / 100)
          << test.name << " / " << name;
    }
  }
  EXPECT_EQ(quadric_renderer().validation_messages(), 0);
}

// The reference on a quadric is the tessellated surface: the GPU's hits are those of a CPU ray trace
// of the same triangles (vertices at texel centres plus the seam and the ends, each pole row on the
// sphere one shared vertex), nearest front face first, seen through the outer surface's finite part.
struct Triangle {
  glm::dvec3 a, b, c;
};

std::vector<Triangle> reference_mesh(const HeightField& field, const View& view) {
  const render::quadric::Shape shape = render::quadric::shape_of(view);
  const int tile = view.tile;
  const long long columns = (long long)field.width * tile + 2, rows = (long long)field.height * tile + 2;
  auto coordinate = [&](long long index, int size) {
    return std::clamp((double(index) - 0.5) / size, 0.0, double(tile));
  };
  std::vector<glm::dvec3> vertices;
  for (long long i = 0; i < rows; ++i) {
    for (long long j = 0; j < columns; ++j) {
      double u = coordinate(j, field.width);
      const double v = coordinate(i, field.height);
      if (u >= tile || (view.surface == Surface::sphere && (v <= 0.0 || v >= tile))) u = 0.0;
      const double h = render::bilinear_height(field, view.address, u, v);
      vertices.push_back(render::quadric::surface_point(shape, u, v, h));
    }
  }
  std::vector<Triangle> triangles;
  for (long long i = 0; i + 1 < rows; ++i) {
    for (long long j = 0; j + 1 < columns; ++j) {
      const long long a = i * columns + j, b = a + 1, c = a + columns, d = c + 1;
      triangles.push_back({vertices[a], vertices[b], vertices[d]});
      triangles.push_back({vertices[a], vertices[d], vertices[c]});
    }
  }
  return triangles;
}

// Nearest front-facing hit of the ray (Moller-Trumbore); -1 for none.
double trace_mesh(const std::vector<Triangle>& triangles, const render::Ray& ray) {
  double nearest = -1.0;
  for (const Triangle& t : triangles) {
    const glm::dvec3 e1 = t.b - t.a, e2 = t.c - t.a;
    if (glm::dot(glm::cross(e1, e2), ray.direction) >= 0.0) continue;  // back face or degenerate
    const glm::dvec3 p = glm::cross(ray.direction, e2);
    const double det = glm::dot(e1, p);
    const glm::dvec3 s = ray.origin - t.a;
    const double u = glm::dot(s, p) / det;
    if (u < 0.0 || u > 1.0) continue;
    const glm::dvec3 q = glm::cross(s, e1);
    const double v = glm::dot(ray.direction, q) / det;
    if (v < 0.0 || u + v > 1.0) continue;
    const double distance = glm::dot(e2, q) / det;
    if (distance > 0.0 && (nearest < 0.0 || distance < nearest)) nearest = distance;
  }
  return nearest;
}

TEST(Quadric, ReferenceIsTheTessellatedSurface) {
  namespace quadric = render::quadric;
  const int size = 16;
  for (Surface surface : {Surface::sphere, Surface::cylinder, Surface::cone}) {
    // oblique, and steeply from above (through the sphere's pole; the cylinder from beside its axis)
    const glm::vec3 above =
        surface == Surface::cylinder ? glm::vec3(1.2f, 0.5f, 1.0f) : glm::vec3(0.5f, 0.5f, 1.2f);
    for (const glm::vec3 eye : {glm::vec3(0.5f, -0.4f, 0.45f), above}) {
      const View view = looking_at(surface, eye, {0.5f, 0.5f, 0.0f}, 40, 36.0f);
      const HeightField field = waves_field(size);
      const Frame frame = render_frame(field, view, Method::reference, 1, 0);
      const std::vector<Triangle> mesh = reference_mesh(field, view);
      const quadric::Shape shape = quadric::shape_of(view);
      long long compared = 0, mismatches = 0, depth_errors = 0;
      for (int py = 0; py < frame.height; ++py) {
        for (int px = 0; px < frame.width; ++px) {
          const std::size_t p = std::size_t(py) * frame.width + px;
          const render::Ray ray = view.camera.pixel_ray(px + 0.5, py + 0.5);
          double distance = trace_mesh(mesh, ray);
          // seen through the outer surface's finite part only
          const glm::dvec3 o = ray.origin - quadric::anchor(shape);
          const quadric::Interval outer = quadric::body_interval(shape, o, ray.direction, 0.0);
          if (outer.empty() || outer.enter < 0.0 ||
              !quadric::range_kept(shape, o, ray.direction, outer.enter, outer.enter)) {
            distance = -1.0;
          }
          if ((distance > 0.0) != hit_at(frame, p)) {
            ++mismatches;
            continue;
          }
          if (distance <= 0.0) continue;
          ++compared;
          if (std::abs(frame.depth[p] - distance) > 1e-4) ++depth_errors;
        }
      }
      std::printf("%-8s eye %.2f,%.2f,%.2f: %lld hits compared, %lld mismatches, %lld depth errors\n",
                  render::surface_name(surface), eye.x, eye.y, eye.z, compared, mismatches, depth_errors);
      EXPECT_GT(compared, 100);
      // pixels whose ray grazes a triangle edge or the silhouette may go either way
      EXPECT_LE(mismatches + depth_errors, compared / 100 + 2) << render::surface_name(surface);
    }
  }
  EXPECT_EQ(quadric_renderer().validation_messages(), 0);
}

// Views through the sphere's poles (down the axis from above and from below), across the equator
// and the axis plane, along and exactly parallel to the cylinder's axis, and through the cone's apex
// region and along its generators. No AOV may be NaN or Inf, and there are no holes: a pixel whose
// ray, and its 8 neighbours' rays, reach the inner surface within the finite part (the exact trace
// on an all-zero field, whose relief is the inner surface) is hit by every method on every field,
// and on the all-one field every pixel inside the outer surface's outline (traced the same way) is.
std::vector<std::size_t> interior_hits(const HeightField& field, const View& view) {
  const int width = view.camera.width, height = view.camera.height;
  std::vector<bool> hit(std::size_t(width) * height);
  for (int py = 0; py < height; ++py)
    for (int px = 0; px < width; ++px)
      hit[std::size_t(py) * width + px] = render::cpu_trace_quadric(field, view, px + 0.5, py + 0.5).hit;
  std::vector<std::size_t> interior;
  for (int py = 1; py + 1 < height; ++py) {
    for (int px = 1; px + 1 < width; ++px) {
      bool all = true;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) all = all && hit[std::size_t(py + dy) * width + px + dx];
      if (all) interior.push_back(std::size_t(py) * width + px);
    }
  }
  return interior;
}

TEST(Quadric, NoNanInfOrHolesThroughPolesAxesAndApex) {
  const float r = 0.25f;
  struct Named {
    std::string name;
    View view;
  };
  const std::vector<Named> views = {
      {"sphere north pole", looking_at(Surface::sphere, {0.5f, 0.5f, 1.2f}, {0.5f, 0.5f, 0.0f}, 33, 30.0f)},
      {"sphere south pole", looking_at(Surface::sphere, {0.5f, 0.5f, -1.2f}, {0.5f, 0.5f, 0.0f}, 33, 30.0f)},
      {"sphere equator", looking_at(Surface::sphere, {0.5f, -0.8f, 0.0f}, {0.5f, 0.5f, 0.0f}, 33, 30.0f)},
      {"sphere pole grazing", looking_at(Surface::sphere, {0.5f, -0.8f, r}, {0.5f, 0.5f, r}, 33, 12.0f)},
      {"cylinder side", looking_at(Surface::cylinder, {0.5f, -0.8f, 0.0f}, {0.5f, 0.5f, 0.0f}, 33, 30.0f)},
      {"cylinder near axis",
       looking_at(Surface::cylinder, {0.5f + 1.1f * r, 0.5f, 0.6f}, {0.5f + r, 0.5f, 0.0f}, 49, 6.0f)},
      {"cylinder parallel", looking_at(Surface::cylinder, {0.5f + 1.1f * r, 0.5f, 0.3f},
                                       {0.5f + 1.1f * r, 0.5f, -1.0f}, 33, 30.0f)},
      {"cone apex from above", looking_at(Surface::cone, {0.5f, 0.5f, 1.2f}, {0.5f, 0.5f, 0.0f}, 33, 24.0f)},
      {"cone apex level", looking_at(Surface::cone, {0.5f, -0.5f, 1.5f * r}, {0.5f, 0.5f, 0.2f}, 33, 40.0f)},
      {"cone along generator", looking_at(Surface::cone, {0.5f, 0.5f - 1.2f * r, 1.5f * r + 2.4f * r},
                                          {0.5f, 0.5f - 0.7f * r, 0.0f}, 33, 30.0f)},
      {"cone from below", looking_at(Surface::cone, {0.5f, -0.9f, -0.7f}, {0.5f, 0.5f, 0.0f}, 33, 16.0f)},
      {"cone side", looking_at(Surface::cone, {0.5f, -0.8f, 0.0f}, {0.5f, 0.5f, 0.0f}, 33, 20.0f)},
  };
  const HeightField zero = constant_field(16, 0.0), one = constant_field(16, 1.0);
  const std::vector<std::pair<std::string, HeightField>> fields = {
      {"all-zero", zero}, {"all-one", one}, {"waves", waves_field(16)}};
  for (const auto& [view_name, view] : views) {
    const std::vector<std::size_t> inner = interior_hits(zero, view), outer = interior_hits(one, view);
    for (const auto& [field_name, field] : fields) {
      quadric_renderer().set_height_field(field);
      const std::vector<std::size_t>& must_hit = field_name == "all-one" ? outer : inner;
      for (Method method : quadric_methods()) {
        const Frame frame = quadric_renderer().render(view, {method, 16, 6});
        const std::string where = view_name + " / " + field_name + " / " + render::method_info(method).name;
        EXPECT_TRUE(all_finite(frame)) << where;
        long long holes = 0;
        for (std::size_t p : must_hit) holes += hit_at(frame, p) ? 0 : 1;
        EXPECT_EQ(holes, 0) << where << " (" << must_hit.size() << " pixels must hit)";
      }
    }
    std::printf("%-22s %4zu pixels inside the inner outline, %4zu inside the outer one\n", view_name.c_str(),
                inner.size(), outer.size());
  }
  EXPECT_EQ(quadric_renderer().validation_messages(), 0);
}

TEST(Quadric, RefusesWhatItCannotRenderWithAClearError) {
  quadric_renderer().set_height_field(constant_field(8, 0.5));
  const View sphere = looking_at(Surface::sphere, {0.5f, -0.45f, 0.55f}, {0.5f, 0.5f, 0.0f}, 8, 30.0f);
  for (const render::MethodInfo& info : render::method_table()) {
    if (render::supports_surface(info.method, Surface::sphere)) continue;
    try {
      quadric_renderer().render(sphere, {info.method, 8, 4});
      ADD_FAILURE() << info.name << " rendered a sphere";
    } catch (const render::RenderError& error) {
      EXPECT_NE(std::string(error.what()).find("does not support --surface sphere"), std::string::npos)
          << error.what();
    }
  }
  View view = sphere;
  view.depth_scale = 0.2f;  // above R / 2
  EXPECT_THROW(quadric_renderer().render(view, {Method::relief, 8, 4}), render::RenderError);
  view = sphere;
  view.radius = 0.0f;
  EXPECT_THROW(quadric_renderer().render(view, {Method::relief, 8, 4}), render::RenderError);
  view = sphere;
  view.camera.eye = {0.5f, 0.5f, 0.2f};  // inside the sphere
  EXPECT_THROW(quadric_renderer().render(view, {Method::relief, 8, 4}), render::RenderError);
  view = looking_at(Surface::cylinder, {0.5f, 0.6f, 0.1f}, {0.5f, 0.5f, -1.0f}, 8,
                    30.0f);  // inside the cylinder
  EXPECT_THROW(quadric_renderer().render(view, {Method::relief, 8, 4}), render::RenderError);
  EXPECT_EQ(quadric_renderer().validation_messages(), 0);
}

}  // namespace
