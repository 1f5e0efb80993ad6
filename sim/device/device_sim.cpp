// sim/device/device_sim.cpp - the moving sources on the renderer's device (sim/device/device_sim.h). The FFT
// ocean (Tessendorf; sim/fft_ocean.cpp is the CPU original): per frame ocean_spectrum.comp.glsl evolves the
// half spectrum and derives the effects' spectra, VkFFT inverts them in place (device_fft.h), and
// ocean_assemble.comp.glsl resamples choppy water onto the grid and writes the heights and foam the
// renderer samples. Sinusoid water: sinusoids.comp.glsl, one pass. The one fact to know is the phase
// precision, kept by anchoring: the phase at t_anchor is reduced modulo 2 pi on the host in double,
// the shaders add w (t - t_anchor) in split floats, and the anchor moves before that exceeds 1e5 rad.
#include "sim/device/device_sim.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numbers>
#include <string>

#include "sim/device/device_fft.h"
#include "sim/device/shaders/ocean.h"
#include "spirv/ocean_assemble_comp.h"
#include "spirv/ocean_spectrum_comp.h"
#include "spirv/sinusoids_comp.h"
#include "vulkan/compute.h"
#include "vulkan/device_maps.h"
#include "vulkan/frames.h"

namespace displace::sim {

using namespace vulkan;  // the Vulkan base (vulkan/): Context, Buffer, Image, kernels, barriers

static_assert(sizeof(gpu::OceanSpectrumPush) == 32);
static_assert(sizeof(gpu::OceanAssemblePush) == 48);
static_assert(sizeof(gpu::SinusoidPush) == 32);

namespace {

// |w (t - t_anchor)| the shader may see, radians: its 2 pi reduction is exact below 2^14 turns
constexpr double anchor_phase_limit = 1.0e5;
// Newton steps of the choppy resampling at most (the CPU pipeline's, pipeline/height_source.cpp), and
// the residual a texel stops at, in texels: a tenth of the CPU's block-wise 3e-4, as each texel stops
// on its own (at the CPU's, 0.2-0.3% of a 64 x 64 ocean's heights were more than 1e-5 of the range
// off the CPU's)
constexpr int choppy_iterations = 8;
constexpr float choppy_settle = 3e-5f;

// the high part of a float: sign, exponent and 11 of 23 mantissa bits (products of two are exact)
float high_part(float value) {
  std::uint32_t bits;
  std::memcpy(&bits, &value, sizeof bits);
  bits &= 0xfffff000u;
  float high;
  std::memcpy(&high, &bits, sizeof high);
  return high;
}

constexpr VkDescriptorType storage_buffer = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
constexpr VkDescriptorType storage_image = VK_DESCRIPTOR_TYPE_STORAGE_IMAGE;
constexpr VkDescriptorType spectrum_bindings[] = {storage_buffer, storage_buffer, storage_buffer,
                                                  storage_buffer};
constexpr VkDescriptorType assemble_bindings[] = {storage_buffer, storage_buffer, storage_image,
                                                  storage_image};
constexpr VkDescriptorType sinusoid_bindings[] = {storage_buffer, storage_buffer, storage_buffer,
                                                  storage_buffer, storage_buffer, storage_image};
// relative difference under which a wave number counts as on the patch's lattice (2 pi m / L)
constexpr double lattice_tolerance = 1e-6;

}  // namespace

struct DeviceSim::State {
  enum class Source { ocean, sinusoids };
  vulkan::Frames& frames;
  Source source = Source::ocean;
  std::shared_ptr<DeviceHeightImages> maps;  // the renderer's handle (map_set.h), cleared when this goes
  int size = 0, half = 0;
  unsigned effects = 0;
  int batches = 1;  // the ocean's spectra, one inverse FFT each
  int wave_count = 0;
  float patch_size = 0.0f, choppiness = 0.0f;
  float scale = 1.0f, bias = 0.0f, foam_start = 0.85f, foam_full = 0.45f;
  // per mode (ocean) or wave (sinusoids): w, and the phase at time 0 (sinusoids: phi; ocean: 0)
  std::vector<float> omega, phase;
  double omega_max = 0.0;
  bool anchored = false;
  double anchor_time = 0.0;
  long long fft_count = 0;

  Buffer coefficients, omega_split, anchor, anchor_staging, spectra, metres, lattice;
  Image heights, foam;
  Buffer readback;
  ComputeKernel spectrum_kernel, assemble_kernel, sinusoid_kernel;
  std::unique_ptr<DeviceFft> fft;
  StageTimer timer;

  explicit State(vulkan::Frames& device_frames) : frames(device_frames) {}
  std::size_t items() const {
    return source == Source::ocean ? std::size_t(size) * std::size_t(half) : std::size_t(wave_count);
  }
  std::size_t texels() const { return std::size_t(size) * std::size_t(size); }
  void make_common();
  void write_anchor(double time);
};

// What both sources make: the outputs (heights image, metres, foam image), the phase buffers, the
// anchor's staging and the timestamps. Expects size, effects, omega and phase set.
void DeviceSim::State::make_common() {
  const Context& context = frames.context();
  for (float w : omega) omega_max = std::max(omega_max, std::abs(double(w)));
  const VkMemoryPropertyFlags device_local = VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT;
  const VkMemoryPropertyFlags host =
      VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
  const VkBufferUsageFlags stored = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
  omega_split = Buffer(context, items() * 8, stored, device_local);
  anchor = Buffer(context, items() * 8, stored, device_local);
  anchor_staging = Buffer(context, items() * 8, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, host);
  metres = Buffer(context, texels() * 4,
                  VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT, device_local);
  const VkImageUsageFlags image_usage =
      VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT;
  heights = Image(context, VK_FORMAT_R32_SFLOAT, std::uint32_t(size), std::uint32_t(size), 1, image_usage,
                  VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_VIEW_TYPE_2D);
  const std::uint32_t foam_side = (effects & device_foam) ? std::uint32_t(size) : 1u;
  foam = Image(context, VK_FORMAT_R32_SFLOAT, foam_side, foam_side, 1, image_usage, VK_IMAGE_ASPECT_COLOR_BIT,
               VK_IMAGE_VIEW_TYPE_2D);
  timer = StageTimer(context);
  // w split, through a staging buffer; the images to GENERAL, where the kernels write them
  Buffer staging(context, items() * 8, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, host);
  auto* split = static_cast<float*>(staging.mapped());
  for (std::size_t item = 0; item < items(); ++item) {
    split[2 * item] = high_part(omega[item]);
    split[2 * item + 1] = omega[item] - split[2 * item];
  }
  context.submit_and_wait([&](VkCommandBuffer commands) {
    const VkBufferCopy copy{0, 0, items() * 8};
    vkCmdCopyBuffer(commands, staging.handle(), omega_split.handle(), 1, &copy);
    for (const Image* image : {&heights, &foam}) {
      image_barrier(commands, image->handle(), 1, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_GENERAL, 0,
                    VK_ACCESS_SHADER_WRITE_BIT, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT,
                    VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT);
    }
  });
}

// The phases at `time`, reduced modulo 2 pi in double: w t (ocean) or phi - w t (sinusoids).
void DeviceSim::State::write_anchor(double time) {
  auto* values = static_cast<float*>(anchor_staging.mapped());
  const double sign = source == Source::ocean ? 1.0 : -1.0;
  for (std::size_t item = 0; item < items(); ++item) {
    const double value =
        std::fmod(double(phase[item]) + sign * double(omega[item]) * time, 2.0 * std::numbers::pi);
    values[2 * item] = float(std::cos(value));
    values[2 * item + 1] = float(std::sin(value));
  }
  anchor_time = time;
  anchored = true;
}

DeviceSim::DeviceSim(vulkan::Frames& frames, const OceanSpectrumView& spectrum, unsigned effects)
    : state_(std::make_unique<State>(frames)) {
  State& s = *state_;
  const int n = spectrum.size;
  if (n < 2 || n % 2 != 0 || n > vulkan::max_map_side)
    throw vulkan::Error("DeviceSim: the ocean's size must be even and between 2 and " +
                        std::to_string(vulkan::max_map_side));
  s.source = State::Source::ocean;
  s.size = n;
  s.half = n / 2 + 1;
  if (spectrum.coefficients.size() != 4 * s.items() || spectrum.omega.size() != s.items())
    throw vulkan::Error("DeviceSim: the ocean's spectrum must hold N x (N/2 + 1) modes");
  if (!(spectrum.patch_size > 0.0f) || !std::isfinite(spectrum.patch_size) ||
      !std::isfinite(spectrum.choppiness) || !std::isfinite(spectrum.scale) || !std::isfinite(spectrum.bias))
    throw vulkan::Error("DeviceSim: patch size, choppiness and mapping must be finite (patch size > 0)");
  s.effects = effects & (device_choppy | device_foam);
  if (spectrum.choppiness == 0.0f) s.effects &= ~unsigned(device_choppy);
  s.batches = 1 + ((s.effects & device_choppy) ? 2 : 0) + ((s.effects & device_foam) ? 3 : 0);
  s.patch_size = spectrum.patch_size;
  s.choppiness = spectrum.choppiness;
  s.scale = spectrum.scale;
  s.bias = spectrum.bias;
  s.foam_start = spectrum.foam_start;
  s.foam_full = spectrum.foam_full;
  s.omega.assign(spectrum.omega.begin(), spectrum.omega.end());
  s.phase.assign(s.items(), 0.0f);
  s.make_common();

  // the spectrum's coefficients, and the spectra the FFTs invert in place
  const Context& context = s.frames.context();
  const VkMemoryPropertyFlags host =
      VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
  s.coefficients =
      Buffer(context, s.items() * 16, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
             VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
  s.spectra = Buffer(context, VkDeviceSize(s.batches) * s.items() * 8, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                     VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
  {
    Buffer staging(context, s.items() * 16, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, host);
    std::memcpy(staging.mapped(), spectrum.coefficients.data(), s.items() * 16);
    context.submit_and_wait([&](VkCommandBuffer commands) {
      const VkBufferCopy copy{0, 0, s.items() * 16};
      vkCmdCopyBuffer(commands, staging.handle(), s.coefficients.handle(), 1, &copy);
    });
  }

  // kernels and the FFT plan
  s.spectrum_kernel =
      ComputeKernel(context, spirv_ocean_spectrum_comp, spectrum_bindings, sizeof(gpu::OceanSpectrumPush));
  s.spectrum_kernel.bind_buffer(0, s.coefficients.handle());
  s.spectrum_kernel.bind_buffer(1, s.omega_split.handle());
  s.spectrum_kernel.bind_buffer(2, s.anchor.handle());
  s.spectrum_kernel.bind_buffer(3, s.spectra.handle());
  s.assemble_kernel =
      ComputeKernel(context, spirv_ocean_assemble_comp, assemble_bindings, sizeof(gpu::OceanAssemblePush));
  s.assemble_kernel.bind_buffer(0, s.spectra.handle());
  s.assemble_kernel.bind_buffer(1, s.metres.handle());
  s.assemble_kernel.bind_image(2, s.heights.view());
  s.assemble_kernel.bind_image(3, s.foam.view());
  s.fft = std::make_unique<DeviceFft>(context, s.spectra.handle(), s.spectra.size(), n, s.batches);

  s.maps = std::make_shared<DeviceHeightImages>(
      DeviceHeightImages{&s.frames, &s.heights, (s.effects & device_foam) ? &s.foam : nullptr});
}

DeviceSim::DeviceSim(vulkan::Frames& frames, const SinusoidWavesView& waves)
    : state_(std::make_unique<State>(frames)) {
  State& s = *state_;
  if (waves.size < 1 || waves.size > vulkan::max_map_side)
    throw vulkan::Error("DeviceSim: the sinusoids' size must be between 1 and " +
                        std::to_string(vulkan::max_map_side));
  if (waves.waves.empty() || waves.waves.size() % 5 != 0)
    throw vulkan::Error(
        "DeviceSim: the waves must be given as (kx, ky, amplitude, omega, phase), one wave at least");
  if (!(waves.patch_size > 0.0f) || !std::isfinite(waves.patch_size) || !std::isfinite(waves.scale) ||
      !std::isfinite(waves.bias))
    throw vulkan::Error("DeviceSim: patch size and mapping must be finite (patch size > 0)");
  for (float value : waves.waves) {
    if (!std::isfinite(value)) throw vulkan::Error("DeviceSim: a wave's value is not finite");
  }
  s.source = State::Source::sinusoids;
  s.size = waves.size;
  s.wave_count = int(waves.waves.size() / 5);
  s.patch_size = waves.patch_size;
  s.scale = waves.scale;
  s.bias = waves.bias;
  for (int i = 0; i < s.wave_count; ++i) {
    s.omega.push_back(waves.waves[std::size_t(5 * i + 3)]);
    s.phase.push_back(waves.waves[std::size_t(5 * i + 4)]);
  }
  s.make_common();

  // the waves: (kx, ky, amplitude, on the lattice) and the lattice indices (m, n)
  const Context& context = s.frames.context();
  const VkBufferUsageFlags stored = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
  s.coefficients = Buffer(context, s.items() * 16, stored, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
  s.lattice = Buffer(context, s.items() * 8, stored, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
  Buffer staging(context, s.items() * 24, VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                 VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
  auto* values = static_cast<float*>(staging.mapped());
  const double lattice_step = 2.0 * std::numbers::pi / double(s.patch_size);
  for (int i = 0; i < s.wave_count; ++i) {
    const float* wave = waves.waves.data() + 5 * i;
    const double m = std::round(double(wave[0]) / lattice_step),
                 n = std::round(double(wave[1]) / lattice_step);
    const double k = std::hypot(double(wave[0]), double(wave[1]));
    const bool on_lattice =
        std::hypot(double(wave[0]) - m * lattice_step, double(wave[1]) - n * lattice_step) <=
            lattice_tolerance * std::max(k, lattice_step) &&
        std::abs(m) * 2.0 * s.size < 1e9 && std::abs(n) * 2.0 * s.size < 1e9;
    values[4 * i] = wave[0];
    values[4 * i + 1] = wave[1];
    values[4 * i + 2] = wave[2];
    values[4 * i + 3] = on_lattice ? 1.0f : 0.0f;
    // m and n modulo 2 size, in [0, 2 size): the shader's % then meets no negative operand (GLSL leaves
    // that undefined: on an NVIDIA H200 the lattice waves came out wrong, on lavapipe right)
    const double twice = 2.0 * s.size;
    values[4 * s.items() + 2 * i] = on_lattice ? float(m - twice * std::floor(m / twice)) : 0.0f;
    values[4 * s.items() + 2 * i + 1] = on_lattice ? float(n - twice * std::floor(n / twice)) : 0.0f;
  }
  context.submit_and_wait([&](VkCommandBuffer commands) {
    const VkBufferCopy waves_copy{0, 0, s.items() * 16};
    vkCmdCopyBuffer(commands, staging.handle(), s.coefficients.handle(), 1, &waves_copy);
    const VkBufferCopy lattice_copy{s.items() * 16, 0, s.items() * 8};
    vkCmdCopyBuffer(commands, staging.handle(), s.lattice.handle(), 1, &lattice_copy);
  });
  s.sinusoid_kernel =
      ComputeKernel(context, spirv_sinusoids_comp, sinusoid_bindings, sizeof(gpu::SinusoidPush));
  s.sinusoid_kernel.bind_buffer(0, s.coefficients.handle());
  s.sinusoid_kernel.bind_buffer(1, s.lattice.handle());
  s.sinusoid_kernel.bind_buffer(2, s.omega_split.handle());
  s.sinusoid_kernel.bind_buffer(3, s.anchor.handle());
  s.sinusoid_kernel.bind_buffer(4, s.metres.handle());
  s.sinusoid_kernel.bind_image(5, s.heights.view());
  s.maps = std::make_shared<DeviceHeightImages>(DeviceHeightImages{&s.frames, &s.heights, nullptr});
}

DeviceSim::~DeviceSim() {
  State& s = *state_;
  s.frames.wait_submitted();
  s.maps->heights = s.maps->foam =
      nullptr;  // (a MapSet may still name them: the renderer then refuses the frame)
}

void DeviceSim::simulate(double time) {
  State& s = *state_;
  if (!std::isfinite(time)) throw vulkan::Error("DeviceSim::simulate: the time must be finite");
  const bool reanchor = !s.anchored || std::abs(time - s.anchor_time) * s.omega_max > anchor_phase_limit;
  if (reanchor) {
    s.frames.wait_submitted();  // an earlier frame's copy may still read the staging buffer
    s.write_anchor(time);
  }
  const int slot = s.frames.slot();
  const VkCommandBuffer commands = s.frames.begin();  // waits for the slot's last frame
  s.timer.begin(commands, slot);

  // the frames before read the maps and buffers this one writes
  rewrite_barrier(commands);
  if (reanchor) {
    const VkBufferCopy copy{0, 0, s.items() * 8};
    vkCmdCopyBuffer(commands, s.anchor_staging.handle(), s.anchor.handle(), 1, &copy);
    VkMemoryBarrier copied{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    copied.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
    copied.dstAccessMask = VK_ACCESS_SHADER_READ_BIT;
    vkCmdPipelineBarrier(commands, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 1,
                         &copied, 0, nullptr, 0, nullptr);
  }
  const double step = time - s.anchor_time;
  const float time_high = high_part(float(step));
  const float time_low = float(step - double(time_high));
  const std::uint32_t tiles = group_count(std::uint32_t(s.size), OCEAN_TILE);

  if (s.source == State::Source::sinusoids) {
    gpu::SinusoidPush push{};
    push.size = s.size;
    push.wave_count = s.wave_count;
    push.patch_size = s.patch_size;
    push.time_high = time_high;
    push.time_low = time_low;
    push.scale = s.scale;
    push.bias = s.bias;
    s.sinusoid_kernel.record(commands, tiles, tiles, 1, &push);
  } else {
    // the spectra at t
    gpu::OceanSpectrumPush spectrum_push{};
    spectrum_push.size = s.size;
    spectrum_push.batches = s.batches;
    spectrum_push.choppy = (s.effects & device_choppy) ? 1 : 0;
    spectrum_push.foam = (s.effects & device_foam) ? 1 : 0;
    spectrum_push.time_high = time_high;
    spectrum_push.time_low = time_low;
    spectrum_push.wave_step = float(2.0 * std::numbers::pi / s.patch_size);
    spectrum_push.choppiness = s.choppiness;
    s.spectrum_kernel.record(commands, group_count(std::uint32_t(s.items()), OCEAN_LOCAL_SIZE), 1, 1,
                             &spectrum_push);
    compute_barrier(commands);
    // the fields
    s.fft->record_inverse(commands);
    compute_barrier(commands);
    s.fft_count += s.batches;
    // the maps
    gpu::OceanAssemblePush assemble_push{};
    assemble_push.size = s.size;
    assemble_push.choppy = spectrum_push.choppy;
    assemble_push.foam = spectrum_push.foam;
    assemble_push.iterations = choppy_iterations;
    assemble_push.texels_per_metre = float(s.size) / s.patch_size;
    assemble_push.settle = choppy_settle;
    assemble_push.scale = s.scale;
    assemble_push.bias = s.bias;
    assemble_push.foam_start = s.foam_start;
    assemble_push.foam_full = s.foam_full;
    s.assemble_kernel.record(commands, tiles, tiles, 1, &assemble_push);
  }
  compute_barrier(commands);
  s.timer.end(commands, slot);
}

void DeviceSim::read_back(std::vector<float>* heights, std::vector<float>* metres, std::vector<float>* foam) {
  State& s = *state_;
  const VkDeviceSize map_bytes = s.texels() * 4;
  if (s.readback.handle() == VK_NULL_HANDLE) {
    s.readback = Buffer(s.frames.context(), 3 * map_bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                        VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
  }
  const bool with_foam = (s.effects & device_foam) != 0;
  const VkCommandBuffer commands = s.frames.begin();
  // each image copied in the transfer layout and given back in GENERAL for the next frame's kernels
  auto copy_image = [&](const Image& image, VkDeviceSize offset) {
    image_barrier(commands, image.handle(), 1, VK_IMAGE_LAYOUT_GENERAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                  VK_ACCESS_SHADER_WRITE_BIT, VK_ACCESS_TRANSFER_READ_BIT,
                  VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT);
    VkBufferImageCopy region{};
    region.bufferOffset = offset;
    region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    region.imageExtent = {std::uint32_t(s.size), std::uint32_t(s.size), 1};
    vkCmdCopyImageToBuffer(commands, image.handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                           s.readback.handle(), 1, &region);
    image_barrier(commands, image.handle(), 1, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_IMAGE_LAYOUT_GENERAL,
                  VK_ACCESS_TRANSFER_READ_BIT, VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT,
                  VK_PIPELINE_STAGE_TRANSFER_BIT,
                  VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT);
  };
  copy_image(s.heights, 0);
  const VkBufferCopy metres_copy{0, map_bytes, map_bytes};
  vkCmdCopyBuffer(commands, s.metres.handle(), s.readback.handle(), 1, &metres_copy);
  if (with_foam) copy_image(s.foam, 2 * map_bytes);
  host_read_barrier(commands);
  s.frames.submit(true);
  const auto* values = static_cast<const float*>(s.readback.mapped());
  if (heights) heights->assign(values, values + s.texels());
  if (metres) metres->assign(values + s.texels(), values + 2 * s.texels());
  if (foam) {
    if (with_foam) {
      foam->assign(values + 2 * s.texels(), values + 3 * s.texels());
    } else {
      foam->clear();
    }
  }
}

void DeviceSim::finish() { state_->frames.submit(true); }

std::shared_ptr<const DeviceHeightImages> DeviceSim::maps() const { return state_->maps; }
int DeviceSim::size() const { return state_->size; }
unsigned DeviceSim::effects() const { return state_->effects; }
long long DeviceSim::fft_count() const { return state_->fft_count; }
double DeviceSim::device_milliseconds() const { return state_->frames.finished_milliseconds(state_->timer); }

}  // namespace displace::sim
