// tests/render/reference_mesh_test.cpp - the tessellated reference (render/reference_mesh.cpp).
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
#include "tests/height_fields.h"
#include "tests/render/render_checks.h"

namespace {

using namespace displace;
using namespace displace::testing;
using render::Frame;
using render::HeightField;
using render::Method;
using render::MethodInfo;
using render::View;

// The plane's reference grid, on the CPU: a vertex on every texel centre of the tiles plus the
// patch border, each cell two triangles, every index in range.
TEST(Mesh, PlaneReferenceHasAVertexOnEveryTexelCentreAndTheBorder) {
  const int width = 5, height = 3, tile = 2;
  const render::PlaneReference reference = render::plane_reference(width, height, tile);
  const std::size_t columns = std::size_t(width) * tile + 2, rows = std::size_t(height) * tile + 2;
  ASSERT_EQ(reference.uv.size(), columns * rows * 2);
  EXPECT_EQ(reference.indices.size(), (columns - 1) * (rows - 1) * 6);
  for (std::uint32_t index : reference.indices) EXPECT_LT(index, columns * rows);
  for (std::size_t j = 1; j + 1 < columns; ++j) {
    EXPECT_FLOAT_EQ(reference.uv[j * 2], (float(j) - 0.5f) / width);  // texel centre j - 1
  }
  EXPECT_EQ(reference.uv[0], 0.0f);
  EXPECT_EQ(reference.uv[(columns - 1) * 2], float(tile));
  EXPECT_EQ(reference.uv[(rows - 1) * columns * 2 + 1], float(tile));
}

// A mesh's reference, on the CPU: sub-edges of at most half a texel, and points on an edge shared
// by two triangles are bit for bit the same in both (no cracks).
TEST(Mesh, MeshReferenceSubdividesFinelyAndSharesEdgePointsExactly) {
  render::Mesh quad;
  quad.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  quad.uvs = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  quad.triangles = {0, 1, 2, 0, 2, 3};
  const std::vector<render::MeshVertex> vertices = render::mesh_vertices(quad);
  const render::MeshReference reference = render::mesh_reference(vertices, quad.triangles, 8, 8, 1);
  EXPECT_GE(reference.subdivisions, 16);  // 8 texels along an edge: at least 2 pieces per texel
  // every vertex on the shared diagonal u = v appears in both triangles with equal bits
  std::vector<glm::vec3> diagonal;
  for (const render::MeshVertex& vertex : reference.vertices) {
    if (std::abs(vertex.u - vertex.v) < 1e-6f) diagonal.push_back(vertex.position);
  }
  ASSERT_EQ(diagonal.size(), std::size_t(2 * (reference.subdivisions + 1)));
  long long unmatched = 0;
  for (const glm::vec3& point : diagonal) {
    unmatched += std::count(diagonal.begin(), diagonal.end(), point) != 2;
  }
  EXPECT_EQ(unmatched, 0);
}

}  // namespace
