// render/reference_mesh.cpp - the tessellated height field that the `reference` method rasterizes:
// a grid through every texel centre on the plane, a uniformly subdivided base mesh on meshes.
// Pure CPU (render/mesh.h); the renderer only uploads the result.
#include <algorithm>
#include <cmath>
#include <cstddef>

#include "render/mesh.h"

namespace displace::render {
namespace {

MeshVertex blend(const MeshVertex& a, const MeshVertex& b, const MeshVertex& c, float wa, float wb,
                 float wc) {
  MeshVertex v;
  v.position = wa * a.position + wb * b.position + wc * c.position;
  v.u = wa * a.u + wb * b.u + wc * c.u;
  v.v = wa * a.v + wb * b.v + wc * c.v;
  v.dp_du = wa * a.dp_du + wb * b.dp_du + wc * c.dp_du;
  v.dp_dv = wa * a.dp_dv + wb * b.dp_dv + wc * c.dp_dv;
  v.normal = glm::normalize(wa * a.normal + wb * b.normal + wc * c.normal);
  v.curvature_uu = wa * a.curvature_uu + wb * b.curvature_uu + wc * c.curvature_uu;
  v.curvature_vv = wa * a.curvature_vv + wb * b.curvature_vv + wc * c.curvature_vv;
  return v;
}

}  // namespace

PlaneReference plane_reference(int width, int height, int tile) {
  const long long columns = (long long)width * tile + 2, rows = (long long)height * tile + 2;
  PlaneReference reference;
  reference.uv.reserve(std::size_t(columns * rows * 2));
  auto coordinate = [&](long long index, int size) {
    return std::clamp((double(index) - 0.5) / size, 0.0, double(tile));
  };
  for (long long i = 0; i < rows; ++i) {
    for (long long j = 0; j < columns; ++j) {
      reference.uv.push_back(float(coordinate(j, width)));
      reference.uv.push_back(float(coordinate(i, height)));
    }
  }
  reference.indices.reserve(std::size_t((columns - 1) * (rows - 1) * 6));
  for (long long i = 0; i + 1 < rows; ++i) {
    for (long long j = 0; j + 1 < columns; ++j) {
      const auto a = std::uint32_t(i * columns + j), b = a + 1, c = a + std::uint32_t(columns), d = c + 1;
      reference.indices.insert(reference.indices.end(), {a, b, d, a, d, c});
    }
  }
  return reference;
}

MeshReference mesh_reference(const std::vector<MeshVertex>& mesh, const std::vector<std::uint32_t>& triangles,
                             int width, int height, int tile) {
  const std::size_t triangle_count = triangles.size() / 3;
  MeshReference reference;
  if (triangle_count == 0) return reference;
  double longest = 1.0;  // texels
  for (std::size_t t = 0; t < triangles.size(); t += 3) {
    for (int e = 0; e < 3; ++e) {
      const MeshVertex& a = mesh[triangles[t + e]];
      const MeshVertex& b = mesh[triangles[t + (e + 1) % 3]];
      longest = std::max(
          {longest, std::abs(double(a.u) - b.u) * width * tile, std::abs(double(a.v) - b.v) * height * tile});
    }
  }
  const long long most =
      (long long)std::sqrt(2.0 * double(max_mesh_reference_vertices) / double(triangle_count));
  const int n =
      int(std::clamp<long long>((long long)std::ceil(2.0 * longest), 1, std::max<long long>(most - 1, 1)));
  const int per_row = n + 1;
  reference.subdivisions = n;
  std::vector<MeshVertex>& vertices = reference.vertices;
  std::vector<std::uint32_t>& indices = reference.indices;
  vertices.reserve(triangle_count * std::size_t(per_row) * std::size_t(n + 2) / 2);
  indices.reserve(triangle_count * std::size_t(n) * std::size_t(n) * 3);
  std::vector<std::uint32_t> grid(std::size_t(per_row) * per_row);
  for (std::size_t t = 0; t < triangles.size(); t += 3) {
    const std::uint32_t corner[3] = {triangles[t], triangles[t + 1], triangles[t + 2]};
    // point (i, j): weights i / n on the first corner, j / n on the second, the rest on the third
    for (int i = 0; i <= n; ++i) {
      for (int j = 0; i + j <= n; ++j) {
        const int counts[3] = {i, j, n - i - j};
        int nonzero = 0;
        for (int c : counts) nonzero += c != 0;
        MeshVertex vertex;
        if (nonzero == 2) {  // on an edge: blend its two vertices in the order of their indices
          int first = -1, second = -1;
          for (int c = 0; c < 3; ++c) {
            if (counts[c] == 0) continue;
            (first < 0 ? first : second) = c;
          }
          if (corner[first] > corner[second]) std::swap(first, second);
          const float w = float(counts[second]) / float(n);
          vertex = blend(mesh[corner[first]], mesh[corner[second]], mesh[corner[first]], 1.0f - w, w, 0.0f);
        } else {
          vertex = blend(mesh[corner[0]], mesh[corner[1]], mesh[corner[2]], float(i) / float(n),
                         float(j) / float(n), float(n - i - j) / float(n));
        }
        grid[std::size_t(i) * per_row + j] = std::uint32_t(vertices.size());
        vertices.push_back(vertex);
      }
    }
    // sub-triangles, with the winding of the triangle (+i towards its first corner, +j its second)
    for (int i = 0; i < n; ++i) {
      for (int j = 0; i + j < n; ++j) {
        const std::uint32_t p = grid[std::size_t(i) * per_row + j],
                            pi = grid[std::size_t(i + 1) * per_row + j],
                            pj = grid[std::size_t(i) * per_row + j + 1];
        indices.insert(indices.end(), {p, pi, pj});
        if (i + j + 1 < n)
          indices.insert(indices.end(), {pi, grid[std::size_t(i + 1) * per_row + j + 1], pj});
      }
    }
  }
  return reference;
}

}  // namespace displace::render
