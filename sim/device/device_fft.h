// sim/device/device_fft.h - VkFFT's inverse 2D FFT, complex to real, in place on a storage buffer: the
// device ocean's FFTs. Internal to sim/device/ (device_fft.cpp is the one file that includes VkFFT).
//
// The buffer holds `batches` half spectra of N x (N/2 + 1) complex values (row i: wave number index
// along y; column j: along x, FFTW's unshifted order), each overwritten by its real field in padded
// rows of N + 2 floats. Unnormalised: the plain sum over the modes, as FFTW's backward transform.
#pragma once

#include <memory>

#include "vulkan/context.h"

namespace displace::sim {

class DeviceFft {
 public:
  // Plans (compiles VkFFT's kernels with glslang) once; throws vulkan::Error when VkFFT cannot.
  DeviceFft(const vulkan::Context& context, VkBuffer buffer, VkDeviceSize bytes, int size, int batches);
  ~DeviceFft();
  DeviceFft(const DeviceFft&) = delete;
  DeviceFft& operator=(const DeviceFft&) = delete;

  void record_inverse(VkCommandBuffer commands);

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace displace::sim
