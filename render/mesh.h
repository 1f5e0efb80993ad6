// render/mesh.h - triangle meshes as base surfaces of the per-pixel methods: the mesh with texture
// coordinates is the top of the relief (height 1); height 0 lies View::depth_scale world units inside it,
// along the normal. Each vertex carries the tangent frame the methods trace in (Premecz, "Iterative
// Parallax Mapping with Slope Information", sec. 2: the texture-space basis is the pair of partial
// derivatives dP/du, dP/dv of the surface point with respect to the texture coordinates, found per
// triangle from its edges and texture-coordinate differences and averaged at the vertices) and the
// local curvature that decides silhouettes.
#ifndef DISPLACE_RENDER_MESH_H
#define DISPLACE_RENDER_MESH_H

#include <cstdint>
#include <glm/glm.hpp>
#include <stdexcept>
#include <string>
#include <vector>

namespace displace::render {

struct MeshError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Unified vertices (one index addresses position, texture coordinates and the optional normal).
struct Mesh {
  std::vector<glm::vec3> positions;
  std::vector<glm::vec2> uvs;
  std::vector<glm::vec3> normals;        // empty: area-weighted face normals are used
  std::vector<std::uint32_t> triangles;  // 3 indices per triangle, counter-clockwise seen from outside
};

// What the mesh vertex shader reads per vertex (std430-compatible: 16 floats).
struct MeshVertex {
  glm::vec3 position;
  float u;
  glm::vec3 dp_du;  // dP/du, orthogonal to the normal, world units per unit of u
  float v;
  glm::vec3 dp_dv;  // dP/dv, orthogonal to the normal
  float curvature_uu;
  glm::vec3 normal;  // unit, pointing out of the relief
  float curvature_vv;
};
static_assert(sizeof(MeshVertex) == 16 * sizeof(float));

// Validates the mesh (finite values, indices in range, at least one triangle with a non-degenerate
// texture mapping) and computes the vertices. Throws MeshError with a clear message.
// Curvature: the surface near a vertex is the quadric depth below its tangent plane
// d = k_uu x^2 + k_vv y^2, x and y world distances along t1 = dP/du / |dP/du| and t2 = n x t1,
// fitted from the normal curvature of the edges to its neighbours; positive where the surface bends
// away from the normal (convex, like a sphere: 1 / 2R).
std::vector<MeshVertex> mesh_vertices(const Mesh& mesh);

// The true-displacement reference's geometry (render/reference_mesh.cpp), made on the CPU and drawn
// by the renderer's `reference` method; the vertex shaders displace it with the height texture.

// The plane's reference: a grid with a vertex at every texel centre of the `tile` x `tile` tiles of a
// width x height map plus the patch border (u = 0 and u = tile, likewise v), so that its triangles
// interpolate the same texel heights as the bilinear texture does. Vertices are (u, v) pairs.
struct PlaneReference {
  std::vector<float> uv;  // 2 per vertex
  std::vector<std::uint32_t> indices;
};
PlaneReference plane_reference(int width, int height, int tile);

// A mesh's reference: every triangle cut into n x n sub-triangles, n chosen so that a sub-edge spans
// at most half a texel of the (tiled) width x height map (capped so that the result stays within
// max_mesh_reference_vertices), the same n everywhere. A point on an edge is blended from the edge's
// two vertices in one fixed order, so neighbouring triangles share it bit for bit: no cracks.
inline constexpr long long max_mesh_reference_vertices = 4 << 20;
struct MeshReference {
  std::vector<MeshVertex> vertices;
  std::vector<std::uint32_t> indices;
  int subdivisions = 0;  // n
};
MeshReference mesh_reference(const std::vector<MeshVertex>& vertices,
                             const std::vector<std::uint32_t>& triangles, int width, int height, int tile);

}  // namespace displace::render

#endif
