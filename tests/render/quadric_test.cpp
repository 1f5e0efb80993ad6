// tests/render/quadric_test.cpp - inverse displacement mapping on the quadrics (sphere, cylinder, cone) with
// the validation layer on: silhouettes and hits of constant-height spheres against the analytic
// sphere, every quadric method against the exact CPU trace, no NaN and no holes on rays through the
// poles, along the axes and through the apex region, self-shadowing (the terminator, a ring's cast
// shadow against an exact CPU light test, hard light directions, no acne), and clear errors for
// what is not supported.
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
#include "render/shaders/config.h"
#include "tests/render_fixtures.h"

namespace {

using namespace displace;
using namespace displace::testing;
using render::Frame;
using render::HeightField;
using render::Method;
using render::Surface;
using render::View;

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

Frame render_quadric_frame(const HeightField& field, const View& view, Method method, int steps, int refine) {
  shared_maps().set_heights(field);
  return draw(view, {method, steps, refine});
}

bool hit_at(const Frame& frame, std::size_t p) { return frame.uv[p * 3 + 2] > 0.5f; }

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
    shared_maps().set_heights(constant_field(map_size, c));
    for (Method method : methods) {
      const Frame frame = draw(view, {method, 128, 8});
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
  EXPECT_EQ(shared_renderer().validation_messages(), 0);
}

struct QuadricHitError {
  double max_texels = 0.0;
  long long over_half_texel = 0, hit_mismatch = 0, compared = 0;
};

QuadricHitError hit_error(const Frame& frame, const HeightField& field, const View& view,
                          const std::vector<render::CpuHit>& truth) {
  QuadricHitError error;
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
      const Frame frame = render_quadric_frame(test.field, view, method, 256, 16);
      const QuadricHitError error = hit_error(frame, test.field, view, truth);
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
  EXPECT_EQ(shared_renderer().validation_messages(), 0);
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
      const Frame frame = render_quadric_frame(field, view, Method::reference, 1, 0);
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
  EXPECT_EQ(shared_renderer().validation_messages(), 0);
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
      shared_maps().set_heights(field);
      const std::vector<std::size_t>& must_hit = field_name == "all-one" ? outer : inner;
      for (Method method : quadric_methods()) {
        const Frame frame = draw(view, {method, 16, 6});
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
  EXPECT_EQ(shared_renderer().validation_messages(), 0);
}

// Self-shadowing on the quadrics (render/shaders/quadric_trace.inc.glsl, quadric_light_visibility).
// The pictures use a white albedo, so that a hit's colour reads its lighting: ambient only (38 in
// every channel) where the light does not reach it, brighter where it does.
const int ambient_only = 38;  // 0.15 of 255: shading.inc.glsl's ambient term on a white albedo

struct WhiteAlbedo {  // sets a white albedo on the shared renderer for the scope of a test
  WhiteAlbedo() { shared_renderer().set_albedo({1, 1, {255, 255, 255, 255}}); }
  ~WhiteAlbedo() { shared_renderer().clear_albedo(); }
};

bool quadric_colour_differs(const Frame& a, const Frame& b, std::size_t p) {
  for (int c = 0; c < 3; ++c) {
    if (std::abs(int(a.color[p * 4 + c]) - int(b.color[p * 4 + c])) > 8) return true;
  }
  return false;
}

int brightest_channel(const Frame& frame, std::size_t p) {
  return std::max({frame.color[p * 4], frame.color[p * 4 + 1], frame.color[p * 4 + 2]});
}

glm::dvec3 hit_point(const View& view, const Frame& frame, int px, int py) {
  const render::Ray ray = view.camera.pixel_ray(px + 0.5, py + 0.5);
  return ray.origin + double(frame.depth[std::size_t(py) * frame.width + px]) * ray.direction;
}

// The base surface's unit outward normal at the foot of world point `point`.
glm::dvec3 base_normal(const View& view, const glm::dvec3& point) {
  const glm::dvec3 q = point - render::quadric::anchor(render::quadric::shape_of(view));
  if (view.surface == Surface::sphere) return glm::normalize(q);
  const glm::dvec3 radial = glm::normalize(glm::dvec3(q.x, q.y, 0.0));
  if (view.surface == Surface::cylinder) return radial;
  const double cone_sin = 1.0 / std::sqrt(1.0 + 1.0 / (CONE_SLOPE * CONE_SLOPE));
  return cone_sin / CONE_SLOPE * radial + glm::dvec3(0.0, 0.0, cone_sin);
}

const std::vector<Method> shadow_methods = {Method::reference, Method::relief, Method::interval, Method::csm,
                                            Method::acm4};

// The terminator. A light from +x on a sphere seen from +y: the left half faces away from it.
// (a) Constant height 0.5: the relief is the sphere of radius 0.2, so a hit whose normal has
// N . L > 0.05 must keep its colour with shadows on (no false shadow up to the terminator), and one
// with N . L < -0.05 must be ambient only. With a constant height the shading normal is N, so (a)'s
// dark half would be dark without shadows too; (b) makes it observable.
// (b) Ripples: a triangle wave of amplitude 0.025 (heights 0.475..0.525) and period 4 texels along u
// on a 256 map tilts the shading normal by up to 27 degrees at the equator (the wave rises 0.025 D
// per 0.0049 of arc), so that hits beyond the terminator face the light with their own normal and
// are lit without shadows. With shadows they must all be dark where N . L < -0.25: the light ray
// from such a hit dips r (1 - cos(asin 0.25)) >= 0.0064 = 0.064 D below it, more than the ripples'
// 0.05 D span, so it passes under the relief - the quadric's own shadow.
TEST(Quadric, ShadowsDarkenWhatLiesBeyondTheTerminator) {
  const WhiteAlbedo white;
  View view = looking_at(Surface::sphere, {0.5f, 1.35f, 0.12f}, {0.5f, 0.5f, 0.0f}, 96, 20.0f);
  view.light_direction = {1.0f, 0.0f, 0.0f};
  const glm::dvec3 light(1.0, 0.0, 0.0);
  View shadow_view = view;
  shadow_view.shadows = true;
  const HeightField constant = constant_field(64, 0.5);
  const HeightField ripples = field_of(256, 256, [](int, int j) {
    const int phase = j % 4;  // 0, 1, 0, -1: a triangle wave through the bilinear interpolation
    return 0.5 + 0.025 * (phase == 1 ? 1.0 : phase == 3 ? -1.0 : 0.0);
  });
  for (Method method : shadow_methods) {
    const char* name = render::method_info(method).name;
    long long lit_pixels = 0, dark_pixels = 0, false_shadows = 0, lit_beyond = 0;
    {
      const Frame lit = render_quadric_frame(constant, view, method, 256, 16);
      const Frame shaded = render_quadric_frame(constant, shadow_view, method, 256, 16);
      for (int py = 0; py < lit.height; ++py) {
        for (int px = 0; px < lit.width; ++px) {
          const std::size_t p = std::size_t(py) * lit.width + px;
          if (!hit_at(lit, p)) continue;
          const double facing = glm::dot(base_normal(view, hit_point(view, lit, px, py)), light);
          if (facing > 0.05) {
            ++lit_pixels;
            false_shadows += quadric_colour_differs(lit, shaded, p);
          } else if (facing < -0.05) {
            ++dark_pixels;
            lit_beyond += brightest_channel(shaded, p) > ambient_only + 1;
          }
        }
      }
    }
    long long ripple_beyond = 0, ripple_lit_beyond = 0, ripple_observable = 0;
    {
      const Frame lit = render_quadric_frame(ripples, view, method, 256, 16);
      const Frame shaded = render_quadric_frame(ripples, shadow_view, method, 256, 16);
      for (int py = 0; py < lit.height; ++py) {
        for (int px = 0; px < lit.width; ++px) {
          const std::size_t p = std::size_t(py) * lit.width + px;
          if (!hit_at(lit, p)) continue;
          if (glm::dot(base_normal(view, hit_point(view, lit, px, py)), light) >= -0.25) continue;
          ++ripple_beyond;
          ripple_observable += brightest_channel(lit, p) > ambient_only + 6;  // lit without shadows
          ripple_lit_beyond += brightest_channel(shaded, p) > ambient_only + 1;
        }
      }
    }
    std::printf(
        "%-10s constant: %lld lit-side hits, %lld false shadows; %lld beyond, %lld of them lit | "
        "ripples: %lld beyond, %lld lit without shadows, %lld with\n",
        name, lit_pixels, false_shadows, dark_pixels, lit_beyond, ripple_beyond, ripple_observable,
        ripple_lit_beyond);
    EXPECT_GT(lit_pixels, 1500) << name;
    EXPECT_GT(dark_pixels, 1500) << name;
    EXPECT_EQ(false_shadows, 0) << name;
    EXPECT_EQ(lit_beyond, 0) << name;
    EXPECT_GT(ripple_observable, 100) << name;
    EXPECT_EQ(ripple_lit_beyond, 0) << name;
  }
  EXPECT_EQ(shared_renderer().validation_messages(), 0);
}

// A relief feature casts its shadow where the geometry puts it. A ring of height 0.9 (4 texel rows of
// v) stands on a floor of 0.2 on the sphere, the cylinder and the cone, lit from above at a low
// angle to the side facing the camera, so that the ring shades the floor below it. For each pixel,
// the CPU's exact light test (quadric::light_occluder, marched at 1/32 texel) from the exact hit's
// point decides: in shadow when the light ray meets the relief or the inner solid farther than
// `near` from it, lit when it meets nothing. Pixels are compared away from the shadow's edge: the
// points 1.5 texels away in u and v must get the same answer, and the method's hit must lie within
// a texel of the exact one. A shadowed pixel must be darker with shadows on (where its diffuse
// light is visible at all), a lit one unchanged; no pixel may be wrong.
TEST(Quadric, ARingCastsItsShadowWhereTheCpuTracePutsIt) {
  namespace quadric = render::quadric;
  const WhiteAlbedo white;
  const int size = 64;
  const HeightField ring = field_of(size, size, [](int i, int) { return i >= 34 && i < 38 ? 0.9 : 0.2; });
  const double texel = 1.0 / size;
  const double near = 0.03;  // world units: an occluder this close to the hit may go either way (bias)
  struct Case {
    Surface surface;
    glm::vec3 eye, light;
  };
  const std::vector<Case> cases = {
      {Surface::sphere, {0.5f, -0.75f, 0.05f}, {0.15f, -0.5f, 0.85f}},
      {Surface::cylinder, {0.5f, -0.75f, 0.05f}, {0.15f, -0.5f, 0.85f}},
      {Surface::cone, {0.5f, -0.75f, 0.15f}, {0.15f, 0.0f, 1.0f}},
  };
  for (const Case& test : cases) {
    View view = looking_at(test.surface, test.eye, {0.5f, 0.5f, 0.0f}, 64, 26.0f);
    view.light_direction = test.light;
    const glm::dvec3 light = glm::normalize(glm::dvec3(test.light));
    const quadric::Shape shape = quadric::shape_of(view);
    auto blocked = [&](double u, double v) {
      if (test.surface != Surface::sphere && (v < 0.0 || v > view.tile)) return -2.0;
      const glm::dvec3 point =
          quadric::surface_point(shape, u, v, render::bilinear_height(ring, view.address, u, v));
      return quadric::light_occluder(ring, view, point, light, 1e-9);
    };
    // the CPU's answer per pixel: 1 shadowed, 0 lit, -1 undecided (or no hit)
    const std::vector<render::CpuHit> truth = exact_hits(ring, view);
    std::vector<int> expected(truth.size(), -1);
    for (std::size_t p = 0; p < truth.size(); ++p) {
      if (!truth[p].hit) continue;
      const double u = truth[p].texture.x, v = truth[p].texture.y;
      const double here = blocked(u, v);
      const double around[] = {blocked(u - 1.5 * texel, v), blocked(u + 1.5 * texel, v),
                               blocked(u, v - 1.5 * texel), blocked(u, v + 1.5 * texel)};
      const bool all_blocked =
          std::all_of(std::begin(around), std::end(around), [](double s) { return s >= 0.0; });
      const bool all_clear =
          std::all_of(std::begin(around), std::end(around), [](double s) { return s == -1.0; });
      if (here > near && all_blocked) expected[p] = 1;
      if (here == -1.0 && all_clear) expected[p] = 0;
    }
    for (Method method : quadric_methods()) {
      if (method == Method::bump) continue;  // no relief to cast a shadow
      const char* name = render::method_info(method).name;
      View shadow_view = view;
      shadow_view.shadows = true;
      const Frame lit = render_quadric_frame(ring, view, method, 256, 16);
      const Frame shaded = render_quadric_frame(ring, shadow_view, method, 256, 16);
      long long shadowed = 0, clear = 0, wrong = 0, band = 0;
      for (std::size_t p = 0; p < truth.size(); ++p) {
        if (!truth[p].hit || !hit_at(lit, p)) continue;
        const double du = std::remainder(lit.uv[p * 3] - truth[p].texture.x, double(view.tile)) * size;
        const double dv = (lit.uv[p * 3 + 1] - truth[p].texture.y) * size;
        if (expected[p] < 0 || std::hypot(du, dv) > 1.0) {
          ++band;
          continue;
        }
        if (expected[p] == 0) {
          ++clear;
          wrong += quadric_colour_differs(lit, shaded, p);
        } else if (brightest_channel(lit, p) > ambient_only + 10) {  // its diffuse light shows
          ++shadowed;
          wrong += !quadric_colour_differs(lit, shaded, p);
        }
      }
      std::printf("%-8s %-13s %lld shadowed, %lld lit, %lld wrong; %lld in the edge band\n",
                  render::surface_name(test.surface), name, shadowed, clear, wrong, band);
      EXPECT_GT(shadowed, 150) << render::surface_name(test.surface) << " / " << name;
      EXPECT_GT(clear, 200) << render::surface_name(test.surface) << " / " << name;
      EXPECT_EQ(wrong, 0) << render::surface_name(test.surface) << " / " << name;
    }
  }
  EXPECT_EQ(shared_renderer().validation_messages(), 0);
}

// Hard light directions with shadows on: along the axis from above and from below, horizontal
// (grazing the cylinder's whole side and the sphere's poles), along a cone generator, slightly off
// the axis, from below at an angle. On views through the poles, the axis and the apex region, every
// quadric method must give finite AOVs, the same hits and depths as without shadows, colours no
// brighter (shadows only take light away) and at least the fetches of the view ray alone (the
// shadow trace's reads are counted); on the all-one field (the outer surface itself) every hit whose
// normal faces the light (N . L > 0.05) must keep its colour.
TEST(Quadric, ShadowsStayFiniteForHardLights) {
  const float r = 0.25f;
  struct Named {
    std::string name;
    View view;
  };
  const std::vector<Named> views = {
      {"sphere north pole", looking_at(Surface::sphere, {0.5f, 0.5f, 1.2f}, {0.5f, 0.5f, 0.0f}, 33, 30.0f)},
      {"sphere south pole", looking_at(Surface::sphere, {0.5f, 0.5f, -1.2f}, {0.5f, 0.5f, 0.0f}, 33, 30.0f)},
      {"cylinder side", looking_at(Surface::cylinder, {0.5f, -0.8f, 0.0f}, {0.5f, 0.5f, 0.0f}, 33, 30.0f)},
      {"cylinder parallel", looking_at(Surface::cylinder, {0.5f + 1.1f * r, 0.5f, 0.3f},
                                       {0.5f + 1.1f * r, 0.5f, -1.0f}, 33, 30.0f)},
      {"cone apex from above", looking_at(Surface::cone, {0.5f, 0.5f, 1.2f}, {0.5f, 0.5f, 0.0f}, 33, 24.0f)},
      {"cone from below", looking_at(Surface::cone, {0.5f, -0.9f, -0.7f}, {0.5f, 0.5f, 0.0f}, 33, 16.0f)},
  };
  const std::vector<glm::vec3> lights = {{0.0f, 0.0f, 1.0f},  {0.0f, 0.0f, -1.0f},
                                         {1.0f, 0.0f, 0.0f},  {0.0f, 0.447214f, 0.894427f},
                                         {1e-4f, 0.0f, 1.0f}, {0.3f, -0.2f, -1.0f}};
  const std::vector<std::pair<std::string, HeightField>> fields = {{"all-one", constant_field(16, 1.0)},
                                                                   {"waves", waves_field(16)}};
  for (const auto& [view_name, view] : views) {
    for (const auto& [field_name, field] : fields) {
      shared_maps().set_heights(field);
      for (Method method : quadric_methods()) {
        for (const glm::vec3& light : lights) {
          View plain = view;
          plain.light_direction = light;
          View shadow_view = plain;
          shadow_view.shadows = true;
          const Frame lit = draw(plain, {method, 16, 6});
          const Frame shaded = draw(shadow_view, {method, 16, 6});
          char where[160];
          std::snprintf(where, sizeof where, "%s / %s / %s / light %g,%g,%g", view_name.c_str(),
                        field_name.c_str(), render::method_info(method).name, light.x, light.y, light.z);
          EXPECT_TRUE(all_finite(shaded)) << where;
          long long changed_hits = 0, brighter = 0, fewer_fetches = 0, acne = 0;
          for (int py = 0; py < lit.height; ++py) {
            for (int px = 0; px < lit.width; ++px) {
              const std::size_t p = std::size_t(py) * lit.width + px;
              changed_hits += hit_at(shaded, p) != hit_at(lit, p) || shaded.depth[p] != lit.depth[p];
              for (int c = 0; c < 3; ++c) brighter += shaded.color[p * 4 + c] > lit.color[p * 4 + c] + 1;
              fewer_fetches += shaded.fetches[p] < lit.fetches[p];
              if (field_name == "all-one" && hit_at(lit, p) &&
                  glm::dot(base_normal(view, hit_point(view, lit, px, py)),
                           glm::normalize(glm::dvec3(light))) > 0.05) {
                acne += quadric_colour_differs(lit, shaded, p);
              }
            }
          }
          EXPECT_EQ(changed_hits, 0) << where;
          EXPECT_EQ(brighter, 0) << where;
          EXPECT_EQ(fewer_fetches, 0) << where;
          EXPECT_EQ(acne, 0) << where;
        }
      }
    }
  }
  EXPECT_EQ(shared_renderer().validation_messages(), 0);
}

// No acne: on constant heights 0, 0.5 and 1 (the inner surface, the middle, the outer surface) with
// a light from above the side the camera sees, every quadric method keeps the colour of every hit
// whose base normal faces the light (N . L > 0.05) when shadows are turned on.
TEST(Quadric, ConstantHeightCastsNoShadowOnItself) {
  struct Case {
    Surface surface;
    glm::vec3 eye, light;
  };
  const std::vector<Case> cases = {
      {Surface::sphere, {0.5f, -0.6f, 0.5f}, {0.3f, -0.4f, 1.0f}},
      {Surface::cylinder, {0.5f, -0.7f, 0.3f}, {0.3f, -1.0f, 0.6f}},
      {Surface::cone, {0.5f, -0.6f, 0.5f}, {0.3f, -0.4f, 1.0f}},
  };
  for (const Case& test : cases) {
    View view = looking_at(test.surface, test.eye, {0.5f, 0.5f, 0.0f}, 64, 32.0f);
    view.light_direction = test.light;
    View shadow_view = view;
    shadow_view.shadows = true;
    const glm::dvec3 light = glm::normalize(glm::dvec3(test.light));
    for (double c : {0.0, 0.5, 1.0}) {
      shared_maps().set_heights(constant_field(32, c));
      for (Method method : quadric_methods()) {
        const Frame lit = draw(view, {method, 64, 8});
        const Frame shaded = draw(shadow_view, {method, 64, 8});
        long long facing = 0, acne = 0;
        for (int py = 0; py < lit.height; ++py) {
          for (int px = 0; px < lit.width; ++px) {
            const std::size_t p = std::size_t(py) * lit.width + px;
            if (!hit_at(lit, p) || glm::dot(base_normal(view, hit_point(view, lit, px, py)), light) <= 0.05)
              continue;
            ++facing;
            acne += quadric_colour_differs(lit, shaded, p);
          }
        }
        const char* name = render::method_info(method).name;
        if (acne > 0 || facing < 400) {
          std::printf("%-8s c %.1f %-13s %lld hits facing the light, %lld darkened\n",
                      render::surface_name(test.surface), c, name, facing, acne);
        }
        EXPECT_GT(facing, 400) << render::surface_name(test.surface) << " c " << c << " / " << name;
        EXPECT_EQ(acne, 0) << render::surface_name(test.surface) << " c " << c << " / " << name;
      }
    }
  }
  EXPECT_EQ(shared_renderer().validation_messages(), 0);
}

TEST(Quadric, RefusesWhatItCannotRenderWithAClearError) {
  shared_maps().set_heights(constant_field(8, 0.5));
  const View sphere = looking_at(Surface::sphere, {0.5f, -0.45f, 0.55f}, {0.5f, 0.5f, 0.0f}, 8, 30.0f);
  for (const render::MethodInfo& info : render::method_table()) {
    if (render::supports_surface(info.method, Surface::sphere)) continue;
    try {
      draw(sphere, {info.method, 8, 4});
      ADD_FAILURE() << info.name << " rendered a sphere";
    } catch (const render::RenderError& error) {
      EXPECT_NE(std::string(error.what()).find("does not support View::surface sphere"), std::string::npos)
          << error.what();
    }
  }
  View view = sphere;
  view.depth_scale = 0.2f;  // above R / 2
  EXPECT_THROW(draw(view, {Method::relief, 8, 4}), render::RenderError);
  view = sphere;
  view.radius = 0.0f;
  EXPECT_THROW(draw(view, {Method::relief, 8, 4}), render::RenderError);
  view = sphere;
  view.camera.eye = {0.5f, 0.5f, 0.2f};  // inside the sphere
  EXPECT_THROW(draw(view, {Method::relief, 8, 4}), render::RenderError);
  view = looking_at(Surface::cylinder, {0.5f, 0.6f, 0.1f}, {0.5f, 0.5f, -1.0f}, 8,
                    30.0f);  // inside the cylinder
  EXPECT_THROW(draw(view, {Method::relief, 8, 4}), render::RenderError);
  EXPECT_EQ(shared_renderer().validation_messages(), 0);
}

}  // namespace
