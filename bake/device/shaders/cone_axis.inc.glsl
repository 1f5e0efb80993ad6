// bake/device/shaders/cone_axis.inc.glsl - one axis of the cell grid of the bilinear surface (bake.h's
// DualMaxPyramid cells, bake/cone_bilinear.cpp's Axis), for the device cone kernels. Positions are in
// half texels: texel t's centre at 2t, its square Q_c spanning [2t - 1, 2t + 1]. Cell n (an unrolled
// index with wrap: the plane is tiled with the map) lies between texel centres a and a + 1, a = n with
// wrap, a = n - 1 with clamp, where cells 0 and `texels` are the half-texel border cells.

// floor(a / b) for b > 0 and any a (GLSL's / and % are undefined for negative operands)
int floor_div(int a, int b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }
int wrap_index(int a, int n) { return a - n * floor_div(a, n); }

int axis_texel(int a, int texels, bool wrap) { return wrap ? wrap_index(a, texels) : clamp(a, 0, texels - 1); }
int cell_left_centre(int n, bool wrap) { return wrap ? n : n - 1; }
int cell_of_left_centre(int a, bool wrap) { return wrap ? a : a + 1; }
bool cell_exists(int n, int cells, bool wrap) { return wrap || (n >= 0 && n < cells); }
int cell_begin(int n, bool wrap) { return wrap ? 2 * n : max(2 * n - 2, -1); }
int cell_end(int n, int texels, bool wrap) { return wrap ? 2 * n + 2 : min(2 * n, 2 * texels - 1); }
