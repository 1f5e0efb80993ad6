// render/shaders/surface_varyings.inc.glsl - what every vertex shader hands the surface fragment
// shader (surface.frag.glsl declares the same locations as inputs).
layout(location = 0) out vec3 out_world;      // world position of the vertex
layout(location = 1) out vec2 out_uv;         // texture coordinates, over [0, K]
layout(location = 2) out vec3 out_tangent_u;  // dP/du
layout(location = 3) out vec3 out_tangent_v;  // dP/dv
layout(location = 4) out vec3 out_normal;     // unit, pointing out of the relief
layout(location = 5) out float out_h;         // the height this vertex lies at: 1 on the base surface
layout(location = 6) out vec2 out_curvature;  // meshes only (mesh.vert.glsl): k_uu, k_vv; 0 elsewhere
