// render/mesh.cpp - per-vertex tangent frames and curvature of a base mesh (Premecz, "Iterative
// Parallax Mapping with Slope Information", sec. 2). Per triangle, the edges E1 = P1 - P0 and
// E2 = P2 - P0 and their texture differences (du1, dv1), (du2, dv2) give the partial derivatives
// [dP/du dP/dv] = [E1 E2] [du1 du2; dv1 dv2]^-1; vertices average them (weighted by triangle area)
// and keep only their parts orthogonal to the vertex normal, so the frame is the tangent plane's.
#include "render/mesh.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <string>
#include <vector>

namespace displace::render {
namespace {

constexpr double min_uv_area = 1e-12;  // |det| of a triangle's texture mapping below this is degenerate
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
    if (index >= vertices)
      throw MeshError("a triangle refers to vertex " + std::to_string(index) + " of " +
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
  std::vector<glm::dvec3> du(count, glm::dvec3(0.0)), dv(count, glm::dvec3(0.0)),
      face_normal(count, glm::dvec3(0.0));
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

  // vertex normals first: the curvature fit reads the neighbours' normals. Face normals are summed
  // over every vertex at the same position, so a texture seam (a closed mesh's u = 0 / 1 column,
  // split into two vertices) does not split the normal: each side alone would see half a fan.
  std::map<std::array<float, 3>, glm::dvec3> by_position;
  for (std::size_t i = 0; i < count; ++i) {
    by_position[{mesh.positions[i].x, mesh.positions[i].y, mesh.positions[i].z}] += face_normal[i];
  }
  for (std::size_t i = 0; i < count; ++i) {
    face_normal[i] = by_position[{mesh.positions[i].x, mesh.positions[i].y, mesh.positions[i].z}];
  }
  std::vector<glm::dvec3> normals(count);
  for (std::size_t i = 0; i < count; ++i) {
    glm::dvec3 normal = mesh.normals.empty() ? face_normal[i] : glm::dvec3(mesh.normals[i]);
    if (glm::length(normal) < min_normal_length) normal = face_normal[i];
    if (glm::length(normal) < min_normal_length) normal = glm::dvec3(0.0, 0.0, 1.0);  // an unused vertex
    normals[i] = glm::normalize(normal);
  }
  std::vector<MeshVertex> vertices(count);
  for (std::size_t i = 0; i < count; ++i) {
    const glm::dvec3 normal = normals[i];
    // the area-weighted mean derivatives, projected onto the tangent plane
    const double weight = mapped_area[i] > 0.0 ? 1.0 / mapped_area[i] : 0.0;
    const glm::dvec3 tangent_u = (du[i] - glm::dot(du[i], normal) * normal) * weight;
    const glm::dvec3 tangent_v = (dv[i] - glm::dot(dv[i], normal) * normal) * weight;
    // curvature: the normal curvature along each edge to a neighbour j, kappa = (n_j - n_i) . d / |d|^2
    // (1 / R on a sphere of radius R, whatever the edge), fitted by least squares as
    // kappa / 2 = k_uu cos^2 + k_vv sin^2 of the edge's angle in the basis t1 = dP/du / |dP/du|,
    // t2 = n x t1 (the shader uses the same basis). Edge normals, not positions: a pole vertex,
    // whose dP/du vanishes, still gets its curvature (any t1 there).
    glm::dvec3 t1 = tangent_u;
    if (glm::length(t1) < 1e-12)
      t1 = glm::cross(normal, std::abs(normal.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0));
    t1 = glm::normalize(t1);
    const glm::dvec3 t2 = glm::cross(normal, t1);
    double scc = 0.0, sss = 0.0, scs = 0.0, bc = 0.0, bs = 0.0;
    for (std::uint32_t j : neighbours[i]) {
      const glm::dvec3 d = glm::dvec3(mesh.positions[j]) - glm::dvec3(mesh.positions[i]);
      const glm::dvec3 along = d - glm::dot(d, normal) * normal;
      const double length2 = glm::dot(d, d), along_length = glm::length(along);
      if (length2 == 0.0 || along_length == 0.0) continue;
      const double half_kappa = 0.5 * glm::dot(normals[j] - normal, d) / length2;
      const double c = glm::dot(along, t1) / along_length, sn = glm::dot(along, t2) / along_length;
      const double cc = c * c, ss = sn * sn;
      scc += cc * cc;
      sss += ss * ss;
      scs += cc * ss;
      bc += cc * half_kappa;
      bs += ss * half_kappa;
    }
    double k_uu = 0.0, k_vv = 0.0;
    const double det = scc * sss - scs * scs;
    if (det > 1e-9 * std::max(scc * sss, 1e-300)) {
      k_uu = (bc * sss - bs * scs) / det;
      k_vv = (bs * scc - bc * scs) / det;
    } else if (scc + sss > 0.0) {  // every edge along one direction: one curvature for both
      k_uu = k_vv = (bc + bs) / (scc + sss + 2.0 * scs);
    }
    const glm::vec3 position = mesh.positions[i];
    vertices[i] = {position,    mesh.uvs[i].x,     glm::vec3(tangent_u), mesh.uvs[i].y, glm::vec3(tangent_v),
                   float(k_uu), glm::vec3(normal), float(k_vv)};
  }
  return vertices;
}

}  // namespace displace::render
