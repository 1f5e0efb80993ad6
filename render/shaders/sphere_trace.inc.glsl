// render/shaders/sphere_trace.inc.glsl - sphere tracing through a 3D distance map (Donnelly,
// "Per-Pixel Displacement Mapping with Distance Functions", GPU Gems 2 ch. 8), finished by an exact
// walk through the bilinear cells. Included by methods.inc.glsl; surface.frag.glsl declares
// `distance_map`.
//
// The one fact: the map (bake_distance_map) is a distance in texture space (u, v, h) with the
// Euclidean metric, one unit of h = one unit of uv = one texture tile, and the rays are traced in
// exactly that space: p(s) = origin + s * descent with descent = (du, dv, -1), u and v in texture
// units over [0, K] and h in [0, 1] (the tangent frame dP/du = 1 / K, dP/dh = D N already put the
// tile count K and the depth scale D into descent.xy). So a sampled distance r lets the ray advance
// by r / |descent| in s, for every K and D; the sampler's repeat addressing maps u in [0, K] onto the
// tile the map was baked for.
//
// The map is conservative for trilinear filtering, so sphere steps never cross the surface; near it
// the stored distance drops to zero (within about a voxel above the surface and a map cell beside
// it), where sphere steps stall. Where a sphere step covers less of the ray than crossing one cell of
// the height map would, the trace walks the cells the ray crosses instead with the exact cell steps
// of methods.inc.glsl (one textureGather per cell; bilinear_cell.inc.glsl solves the cell). The walk
// hands back to sphere steps where the ray has risen high enough above the surface for a long sphere
// step. Every sphere step and every cell is one iteration; `steps` bounds them together, and a ray
// that runs out of them ends at its last point above the surface. --refine is not used: the cell
// walk's root is exact.

// tuning constants of sphere tracing
const float sphere_walk_cells = 1.0;    // cells: walk when a sphere step covers less s than this many cell crossings
const float sphere_resume_cells = 4.0;  // cells: sphere steps resume when one may cover this many cell crossings
const float sphere_stall_slices = 2.0;  // voxels along h: where the map may read 0 above the surface
const float sphere_edge_nudge = 1e-3;   // texels: a ray on a cell edge starts its walk in the cell it enters

// The map's trilinear read at p, made safe for the sampler's fixed-point weights. With weights in
// steps of w = 2^-subTexelPrecisionBits (frame.surface.w) a device returns the exact trilinear
// interpolation at some point p' no more than one step w of a voxel from p along each axis; the map
// is conservative at p' (for any point, bake_distance_map), and the distance is 1-Lipschitz, so the
// read less |p' - p| <= w |voxel| is conservative at p. (What the argument
// needs; on an NVIDIA H200, w = 1/256, no failure was traced to it: the sphere rays that ended past
// the crossing there came from rays built from interpolated attributes, see surface.frag.glsl.)
float fetch_distance(vec3 p, float filter_margin) {
  g_fetches += 1u;
  return max(textureLod(distance_map, p, 0.0).r - filter_margin, 0.0);
}

float sphere_trace(vec3 origin, vec3 descent, int steps) {
  float ray_length = length(descent);  // texture-space length per unit s
  vec2 a = descent.xy * frame.map_size.xy;
  // s the ray needs to cross one cell along its faster axis (huge for a vertical ray)
  float cell_s = 1.0 / max(max(abs(a.x), abs(a.y)), min_denominator);
  vec3 voxels = vec3(textureSize(distance_map, 0));
  float stall_band = sphere_stall_slices / voxels.z;
  float filter_margin = frame.surface.w * length(1.0 / voxels);
  vec2 toward = sign(a);
  float s = 0.0;
  bool walking = false, resumed = false;
  float resume_cells = sphere_resume_cells;
  ivec2 cell = ivec2(0);
  for (int i = 0; i < steps; ++i) {
    g_iterations += 1u;
    if (!walking) {
      vec3 p = origin + s * descent;
      float step = fetch_distance(p, filter_margin) / ray_length;
      if (step >= sphere_walk_cells * cell_s) {
        resumed = false;
        s = min(s + step, 1.0);
        continue;
      }
      if (resumed) resume_cells *= 2.0;  // the gap promised a long step and the map did not give it
      walking = true;
      resumed = false;
      // the cell the ray is in, or enters when it is on an edge
      cell = ivec2(floor(p.xy * frame.map_size.xy - 0.5 + sphere_edge_nudge * toward));
    }
    bool exact;
    float exit_gap;
    s = cell_step(origin, descent, s, cell, exact, exit_gap);
    if (exact) return s;
    if (s >= 1.0) return 1.0;  // at h = 0 the ray is on or under the surface
    // far enough above the surface (the gap there bounds the distance) for a long sphere step again
    if ((exit_gap - stall_band) / ray_length >= resume_cells * cell_s) {
      walking = false;
      resumed = true;
    }
  }
  return s;
}
