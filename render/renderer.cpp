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
#include <cstdint>
#include <cstring>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "render/render.h"
#include "render/shaders/config.h"
#include "render/vulkan_context.h"
#include "spirv/reference_vert.h"
#include "spirv/relief_vert.h"
#include "spirv/surface_frag.h"

namespace displace::render {

static_assert(sizeof(gpu::FrameUniforms) == 64 + 16 * 6, "FrameUniforms must match the std140 layout");
static_assert(offsetof(gpu::FrameUniforms, eye) == 64);
static_assert(offsetof(gpu::FrameUniforms, counts) == 64 + 16 * 4);

namespace {

// limits on what a frame may ask for
constexpr int max_tile = 64;
constexpr float max_depth_scale = 10.0f;  // world units
constexpr int max_steps = 4096;
constexpr int max_refine = 64;
constexpr int max_map_side = 16384;

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
// (bake::bake_bilinear_cones; relaxed maps have none).
struct ConeMaps {
  std::vector<float> ratios;  // interleaved, bake conventions
  std::vector<float> apex;    // empty for relaxed cones
};

// Packs a cone map into RG32F layers, one per sector: layer k of texel t holds (ratio_k, apex_t),
// so that a cone step reads its ray's sector and the apex in one fetch (apex 0 without one).
std::vector<float> cone_layers(const ConeMaps& maps, int width, int height, int sectors) {
  const std::size_t texels = std::size_t(width) * height;
  std::vector<float> packed(texels * 2 * sectors);
  for (int k = 0; k < sectors; ++k)
    for (std::size_t t = 0; t < texels; ++t) {
      packed[(std::size_t(k) * texels + t) * 2 + 0] = maps.ratios[t * sectors + k];
      packed[(std::size_t(k) * texels + t) * 2 + 1] = maps.apex.empty() ? 0.0f : maps.apex[t];
    }
  return packed;
}

// Cone maps are baked for one sector count, address mode and kind.
enum class ConeKind {
  bilinear,  // bake_bilinear_cones: conservative for the bilinear surface, with apex heights
  relaxed,   // bake_relaxed
};
int cone_key(int sectors, bake::Address address, ConeKind kind) {
  return (sectors * 2 + (address == bake::Address::wrap ? 0 : 1)) * 2 + int(kind);
}
ConeKind cone_kind(const MethodInfo& info) {
  return info.relaxed_cones ? ConeKind::relaxed : ConeKind::bilinear;
}

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
  std::map<int, OwnedPipeline> pipelines;  // by shader id
  OwnedSampler linear_wrap, linear_clamp, nearest_wrap, nearest_clamp;
  OwnedQueryPool timestamps;
  Buffer uniforms;

  HeightField field;
  Image height_image;
  Image dummy_cones;
  std::map<int, ConeMaps> cone_maps;  // by cone_key, baked for `field`
  int uploaded_cone_key = -1;  // cone_key of cone_image, -1 for none
  Image cone_image;

  Buffer reference_vertices, reference_indices;
  std::uint32_t reference_index_count = 0;
  int reference_tile = 0;

  Targets targets;

  void create_layouts();
  void create_render_pass();
  VkPipeline pipeline(const MethodInfo& info);
  Image upload_image(VkFormat format, int width, int height, int layers, VkImageViewType view_type, const void* data,
                     std::size_t bytes);
  const ConeMaps& cones(int sectors, bake::Address address, ConeKind kind);
  void ensure_targets(int width, int height);
  void ensure_reference_mesh(int tile);
  void bind_maps(const View& view, const MethodInfo& info);
};

void Renderer::Impl::create_layouts() {
  const VkDevice device = context.device();
  std::array<VkDescriptorSetLayoutBinding, 3> bindings{};
  bindings[0] = {BINDING_FRAME, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1,
                 VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, nullptr};
  bindings[1] = {BINDING_HEIGHT, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1,
                 VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, nullptr};
  bindings[2] = {BINDING_CONES, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1, VK_SHADER_STAGE_FRAGMENT_BIT, nullptr};
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

  const std::array<VkDescriptorPoolSize, 2> sizes = {
      VkDescriptorPoolSize{VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1},
      VkDescriptorPoolSize{VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 2}};
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

  auto sampler = [&](VkFilter filter, VkSamplerAddressMode address) {
    VkSamplerCreateInfo info{VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO};
    info.magFilter = filter;
    info.minFilter = filter;
    info.mipmapMode = VK_SAMPLER_MIPMAP_MODE_NEAREST;
    info.addressModeU = address;
    info.addressModeV = address;
    info.addressModeW = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE;
    info.maxLod = 0.0f;
    VkSampler handle = VK_NULL_HANDLE;
    DISPLACE_VK_CHECK(vkCreateSampler(device, &info, nullptr, &handle));
    return OwnedSampler(device, handle);
  };
  linear_wrap = sampler(VK_FILTER_LINEAR, VK_SAMPLER_ADDRESS_MODE_REPEAT);
  linear_clamp = sampler(VK_FILTER_LINEAR, VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE);
  nearest_wrap = sampler(VK_FILTER_NEAREST, VK_SAMPLER_ADDRESS_MODE_REPEAT);
  nearest_clamp = sampler(VK_FILTER_NEAREST, VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE);

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
}

VkPipeline Renderer::Impl::pipeline(const MethodInfo& info) {
  if (const auto found = pipelines.find(info.shader_id); found != pipelines.end()) return found->second.get();
  const bool reference = info.family == MethodFamily::reference;

  const std::int32_t method_id = info.shader_id;
  const VkSpecializationMapEntry entry{0, 0, sizeof(method_id)};
  VkSpecializationInfo specialization{1, &entry, sizeof(method_id), &method_id};
  std::array<VkPipelineShaderStageCreateInfo, 2> stages{};
  stages[0] = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
  stages[0].stage = VK_SHADER_STAGE_VERTEX_BIT;
  stages[0].module = reference ? reference_vertex.get() : relief_vertex.get();
  stages[0].pName = "main";
  stages[1] = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
  stages[1].stage = VK_SHADER_STAGE_FRAGMENT_BIT;
  stages[1].module = surface_fragment.get();
  stages[1].pName = "main";
  stages[1].pSpecializationInfo = &specialization;

  const VkVertexInputBindingDescription vertex_binding{0, sizeof(float) * 2, VK_VERTEX_INPUT_RATE_VERTEX};
  const VkVertexInputAttributeDescription vertex_attribute{0, 0, VK_FORMAT_R32G32_SFLOAT, 0};
  VkPipelineVertexInputStateCreateInfo vertex_input{VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO};
  if (reference) {
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
  return pipelines.emplace(info.shader_id, OwnedPipeline(context.device(), handle)).first->second.get();
}

Image Renderer::Impl::upload_image(VkFormat format, int width, int height, int layers, VkImageViewType view_type,
                                   const void* data, std::size_t bytes) {
  Image image(context, format, std::uint32_t(width), std::uint32_t(height), std::uint32_t(layers),
              VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT, VK_IMAGE_ASPECT_COLOR_BIT, view_type);
  Buffer staging(context, bytes, VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                 VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
  std::memcpy(staging.mapped(), data, bytes);
  context.submit_and_wait([&](VkCommandBuffer commands) {
    image_barrier(commands, image.handle(), std::uint32_t(layers), VK_IMAGE_LAYOUT_UNDEFINED,
                  VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 0, VK_ACCESS_TRANSFER_WRITE_BIT,
                  VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT);
    VkBufferImageCopy region{};
    region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, std::uint32_t(layers)};
    region.imageExtent = {std::uint32_t(width), std::uint32_t(height), 1};
    vkCmdCopyBufferToImage(commands, staging.handle(), image.handle(), VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1,
                           &region);
    image_barrier(commands, image.handle(), std::uint32_t(layers), VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                  VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, VK_ACCESS_TRANSFER_WRITE_BIT, VK_ACCESS_SHADER_READ_BIT,
                  VK_PIPELINE_STAGE_TRANSFER_BIT,
                  VK_PIPELINE_STAGE_VERTEX_SHADER_BIT | VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT);
  });
  return image;
}

const ConeMaps& Renderer::Impl::cones(int sectors, bake::Address address, ConeKind kind) {
  const int key = cone_key(sectors, address, kind);
  auto found = cone_maps.find(key);
  if (found != cone_maps.end()) return found->second;
  ConeMaps maps;
  maps.ratios.resize(std::size_t(field.width) * field.height * sectors);
  const bake::HeightView heights{field.heights.data(), field.width, field.height};
  const bake::ConeView out{maps.ratios.data(), field.width, field.height, sectors};
  if (kind == ConeKind::relaxed) {
    bake::bake_relaxed(heights, address, out);
  } else {
    maps.apex.resize(field.heights.size());
    bake::bake_bilinear_cones(heights, address, out, maps.apex);
  }
  return cone_maps.emplace(key, std::move(maps)).first->second;
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
  VkImageView cone_view = dummy_cones.view();
  if (info.cone_sectors > 0) {
    const int key = cone_key(info.cone_sectors, view.address, cone_kind(info));
    if (uploaded_cone_key != key) {
      const std::vector<float> packed = cone_layers(cones(info.cone_sectors, view.address, cone_kind(info)),
                                                    field.width, field.height, info.cone_sectors);
      cone_image = upload_image(VK_FORMAT_R32G32_SFLOAT, field.width, field.height, info.cone_sectors,
                                VK_IMAGE_VIEW_TYPE_2D_ARRAY, packed.data(), packed.size() * sizeof(float));
      uploaded_cone_key = key;
    }
    cone_view = cone_image.view();
  }
  const VkDescriptorBufferInfo uniform_info{uniforms.handle(), 0, sizeof(gpu::FrameUniforms)};
  const VkDescriptorImageInfo height_info{wrap ? linear_wrap.get() : linear_clamp.get(), height_image.view(),
                                          VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
  const VkDescriptorImageInfo cone_info{wrap ? nearest_wrap.get() : nearest_clamp.get(), cone_view,
                                        VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
  std::array<VkWriteDescriptorSet, 3> writes{};
  for (auto& write : writes) {
    write = {VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
    write.dstSet = descriptor_set;
    write.descriptorCount = 1;
  }
  writes[0].dstBinding = BINDING_FRAME;
  writes[0].descriptorType = VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER;
  writes[0].pBufferInfo = &uniform_info;
  writes[1].dstBinding = BINDING_HEIGHT;
  writes[1].descriptorType = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
  writes[1].pImageInfo = &height_info;
  writes[2].dstBinding = BINDING_CONES;
  writes[2].descriptorType = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
  writes[2].pImageInfo = &cone_info;
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

void Renderer::set_height_field(const HeightField& field) {
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
  impl.cone_maps.clear();
  impl.uploaded_cone_key = -1;
  impl.cone_image = Image{};
  impl.reference_vertices = Buffer{};
  impl.reference_indices = Buffer{};
  impl.reference_tile = 0;
  impl.height_image = impl.upload_image(VK_FORMAT_R32_SFLOAT, field.width, field.height, 1, VK_IMAGE_VIEW_TYPE_2D,
                                        field.heights.data(),
                                        field.heights.size() * sizeof(float));
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

  // maps and descriptors
  impl.bind_maps(view, info);
  const VkPipeline pipeline = impl.pipeline(info);
  if (info.family == MethodFamily::reference) impl.ensure_reference_mesh(view.tile);

  // frame uniforms: near and far planes enclose the relief box [0,1]^2 x [-D, 0]
  double far_plane = 0.0;
  for (int corner = 0; corner < 8; ++corner) {
    const glm::dvec3 p(corner & 1, (corner >> 1) & 1, (corner & 4) ? -double(view.depth_scale) : 0.0);
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
  uniforms.counts = glm::ivec4(method.steps, method.refine,
                               view.address == bake::Address::wrap ? FLAG_WRAP : 0, info.cone_sectors);
  uniforms.background = glm::vec4(background[0], background[1], background[2], background[3]);
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
    if (info.family == MethodFamily::reference) {
      const VkDeviceSize offset = 0;
      const VkBuffer vertex_buffer = impl.reference_vertices.handle();
      vkCmdBindVertexBuffers(commands, 0, 1, &vertex_buffer, &offset);
      vkCmdBindIndexBuffer(commands, impl.reference_indices.handle(), 0, VK_INDEX_TYPE_UINT32);
      vkCmdDrawIndexed(commands, impl.reference_index_count, 1, 0, 0, 0);
    } else {
      vkCmdDraw(commands, 6, 1, 0, 0);
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
