// render/mesh.cpp - per-vertex tangent frames and curvature of a base mesh (Premecz, "Iterative
// Parallax Mapping with Slope Information", sec. 2). Per triangle, the edges E1 = P1 - P0 and
// E2 = P2 - P0 and their texture differences (du1, dv1), (du2, dv2) give the partial derivatives
// [dP/du dP/dv] = [E1 E2] [du1 du2; dv1 dv2]^-1; vertices average them (weighted by triangle area)
// and keep only their parts orthogonal to the vertex normal, so the frame is the tangent plane's.
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "render/mesh.h"

namespace displace::render {
namespace {

constexpr double min_uv_area = 1e-12;    // |det| of a triangle's texture mapping below this is degenerate
constexpr double min_normal_length = 1e-12;

bool finite(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

void validate(const Mesh& mesh) {
  const std::size_t vertices = mesh.positions.size();
  if (vertices == 0 || mesh.triangles.empty()) throw MeshError("the mesh has no triangles");
  if (mesh.uvs.size() != vertices) throw MeshError("every mesh vertex needs texture coordinates");
  if (!mesh.normals.empty() && mesh.normals.size() != vertices) {
    throw MeshError("the mesh has normals for some vertices only");
  }
  if (mesh.triangles.size() % 3 != 0) throw MeshError("the triangle list is not a multiple of 3 indices");
  for (std::uint32_t index : mesh.triangles) {
    if (index >= vertices) throw MeshError("a triangle refers to vertex " + std::to_string(index) + " of " +
                                           std::to_string(vertices));
  }
  for (std::size_t i = 0; i < vertices; ++i) {
    if (!finite(mesh.positions[i]) || !std::isfinite(mesh.uvs[i].x) || !std::isfinite(mesh.uvs[i].y) ||
        (!mesh.normals.empty() && !finite(mesh.normals[i]))) {
      throw MeshError("mesh vertex " + std::to_string(i) + " has a value that is not finite");
    }
  }
}

}  // namespace

std::vector<MeshVertex> mesh_vertices(const Mesh& mesh) {
  validate(mesh);
  const std::size_t count = mesh.positions.size();
  std::vector<glm::dvec3> du(count, glm::dvec3(0.0)), dv(count, glm::dvec3(0.0)), face_normal(count, glm::dvec3(0.0));
  std::vector<double> mapped_area(count, 0.0);
  std::vector<std::vector<std::uint32_t>> neighbours(count);
  std::size_t mapped = 0;
  // per triangle: the partial derivatives, weighted by area, summed at its vertices
  for (std::size_t t = 0; t < mesh.triangles.size(); t += 3) {
    const std::uint32_t a = mesh.triangles[t], b = mesh.triangles[t + 1], c = mesh.triangles[t + 2];
    const glm::dvec3 p0(mesh.positions[a]), e1 = glm::dvec3(mesh.positions[b]) - p0,
        e2 = glm::dvec3(mesh.positions[c]) - p0;
    const glm::dvec2 t0(mesh.uvs[a]), d1 = glm::dvec2(mesh.uvs[b]) - t0, d2 = glm::dvec2(mesh.uvs[c]) - t0;
    const glm::dvec3 area_normal = glm::cross(e1, e2);  // twice the area, along the face normal
    const double area = glm::length(area_normal);
    for (std::uint32_t i : {a, b, c}) face_normal[i] += area_normal;
    for (std::uint32_t i : {a, b, c}) {
      for (std::uint32_t j : {a, b, c}) {
        if (i != j) neighbours[i].push_back(j);
      }
    }
    const double det = d1.x * d2.y - d2.x * d1.y;
    if (std::abs(det) < min_uv_area || area == 0.0) continue;
    ++mapped;
    const glm::dvec3 dp_du = (e1 * d2.y - e2 * d1.y) / det;
    const glm::dvec3 dp_dv = (e2 * d1.x - e1 * d2.x) / det;
    for (std::uint32_t i : {a, b, c}) {
      du[i] += area * dp_du;
      dv[i] += area * dp_dv;
      mapped_area[i] += area;
    }
  }
  if (mapped == 0) throw MeshError("no triangle of the mesh has a non-degenerate texture mapping");

  std::vector<MeshVertex> vertices(count);
  for (std::size_t i = 0; i < count; ++i) {
    glm::dvec3 normal = mesh.normals.empty() ? face_normal[i] : glm::dvec3(mesh.normals[i]);
    if (glm::length(normal) < min_normal_length) normal = face_normal[i];
    if (glm::length(normal) < min_normal_length) normal = glm::dvec3(0.0, 0.0, 1.0);  // an unused vertex
    normal = glm::normalize(normal);
    // the area-weighted mean derivatives, projected onto the tangent plane
    const double weight = mapped_area[i] > 0.0 ? 1.0 / mapped_area[i] : 0.0;
    const glm::dvec3 tangent_u = (du[i] - glm::dot(du[i], normal) * normal) * weight;
    const glm::dvec3 tangent_v = (dv[i] - glm::dot(dv[i], normal) * normal) * weight;
    // curvature: least squares of depth = k_uu x^2 + k_vv y^2 over the neighbours
    double suu = 0.0, svv = 0.0, suv = 0.0, bu = 0.0, bv = 0.0;
    const double length_u = glm::length(tangent_u), length_v = glm::length(tangent_v);
    for (std::uint32_t j : neighbours[i]) {
      if (length_u == 0.0 || length_v == 0.0) break;
      const glm::dvec3 offset = glm::dvec3(mesh.positions[j]) - glm::dvec3(mesh.positions[i]);
      const double x = glm::dot(offset, tangent_u) / length_u, y = glm::dot(offset, tangent_v) / length_v;
      const double depth = -glm::dot(offset, normal);
      const double xx = x * x, yy = y * y;
      suu += xx * xx;
      svv += yy * yy;
      suv += xx * yy;
      bu += xx * depth;
      bv += yy * depth;
    }
    double k_uu = 0.0, k_vv = 0.0;
    const double det = suu * svv - suv * suv;
    if (det > 1e-12 * std::max(suu * svv, 1e-300)) {
      k_uu = (bu * svv - bv * suv) / det;
      k_vv = (bv * suu - bu * suv) / det;
    }
    const glm::vec3 position = mesh.positions[i];
    vertices[i] = {position,          mesh.uvs[i].x,         glm::vec3(tangent_u), mesh.uvs[i].y,
                   glm::vec3(tangent_v), float(k_uu), glm::vec3(normal),    float(k_vv)};
  }
  return vertices;
}

}  // namespace displace::render
