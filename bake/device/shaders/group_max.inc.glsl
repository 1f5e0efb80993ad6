// bake/device/shaders/group_max.inc.glsl - the largest of a value over a CONE_TILE x CONE_TILE group, for
// the cone kernels' per-group reductions before one atomic max of its bits (cone_cells.comp.glsl's
// Lipschitz constant, cone_lift.comp.glsl's lift). Every invocation of the group calls it (it holds
// barriers), and each gets the group's largest back.
shared float group_values[CONE_TILE * CONE_TILE];

float group_max(float value) {
  const uint local = gl_LocalInvocationIndex;
  group_values[local] = value;
  barrier();
  for (uint stride = CONE_TILE * CONE_TILE / 2; stride > 0; stride /= 2) {
    if (local < stride) group_values[local] = max(group_values[local], group_values[local + stride]);
    barrier();
  }
  return group_values[0];
}
