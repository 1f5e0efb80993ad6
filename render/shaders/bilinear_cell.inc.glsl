// render/shaders/bilinear_cell.inc.glsl - the exact crossing of a ray with the bilinear surface over
// one cell between four texel centres (see render/cpu_trace.cpp): the ray's height above the patch
// is a quadratic in the ray parameter s. If it is above the patch at both ends of the segment, only
// a convex gap can dip below in between, at its minimum; the first root of the first piece that
// changes sign is then solved in closed form (the cancellation-free pair g0 / q, q / a). It replaced
// 24 bisections per piece, which made sphere and cone frames 3-4x slower on lavapipe with the same
// error. (render/cpu_trace.cpp bisects in double: the slow exact one the tests compare against.)
// Used by the reference's cell walk and by the cone, pyramid and sphere methods' exact cell steps.
// Pure arithmetic: no texture reads.

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

// The first s in [s0, s1] where the ray is at or below the cell's patch, or -1.
float cell_first_root(BilinearCell c, float s0, float s1) {
  float twist = c.h.x - c.h.y - c.h.z + c.h.w;
  float a = -twist * c.df.x * c.df.y;
  float b = -1.0 - (c.h.y - c.h.x) * c.df.x - (c.h.z - c.h.x) * c.df.y - twist * (c.f0.x * c.df.y + c.f0.y * c.df.x);
  float g0 = cell_gap(c, s0);
  if (g0 <= 0.0) return s0;
  float end = s1, g_end = cell_gap(c, s1);
  if (g_end > 0.0) {
    float split = a > 0.0 ? -b / (2.0 * a) : -1.0;
    if (!(split > s0 && split < s1)) return -1.0;
    g_end = cell_gap(c, split);
    if (g_end > 0.0) return -1.0;
    end = split;
  }
  // local quadratic around s0: g(s0 + t) = g0 + t (b + 2 a s0) + a t^2
  float b0 = b + 2.0 * a * s0, span = end - s0;
  float root = span * clamp(g0 / max(g0 - g_end, 1e-12), 0.0, 1.0);
  float q = -0.5 * (b0 + (b0 >= 0.0 ? 1.0 : -1.0) * sqrt(max(b0 * b0 - 4.0 * a * g0, 0.0)));
  float near_root = q != 0.0 ? g0 / q : -1.0;
  float far_root = a != 0.0 ? q / a : -1.0;
  if (near_root >= 0.0 && near_root <= span) root = near_root;
  else if (far_root >= 0.0 && far_root <= span) root = far_root;
  return s0 + clamp(root, 0.0, span);
}
