// render/shaders/shading.inc.glsl - the shading every method shares, so that pictures differ only by
// their hit points: an albedo image or a procedural grid with Lambert + Blinn-Phong, or the water
// material; one directional light, the normal from the height field at the hit. Reads that shading makes are not counted as method fetches.

const float albedo_cells = 8.0;       // checker cells per texture tile
const float grid_line_width = 0.06;   // fraction of a cell
const float ambient = 0.15;
const float specular_strength = 0.25;
const float specular_exponent = 48.0;

// The surface of the level the pixel traced (g_level): the hit lies on it, and it is shaded with its
// own normal and height. Level 0 (every view without levels) keeps its own functions, untouched.
float shading_height(vec2 uv) { return bilinear_height_of(height_map, uv); }

// World normal of the displaced surface at texture point uv, from central differences one texel apart.
vec3 surface_normal(vec2 uv, mat3 tangent_frame) {
  vec2 texel = frame.map_size.zw;
  float dh_du = (shading_height(uv + vec2(texel.x, 0.0)) - shading_height(uv - vec2(texel.x, 0.0))) / (2.0 * texel.x);
  float dh_dv = (shading_height(uv + vec2(0.0, texel.y)) - shading_height(uv - vec2(0.0, texel.y))) / (2.0 * texel.y);
  vec3 along_u = tangent_frame[0] + dh_du * tangent_frame[2];
  vec3 along_v = tangent_frame[1] + dh_dv * tangent_frame[2];
  return normalize(cross(along_u, along_v));
}

// The same on a coarser level: central differences one of its texels apart.
vec3 level_surface_normal(vec2 uv, mat3 tangent_frame) {
  vec2 texel = g_level_size.zw;
  float dh_du = (level_bilinear_height(uv + vec2(texel.x, 0.0)) - level_bilinear_height(uv - vec2(texel.x, 0.0))) / (2.0 * texel.x);
  float dh_dv = (level_bilinear_height(uv + vec2(0.0, texel.y)) - level_bilinear_height(uv - vec2(0.0, texel.y))) / (2.0 * texel.y);
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

// ---- the water material (FLAG_WATER): what the eye sees of water is mostly the sky it reflects,
// weighted by Fresnel's law, plus light scattered back from the water body, darker where the water is
// deeper, a glint where the sun's reflection meets the eye, and foam where the surface folds.
const float water_f0 = 0.02;                      // Fresnel reflectance at normal incidence (n = 1.33)
const vec3 sky_zenith = vec3(0.18, 0.36, 0.66);
const vec3 sky_horizon = vec3(SKY_HORIZON_R, SKY_HORIZON_G, SKY_HORIZON_B);
const vec3 water_deep = vec3(0.004, 0.030, 0.060);    // scattered colour over the troughs (height 0)
const vec3 water_shallow = vec3(0.030, 0.170, 0.190); // over the crests (height 1): less water below
const float sun_glint_exponent = 300.0;
const float sun_glint_strength = 3.0;

vec3 sky(vec3 direction) {
  float up = clamp(direction.z, 0.0, 1.0);
  return mix(sky_horizon, sky_zenith, pow(up, 0.6));
}

// The sky seen directly (the unbounded plane's background): the gradient, the sun's disc and its glow.
const float sun_disc_cosine = 0.99990;  // cos of the disc's angular radius (about 0.8 degrees)
vec3 sky_with_sun(vec3 direction) {
  vec3 l = normalize(frame.light.xyz);
  float towards = max(dot(normalize(direction), l), 0.0);
  vec3 glow = vec3(1.0, 0.85, 0.6) * (0.35 * pow(towards, 64.0) + 0.15 * pow(towards, 8.0));
  vec3 disc = towards >= sun_disc_cosine ? vec3(8.0, 7.5, 6.5) : vec3(0.0);
  return sky(direction) + glow + disc;
}

vec3 shade_water(vec2 uv, vec3 n, vec3 view_direction, vec3 l, float lit) {
  vec3 to_eye = -view_direction;
  float cosine = clamp(dot(n, to_eye), 0.0, 1.0);
  float m = 1.0 - cosine, m2 = m * m;  // Schlick's (1 - cos)^5 by products: pow is exp2(log2) per pixel
  float fresnel = water_f0 + (1.0 - water_f0) * (m2 * m2 * m);
  vec3 reflected = reflect(view_direction, n);
  vec3 reflection = sky(reflected);
  float glint = lit * sun_glint_strength * pow(max(dot(reflected, l), 0.0), sun_glint_exponent);
  float h = on_level() ? level_bilinear_height(uv) : shading_height(uv);
  vec3 body = mix(water_deep, water_shallow, h) * (ambient + (1.0 - ambient) * lit * max(dot(n, l), 0.0));
  vec3 colour = mix(body, reflection, fresnel) + glint;
  if ((frame.counts.z & FLAG_FOAM) != 0) {
    float foam = clamp(textureLod(foam_map, uv, 0.0).r, 0.0, 1.0);
    colour = mix(colour, frame.foam.rgb * (ambient + (1.0 - ambient) * lit * max(dot(n, l), 0.0)),
                 foam * frame.foam.a);
  }
  return min(colour, vec3(1.0));
}

// Water on a coarser level: the level's surface is smooth where level 0 was not, and a far pixel
// averages the slopes it left out. Their spread is the level's slope moments' variance (the mean of
// |g|^2 less the square of the mean g, split evenly between u and v), and the colour is its mean over
// those slopes around the level's own normal: a 3 x 3 Gauss-Hermite rule (nodes 0 and +-sqrt(3)
// sigma, weights 2/3 and 1/6 a side), each facet weighted by the area it shows the eye (n . v over
// n . z: facets that face the eye fill more of the pixel, and those that face away none). The glint
// (too narrow for nine nodes) is that of the mean normal the eye sees, its lobe widened by the
// spread (the reflection turns by twice the facet's tilt: per-axis angular variances 1 / n + 4
// sigma^2 add) and scaled to keep its energy.
vec3 shade_water_level(vec2 uv, mat3 tangent_frame, vec3 view_direction, vec3 l, float lit) {
  vec2 texel = g_level_size.zw;
  float dh_du = (level_bilinear_height(uv + vec2(texel.x, 0.0)) - level_bilinear_height(uv - vec2(texel.x, 0.0))) / (2.0 * texel.x);
  float dh_dv = (level_bilinear_height(uv + vec2(0.0, texel.y)) - level_bilinear_height(uv - vec2(0.0, texel.y))) / (2.0 * texel.y);
  vec4 here = level_height_and_moments(uv);
  vec3 moments = here.gba;
  float sigma = sqrt(max(moments.z - dot(moments.xy, moments.xy), 0.0) * 0.5);  // per axis, per uv
  vec3 up = normalize(tangent_frame[2]);
  vec3 to_eye = -view_direction;
  float h = here.r;
  vec3 body_colour = mix(water_deep, water_shallow, h);
  const float node = 1.7320508;  // sqrt(3)
  const float weights[3] = float[3](1.0 / 6.0, 2.0 / 3.0, 1.0 / 6.0);
  vec3 colour = vec3(0.0), seen_normal = vec3(0.0);
  float shown = 0.0;
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) {
      vec3 along_u = tangent_frame[0] + (dh_du + float(a - 1) * node * sigma) * tangent_frame[2];
      vec3 along_v = tangent_frame[1] + (dh_dv + float(b - 1) * node * sigma) * tangent_frame[2];
      vec3 n = normalize(cross(along_u, along_v));
      float area = weights[a] * weights[b] * max(dot(n, to_eye), 0.0) / max(dot(n, up), 1e-4);
      if (area <= 0.0) continue;
      float cosine = clamp(dot(n, to_eye), 0.0, 1.0);
      float m = 1.0 - cosine, m2 = m * m;
      float fresnel = water_f0 + (1.0 - water_f0) * (m2 * m2 * m);
      vec3 body = body_colour * (ambient + (1.0 - ambient) * lit * max(dot(n, l), 0.0));
      colour += area * mix(body, sky(reflect(view_direction, n)), fresnel);
      seen_normal += area * n;
      shown += area;
    }
  vec3 along_u = tangent_frame[0] + dh_du * tangent_frame[2];
  vec3 along_v = tangent_frame[1] + dh_dv * tangent_frame[2];
  vec3 n = normalize(cross(along_u, along_v));
  if (shown > 0.0) {
    colour /= shown;
    n = normalize(seen_normal);  // the glint's: the facets the eye sees lean towards it
  } else {  // every facet faces away (a ray at the level's silhouette): its own normal
    float m = 1.0 - clamp(dot(n, to_eye), 0.0, 1.0), m2 = m * m;
    vec3 body = body_colour * (ambient + (1.0 - ambient) * lit * max(dot(n, l), 0.0));
    colour = mix(body, sky(reflect(view_direction, n)), water_f0 + (1.0 - water_f0) * (m2 * m2 * m));
  }
  float tilt = sigma * length(tangent_frame[2]) / length(tangent_frame[0]);  // world slope, per axis
  float exponent = 1.0 / (1.0 / sun_glint_exponent + 4.0 * tilt * tilt);
  colour += lit * sun_glint_strength * (exponent / sun_glint_exponent) *
            pow(max(dot(reflect(view_direction, n), l), 0.0), exponent);
  if ((frame.counts.z & FLAG_FOAM) != 0) {
    float foam = clamp(textureLod(foam_map, uv, 0.0).r, 0.0, 1.0);
    colour = mix(colour, frame.foam.rgb * (ambient + (1.0 - ambient) * lit * max(dot(n, l), 0.0)),
                 foam * frame.foam.a);
  }
  return min(colour, vec3(1.0));
}

// lit: 1 where the light reaches the hit, 0 in shadow (then only the ambient term is left)
vec3 shade(vec2 uv, mat3 tangent_frame, vec3 view_direction, float lit) {
  if (water_on && on_level())
    return shade_water_level(uv, tangent_frame, view_direction, normalize(frame.light.xyz), lit);
  vec3 n = on_level() ? level_surface_normal(uv, tangent_frame) : surface_normal(uv, tangent_frame);
  if (water_on) return shade_water(uv, n, view_direction, normalize(frame.light.xyz), lit);
  vec3 l = normalize(frame.light.xyz);
  vec3 half_vector = normalize(l - view_direction);
  float diffuse = lit * max(dot(n, l), 0.0);
  float specular = diffuse > 0.0 ? pow(max(dot(n, half_vector), 0.0), specular_exponent) : 0.0;
  return albedo(uv) * (ambient + (1.0 - ambient) * diffuse) + specular_strength * specular;
}
