// render/shaders/max_pyramid.inc.glsl - the two max-pyramid traversals: maximum mipmaps (Tevs, Ihrke
// & Seidel, "Maximum Mipmaps for Fast, Accurate, and Scalable Dynamic Height Field Rendering", I3D
// 2008) and quadtree displacement mapping (Drobot, "Quadtree Displacement Mapping with Height
// Blending", GPU Pro 2010). Included by methods.inc.glsl; declares the pyramid's storage buffer.
//
// The pyramid bounds the BILINEAR surface: it is built on the dual grid (bake::build_dual_max_pyramid,
// bake/bake.h), in cell coordinates x = u W - 0.5 - origin, y = v H - 0.5 - origin, where level-0 cell
// (i, j) is the square [j, j + 1] x [i, i + 1] between four texel centres and node a of level L covers
// cells [a 2^L, min((a + 1) 2^L, n)) along each axis (n cells at level 0). With wrap the cell grid is
// one period and tiles the plane: a node is addressed by its period and its index in the period.
//
// Both traversals start at the top level and visit nodes in the order the ray crosses them. At a node
// the ray is tested against the box [footprint] x [0, node max]: the ray at height z = 1 - s is below
// the max from s = 1 - max on, so it meets the box inside the footprint when max(s, 1 - max) <= the
// parameter where it leaves the footprint. Then the ray is advanced to that point and the traversal
// goes down to the child under it. Otherwise the ray is advanced to the node's exit boundary, the
// traversal moves to the neighbouring node there and goes up:
// - maxmip (Tevs et al.): one level up when the new node has a different parent;
// - qdm (Drobot): one level up after every boundary crossing (his loop's `level += 2` before the
//   `level--` that ends each iteration).
// Nodes are tracked by integer index (a DDA over the level's nodes), not recomputed from the rounded
// ray point, so a rounding error can never skip a node, and s never decreases.
// At level 0 both solve the ray against the bilinear patch exactly: along the ray the height over
// one cell is a quadratic in s, and its first root in the cell is the hit.
// The ray also stops where it leaves the patch [0, K]^2 through a side (its hit would be discarded):
// it then returns s = 1, a point beyond that side. Each node visit is one iteration and reads one
// value (a pyramid node, or at level 0 the cell's four corner heights with one textureGather).
// --steps caps the visits; a ray that runs out ends where it is, above the surface.

layout(std430, binding = BINDING_MAX_PYRAMID) readonly buffer MaxPyramidBlock {
  MaxPyramidHeader pyramid;
  float pyramid_values[];
};

const float pyramid_no_exit = 1e30;  // exit parameter along an axis the ray does not move along

float fetch_pyramid(int level, ivec2 node) {
  g_fetches += 1u;
  ivec4 shape = pyramid.levels[level];
  return pyramid_values[shape.x + node.y * shape.y + node.x];
}

// The heights at the corners of level-0 cell `cell` (index in its period) as (h00, h10, h01, h11):
// h_xy with x = 1 one texel further along u, y = 1 one texel further along v. One gather at the
// cell's centre reads exactly those four texels with the sampler's address mode.
vec4 fetch_cell_corners(ivec2 cell) {
  g_fetches += 1u;
  vec2 centre = (vec2(cell) + float(pyramid.shape.y) + 1.0) * frame.map_size.zw;
  vec4 gathered = textureGather(height_map, centre);  // (u0 v1, u1 v1, u1 v0, u0 v0)
  return vec4(gathered.w, gathered.z, gathered.x, gathered.y);
}

// The first s in [s0, s1] where the ray meets the bilinear patch of one cell, or -1. `corners` as
// fetch_cell_corners returns them; `cell_start` is the ray's cell coordinates at s = 0 relative to
// the cell's lower corner, `delta` their change per unit s. Over the interval the gap (ray height
// minus surface height) is g0 + g1 t + g2 t^2 with t = (s - s0) / (s1 - s0) in [0, 1], so every
// coefficient stays of the order of the heights even for grazing rays.
float cell_crossing(vec4 corners, float origin_h, vec2 cell_start, vec2 delta, float s0, float s1) {
  float span = s1 - s0;
  vec2 f = clamp(cell_start + s0 * delta, 0.0, 1.0);
  vec2 df = delta * span;
  // h(fx, fy) = a + b fx + c fy + d fx fy
  float a = corners.x, b = corners.y - corners.x, c = corners.z - corners.x;
  float d = corners.x - corners.y - corners.z + corners.w;
  float g0 = origin_h - s0 - (a + b * f.x + c * f.y + d * f.x * f.y);
  if (g0 <= 0.0) return s0;
  float g1 = -span - b * df.x - c * df.y - d * (f.x * df.y + f.y * df.x);
  float g2 = -d * df.x * df.y;
  float t = 2.0;  // no root in [0, 1]
  if (g2 == 0.0) {
    if (g1 < 0.0) t = g0 / -g1;
  } else {
    float discriminant = g1 * g1 - 4.0 * g2 * g0;
    if (discriminant >= 0.0) {
      // both roots without cancellation; g0 > 0, so neither is 0
      float q = -0.5 * (g1 + (g1 >= 0.0 ? 1.0 : -1.0) * sqrt(discriminant));
      float first = q / g2, second = q != 0.0 ? g0 / q : 2.0;
      t = min(first >= 0.0 ? first : 2.0, second >= 0.0 ? second : 2.0);
    }
  }
  return t <= 1.0 ? s0 + t * span : -1.0;
}

// The ray parameter s of the first hit (see the top of this file). every_crossing_ascends: qdm's
// rule; otherwise maxmip's.
float max_pyramid_trace(vec3 origin, vec3 descent, int steps, bool every_crossing_ascends) {
  int levels = pyramid.shape.x;
  if (levels <= 0) return 0.0;
  bool wrap = (frame.counts.z & FLAG_WRAP) != 0;
  ivec2 cells = pyramid.levels[0].yz;
  vec2 start = origin.xy * frame.map_size.xy - 0.5 - float(pyramid.shape.y);
  vec2 delta = descent.xy * frame.map_size.xy;
  ivec2 direction = ivec2(sign(delta));

  // where the ray leaves the patch [0, K]^2 through a side
  float s_end = 1.0;
  for (int axis = 0; axis < 2; ++axis) {
    if (descent[axis] > 0.0) s_end = min(s_end, (frame.surface.x - origin[axis]) / descent[axis]);
    if (descent[axis] < 0.0) s_end = min(s_end, -origin[axis] / descent[axis]);
  }
  s_end = max(s_end, 0.0);

  int level = levels - 1;
  ivec2 period = wrap ? ivec2(floor(start / vec2(cells))) : ivec2(0);
  ivec2 node = ivec2(0);
  float s = 0.0;
  for (int i = 0; i < steps; ++i) {
    g_iterations += 1u;
    // the node's footprint in cell coordinates, and where the ray leaves it along each axis
    ivec2 base = period * cells;
    vec2 lo = vec2(base + (node << level));
    vec2 hi = vec2(base + min((node + 1) << level, cells));
    vec2 exits = vec2(pyramid_no_exit);
    for (int axis = 0; axis < 2; ++axis) {
      if (delta[axis] > 0.0) exits[axis] = (hi[axis] - start[axis]) / delta[axis];
      if (delta[axis] < 0.0) exits[axis] = (lo[axis] - start[axis]) / delta[axis];
    }
    float s_exit = max(min(exits.x, exits.y), s);
    vec4 corners = vec4(0.0);
    float node_max;
    if (level == 0) {
      corners = fetch_cell_corners(node);
      node_max = max(max(corners.x, corners.y), max(corners.z, corners.w));
    } else {
      node_max = fetch_pyramid(level, node);
    }
    float s_box = max(s, origin.z - node_max);
    float s_far = min(s_exit, s_end);
    if (s_box <= s_far) {
      if (level == 0) {
        float hit = cell_crossing(corners, origin.z, start - lo, delta, s_box, s_far);
        if (hit >= 0.0) return hit;
      } else {
        // down to the child the ray is in where it enters the box (on the split line, the one
        // ahead): s against where the ray crosses the split line, computed as the exits are, so
        // that a rounded ray point can never send the traversal back into a node it has left
        s = s_box;
        level -= 1;
        ivec2 child = node * 2;
        for (int axis = 0; axis < 2; ++axis) {
          int split = (child[axis] + 1) << level;
          if (split >= cells[axis]) continue;  // a truncated node with one child along this axis
          float line = float(base[axis] + split);
          bool upper = start[axis] >= line;
          if (delta[axis] > 0.0) upper = s >= (line - start[axis]) / delta[axis];
          if (delta[axis] < 0.0) upper = s < (line - start[axis]) / delta[axis];
          if (upper) child[axis] += 1;
        }
        node = child;
        continue;
      }
    }
    // past the box: on to the neighbouring node across the exit boundary
    if (s_exit >= s_end) return 1.0;
    s = s_exit;
    float nearest_exit = min(exits.x, exits.y);
    ivec2 count = pyramid.levels[level].yz;
    ivec2 parent = node >> 1;
    ivec2 old_period = period;
    for (int axis = 0; axis < 2; ++axis) {
      if (exits[axis] != nearest_exit) continue;
      node[axis] += direction[axis];
      if (node[axis] < 0) {
        period[axis] -= 1;
        node[axis] = count[axis] - 1;
      } else if (node[axis] >= count[axis]) {
        period[axis] += 1;
        node[axis] = 0;
      }
    }
    if (!wrap && period != ivec2(0)) return 1.0;  // off the clamped grid (beyond the patch)
    bool new_parent = any(notEqual(node >> 1, parent)) || period != old_period;
    if (level < levels - 1 && (every_crossing_ascends || new_parent)) {
      level += 1;
      node >>= 1;
    }
  }
  return s;
}
