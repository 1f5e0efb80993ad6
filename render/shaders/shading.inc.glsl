// render/shaders/shading.inc.glsl - the shading every method shares, so that pictures differ only by
// their hit points: an albedo image or a procedural grid, Lambert + Blinn-Phong, one directional light, the normal
// from the height field at the hit. Reads that shading makes are not counted as method fetches.

const float albedo_cells = 8.0;       // checker cells per texture tile
const float grid_line_width = 0.06;   // fraction of a cell
const float ambient = 0.15;
const float specular_strength = 0.25;
const float specular_exponent = 48.0;

float shading_height(vec2 uv) { return textureLod(height_map, uv, 0.0).r; }

// World normal of the displaced surface at texture point uv, from central differences one texel apart.
vec3 surface_normal(vec2 uv, mat3 tangent_frame) {
  vec2 texel = frame.map_size.zw;
  float dh_du = (shading_height(uv + vec2(texel.x, 0.0)) - shading_height(uv - vec2(texel.x, 0.0))) / (2.0 * texel.x);
  float dh_dv = (shading_height(uv + vec2(0.0, texel.y)) - shading_height(uv - vec2(0.0, texel.y))) / (2.0 * texel.y);
  vec3 along_u = tangent_frame[0] + dh_du * tangent_frame[2];
  vec3 along_v = tangent_frame[1] + dh_dv * tangent_frame[2];
  return normalize(cross(along_u, along_v));
}

vec3 grid_albedo(vec2 uv) {
  vec2 cell = uv * albedo_cells;
  vec2 f = fract(cell);
  bool line = min(f.x, f.y) < grid_line_width;
  float checker = mod(floor(cell.x) + floor(cell.y), 2.0);
  vec3 base = mix(vec3(0.78, 0.64, 0.46), vec3(0.52, 0.66, 0.80), checker);
  return line ? base * 0.35 : base;
}

vec3 albedo(vec2 uv) {
  if ((frame.counts.z & FLAG_ALBEDO) != 0) return textureLod(albedo_map, uv, 0.0).rgb;
  return grid_albedo(uv);
}

// lit: 1 where the light reaches the hit, 0 in shadow (then only the ambient term is left)
vec3 shade(vec2 uv, mat3 tangent_frame, vec3 view_direction, float lit) {
  vec3 n = surface_normal(uv, tangent_frame);
  vec3 l = normalize(frame.light.xyz);
  vec3 half_vector = normalize(l - view_direction);
  float diffuse = lit * max(dot(n, l), 0.0);
  float specular = diffuse > 0.0 ? pow(max(dot(n, half_vector), 0.0), specular_exponent) : 0.0;
  return albedo(uv) * (ambient + (1.0 - ambient) * diffuse) + specular_strength * specular;
}
