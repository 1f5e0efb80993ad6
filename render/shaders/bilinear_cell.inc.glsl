// render/shaders/bilinear_cell.inc.glsl - the exact crossing of a ray with the bilinear surface over
// one cell between four texel centres (see render/cpu_trace.cpp): the ray's height above the patch
// is a quadratic in the ray parameter s; the segment is split at its extremum and the first monotone
// piece that changes sign is bisected. Used by the reference's cell walk and by the cone methods'
// exact cell steps. Pure arithmetic: no texture reads.

const int cell_bisections = 24;  // halvings of a monotone piece: float precision of s

// The ray's height above one cell's bilinear patch: corners h = (h00, h10, h01, h11), the ray's
// position in the cell f(s) = f0 + s * df (0..1 between the cell's texel centres).
struct BilinearCell {
  float z0;
  vec2 f0, df;
  vec4 h;
};

float cell_gap(BilinearCell c, float s) {
  vec2 f = c.f0 + s * c.df;
  float top = mix(c.h.x, c.h.y, f.x), bottom = mix(c.h.z, c.h.w, f.x);
  return c.z0 - s - mix(top, bottom, f.y);
}

// The first s in [s0, s1] with gap <= 0, given that the gap is monotone there; -1 if none.
float cell_monotone_root(BilinearCell c, float s0, float s1) {
  if (cell_gap(c, s0) <= 0.0) return s0;
  if (cell_gap(c, s1) > 0.0) return -1.0;
  for (int i = 0; i < cell_bisections; ++i) {
    float mid = 0.5 * (s0 + s1);
    if (cell_gap(c, mid) > 0.0) s0 = mid; else s1 = mid;
  }
  return s1;
}

// The first s in [s0, s1] where the ray is at or below the cell's patch, or -1.
float cell_first_root(BilinearCell c, float s0, float s1) {
  float twist = c.h.x - c.h.y - c.h.z + c.h.w;
  float a = -twist * c.df.x * c.df.y;
  float b = -1.0 - (c.h.y - c.h.x) * c.df.x - (c.h.z - c.h.x) * c.df.y - twist * (c.f0.x * c.df.y + c.f0.y * c.df.x);
  float split = a != 0.0 ? -b / (2.0 * a) : -1.0;
  if (split > s0 && split < s1) {
    float s = cell_monotone_root(c, s0, split);
    return s >= 0.0 ? s : cell_monotone_root(c, split, s1);
  }
  return cell_monotone_root(c, s0, s1);
}
