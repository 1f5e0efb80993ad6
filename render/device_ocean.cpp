// render/device_ocean.cpp - Tessendorf's FFT ocean on the renderer's device (render/device.h): per
// frame, ocean_spectrum.comp.glsl evolves the half spectrum and derives the effects' spectra, VkFFT
// inverts them in place (device_fft.h), and ocean_assemble.comp.glsl resamples choppy water onto the
// grid and writes the heights and foam the renderer samples. sim/fft_ocean.cpp is the CPU original;
// the one fact to know is its phase precision, kept here by anchoring: w t_anchor is reduced modulo
// 2 pi on the host in double, the shader adds w (t - t_anchor) in split floats.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <numbers>
#include <string>

#include "render/compute.h"
#include "render/device.h"
#include "render/device_fft.h"
#include "render/renderer_impl.h"
#include "render/shaders/ocean.h"
#include "spirv/ocean_assemble_comp.h"
#include "spirv/ocean_spectrum_comp.h"

namespace displace::render {

static_assert(sizeof(gpu::OceanSpectrumPush) == 32);
static_assert(sizeof(gpu::OceanAssemblePush) == 48);

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

}  // namespace

struct DeviceOcean::State {
  Renderer::Impl& impl;
  int size = 0, half = 0;
  unsigned effects = 0;
  int batches = 1;
  float patch_size = 0.0f, choppiness = 0.0f;
  float scale = 1.0f, bias = 0.0f, foam_start = 0.85f, foam_full = 0.45f;
  std::vector<float> omega;  // per mode, for the anchors
  double omega_max = 0.0;
  bool anchored = false;
  double anchor_time = 0.0;
  long long fft_count = 0;

  Buffer coefficients, omega_split, anchor, anchor_staging, spectra, metres;
  Image heights, foam;
  Buffer readback;
  ComputeKernel spectrum_kernel, assemble_kernel;
  std::unique_ptr<DeviceFft> fft;

  explicit State(Renderer::Impl& renderer) : impl(renderer) {}
  std::size_t modes() const { return std::size_t(size) * std::size_t(half); }
  std::size_t texels() const { return std::size_t(size) * std::size_t(size); }
  void write_anchor(double time);
};

void DeviceOcean::State::write_anchor(double time) {
  auto* values = static_cast<float*>(anchor_staging.mapped());
  for (std::size_t mode = 0; mode < modes(); ++mode) {
    const double phase = std::fmod(double(omega[mode]) * time, 2.0 * std::numbers::pi);
    values[2 * mode] = float(std::cos(phase));
    values[2 * mode + 1] = float(std::sin(phase));
  }
  anchor_time = time;
  anchored = true;
}

DeviceOcean::DeviceOcean(Renderer& renderer, const OceanSpectrumView& spectrum, unsigned effects)
    : state_(std::make_unique<State>(*renderer.impl_)) {
  State& s = *state_;
  const int n = spectrum.size;
  if (n < 2 || n % 2 != 0 || n > max_map_side)
    throw RenderError("DeviceOcean: the ocean's size must be even and between 2 and " +
                      std::to_string(max_map_side));
  s.size = n;
  s.half = n / 2 + 1;
  if (spectrum.coefficients.size() != 4 * s.modes() || spectrum.omega.size() != s.modes())
    throw RenderError("DeviceOcean: the spectrum must hold N x (N/2 + 1) modes");
  if (!(spectrum.patch_size > 0.0f) || !std::isfinite(spectrum.choppiness) ||
      !std::isfinite(spectrum.scale) || !std::isfinite(spectrum.bias))
    throw RenderError("DeviceOcean: patch size, choppiness and mapping must be finite (patch size > 0)");
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
  for (float w : s.omega) s.omega_max = std::max(s.omega_max, std::abs(double(w)));

  // buffers and images, made once
  const Context& context = s.impl.context;
  const VkMemoryPropertyFlags device_local = VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT;
  const VkMemoryPropertyFlags host =
      VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
  const VkBufferUsageFlags stored = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
  s.coefficients = Buffer(context, s.modes() * 16, stored, device_local);
  s.omega_split = Buffer(context, s.modes() * 8, stored, device_local);
  s.anchor = Buffer(context, s.modes() * 8, stored, device_local);
  s.anchor_staging = Buffer(context, s.modes() * 8, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, host);
  s.spectra = Buffer(context, VkDeviceSize(s.batches) * s.modes() * 8, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                     device_local);
  s.metres = Buffer(context, s.texels() * 4,
                    VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT, device_local);
  const VkImageUsageFlags image_usage =
      VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT;
  s.heights = Image(context, VK_FORMAT_R32_SFLOAT, std::uint32_t(n), std::uint32_t(n), 1, image_usage,
                    VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_VIEW_TYPE_2D);
  const std::uint32_t foam_side = (s.effects & device_foam) ? std::uint32_t(n) : 1u;
  s.foam = Image(context, VK_FORMAT_R32_SFLOAT, foam_side, foam_side, 1, image_usage,
                 VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_VIEW_TYPE_2D);

  // the spectrum's constant parts, through one staging buffer
  {
    Buffer staging(context, s.modes() * 24, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, host);
    auto* bytes = static_cast<std::byte*>(staging.mapped());
    std::memcpy(bytes, spectrum.coefficients.data(), s.modes() * 16);
    auto* split = reinterpret_cast<float*>(bytes + s.modes() * 16);
    for (std::size_t mode = 0; mode < s.modes(); ++mode) {
      split[2 * mode] = high_part(s.omega[mode]);
      split[2 * mode + 1] = s.omega[mode] - split[2 * mode];
    }
    context.submit_and_wait([&](VkCommandBuffer commands) {
      const VkBufferCopy coefficient_copy{0, 0, s.modes() * 16};
      vkCmdCopyBuffer(commands, staging.handle(), s.coefficients.handle(), 1, &coefficient_copy);
      const VkBufferCopy omega_copy{s.modes() * 16, 0, s.modes() * 8};
      vkCmdCopyBuffer(commands, staging.handle(), s.omega_split.handle(), 1, &omega_copy);
      for (const Image* image : {&s.heights, &s.foam}) {
        image_barrier(commands, image->handle(), 1, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_GENERAL, 0,
                      VK_ACCESS_SHADER_WRITE_BIT, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT,
                      VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT);
      }
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

  s.impl.device_heights = &s.heights;
  s.impl.device_foam = (s.effects & device_foam) ? &s.foam : nullptr;
}

DeviceOcean::~DeviceOcean() {
  State& s = *state_;
  s.impl.wait_submitted();
  if (s.impl.device_heights == &s.heights) {
    s.impl.device_heights = nullptr;
    s.impl.device_foam = nullptr;
  }
}

void DeviceOcean::simulate(double time) {
  State& s = *state_;
  if (!std::isfinite(time)) throw RenderError("DeviceOcean::simulate: the time must be finite");
  const bool reanchor = !s.anchored || std::abs(time - s.anchor_time) * s.omega_max > anchor_phase_limit;
  if (reanchor) {
    s.impl.wait_submitted();  // an earlier frame's copy may still read the staging buffer
    s.write_anchor(time);
  }
  const VkCommandBuffer commands = s.impl.begin_slot().commands;

  // the frames before read the maps and buffers this one writes
  VkMemoryBarrier before{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  before.srcAccessMask = VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_READ_BIT;
  before.dstAccessMask = VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT;
  vkCmdPipelineBarrier(commands,
                       VK_PIPELINE_STAGE_VERTEX_SHADER_BIT | VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT |
                           VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
                       VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 1, &before,
                       0, nullptr, 0, nullptr);
  if (reanchor) {
    const VkBufferCopy copy{0, 0, s.modes() * 8};
    vkCmdCopyBuffer(commands, s.anchor_staging.handle(), s.anchor.handle(), 1, &copy);
    VkMemoryBarrier copied{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    copied.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
    copied.dstAccessMask = VK_ACCESS_SHADER_READ_BIT;
    vkCmdPipelineBarrier(commands, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 1,
                         &copied, 0, nullptr, 0, nullptr);
  }

  // the spectra at t
  const double step = time - s.anchor_time;
  gpu::OceanSpectrumPush spectrum_push{};
  spectrum_push.size = s.size;
  spectrum_push.batches = s.batches;
  spectrum_push.choppy = (s.effects & device_choppy) ? 1 : 0;
  spectrum_push.foam = (s.effects & device_foam) ? 1 : 0;
  spectrum_push.time_high = high_part(float(step));
  spectrum_push.time_low = float(step - double(spectrum_push.time_high));
  spectrum_push.wave_step = float(2.0 * std::numbers::pi / s.patch_size);
  spectrum_push.choppiness = s.choppiness;
  s.spectrum_kernel.record(commands, group_count(std::uint32_t(s.modes()), OCEAN_LOCAL_SIZE), 1, 1,
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
  const std::uint32_t groups = group_count(std::uint32_t(s.size), OCEAN_TILE);
  s.assemble_kernel.record(commands, groups, groups, 1, &assemble_push);
  compute_barrier(commands);
}

void DeviceOcean::read_back(std::vector<float>* heights, std::vector<float>* metres,
                            std::vector<float>* foam) {
  State& s = *state_;
  const VkDeviceSize map_bytes = s.texels() * 4;
  if (s.readback.handle() == VK_NULL_HANDLE) {
    s.readback = Buffer(s.impl.context, 3 * map_bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                        VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
  }
  const bool with_foam = (s.effects & device_foam) != 0;
  const VkCommandBuffer commands = s.impl.begin_slot().commands;
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
  VkMemoryBarrier to_host{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  to_host.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
  to_host.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
  vkCmdPipelineBarrier(commands, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &to_host,
                       0, nullptr, 0, nullptr);
  s.impl.submit_slot(true);
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

int DeviceOcean::size() const { return state_->size; }
unsigned DeviceOcean::effects() const { return state_->effects; }
long long DeviceOcean::fft_count() const { return state_->fft_count; }

}  // namespace displace::render
