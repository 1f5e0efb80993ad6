// render/renderer.cpp - the frame pipeline: maps (bake once per height field), uploads, pipelines
// (one per method, made once), record + submit, read back.
//
// Stages of a frame: validate the view -> ensure the method's maps are baked and uploaded -> write
// the frame uniforms -> (re)size the render targets -> record the draw and the copies -> submit and
// wait -> read back into a Frame.
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "render/mesh.h"
#include "render/quadric.h"
#include "render/render.h"
#include "render/shaders/config.h"
#include "render/vulkan_context.h"
#include "spirv/mesh_vert.h"
#include "spirv/quadric_proxy_vert.h"
#include "spirv/quadric_reference_vert.h"
#include "spirv/reference_vert.h"
#include "spirv/relief_vert.h"
#include "spirv/surface_frag.h"

namespace displace::render {

static_assert(sizeof(gpu::FrameUniforms) == 64 + 16 * 7, "FrameUniforms must match the std140 layout");
static_assert(offsetof(gpu::FrameUniforms, eye) == 64);
static_assert(offsetof(gpu::FrameUniforms, counts) == 64 + 16 * 4);
static_assert(sizeof(gpu::MaxPyramidHeader) == 16 * (1 + MAX_PYRAMID_LEVELS),
              "MaxPyramidHeader must match std430");
static_assert(offsetof(gpu::FrameUniforms, quadric) == 64 + 16 * 6);

namespace {

// limits on what a frame may ask for
constexpr int max_tile = 64;
constexpr float max_depth_scale = 10.0f;  // world units
constexpr int max_steps = 4096;
constexpr int max_refine = 64;
constexpr int max_map_side = 16384;

// The distance map of sphere tracing (bake_distance_map): the height map's uv resolution up to
// distance_max_side voxels a side (and the device's 3D limit), distance_slices voxels along h. A
// coarser map costs sphere steps, never accuracy: the cell walk finishes every ray exactly. Measured
// (fetches per pixel once converged): 64 slices instead of 16, and the full uv resolution instead of
// half, each save 6-23% on the ocean, grazing and deep views; 512 x 512 x 64 R32F is 67 MB and bakes
// in about 0.27 s on 2 cores.
constexpr int distance_slices = 64;     // voxels along h
constexpr int distance_max_side = 512;  // voxels along u and v at most

constexpr VkFormat color_format = VK_FORMAT_R8G8B8A8_UNORM;
constexpr VkFormat hit_format = VK_FORMAT_R32G32B32A32_SFLOAT;
constexpr VkFormat counters_format = VK_FORMAT_R32G32_SFLOAT;
constexpr VkFormat depth_format = VK_FORMAT_D32_SFLOAT;
constexpr std::array<float, 4> background = {0.08f, 0.08f, 0.10f, 1.0f};

template <std::size_t size>
VkShaderModule make_shader(VkDevice device, const std::uint32_t (&code)[size]) {
  VkShaderModuleCreateInfo info{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
  info.codeSize = sizeof(code);
  info.pCode = code;
  VkShaderModule module = VK_NULL_HANDLE;
  DISPLACE_VK_CHECK(vkCreateShaderModule(device, &info, nullptr, &module));
  return module;
}

void image_barrier(VkCommandBuffer commands, VkImage image, std::uint32_t layers, VkImageLayout from, VkImageLayout to,
                   VkAccessFlags src_access, VkAccessFlags dst_access, VkPipelineStageFlags src_stage,
                   VkPipelineStageFlags dst_stage) {
  VkImageMemoryBarrier barrier{VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER};
  barrier.srcAccessMask = src_access;
  barrier.dstAccessMask = dst_access;
  barrier.oldLayout = from;
  barrier.newLayout = to;
  barrier.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  barrier.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  barrier.image = image;
  barrier.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, layers};
  vkCmdPipelineBarrier(commands, src_stage, dst_stage, 0, 0, nullptr, 0, nullptr, 1, &barrier);
}

// The cone maps of the cone methods: per texel and sector a ratio, and per texel an apex height
// (bake::BilinearBaker, bake_bilinear_cones' contract); for relaxed cone stepping also a 1-sector
// relaxed ratio (bake::bake_relaxed).
struct ConeMaps {
  std::vector<float> ratios;   // interleaved, bake conventions
  std::vector<float> apex;
  std::vector<float> relaxed;  // empty but for relaxed cones
};

// Packs a cone map into RG32F layers, one per sector: layer k of texel t holds (ratio_k, apex_t),
// so that a cone step reads its ray's sector and the apex in one fetch.
// Layer k < n holds (r_k, H_c); with n > 1 sectors, layer n holds (min over k of r_k, H_c), the
// isotropic bound the quadric cone march needs near a step's start (one fetch instead of n). With
// relaxed ratios, one more layer holds (relaxed ratio, H_c) (relaxed_march.inc.glsl).
int cone_layer_count(int sectors, bool relaxed) { return (sectors > 1 ? sectors + 1 : 1) + (relaxed ? 1 : 0); }
std::vector<float> cone_layers(const ConeMaps& maps, int width, int height, int sectors) {
  const std::size_t texels = std::size_t(width) * height;
  const bool relaxed = !maps.relaxed.empty();
  const int layers = cone_layer_count(sectors, relaxed);
  std::vector<float> packed(texels * 2 * std::size_t(layers));
  for (int k = 0; k < layers; ++k)
    for (std::size_t t = 0; t < texels; ++t) {
      float ratio = 0.0f;
      if (relaxed && k == layers - 1) {
        ratio = maps.relaxed[t];
      } else if (k < sectors) {
        ratio = maps.ratios[t * sectors + k];
      } else {
        ratio = *std::min_element(maps.ratios.begin() + std::ptrdiff_t(t * sectors),
                                  maps.ratios.begin() + std::ptrdiff_t((t + 1) * sectors));
      }
      packed[(std::size_t(k) * texels + t) * 2 + 0] = ratio;
      packed[(std::size_t(k) * texels + t) * 2 + 1] = maps.apex[t];
    }
  return packed;
}

// The dual-grid max pyramid as the shader reads it at BINDING_MAX_PYRAMID: the header, then the values.
std::vector<std::byte> pack_max_pyramid(const bake::DualMaxPyramid& pyramid) {
  const std::size_t levels = pyramid.widths.size();
  if (levels > MAX_PYRAMID_LEVELS) throw RenderError("max pyramid has more levels than the shader holds");
  gpu::MaxPyramidHeader header{};
  header.shape = glm::ivec4(int(levels), pyramid.origin, 0, 0);
  for (std::size_t level = 0; level < levels; ++level) {
    header.levels[level] =
        glm::ivec4(int(pyramid.offsets[level]), pyramid.widths[level], pyramid.heights[level], 0);
  }
  std::vector<std::byte> packed(sizeof header + pyramid.values.size() * sizeof(float));
  std::memcpy(packed.data(), &header, sizeof header);
  std::memcpy(packed.data() + sizeof header, pyramid.values.data(), pyramid.values.size() * sizeof(float));
  return packed;
}

// SURFACE_* of a surface (specialization constant 1).
int surface_id(Surface surface) {
  switch (surface) {
    case Surface::plane: return SURFACE_PLANE;
    case Surface::sphere: return SURFACE_SPHERE;
    case Surface::cylinder: return SURFACE_CYLINDER;
    case Surface::cone: return SURFACE_CONE;
    case Surface::mesh: return SURFACE_MESH;
  }
  throw std::logic_error("render::Surface without a shader id");
}

// Cone maps are baked for one sector count, address mode and kind.
enum class ConeKind {
  bilinear,  // BilinearBaker: conservative for the bilinear surface, with apex heights
  relaxed,   // the bilinear cones and bake_relaxed's 1-sector ratios
};
int cone_key(int sectors, bake::Address address, ConeKind kind) {
  return (sectors * 2 + (address == bake::Address::wrap ? 0 : 1)) * 2 + int(kind);
}
ConeKind cone_kind(const MethodInfo& info) {
  return info.relaxed_cones ? ConeKind::relaxed : ConeKind::bilinear;
}

// A distance map baked for one address mode: W x H x D voxels, bake conventions.
struct DistanceMap {
  int width = 0, height = 0, depth = 0;
  std::vector<float> values;
};

struct Targets {
  int width = 0, height = 0;
  Image color, hit, counters, depth;
  OwnedFramebuffer framebuffer;
  Buffer color_readback, hit_readback, counters_readback;
};

}  // namespace

struct Renderer::Impl {
  explicit Impl(const RendererOptions& options) : context(options) {}

  Context context;
  OwnedDescriptorSetLayout set_layout;
  OwnedPipelineLayout pipeline_layout;
  OwnedDescriptorPool descriptor_pool;
  VkDescriptorSet descriptor_set = VK_NULL_HANDLE;
  OwnedRenderPass render_pass;
  OwnedShaderModule relief_vertex, reference_vertex, surface_fragment;
  OwnedShaderModule quadric_proxy_vertex, quadric_reference_vertex, mesh_vertex;
  std::map<int, OwnedPipeline> pipelines;  // by shader id * 4 + surface id
  OwnedSampler linear_wrap, linear_clamp, nearest_wrap, nearest_clamp;
  OwnedSampler linear_wrap_u, nearest_wrap_u;  // quadrics with --address clamp: u wraps, v clamps
  OwnedQueryPool timestamps;
  Buffer uniforms;

  HeightField field;
  bake::Budget cone_budget;  // of the BilinearBaker that makes cone_maps
  Image height_image;
  Image dummy_cones;
  Image albedo_image, dummy_albedo;
  bool has_albedo = false;
  std::map<int, ConeMaps> cone_maps;  // by cone_key, baked for `field`
  int uploaded_cone_key = -1;  // cone_key of cone_image, -1 for none
  Image cone_image;
  int uploaded_pyramid_address = -1;  // the bake::Address of max_pyramid, -1 for none
  Buffer max_pyramid, dummy_pyramid;
  Image dummy_distance;
  std::map<int, DistanceMap> distance_maps;  // by address mode, baked for `field`
  int uploaded_distance_key = -1;            // address mode of distance_image, -1 for none
  Image distance_image;

  Buffer reference_vertices, reference_indices;
  std::uint32_t reference_index_count = 0;

  // the base mesh (set_mesh) and its tessellation for the reference, made for one tile and map size
  std::vector<MeshVertex> mesh_cpu;
  std::vector<std::uint32_t> mesh_triangles;
  glm::dvec3 mesh_lo{0.0}, mesh_hi{0.0};
  Buffer mesh_vertices, mesh_indices;
  std::uint32_t mesh_index_count = 0;
  Buffer mesh_reference_vertices, mesh_reference_indices;
  std::uint32_t mesh_reference_index_count = 0;
  std::array<int, 3> mesh_reference_key{0, 0, 0};  // tile, map width, map height
  int reference_tile = 0;

  Targets targets;

  void create_layouts();
  void create_render_pass();
  VkPipeline pipeline(const MethodInfo& info, Surface surface);
  Image upload_image(VkFormat format, int width, int height, int layers, VkImageViewType view_type, const void* data,
                     std::size_t bytes);
  Buffer upload_storage_buffer(std::span<const std::byte> data);
  const ConeMaps& cones(int sectors, bake::Address address, ConeKind kind);
  const DistanceMap& distance_map(bake::Address address);
  void ensure_targets(int width, int height);
  void ensure_reference_mesh(int tile);
  void ensure_mesh_reference(int tile);
  template <typename T>
  Buffer host_buffer(const std::vector<T>& data, VkBufferUsageFlags usage);
  void bind_maps(const View& view, const MethodInfo& info);
};

void Renderer::Impl::create_layouts() {
  const VkDevice device = context.device();
  std::array<VkDescriptorSetLayoutBinding, 6> bindings{};
  bindings[0] = {BINDING_FRAME, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1,
                 VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, nullptr};
  bindings[1] = {BINDING_HEIGHT, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1,
                 VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, nullptr};
  bindings[2] = {BINDING_CONES, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1, VK_SHADER_STAGE_FRAGMENT_BIT, nullptr};
  bindings[3] = {BINDING_MAX_PYRAMID, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, VK_SHADER_STAGE_FRAGMENT_BIT,
                 nullptr};
  bindings[4] = {BINDING_ALBEDO, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1, VK_SHADER_STAGE_FRAGMENT_BIT, nullptr};
  bindings[5] = {BINDING_DISTANCE, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1, VK_SHADER_STAGE_FRAGMENT_BIT,
                 nullptr};
  VkDescriptorSetLayoutCreateInfo set_info{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
  set_info.bindingCount = std::uint32_t(bindings.size());
  set_info.pBindings = bindings.data();
  VkDescriptorSetLayout layout = VK_NULL_HANDLE;
  DISPLACE_VK_CHECK(vkCreateDescriptorSetLayout(device, &set_info, nullptr, &layout));
  set_layout = OwnedDescriptorSetLayout(device, layout);

  VkPipelineLayoutCreateInfo pipeline_info{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
  pipeline_info.setLayoutCount = 1;
  pipeline_info.pSetLayouts = &layout;
  VkPipelineLayout pipeline_handle = VK_NULL_HANDLE;
  DISPLACE_VK_CHECK(vkCreatePipelineLayout(device, &pipeline_info, nullptr, &pipeline_handle));
  pipeline_layout = OwnedPipelineLayout(device, pipeline_handle);

  const std::array<VkDescriptorPoolSize, 3> sizes = {
      VkDescriptorPoolSize{VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1},
      VkDescriptorPoolSize{VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 4},
      VkDescriptorPoolSize{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1}};
  VkDescriptorPoolCreateInfo pool_info{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
  pool_info.maxSets = 1;
  pool_info.poolSizeCount = std::uint32_t(sizes.size());
  pool_info.pPoolSizes = sizes.data();
  VkDescriptorPool pool = VK_NULL_HANDLE;
  DISPLACE_VK_CHECK(vkCreateDescriptorPool(device, &pool_info, nullptr, &pool));
  descriptor_pool = OwnedDescriptorPool(device, pool);
  VkDescriptorSetAllocateInfo allocate{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
  allocate.descriptorPool = pool;
  allocate.descriptorSetCount = 1;
  allocate.pSetLayouts = &layout;
  DISPLACE_VK_CHECK(vkAllocateDescriptorSets(device, &allocate, &descriptor_set));

  auto sampler = [&](VkFilter filter, VkSamplerAddressMode address, VkSamplerAddressMode address_u) {
    VkSamplerCreateInfo info{VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO};
    info.magFilter = filter;
    info.minFilter = filter;
    info.mipmapMode = VK_SAMPLER_MIPMAP_MODE_NEAREST;
    info.addressModeU = address_u;
    info.addressModeV = address;
    info.addressModeW = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE;
    info.maxLod = 0.0f;
    VkSampler handle = VK_NULL_HANDLE;
    DISPLACE_VK_CHECK(vkCreateSampler(device, &info, nullptr, &handle));
    return OwnedSampler(device, handle);
  };
  const VkSamplerAddressMode repeat = VK_SAMPLER_ADDRESS_MODE_REPEAT, clamp = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE;
  linear_wrap = sampler(VK_FILTER_LINEAR, repeat, repeat);
  linear_clamp = sampler(VK_FILTER_LINEAR, clamp, clamp);
  nearest_wrap = sampler(VK_FILTER_NEAREST, repeat, repeat);
  nearest_clamp = sampler(VK_FILTER_NEAREST, clamp, clamp);
  linear_wrap_u = sampler(VK_FILTER_LINEAR, clamp, repeat);
  nearest_wrap_u = sampler(VK_FILTER_NEAREST, clamp, repeat);

  if (context.has_timestamps()) {
    VkQueryPoolCreateInfo query_info{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
    query_info.queryType = VK_QUERY_TYPE_TIMESTAMP;
    query_info.queryCount = 2;
    VkQueryPool query_pool = VK_NULL_HANDLE;
    DISPLACE_VK_CHECK(vkCreateQueryPool(device, &query_info, nullptr, &query_pool));
    timestamps = OwnedQueryPool(device, query_pool);
  }
  uniforms = Buffer(context, sizeof(gpu::FrameUniforms), VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT,
                    VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
  const std::array<float, 2> one = {1.0f, 1.0f};
  dummy_cones =
      upload_image(VK_FORMAT_R32G32_SFLOAT, 1, 1, 1, VK_IMAGE_VIEW_TYPE_2D_ARRAY, one.data(), sizeof one);
  const std::array<std::uint8_t, 4> white = {255, 255, 255, 255};
  dummy_albedo = upload_image(VK_FORMAT_R8G8B8A8_UNORM, 1, 1, 1, VK_IMAGE_VIEW_TYPE_2D, white.data(), sizeof white);
  std::array<std::byte, sizeof(gpu::MaxPyramidHeader) + sizeof(float)> no_pyramid{};  // 0 levels
  dummy_pyramid = upload_storage_buffer(no_pyramid);
  const float zero = 0.0f;
  dummy_distance = upload_image(VK_FORMAT_R32_SFLOAT, 1, 1, 1, VK_IMAGE_VIEW_TYPE_3D, &zero, sizeof zero);
}

void Renderer::Impl::create_render_pass() {
  std::array<VkAttachmentDescription, 4> attachments{};
  const std::array<VkFormat, 3> color_formats = {color_format, hit_format, counters_format};
  for (std::size_t i = 0; i < 3; ++i) {
    attachments[i].format = color_formats[i];
    attachments[i].samples = VK_SAMPLE_COUNT_1_BIT;
    attachments[i].loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
    attachments[i].storeOp = VK_ATTACHMENT_STORE_OP_STORE;
    attachments[i].stencilLoadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE;
    attachments[i].stencilStoreOp = VK_ATTACHMENT_STORE_OP_DONT_CARE;
    attachments[i].initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
    attachments[i].finalLayout = VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL;
  }
  attachments[3].format = depth_format;
  attachments[3].samples = VK_SAMPLE_COUNT_1_BIT;
  attachments[3].loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
  attachments[3].storeOp = VK_ATTACHMENT_STORE_OP_DONT_CARE;
  attachments[3].stencilLoadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE;
  attachments[3].stencilStoreOp = VK_ATTACHMENT_STORE_OP_DONT_CARE;
  attachments[3].initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
  attachments[3].finalLayout = VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL;

  const std::array<VkAttachmentReference, 3> color_refs = {
      VkAttachmentReference{0, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL},
      VkAttachmentReference{1, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL},
      VkAttachmentReference{2, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL}};
  const VkAttachmentReference depth_ref{3, VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL};
  VkSubpassDescription subpass{};
  subpass.pipelineBindPoint = VK_PIPELINE_BIND_POINT_GRAPHICS;
  subpass.colorAttachmentCount = std::uint32_t(color_refs.size());
  subpass.pColorAttachments = color_refs.data();
  subpass.pDepthStencilAttachment = &depth_ref;

  std::array<VkSubpassDependency, 2> dependencies{};
  dependencies[0].srcSubpass = VK_SUBPASS_EXTERNAL;
  dependencies[0].dstSubpass = 0;
  dependencies[0].srcStageMask = VK_PIPELINE_STAGE_TRANSFER_BIT;
  dependencies[0].dstStageMask = VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT |
                                 VK_PIPELINE_STAGE_EARLY_FRAGMENT_TESTS_BIT | VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT;
  dependencies[0].srcAccessMask = VK_ACCESS_TRANSFER_READ_BIT;
  dependencies[0].dstAccessMask =
      VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT | VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT;
  dependencies[1].srcSubpass = 0;
  dependencies[1].dstSubpass = VK_SUBPASS_EXTERNAL;
  dependencies[1].srcStageMask = VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT;
  dependencies[1].dstStageMask = VK_PIPELINE_STAGE_TRANSFER_BIT;
  dependencies[1].srcAccessMask = VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT;
  dependencies[1].dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT;

  VkRenderPassCreateInfo info{VK_STRUCTURE_TYPE_RENDER_PASS_CREATE_INFO};
  info.attachmentCount = std::uint32_t(attachments.size());
  info.pAttachments = attachments.data();
  info.subpassCount = 1;
  info.pSubpasses = &subpass;
  info.dependencyCount = std::uint32_t(dependencies.size());
  info.pDependencies = dependencies.data();
  VkRenderPass pass = VK_NULL_HANDLE;
  DISPLACE_VK_CHECK(vkCreateRenderPass(context.device(), &info, nullptr, &pass));
  render_pass = OwnedRenderPass(context.device(), pass);

  relief_vertex = OwnedShaderModule(context.device(), make_shader(context.device(), spirv_relief_vert));
  reference_vertex = OwnedShaderModule(context.device(), make_shader(context.device(), spirv_reference_vert));
  surface_fragment = OwnedShaderModule(context.device(), make_shader(context.device(), spirv_surface_frag));
  quadric_proxy_vertex = OwnedShaderModule(context.device(), make_shader(context.device(), spirv_quadric_proxy_vert));
  quadric_reference_vertex =
      OwnedShaderModule(context.device(), make_shader(context.device(), spirv_quadric_reference_vert));
  mesh_vertex = OwnedShaderModule(context.device(), make_shader(context.device(), spirv_mesh_vert));
}

VkPipeline Renderer::Impl::pipeline(const MethodInfo& info, Surface surface) {
  const int key = info.shader_id * 8 + surface_id(surface);
  if (const auto found = pipelines.find(key); found != pipelines.end()) return found->second.get();
  const bool reference = info.family == MethodFamily::reference;
  const bool quadric = is_quadric(surface);
  const bool mesh = surface == Surface::mesh;

  // specialization constants 0 (METHOD) and 1 (SURFACE)
  const std::array<std::int32_t, 2> constants = {info.shader_id, surface_id(surface)};
  const std::array<VkSpecializationMapEntry, 2> entries = {
      VkSpecializationMapEntry{0, 0, sizeof(std::int32_t)},
      VkSpecializationMapEntry{1, sizeof(std::int32_t), sizeof(std::int32_t)}};
  VkSpecializationInfo specialization{std::uint32_t(entries.size()), entries.data(), sizeof(constants), constants.data()};
  std::array<VkPipelineShaderStageCreateInfo, 2> stages{};
  stages[0] = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
  stages[0].stage = VK_SHADER_STAGE_VERTEX_BIT;
  if (quadric) {
    stages[0].module = reference ? quadric_reference_vertex.get() : quadric_proxy_vertex.get();
    stages[0].pSpecializationInfo = &specialization;
  } else if (mesh) {
    stages[0].module = mesh_vertex.get();
    stages[0].pSpecializationInfo = &specialization;
  } else {
    stages[0].module = reference ? reference_vertex.get() : relief_vertex.get();
  }
  stages[0].pName = "main";
  stages[1] = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
  stages[1].stage = VK_SHADER_STAGE_FRAGMENT_BIT;
  stages[1].module = surface_fragment.get();
  stages[1].pName = "main";
  stages[1].pSpecializationInfo = &specialization;

  const VkVertexInputBindingDescription vertex_binding{0, sizeof(float) * 2, VK_VERTEX_INPUT_RATE_VERTEX};
  const VkVertexInputAttributeDescription vertex_attribute{0, 0, VK_FORMAT_R32G32_SFLOAT, 0};
  VkPipelineVertexInputStateCreateInfo vertex_input{VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO};
  // meshes: MeshVertex, four vec4 per vertex
  const VkVertexInputBindingDescription mesh_binding{0, sizeof(MeshVertex), VK_VERTEX_INPUT_RATE_VERTEX};
  std::array<VkVertexInputAttributeDescription, 4> mesh_attributes{};
  for (std::uint32_t a = 0; a < 4; ++a) {
    mesh_attributes[a] = {a, 0, VK_FORMAT_R32G32B32A32_SFLOAT, std::uint32_t(a * 4 * sizeof(float))};
  }
  if (mesh) {
    vertex_input.vertexBindingDescriptionCount = 1;
    vertex_input.pVertexBindingDescriptions = &mesh_binding;
    vertex_input.vertexAttributeDescriptionCount = std::uint32_t(mesh_attributes.size());
    vertex_input.pVertexAttributeDescriptions = mesh_attributes.data();
  } else if (reference) {
    vertex_input.vertexBindingDescriptionCount = 1;
    vertex_input.pVertexBindingDescriptions = &vertex_binding;
    vertex_input.vertexAttributeDescriptionCount = 1;
    vertex_input.pVertexAttributeDescriptions = &vertex_attribute;
  }
  VkPipelineInputAssemblyStateCreateInfo assembly{VK_STRUCTURE_TYPE_PIPELINE_INPUT_ASSEMBLY_STATE_CREATE_INFO};
  assembly.topology = VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST;
  VkPipelineViewportStateCreateInfo viewport{VK_STRUCTURE_TYPE_PIPELINE_VIEWPORT_STATE_CREATE_INFO};
  viewport.viewportCount = 1;
  viewport.scissorCount = 1;
  VkPipelineRasterizationStateCreateInfo raster{VK_STRUCTURE_TYPE_PIPELINE_RASTERIZATION_STATE_CREATE_INFO};
  raster.polygonMode = VK_POLYGON_MODE_FILL;
  raster.cullMode = VK_CULL_MODE_NONE;  // the fragment shader rejects the plane seen from below
  if (quadric) {
    // the tessellated relief is seen from outside only; the proxy box draws its back faces only
    raster.cullMode = reference ? VK_CULL_MODE_BACK_BIT : VK_CULL_MODE_FRONT_BIT;
  }
  if (mesh) raster.cullMode = VK_CULL_MODE_BACK_BIT;  // counter-clockwise seen from outside
  raster.frontFace = VK_FRONT_FACE_COUNTER_CLOCKWISE;
  raster.lineWidth = 1.0f;
  VkPipelineMultisampleStateCreateInfo multisample{VK_STRUCTURE_TYPE_PIPELINE_MULTISAMPLE_STATE_CREATE_INFO};
  multisample.rasterizationSamples = VK_SAMPLE_COUNT_1_BIT;
  VkPipelineDepthStencilStateCreateInfo depth{VK_STRUCTURE_TYPE_PIPELINE_DEPTH_STENCIL_STATE_CREATE_INFO};
  depth.depthTestEnable = VK_TRUE;
  depth.depthWriteEnable = VK_TRUE;
  depth.depthCompareOp = VK_COMPARE_OP_LESS;
  std::array<VkPipelineColorBlendAttachmentState, 3> blend{};
  for (auto& attachment : blend) {
    attachment.colorWriteMask =
        VK_COLOR_COMPONENT_R_BIT | VK_COLOR_COMPONENT_G_BIT | VK_COLOR_COMPONENT_B_BIT | VK_COLOR_COMPONENT_A_BIT;
  }
  VkPipelineColorBlendStateCreateInfo blending{VK_STRUCTURE_TYPE_PIPELINE_COLOR_BLEND_STATE_CREATE_INFO};
  blending.attachmentCount = std::uint32_t(blend.size());
  blending.pAttachments = blend.data();
  const std::array<VkDynamicState, 2> dynamic_states = {VK_DYNAMIC_STATE_VIEWPORT, VK_DYNAMIC_STATE_SCISSOR};
  VkPipelineDynamicStateCreateInfo dynamic{VK_STRUCTURE_TYPE_PIPELINE_DYNAMIC_STATE_CREATE_INFO};
  dynamic.dynamicStateCount = std::uint32_t(dynamic_states.size());
  dynamic.pDynamicStates = dynamic_states.data();

  VkGraphicsPipelineCreateInfo create{VK_STRUCTURE_TYPE_GRAPHICS_PIPELINE_CREATE_INFO};
  create.stageCount = std::uint32_t(stages.size());
  create.pStages = stages.data();
  create.pVertexInputState = &vertex_input;
  create.pInputAssemblyState = &assembly;
  create.pViewportState = &viewport;
  create.pRasterizationState = &raster;
  create.pMultisampleState = &multisample;
  create.pDepthStencilState = &depth;
  create.pColorBlendState = &blending;
  create.pDynamicState = &dynamic;
  create.layout = pipeline_layout.get();
  create.renderPass = render_pass.get();
  VkPipeline handle = VK_NULL_HANDLE;
  DISPLACE_VK_CHECK(vkCreateGraphicsPipelines(context.device(), VK_NULL_HANDLE, 1, &create, nullptr, &handle));
  return pipelines.emplace(key, OwnedPipeline(context.device(), handle)).first->second.get();
}

Image Renderer::Impl::upload_image(VkFormat format, int width, int height, int layers, VkImageViewType view_type,
                                   const void* data, std::size_t bytes) {
  Image image(context, format, std::uint32_t(width), std::uint32_t(height), std::uint32_t(layers),
              VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT, VK_IMAGE_ASPECT_COLOR_BIT, view_type);
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
    vkCmdCopyBufferToImage(commands, staging.handle(), image.handle(), VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1,
                           &region);
    image_barrier(commands, image.handle(), array_layers, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                  VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, VK_ACCESS_TRANSFER_WRITE_BIT, VK_ACCESS_SHADER_READ_BIT,
                  VK_PIPELINE_STAGE_TRANSFER_BIT,
                  VK_PIPELINE_STAGE_VERTEX_SHADER_BIT | VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT);
  });
  return image;
}

Buffer Renderer::Impl::upload_storage_buffer(std::span<const std::byte> data) {
  Buffer buffer(context, data.size(), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
  Buffer staging(context, data.size(), VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                 VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
  std::memcpy(staging.mapped(), data.data(), data.size());
  context.submit_and_wait([&](VkCommandBuffer commands) {
    const VkBufferCopy region{0, 0, data.size()};
    vkCmdCopyBuffer(commands, staging.handle(), buffer.handle(), 1, &region);
    VkBufferMemoryBarrier barrier{VK_STRUCTURE_TYPE_BUFFER_MEMORY_BARRIER};
    barrier.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
    barrier.dstAccessMask = VK_ACCESS_SHADER_READ_BIT;
    barrier.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    barrier.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    barrier.buffer = buffer.handle();
    barrier.size = VK_WHOLE_SIZE;
    vkCmdPipelineBarrier(commands, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT, 0,
                         0, nullptr, 1, &barrier, 0, nullptr);
  });
  return buffer;
}

const ConeMaps& Renderer::Impl::cones(int sectors, bake::Address address, ConeKind kind) {
  const int key = cone_key(sectors, address, kind);
  auto found = cone_maps.find(key);
  if (found != cone_maps.end()) return found->second;
  ConeMaps maps;
  const bake::HeightView heights{field.heights.data(), field.width, field.height};
  if (kind == ConeKind::relaxed) {
    maps = cones(sectors, address, ConeKind::bilinear);
    maps.relaxed.resize(field.heights.size());
    bake::bake_relaxed(heights, address, bake::ConeView{maps.relaxed.data(), field.width, field.height, 1});
  } else {
    maps.ratios.resize(std::size_t(field.width) * field.height * sectors);
    maps.apex.resize(field.heights.size());
    bake::BilinearBaker baker(field.width, field.height, sectors, address);
    baker.bake(heights, cone_budget, bake::ConeView{maps.ratios.data(), field.width, field.height, sectors},
               maps.apex);
  }
  return cone_maps.emplace(key, std::move(maps)).first->second;
}

const DistanceMap& Renderer::Impl::distance_map(bake::Address address) {
  const int key = int(address);
  if (const auto found = distance_maps.find(key); found != distance_maps.end()) return found->second;
  VkPhysicalDeviceProperties properties;
  vkGetPhysicalDeviceProperties(context.physical_device(), &properties);
  const int side_limit = std::min(distance_max_side, int(properties.limits.maxImageDimension3D));
  DistanceMap map;
  map.width = std::min(field.width, side_limit);
  map.height = std::min(field.height, side_limit);
  map.depth = std::min(distance_slices, int(properties.limits.maxImageDimension3D));
  map.values.resize(std::size_t(map.width) * map.height * map.depth);
  bake::bake_distance_map({field.heights.data(), field.width, field.height}, address,
                          {map.values.data(), map.width, map.height, map.depth});
  return distance_maps.emplace(key, std::move(map)).first->second;
}

void Renderer::Impl::ensure_targets(int width, int height) {
  if (targets.width == width && targets.height == height) return;
  targets = Targets{};
  const auto w = std::uint32_t(width), h = std::uint32_t(height);
  const VkImageUsageFlags color_usage = VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT;
  targets.color = Image(context, color_format, w, h, 1, color_usage, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_VIEW_TYPE_2D);
  targets.hit = Image(context, hit_format, w, h, 1, color_usage, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_VIEW_TYPE_2D);
  targets.counters =
      Image(context, counters_format, w, h, 1, color_usage, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_VIEW_TYPE_2D);
  targets.depth = Image(context, depth_format, w, h, 1, VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT,
                        VK_IMAGE_ASPECT_DEPTH_BIT, VK_IMAGE_VIEW_TYPE_2D);
  const std::array<VkImageView, 4> views = {targets.color.view(), targets.hit.view(), targets.counters.view(),
                                            targets.depth.view()};
  VkFramebufferCreateInfo info{VK_STRUCTURE_TYPE_FRAMEBUFFER_CREATE_INFO};
  info.renderPass = render_pass.get();
  info.attachmentCount = std::uint32_t(views.size());
  info.pAttachments = views.data();
  info.width = w;
  info.height = h;
  info.layers = 1;
  VkFramebuffer framebuffer = VK_NULL_HANDLE;
  DISPLACE_VK_CHECK(vkCreateFramebuffer(context.device(), &info, nullptr, &framebuffer));
  targets.framebuffer = OwnedFramebuffer(context.device(), framebuffer);
  const VkMemoryPropertyFlags host = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
  const VkDeviceSize pixels = VkDeviceSize(w) * h;
  targets.color_readback = Buffer(context, pixels * 4, VK_BUFFER_USAGE_TRANSFER_DST_BIT, host);
  targets.hit_readback = Buffer(context, pixels * 16, VK_BUFFER_USAGE_TRANSFER_DST_BIT, host);
  targets.counters_readback = Buffer(context, pixels * 8, VK_BUFFER_USAGE_TRANSFER_DST_BIT, host);
  targets.width = width;
  targets.height = height;
}

// Vertices at every texel centre of the K x K tiles plus the patch border (u = 0 and u = K), so the
// triangles interpolate the same texel heights as the bilinear texture does.
template <typename T>
Buffer Renderer::Impl::host_buffer(const std::vector<T>& data, VkBufferUsageFlags usage) {
  const VkMemoryPropertyFlags host = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
  Buffer buffer(context, data.size() * sizeof(T), usage, host);
  std::memcpy(buffer.mapped(), data.data(), data.size() * sizeof(T));
  return buffer;
}

namespace {

constexpr long long max_mesh_reference_vertices = 4 << 20;  // the tessellated reference of a mesh

MeshVertex blend(const MeshVertex& a, const MeshVertex& b, const MeshVertex& c, float wa, float wb, float wc) {
  MeshVertex v;
  v.position = wa * a.position + wb * b.position + wc * c.position;
  v.u = wa * a.u + wb * b.u + wc * c.u;
  v.v = wa * a.v + wb * b.v + wc * c.v;
  v.dp_du = wa * a.dp_du + wb * b.dp_du + wc * c.dp_du;
  v.dp_dv = wa * a.dp_dv + wb * b.dp_dv + wc * c.dp_dv;
  v.normal = glm::normalize(wa * a.normal + wb * b.normal + wc * c.normal);
  v.curvature_uu = wa * a.curvature_uu + wb * b.curvature_uu + wc * c.curvature_uu;
  v.curvature_vv = wa * a.curvature_vv + wb * b.curvature_vv + wc * c.curvature_vv;
  return v;
}

}  // namespace

// The mesh's reference: every triangle cut into n x n sub-triangles, n chosen so that a sub-edge
// spans at most half a texel of the (tiled) map, the same n everywhere (vertices fall between texel
// centres as well as on them, so sharp features are sampled, not exactly kept: the reference on a
// mesh is its tessellation); a point on an edge is blended from
// the edge's two vertices in one fixed order, so neighbouring triangles share it bit for bit and the
// displaced surface has no cracks. The vertex shader displaces each vertex along its normal.
void Renderer::Impl::ensure_mesh_reference(int tile) {
  const std::array<int, 3> key{tile, field.width, field.height};
  if (mesh_reference_key == key && mesh_reference_vertices.handle()) return;
  const std::size_t triangles = mesh_triangles.size() / 3;
  double longest = 1.0;  // texels
  for (std::size_t t = 0; t < mesh_triangles.size(); t += 3) {
    for (int e = 0; e < 3; ++e) {
      const MeshVertex& a = mesh_cpu[mesh_triangles[t + e]];
      const MeshVertex& b = mesh_cpu[mesh_triangles[t + (e + 1) % 3]];
      longest = std::max({longest, std::abs(double(a.u) - b.u) * field.width * tile,
                          std::abs(double(a.v) - b.v) * field.height * tile});
    }
  }
  const long long most = (long long)std::sqrt(2.0 * double(max_mesh_reference_vertices) / double(triangles));
  const int n = int(std::clamp<long long>((long long)std::ceil(2.0 * longest), 1, std::max<long long>(most - 1, 1)));
  const int per_row = n + 1;
  std::vector<MeshVertex> vertices;
  std::vector<std::uint32_t> indices;
  vertices.reserve(triangles * std::size_t(per_row) * std::size_t(n + 2) / 2);
  indices.reserve(triangles * std::size_t(n) * std::size_t(n) * 3);
  std::vector<std::uint32_t> grid(std::size_t(per_row) * per_row);
  for (std::size_t t = 0; t < mesh_triangles.size(); t += 3) {
    const std::uint32_t corner[3] = {mesh_triangles[t], mesh_triangles[t + 1], mesh_triangles[t + 2]};
    // point (i, j): weights i / n on the first corner, j / n on the second, the rest on the third
    for (int i = 0; i <= n; ++i) {
      for (int j = 0; i + j <= n; ++j) {
        const int counts[3] = {i, j, n - i - j};
        int nonzero = 0;
        for (int c : counts) nonzero += c != 0;
        MeshVertex vertex;
        if (nonzero == 2) {  // on an edge: blend its two vertices in the order of their indices
          int first = -1, second = -1;
          for (int c = 0; c < 3; ++c) {
            if (counts[c] == 0) continue;
            (first < 0 ? first : second) = c;
          }
          if (corner[first] > corner[second]) std::swap(first, second);
          const float w = float(counts[second]) / float(n);
          vertex = blend(mesh_cpu[corner[first]], mesh_cpu[corner[second]], mesh_cpu[corner[first]], 1.0f - w, w, 0.0f);
        } else {
          vertex = blend(mesh_cpu[corner[0]], mesh_cpu[corner[1]], mesh_cpu[corner[2]], float(i) / float(n),
                         float(j) / float(n), float(n - i - j) / float(n));
        }
        grid[std::size_t(i) * per_row + j] = std::uint32_t(vertices.size());
        vertices.push_back(vertex);
      }
    }
    // sub-triangles, with the winding of the triangle (+i towards its first corner, +j its second)
    for (int i = 0; i < n; ++i) {
      for (int j = 0; i + j < n; ++j) {
        const std::uint32_t p = grid[std::size_t(i) * per_row + j], pi = grid[std::size_t(i + 1) * per_row + j],
                            pj = grid[std::size_t(i) * per_row + j + 1];
        indices.insert(indices.end(), {p, pi, pj});
        if (i + j + 1 < n) indices.insert(indices.end(), {pi, grid[std::size_t(i + 1) * per_row + j + 1], pj});
      }
    }
  }
  mesh_reference_vertices = host_buffer(vertices, VK_BUFFER_USAGE_VERTEX_BUFFER_BIT);
  mesh_reference_indices = host_buffer(indices, VK_BUFFER_USAGE_INDEX_BUFFER_BIT);
  mesh_reference_index_count = std::uint32_t(indices.size());
  mesh_reference_key = key;
}

void Renderer::Impl::ensure_reference_mesh(int tile) {
  if (reference_tile == tile && reference_vertices.handle()) return;
  const long long columns = (long long)field.width * tile + 2, rows = (long long)field.height * tile + 2;
  std::vector<float> vertices;
  vertices.reserve(std::size_t(columns * rows * 2));
  auto coordinate = [&](long long index, int size) {
    return std::clamp((double(index) - 0.5) / size, 0.0, double(tile));
  };
  for (long long i = 0; i < rows; ++i) {
    for (long long j = 0; j < columns; ++j) {
      vertices.push_back(float(coordinate(j, field.width)));
      vertices.push_back(float(coordinate(i, field.height)));
    }
  }
  std::vector<std::uint32_t> indices;
  indices.reserve(std::size_t((columns - 1) * (rows - 1) * 6));
  for (long long i = 0; i + 1 < rows; ++i) {
    for (long long j = 0; j + 1 < columns; ++j) {
      const auto a = std::uint32_t(i * columns + j), b = a + 1, c = a + std::uint32_t(columns), d = c + 1;
      indices.insert(indices.end(), {a, b, d, a, d, c});
    }
  }
  const VkMemoryPropertyFlags host = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
  reference_vertices = Buffer(context, vertices.size() * sizeof(float), VK_BUFFER_USAGE_VERTEX_BUFFER_BIT, host);
  std::memcpy(reference_vertices.mapped(), vertices.data(), vertices.size() * sizeof(float));
  reference_indices = Buffer(context, indices.size() * sizeof(std::uint32_t), VK_BUFFER_USAGE_INDEX_BUFFER_BIT, host);
  std::memcpy(reference_indices.mapped(), indices.data(), indices.size() * sizeof(std::uint32_t));
  reference_index_count = std::uint32_t(indices.size());
  reference_tile = tile;
}

void Renderer::Impl::bind_maps(const View& view, const MethodInfo& info) {
  const bool wrap = view.address == bake::Address::wrap;
  // u closes around a quadric's axis: its cones are baked with wrap (conservative for a clamped v)
  const bool quadric = is_quadric(view.surface);
  const bake::Address cone_address = quadric ? bake::Address::wrap : view.address;
  VkImageView cone_view = dummy_cones.view();
  if (info.cone_sectors > 0) {
    const int key = cone_key(info.cone_sectors, cone_address, cone_kind(info));
    if (uploaded_cone_key != key) {
      const std::vector<float> packed = cone_layers(cones(info.cone_sectors, cone_address, cone_kind(info)),
                                                    field.width, field.height, info.cone_sectors);
      cone_image = upload_image(VK_FORMAT_R32G32_SFLOAT, field.width, field.height,
                                cone_layer_count(info.cone_sectors, info.relaxed_cones), VK_IMAGE_VIEW_TYPE_2D_ARRAY,
                                packed.data(), packed.size() * sizeof(float));
      uploaded_cone_key = key;
    }
    cone_view = cone_image.view();
  }
  VkBuffer pyramid_buffer = dummy_pyramid.handle();
  if (info.family == MethodFamily::pyramid) {
    if (uploaded_pyramid_address != int(view.address)) {
      const bake::HeightView heights{field.heights.data(), field.width, field.height};
      const std::vector<std::byte> packed =
          pack_max_pyramid(bake::build_dual_max_pyramid(heights, view.address));
      VkPhysicalDeviceProperties properties;
      vkGetPhysicalDeviceProperties(context.physical_device(), &properties);
      if (packed.size() > properties.limits.maxStorageBufferRange) {
        throw RenderError("the max pyramid of a " + std::to_string(field.width) + "x" +
                          std::to_string(field.height) + " map needs " + std::to_string(packed.size()) +
                          " bytes, more than this device's " +
                          std::to_string(properties.limits.maxStorageBufferRange) + "-byte storage buffers");
      }
      max_pyramid = upload_storage_buffer(packed);
      uploaded_pyramid_address = int(view.address);
    }
    pyramid_buffer = max_pyramid.handle();
  }
  VkImageView distance_view = dummy_distance.view();
  if (info.family == MethodFamily::distance) {
    if (uploaded_distance_key != int(view.address)) {
      const DistanceMap& map = distance_map(view.address);
      distance_image =
          upload_image(VK_FORMAT_R32_SFLOAT, map.width, map.height, map.depth, VK_IMAGE_VIEW_TYPE_3D,
                       map.values.data(), map.values.size() * sizeof(float));
      uploaded_distance_key = int(view.address);
    }
    distance_view = distance_image.view();
  }
  const VkDescriptorBufferInfo uniform_info{uniforms.handle(), 0, sizeof(gpu::FrameUniforms)};
  const VkDescriptorImageInfo height_info{
      wrap ? linear_wrap.get() : (quadric ? linear_wrap_u.get() : linear_clamp.get()), height_image.view(),
      VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
  const VkDescriptorImageInfo cone_info{
      wrap ? nearest_wrap.get() : (quadric ? nearest_wrap_u.get() : nearest_clamp.get()), cone_view,
      VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
  const VkDescriptorImageInfo albedo_info{
      wrap ? linear_wrap.get() : (quadric ? linear_wrap_u.get() : linear_clamp.get()),
      has_albedo ? albedo_image.view() : dummy_albedo.view(), VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
  const VkDescriptorBufferInfo pyramid_info{pyramid_buffer, 0, VK_WHOLE_SIZE};
  const VkDescriptorImageInfo distance_info{wrap ? linear_wrap.get() : linear_clamp.get(), distance_view,
                                            VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
  auto write = [&](std::uint32_t binding, VkDescriptorType type, const VkDescriptorImageInfo* image,
                   const VkDescriptorBufferInfo* buffer) {
    VkWriteDescriptorSet w{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
    w.dstSet = descriptor_set;
    w.dstBinding = binding;
    w.descriptorCount = 1;
    w.descriptorType = type;
    w.pImageInfo = image;
    w.pBufferInfo = buffer;
    return w;
  };
  constexpr VkDescriptorType sampled = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
  const std::array<VkWriteDescriptorSet, 6> writes = {
      write(BINDING_FRAME, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, nullptr, &uniform_info),
      write(BINDING_HEIGHT, sampled, &height_info, nullptr),
      write(BINDING_CONES, sampled, &cone_info, nullptr),
      write(BINDING_MAX_PYRAMID, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, nullptr, &pyramid_info),
      write(BINDING_ALBEDO, sampled, &albedo_info, nullptr),
      write(BINDING_DISTANCE, sampled, &distance_info, nullptr)};
  vkUpdateDescriptorSets(context.device(), std::uint32_t(writes.size()), writes.data(), 0, nullptr);
}

Renderer::Renderer(const RendererOptions& options) : impl_(std::make_unique<Impl>(options)) {
  impl_->create_layouts();
  impl_->create_render_pass();
}

Renderer::~Renderer() = default;
Renderer::Renderer(Renderer&&) noexcept = default;
Renderer& Renderer::operator=(Renderer&&) noexcept = default;

const DeviceInfo& Renderer::device() const { return impl_->context.info(); }

long long Renderer::validation_messages() const { return impl_->context.validation_messages(); }

void Renderer::set_height_field(const HeightField& field, const bake::Budget& cone_budget) {
  if (field.width < 1 || field.height < 1 || field.width > max_map_side || field.height > max_map_side ||
      field.heights.size() != std::size_t(field.width) * field.height) {
    throw RenderError("height field must be between 1x1 and 16384x16384 texels with one height per texel");
  }
  for (float h : field.heights) {
    if (!(h >= 0.0f && h <= 1.0f)) throw RenderError("heights must be finite and in [0, 1]");
  }
  Impl& impl = *impl_;
  vkDeviceWaitIdle(impl.context.device());
  impl.field = field;
  impl.cone_budget = cone_budget;
  impl.cone_maps.clear();
  impl.uploaded_cone_key = -1;
  impl.cone_image = Image{};
  impl.uploaded_pyramid_address = -1;
  impl.max_pyramid = Buffer{};
  impl.distance_maps.clear();
  impl.uploaded_distance_key = -1;
  impl.distance_image = Image{};
  impl.reference_vertices = Buffer{};
  impl.reference_indices = Buffer{};
  impl.reference_tile = 0;
  impl.height_image = impl.upload_image(VK_FORMAT_R32_SFLOAT, field.width, field.height, 1, VK_IMAGE_VIEW_TYPE_2D,
                                        field.heights.data(),
                                        field.heights.size() * sizeof(float));
}

void Renderer::set_mesh(const Mesh& mesh) {
  std::vector<MeshVertex> vertices;
  try {
    vertices = mesh_vertices(mesh);
  } catch (const MeshError& error) {
    throw RenderError(std::string("mesh: ") + error.what());
  }
  Impl& impl = *impl_;
  vkDeviceWaitIdle(impl.context.device());
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
    throw RenderError("albedo image must be between 1x1 and 16384x16384 pixels with 4 bytes (RGBA) per pixel");
  }
  Impl& impl = *impl_;
  vkDeviceWaitIdle(impl.context.device());
  impl.albedo_image = impl.upload_image(VK_FORMAT_R8G8B8A8_UNORM, albedo.width, albedo.height, 1, VK_IMAGE_VIEW_TYPE_2D,
                                        albedo.rgba.data(), albedo.rgba.size());
  impl.has_albedo = true;
}

void Renderer::clear_albedo() {
  Impl& impl = *impl_;
  vkDeviceWaitIdle(impl.context.device());
  impl.has_albedo = false;
  impl.albedo_image = Image{};
}

Frame Renderer::render(const View& view, const MethodSettings& method) {
  Impl& impl = *impl_;
  // validate the view
  if (!impl.height_image.handle()) throw RenderError("render: no height field was set");
  view.camera.validate();
  if (view.tile < 1 || view.tile > max_tile) throw RenderError("--tile must be between 1 and " + std::to_string(max_tile));
  if (view.tile > 1 && view.address != bake::Address::wrap) throw RenderError("--tile above 1 needs --address wrap");
  if (!(view.depth_scale > 0.0f && view.depth_scale <= max_depth_scale)) {
    throw RenderError("--depth-scale must be above 0 and at most 10");
  }
  if (!std::isfinite(view.light_direction.x) || !std::isfinite(view.light_direction.y) ||
      !std::isfinite(view.light_direction.z) || glm::length(view.light_direction) < 1e-6f) {
    throw RenderError("the light direction must be finite and non-zero");
  }
  if (method.steps < 1 || method.steps > max_steps) throw RenderError("--steps must be between 1 and 4096");
  if (method.refine < 0 || method.refine > max_refine) throw RenderError("--refine must be between 0 and 64");
  const MethodInfo& info = method_info(method.method);
  const Camera& camera = view.camera;
  const bool quadric = is_quadric(view.surface);
  const bool mesh = view.surface == Surface::mesh;
  if (mesh && impl.mesh_index_count == 0) throw RenderError("--surface mesh: no mesh was set");
  if (!supports_surface(info.method, view.surface)) {
    std::string supported;
    for (const MethodInfo& other : method_table()) {
      if (!supports_surface(other.method, view.surface)) continue;
      supported += (supported.empty() ? "" : ", ") + std::string(other.name);
    }
    throw RenderError(std::string("--method ") + info.name + " does not support --surface " +
                      surface_name(view.surface) + " (methods there: " + supported + ")");
  }
  if (quadric) quadric::validate(view);

  // maps and descriptors
  impl.bind_maps(view, info);
  const VkPipeline pipeline = impl.pipeline(info, view.surface);
  if (info.family == MethodFamily::reference) {
    if (mesh) {
      impl.ensure_mesh_reference(view.tile);
    } else {
      impl.ensure_reference_mesh(view.tile);
    }
  }

  // frame uniforms: near and far planes enclose the relief box ([0,1]^2 x [-D, 0] on the plane)
  glm::dvec3 box_lo(0.0, 0.0, -double(view.depth_scale)), box_hi(1.0, 1.0, 0.0);
  if (quadric) quadric::relief_box(quadric::shape_of(view), box_lo, box_hi);
  if (mesh) {
    box_lo = impl.mesh_lo - glm::dvec3(view.depth_scale);
    box_hi = impl.mesh_hi + glm::dvec3(view.depth_scale);
  }
  double far_plane = 0.0;
  for (int corner = 0; corner < 8; ++corner) {
    const glm::dvec3 p((corner & 1) ? box_hi.x : box_lo.x, (corner & 2) ? box_hi.y : box_lo.y,
                       (corner & 4) ? box_lo.z : box_hi.z);
    far_plane = std::max(far_plane, glm::length(p - glm::dvec3(camera.eye)));
  }
  far_plane = far_plane * 1.01 + 1e-3;
  const double near_plane = far_plane * 1e-5;
  gpu::FrameUniforms uniforms{};
  uniforms.view_projection = camera.view_projection(float(near_plane), float(far_plane));
  uniforms.eye = glm::vec4(camera.eye, 1.0f);
  uniforms.light = glm::vec4(glm::normalize(view.light_direction), 0.0f);
  uniforms.surface = glm::vec4(float(view.tile), view.depth_scale, 1.0f / float(view.tile), 0.0f);
  uniforms.map_size = glm::vec4(float(impl.field.width), float(impl.field.height), 1.0f / float(impl.field.width),
                                1.0f / float(impl.field.height));
  const int flags = (view.address == bake::Address::wrap ? FLAG_WRAP : 0) | (view.shadows ? FLAG_SHADOWS : 0) |
                    (impl.has_albedo ? FLAG_ALBEDO : 0);
  uniforms.counts = glm::ivec4(method.steps, method.refine, flags, info.cone_sectors);
  uniforms.background = glm::vec4(background[0], background[1], background[2], background[3]);
  uniforms.quadric = glm::vec4(quadric ? view.radius : 0.0f, 0.0f, 0.0f, 0.0f);
  std::memcpy(impl.uniforms.mapped(), &uniforms, sizeof uniforms);

  impl.ensure_targets(camera.width, camera.height);
  Targets& targets = impl.targets;
  const auto width = std::uint32_t(camera.width), height = std::uint32_t(camera.height);

  // record, submit, wait
  impl.context.submit_and_wait([&](VkCommandBuffer commands) {
    if (impl.timestamps.get()) vkCmdResetQueryPool(commands, impl.timestamps.get(), 0, 2);
    std::array<VkClearValue, 4> clears{};
    std::memcpy(clears[0].color.float32, background.data(), sizeof(float) * 4);
    clears[3].depthStencil = {1.0f, 0};
    VkRenderPassBeginInfo begin{VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO};
    begin.renderPass = impl.render_pass.get();
    begin.framebuffer = targets.framebuffer.get();
    begin.renderArea = {{0, 0}, {width, height}};
    begin.clearValueCount = std::uint32_t(clears.size());
    begin.pClearValues = clears.data();
    if (impl.timestamps.get()) {
      vkCmdWriteTimestamp(commands, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, impl.timestamps.get(), 0);
    }
    vkCmdBeginRenderPass(commands, &begin, VK_SUBPASS_CONTENTS_INLINE);
    vkCmdBindPipeline(commands, VK_PIPELINE_BIND_POINT_GRAPHICS, pipeline);
    const VkViewport viewport{0.0f, 0.0f, float(width), float(height), 0.0f, 1.0f};
    const VkRect2D scissor{{0, 0}, {width, height}};
    vkCmdSetViewport(commands, 0, 1, &viewport);
    vkCmdSetScissor(commands, 0, 1, &scissor);
    vkCmdBindDescriptorSets(commands, VK_PIPELINE_BIND_POINT_GRAPHICS, impl.pipeline_layout.get(), 0, 1,
                            &impl.descriptor_set, 0, nullptr);
    if (mesh) {
      const bool reference = info.family == MethodFamily::reference;
      const VkDeviceSize offset = 0;
      const VkBuffer vertex_buffer = reference ? impl.mesh_reference_vertices.handle() : impl.mesh_vertices.handle();
      vkCmdBindVertexBuffers(commands, 0, 1, &vertex_buffer, &offset);
      vkCmdBindIndexBuffer(commands, reference ? impl.mesh_reference_indices.handle() : impl.mesh_indices.handle(), 0,
                           VK_INDEX_TYPE_UINT32);
      vkCmdDrawIndexed(commands, reference ? impl.mesh_reference_index_count : impl.mesh_index_count, 1, 0, 0, 0);
    } else if (info.family == MethodFamily::reference) {
      const VkDeviceSize offset = 0;
      const VkBuffer vertex_buffer = impl.reference_vertices.handle();
      vkCmdBindVertexBuffers(commands, 0, 1, &vertex_buffer, &offset);
      vkCmdBindIndexBuffer(commands, impl.reference_indices.handle(), 0, VK_INDEX_TYPE_UINT32);
      vkCmdDrawIndexed(commands, impl.reference_index_count, 1, 0, 0, 0);
    } else {
      vkCmdDraw(commands, quadric ? 36 : 6, 1, 0, 0);  // the proxy box, or the plane's two triangles
    }
    vkCmdEndRenderPass(commands);
    if (impl.timestamps.get()) {
      vkCmdWriteTimestamp(commands, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, impl.timestamps.get(), 1);
    }
    VkBufferImageCopy region{};
    region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    region.imageExtent = {width, height, 1};
    vkCmdCopyImageToBuffer(commands, targets.color.handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                           targets.color_readback.handle(), 1, &region);
    vkCmdCopyImageToBuffer(commands, targets.hit.handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                           targets.hit_readback.handle(), 1, &region);
    vkCmdCopyImageToBuffer(commands, targets.counters.handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                           targets.counters_readback.handle(), 1, &region);
    VkMemoryBarrier to_host{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    to_host.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
    to_host.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
    vkCmdPipelineBarrier(commands, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &to_host, 0,
                         nullptr, 0, nullptr);
  });

  // read back
  Frame frame;
  frame.width = camera.width;
  frame.height = camera.height;
  const std::size_t pixels = std::size_t(width) * height;
  frame.color.resize(pixels * 4);
  std::memcpy(frame.color.data(), targets.color_readback.mapped(), pixels * 4);
  const auto* hit = static_cast<const float*>(targets.hit_readback.mapped());
  const auto* counters = static_cast<const float*>(targets.counters_readback.mapped());
  frame.uv.resize(pixels * 3);
  frame.depth.resize(pixels);
  frame.iterations.resize(pixels);
  frame.fetches.resize(pixels);
  for (std::size_t p = 0; p < pixels; ++p) {
    frame.uv[p * 3 + 0] = hit[p * 4 + 0];
    frame.uv[p * 3 + 1] = hit[p * 4 + 1];
    frame.uv[p * 3 + 2] = hit[p * 4 + 2];
    frame.depth[p] = hit[p * 4 + 3];
    frame.iterations[p] = counters[p * 2 + 0];
    frame.fetches[p] = counters[p * 2 + 1];
  }
  if (impl.timestamps.get()) {
    std::array<std::uint64_t, 2> ticks{};
    if (vkGetQueryPoolResults(impl.context.device(), impl.timestamps.get(), 0, 2, sizeof ticks, ticks.data(),
                              sizeof(std::uint64_t), VK_QUERY_RESULT_64_BIT) == VK_SUCCESS) {
      frame.gpu_milliseconds = double(ticks[1] - ticks[0]) * impl.context.timestamp_period_ns() * 1e-6;
    }
  }
  return frame;
}

}  // namespace displace::render
