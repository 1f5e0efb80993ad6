// pipeline/query.h - camera-independent height queries: for any world x, y and time, the height of
// exactly the surface the renderer draws (the bilinear surface of the scene's heights, with the
// scene's address: periodic sources repeat), its normal and, for choppy water, the horizontal
// displacement of the water there. For buoyancy, collision and analysis.
//
//   pipeline::HeightQuery query(scene);
//   pipeline::QueryResult result;
//   query.query(points, /*time*/ 2.5, result);  // result.height_m[i], z[i], normal[i], displacement[i]
//
// Units: x, y in metres from the patch's corner (sources without metres - bricks, cliff, images - in
// patch widths); height_m the source's metres (the inverse of its [0, 1] mapping: [0, 1] itself for
// those); z, normal in the renderer's world (render.h: the plane's u = x / patch / tile, z = D (h - 1)).
// The heights for a time are made once (the effects the surface needs: heights, and the choppy
// resampling for choppy water) and kept for later queries at that time; a query allocates nothing
// once its vectors are large enough.
#pragma once

#include <glm/glm.hpp>
#include <memory>
#include <span>
#include <vector>

#include "pipeline/height_source.h"
#include "pipeline/scene.h"

namespace displace::pipeline {

struct QueryPoint {
  double x = 0.0, y = 0.0;  // metres (patch widths for sources without metres)
};

struct QueryResult {
  std::vector<float> height_m;          // metres above the source's zero ([0, 1] heights without metres)
  std::vector<float> z;                 // the renderer's world z of the surface
  std::vector<glm::vec3> normal;        // the renderer's world normal, unit length
  std::vector<glm::vec2> displacement;  // metres: where the water there came from, p + D(p) = x (0: none)
};

class HeightQuery {
 public:
  // Throws SceneError for a scene whose heights cannot be made (as HeightSource).
  explicit HeightQuery(const Scene& scene, HeightLoader loader = {});
  ~HeightQuery();
  HeightQuery(HeightQuery&&) noexcept;
  HeightQuery& operator=(HeightQuery&&) noexcept;

  // Fills `out` (resized to points.size()) for `time` in seconds.
  void query(std::span<const QueryPoint> points, double time, QueryResult& out);

  double patch_metres() const;     // metres one patch covers (1 for sources without metres)
  long long heights_made() const;  // times heights were made (work counter: once per time asked)

  struct State;

 private:
  std::unique_ptr<State> state_;
};

}  // namespace displace::pipeline
