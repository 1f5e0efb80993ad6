// render/shaders/height_fetch.inc.glsl - the bilinear height surface read exactly, in every stage.
// Include after frame_block.inc.glsl.
//
// The bakers (bake/) and the CPU traces (render/cpu_trace.cpp) define the surface as the bilinear
// interpolation of the texels with exact weights. A linear sampler does not give that surface on
// every device: the weights are fixed point with VkPhysicalDeviceLimits::subTexelPrecisionBits bits
// (8 on NVIDIA; on an H200, relief refined against the sampled surface never came within 0.01
// texels of the exact hit on a smooth field, whatever its steps; lavapipe filters float images
// exactly, so it never showed here).
// So the four texels come from one gather and the weights are applied here in float. The gather is
// taken at the corner the four texels share, where the sampler's own coordinate rounding (a fraction
// of 1/2^bits of a texel) cannot move the footprint to another texel.
float bilinear_height_of(sampler2D map, vec2 uv) {
  vec2 x = uv * frame.map_size.xy - 0.5;
  vec2 cell = floor(x);
  vec2 f = x - cell;
  // (u0 v1, u1 v1, u1 v0, u0 v0): u0 = cell.x, u1 = cell.x + 1, likewise v, with the address mode
  vec4 c = textureGather(map, (cell + 1.0) * frame.map_size.zw, 0);
  return mix(mix(c.w, c.z, f.x), mix(c.x, c.y, f.x), f.y);
}
