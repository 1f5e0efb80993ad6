// render/renderer.cpp - the renderer object: the device and its frames in flight (vulkan::Frames,
// shared with the device stages), the renderer's own part of each frame slot (descriptor set,
// uniforms, staging, readback), set-up uploads (albedo, mesh, the 1x1 stand-ins for maps a method
// does not read) and the counters.
//
// The frame cycle (vulkan/frames.h): the current slot begins recording when maps are handed over,
// a device stage records or a frame is rendered (after waiting for that slot's previous frame), the
// frame ends it and submits it with the slot's fence, and the next frame takes the next slot. Nothing is
// allocated in that cycle once the sizes are known: command buffers are reset, not freed; staging and
// readback buffers grow only.
#include <algorithm>
#include <cstring>
#include <limits>
#include <string>

#include "render/renderer_impl.h"
#include "render/shaders/config.h"
#include "render/testing.h"

namespace displace::render {

static_assert(sizeof(gpu::FrameUniforms) == 64 + 16 * 16, "FrameUniforms must match the std430 layout");
static_assert(offsetof(gpu::FrameUniforms, foam) == 64 + 16 * 10);
static_assert(offsetof(gpu::FrameUniforms, levels) == 64 + 16 * 11);
static_assert(offsetof(gpu::FrameUniforms, level_tops) == 64 + 16 * 12);
static_assert(offsetof(gpu::FrameUniforms, ray_along_y) == 64 + 16 * 9);
static_assert(offsetof(gpu::FrameUniforms, eye) == 64);
static_assert(offsetof(gpu::FrameUniforms, counts) == 64 + 16 * 4);
static_assert(sizeof(gpu::MaxPyramidHeader) == 16 * (1 + MAX_PYRAMID_LEVELS),
              "MaxPyramidHeader must match std430");
static_assert(offsetof(gpu::FrameUniforms, quadric) == 64 + 16 * 6);

void Renderer::Impl::create_frame_slots() {
  const VkDevice device = context.device();
  if (context.has_timestamps()) {
    VkQueryPoolCreateInfo query_info{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
    query_info.queryType = VK_QUERY_TYPE_TIMESTAMP;
    query_info.queryCount = 2 * frames_in_flight;
    VkQueryPool query_pool = VK_NULL_HANDLE;
    DISPLACE_VK_CHECK(vkCreateQueryPool(device, &query_info, nullptr, &query_pool));
    timestamps = OwnedQueryPool(device, query_pool);
  }
  const VkDescriptorSetLayout layout = set_layout.get();
  for (FrameSlot& frame_slot : slots) {
    VkDescriptorSetAllocateInfo allocate{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
    allocate.descriptorPool = descriptor_pool.get();
    allocate.descriptorSetCount = 1;
    allocate.pSetLayouts = &layout;
    DISPLACE_VK_CHECK(vkAllocateDescriptorSets(device, &allocate, &frame_slot.descriptor_set));
    // a DeviceLevels' tops are copied in on the device (frame.cpp)
    frame_slot.uniforms = Buffer(context, sizeof(gpu::FrameUniforms),
                                 VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                 VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
  }

  // stand-ins bound where a method reads no map of that kind
  const std::array<std::uint16_t, 2> cone_one = {0x3c00, 65535};  // ratio 1 (half float), apex 1
  dummy_cones =
      upload_image_now(cone_format, 1, 1, 1, VK_IMAGE_VIEW_TYPE_2D_ARRAY, cone_one.data(), sizeof cone_one);
  const std::array<std::uint8_t, 4> white = {255, 255, 255, 255};
  dummy_albedo =
      upload_image_now(VK_FORMAT_R8G8B8A8_UNORM, 1, 1, 1, VK_IMAGE_VIEW_TYPE_2D, white.data(), sizeof white);
  const float zero = 0.0f;
  dummy_distance = upload_image_now(VK_FORMAT_R32_SFLOAT, 1, 1, 1, VK_IMAGE_VIEW_TYPE_3D, &zero, sizeof zero);
  dummy_foam = upload_image_now(VK_FORMAT_R32_SFLOAT, 1, 1, 1, VK_IMAGE_VIEW_TYPE_2D, &zero, sizeof zero);
  // a pyramid of 0 levels: the header, then one value
  dummy_pyramid =
      Buffer(context, sizeof(gpu::MaxPyramidHeader) + sizeof(float), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
             VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
  std::memset(dummy_pyramid.mapped(), 0, sizeof(gpu::MaxPyramidHeader) + sizeof(float));
}

FrameSlot& Renderer::Impl::begin_slot() {
  FrameSlot& frame_slot = slots[std::size_t(frames.slot())];
  if (!frames.recording()) frame_slot.staging_used = 0;  // its previous frame is waited for below
  frames.begin();
  return frame_slot;
}

void testing::hold_async_work(Renderer& renderer, bool hold) { renderer.frames().hold_async_work(hold); }

Renderer::ColorTarget Renderer::color_target() const {
  const Targets& targets = impl_->targets;
  return {targets.color.handle(), targets.width, targets.height};
}

Image Renderer::Impl::upload_image_now(VkFormat format, int width, int height, int layers,
                                       VkImageViewType view_type, const void* data, std::size_t bytes) {
  Image image(context, format, std::uint32_t(width), std::uint32_t(height), std::uint32_t(layers),
              VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT, VK_IMAGE_ASPECT_COLOR_BIT,
              view_type);
  Buffer staging(context, bytes, VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                 VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
  std::memcpy(staging.mapped(), data, bytes);
  const bool volume = view_type == VK_IMAGE_VIEW_TYPE_3D;  // `layers` is the depth
  const std::uint32_t array_layers = volume ? 1 : std::uint32_t(layers);
  context.submit_and_wait([&](VkCommandBuffer commands) {
    image_barrier(commands, image.handle(), array_layers, VK_IMAGE_LAYOUT_UNDEFINED,
                  VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 0, VK_ACCESS_TRANSFER_WRITE_BIT,
                  VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT);
    VkBufferImageCopy region{};
    region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, array_layers};
    region.imageExtent = {std::uint32_t(width), std::uint32_t(height), volume ? std::uint32_t(layers) : 1};
    vkCmdCopyBufferToImage(commands, staging.handle(), image.handle(), VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                           1, &region);
    image_barrier(commands, image.handle(), array_layers, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                  VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, VK_ACCESS_TRANSFER_WRITE_BIT,
                  VK_ACCESS_SHADER_READ_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
                  VK_PIPELINE_STAGE_VERTEX_SHADER_BIT | VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT);
  });
  return image;
}

Renderer::Renderer(const RendererOptions& options) : impl_(std::make_unique<Impl>(options)) {
  impl_->create_layouts();
  impl_->create_render_pass();
  impl_->load_pipeline_cache(options.pipeline_cache);
  impl_->create_frame_slots();
}

Renderer::~Renderer() {
  if (!impl_) return;
  try {
    impl_->drain();
  } catch (...) {
  }
  impl_->save_pipeline_cache();
}
Renderer::Renderer(Renderer&&) noexcept = default;
Renderer& Renderer::operator=(Renderer&&) noexcept = default;

const DeviceInfo& Renderer::device() const { return impl_->context.info(); }
vulkan::Frames& Renderer::frames() { return impl_->frames; }
long long Renderer::validation_messages() const { return impl_->context.validation_messages(); }
long long Renderer::memory_allocations() const { return impl_->context.memory_allocations(); }
long long Renderer::pipelines_created() const { return impl_->pipelines_created; }
bool Renderer::host_written_maps() const { return impl_->heights.host_written; }
MemoryLimits Renderer::memory_limits() const { return impl_->memory_limits(); }
void Renderer::wait_idle() { impl_->drain(); }

void Renderer::set_maps(const MapSet& maps) { impl_->take_maps(maps); }

void Renderer::render(const View& view, const MethodSettings& method, Frame& frame, unsigned outputs) {
  impl_->render(view, method, frame, outputs);
}

Frame Renderer::render(const View& view, const MethodSettings& method, unsigned outputs) {
  Frame frame;
  impl_->render(view, method, frame, outputs);
  return frame;
}

void Renderer::set_mesh(const Mesh& mesh) {
  std::vector<MeshVertex> vertices;
  try {
    vertices = mesh_vertices(mesh);
  } catch (const MeshError& error) {
    throw RenderError(std::string("mesh: ") + error.what());
  }
  Impl& impl = *impl_;
  impl.drain();
  impl.mesh_lo = glm::dvec3(std::numeric_limits<double>::max());
  impl.mesh_hi = glm::dvec3(std::numeric_limits<double>::lowest());
  for (const MeshVertex& vertex : vertices) {
    impl.mesh_lo = glm::min(impl.mesh_lo, glm::dvec3(vertex.position));
    impl.mesh_hi = glm::max(impl.mesh_hi, glm::dvec3(vertex.position));
  }
  impl.mesh_cpu = std::move(vertices);
  impl.mesh_triangles = mesh.triangles;
  impl.mesh_vertices = impl.host_buffer(impl.mesh_cpu, VK_BUFFER_USAGE_VERTEX_BUFFER_BIT);
  impl.mesh_indices = impl.host_buffer(impl.mesh_triangles, VK_BUFFER_USAGE_INDEX_BUFFER_BIT);
  impl.mesh_index_count = std::uint32_t(impl.mesh_triangles.size());
  impl.mesh_reference_vertices = Buffer{};
  impl.mesh_reference_indices = Buffer{};
  impl.mesh_reference_index_count = 0;
}

void Renderer::set_albedo(const Albedo& albedo) {
  if (albedo.width < 1 || albedo.height < 1 || albedo.width > max_map_side || albedo.height > max_map_side ||
      albedo.rgba.size() != std::size_t(albedo.width) * albedo.height * 4) {
    throw RenderError("Albedo::width and Albedo::height must be between 1 and " +
                      std::to_string(max_map_side) + " pixels, with 4 bytes (RGBA) per pixel");
  }
  Impl& impl = *impl_;
  impl.drain();
  impl.albedo_image = impl.upload_image_now(VK_FORMAT_R8G8B8A8_UNORM, albedo.width, albedo.height, 1,
                                            VK_IMAGE_VIEW_TYPE_2D, albedo.rgba.data(), albedo.rgba.size());
  impl.has_albedo = true;
}

void Renderer::clear_albedo() {
  Impl& impl = *impl_;
  impl.drain();
  impl.has_albedo = false;
  impl.albedo_image = Image{};
}

}  // namespace displace::render
