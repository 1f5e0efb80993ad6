// render/shaders/reference.inc.glsl - the reference's exact hit on the bilinear surface, the same
// cell-by-cell walk as render/cpu_trace.cpp (which documents it), in float, with the cell solver of
// bilinear_cell.inc.glsl. Included by surface.frag.glsl after `frame` and `height_map`. Its reads are not counted: the reference is the
// truth, not a method whose cost is measured.

float reference_texel(ivec2 ij) {
  ivec2 size = textureSize(height_map, 0);
  if ((frame.counts.z & FLAG_WRAP) != 0) {
    ij -= size * ivec2(floor(vec2(ij) / vec2(size)));
  } else {
    ij = clamp(ij, ivec2(0), size - 1);
  }
  return texelFetch(height_map, ij, 0).r;
}

// The first s in [0, s_end] where origin + s * descent (descent.z = -1) reaches the bilinear surface,
// or s_end. Bounded: where the ray leaves the [0, K]^2 patch first, an s whose point lies outside it.
// Unbounded (shadow rays, which start outside the patch at times): the relief continues beyond the
// patch with the address mode.
float reference_first_crossing(vec3 origin, vec3 descent, float s_end, bool bounded) {
  vec2 size = frame.map_size.xy;
  vec2 x0 = origin.xy * size - 0.5;
  vec2 dx = descent.xy * size;
  ivec2 cell = ivec2(floor(x0));
  ivec2 dir = ivec2(sign(dx));
  // s of the next cell boundary along each axis; a huge value along an axis the ray does not move on
  vec2 next = vec2(3.0e38);
  for (int axis = 0; axis < 2; ++axis) {
    if (dir[axis] != 0) next[axis] = (float(cell[axis] + max(dir[axis], 0)) - x0[axis]) / dx[axis];
  }
  // a ray crosses at most every cell of the patch in a row and a column before it leaves
  int max_cells = 2 * int(frame.surface.x * (size.x + size.y)) + 8;
  float s0 = 0.0;
  for (int n = 0; n < max_cells; ++n) {
    float s1 = min(min(next.x, next.y), s_end);
    BilinearCell c;
    c.z0 = origin.z;
    c.f0 = x0 - vec2(cell);
    c.df = dx;
    c.h = vec4(reference_texel(cell), reference_texel(cell + ivec2(1, 0)), reference_texel(cell + ivec2(0, 1)),
               reference_texel(cell + ivec2(1, 1)));
    float s = cell_first_root(c, s0, max(s1, s0));
    if (s >= 0.0) return s;
    if (s1 >= s_end) return s_end;
    s0 = s1;
    vec2 p = origin.xy + s0 * descent.xy;
    if (bounded && (any(lessThan(p, vec2(0.0))) || any(greaterThan(p, vec2(frame.surface.x))))) return s0;
    for (int axis = 0; axis < 2; ++axis) {
      if (next[axis] <= s1) {
        cell[axis] += dir[axis];
        next[axis] = (float(cell[axis] + max(dir[axis], 0)) - x0[axis]) / dx[axis];
      }
    }
  }
  return s0;
}
