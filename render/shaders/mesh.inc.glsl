// render/shaders/mesh.inc.glsl - the fragment path on a mesh (render/mesh.h). Each fragment traces in
// its own tangent frame (dP/du, dP/dv, D N), as on the plane (Premecz's local planar approximation);
// With wrap the relief continues across texture seams (a closed mesh's u = 0 / 1 seam); with clamp a
// hit outside [0, K]^2 left the textured chart through its side and is discarded, as on the plane.
// Silhouettes: near a vertex the mesh is the quadric d = k_uu x^2 + k_vv y^2 below its tangent plane
// (mesh_vertices), so in relief coordinates a ray descends along z(s) = 1 - s + k s^2 instead of the
// line 1 - s, k = (k_uu x'^2 + k_vv y'^2) / D with x', y' its world travel per unit of s along
// t1 = dP/du / |dP/du| and t2 = n x t1. That bent ray reaches the hit's height h only where 1 - 4 k (1 - h) >= 0; otherwise it
// leaves the relief volume through the top before it gets there, and the fragment is discarded. For
// a sphere of constant height this is exactly where the ray misses the inner sphere (to second
// order in the shell's thickness). Concave curvature (k < 0) is taken as flat. The hit itself stays
// the planar trace's: what the bend changes is only whether the ray gets there.
// The reference on a mesh is its tessellation, displaced along the interpolated normal; no exact
// bilinear walk (that is for the plane).
// The methods trace the pixel's own ray (pixel_direction) from where it meets the fragment's tangent
// plane (tangent_plane_entry), as on the plane.

void mesh_fragment() {
  vec3 d = METHOD == METHOD_REFERENCE ? normalize(in_world - frame.eye.xyz) : pixel_direction();
  vec3 normal = normalize(in_normal);
  mat3 tangent_frame = mat3(in_tangent_u, in_tangent_v, normal * frame.surface.y);
  vec3 hit = vec3(in_uv, in_h);
  Entry entry;
  entry.world = in_world;
  entry.texture = vec3(in_uv, in_h);
  if (METHOD != METHOD_REFERENCE) {
    if (dot(d, normal) >= 0.0) discard;  // seen from outside only
    mat3 to_texture = inverse(tangent_frame);
    entry = tangent_plane_entry(d, normal, to_texture);
    vec3 direction = to_texture * d;
    Trace traced = trace(vec3(entry.texture.xy, 1.0), direction, -dot(d, normal));
    hit = traced.p;
    float dz = min(direction.z, -min_descent);
    // world travel per unit of s in the basis of the curvature fit: t1 along dP/du, t2 = n x t1
    vec3 travel = (in_tangent_u * direction.x + in_tangent_v * direction.y) / -dz;
    vec3 t1 = normalize(in_tangent_u);
    vec2 along = vec2(dot(travel, t1), dot(travel, cross(normal, t1)));
    float bend = max(dot(in_curvature, along * along), 0.0) / frame.surface.y;
    if (1.0 - 4.0 * bend * (1.0 - hit.z) < 0.0) discard;
    bool outside = any(lessThan(hit.xy, vec2(0.0))) || any(greaterThan(hit.xy, vec2(frame.surface.x)));
    if ((frame.counts.z & FLAG_WRAP) == 0 && outside) discard;
  }
  write_hit(hit, tangent_frame, d, normal, entry.world, entry.texture);
}
