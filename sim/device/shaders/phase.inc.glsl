// sim/device/shaders/phase.inc.glsl - w (t - t_anchor) reduced to [-pi, pi], for the device sim's
// anchored phases (ocean_spectrum.comp.glsl, sinusoids.comp.glsl; sim/device/device_sim.cpp): w and
// t - t_anchor each come as a high part of 12 significant bits (whose product is exact in float) and
// the rest, |w (t - t_anchor)| < 1e5 rad.
//
// 2 pi = 6.28125 + 1.934051513671875e-3 + 1.2556659e-6: the first two parts of 8 and 10 significant
// bits, so that their products with turns < 2^14 are exact (three Cody-Waite steps).
float phase_since_anchor(vec2 w, float time_high, float time_low) {
  const float phase_high = w.x * time_high;
  const float phase_low = w.x * time_low + w.y * time_high + w.y * time_low;
  const float turns = round((phase_high + phase_low) * 0.15915494309189535);
  return (((phase_high - turns * 6.28125) - turns * 1.934051513671875e-3) - turns * 1.2556659e-6) + phase_low;
}
