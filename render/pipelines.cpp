// render/pipelines.cpp - descriptor and pipeline layouts, the render pass, samplers, shader modules,
// one graphics pipeline per method and surface (specialization constants METHOD, SURFACE and
// FEATURES, frozen into the module before the driver sees it: specialised_shader), and the
// VkPipelineCache kept on disk between runs so that a second process starts without compiling.
#include <unistd.h>

#include <array>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <system_error>
#include <vector>

#include "render/files.h"
#include "render/renderer_impl.h"
#include "render/shaders/config.h"
#include "spirv/mesh_vert.h"
#include "spirv/quadric_proxy_vert.h"
#include "spirv/quadric_reference_vert.h"
#include "spirv/reference_vert.h"
#include "spirv/relief_vert.h"
#include "spirv/surface_planar_frag.h"
#include "spirv/surface_quadric_frag.h"

namespace displace::render {
namespace {

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

// The cache's data starts with VkPipelineCacheHeaderVersionOne; data made by another driver or
// device is not handed to this one (the driver checks too, but a foreign file is simply unused).
bool cache_matches_device(const std::vector<char>& data, const VkPhysicalDeviceProperties& properties) {
  VkPipelineCacheHeaderVersionOne header{};
  if (data.size() < sizeof header) return false;
  std::memcpy(&header, data.data(), sizeof header);
  return header.headerSize >= sizeof header && header.headerSize <= data.size() &&
         header.headerVersion == VK_PIPELINE_CACHE_HEADER_VERSION_ONE &&
         header.vendorID == properties.vendorID && header.deviceID == properties.deviceID &&
         std::memcmp(header.pipelineCacheUUID, properties.pipelineCacheUUID, VK_UUID_SIZE) == 0;
}

}  // namespace

std::string default_pipeline_cache_dir() {
  if (const char* set = std::getenv("DISPLACE_PIPELINE_CACHE"); set && *set) return set;
  if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg && *xdg) return std::string(xdg) + "/displace";
  if (const char* home = std::getenv("HOME"); home && *home) return std::string(home) + "/.cache/displace";
  return "off";
}

void Renderer::Impl::load_pipeline_cache(const std::string& requested) {
  const std::string directory = requested.empty() ? default_pipeline_cache_dir() : requested;
  std::vector<char> data;
  if (directory != "off") {
    VkPhysicalDeviceProperties properties;
    vkGetPhysicalDeviceProperties(context.physical_device(), &properties);
    char uuid[2 * VK_UUID_SIZE + 1] = {};
    for (int i = 0; i < int(VK_UUID_SIZE); ++i)
      std::snprintf(uuid + 2 * i, 3, "%02x", properties.pipelineCacheUUID[i]);
    pipeline_cache_file = directory + "/pipelines-" + std::to_string(properties.vendorID) + "-" +
                          std::to_string(properties.deviceID) + "-" + uuid + ".bin";
    std::ifstream file(pipeline_cache_file, std::ios::binary);
    if (file) data.assign(std::istreambuf_iterator<char>(file), std::istreambuf_iterator<char>());
    if (!cache_matches_device(data, properties)) data.clear();
  }
  VkPipelineCacheCreateInfo info{VK_STRUCTURE_TYPE_PIPELINE_CACHE_CREATE_INFO};
  info.initialDataSize = data.size();
  info.pInitialData = data.empty() ? nullptr : data.data();
  VkPipelineCache cache = VK_NULL_HANDLE;
  DISPLACE_VK_CHECK(vkCreatePipelineCache(context.device(), &info, nullptr, &cache));
  pipeline_cache = OwnedPipelineCache(context.device(), cache);
}

// Written by the checked writer (render/files.h), so that processes sharing the directory never read
// half a file; a cache that cannot be written costs the next run its compile time, nothing more.
void Renderer::Impl::save_pipeline_cache() noexcept {
  if (pipeline_cache_file.empty() || !pipeline_cache.get() || pipelines_created == 0) return;
  try {
    std::size_t size = 0;
    if (vkGetPipelineCacheData(context.device(), pipeline_cache.get(), &size, nullptr) != VK_SUCCESS) return;
    std::vector<std::byte> data(size);
    if (vkGetPipelineCacheData(context.device(), pipeline_cache.get(), &size, data.data()) != VK_SUCCESS)
      return;
    const std::filesystem::path path(pipeline_cache_file);
    std::error_code error;
    std::filesystem::create_directories(path.parent_path(), error);
    files::write_file(path, std::span(data.data(), size));
  } catch (const files::WriteError& error) {
    std::fprintf(stderr, "displace: warning: the pipeline cache is not saved: %s\n", error.what());
  } catch (...) {
  }
}

void Renderer::Impl::create_layouts() {
  const VkDevice device = context.device();
  std::array<VkDescriptorSetLayoutBinding, 9> bindings{};
  // FrameUniforms is a storage buffer, not a uniform buffer: see shaders/frame_block.inc.glsl
  bindings[0] = {BINDING_FRAME, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1,
                 VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, nullptr};
  bindings[1] = {BINDING_HEIGHT, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1,
                 VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, nullptr};
  bindings[2] = {BINDING_CONES, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1, VK_SHADER_STAGE_FRAGMENT_BIT,
                 nullptr};
  bindings[3] = {BINDING_MAX_PYRAMID, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, VK_SHADER_STAGE_FRAGMENT_BIT,
                 nullptr};
  bindings[4] = {BINDING_ALBEDO, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1, VK_SHADER_STAGE_FRAGMENT_BIT,
                 nullptr};
  bindings[6] = {BINDING_FOAM, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1, VK_SHADER_STAGE_FRAGMENT_BIT,
                 nullptr};
  bindings[5] = {BINDING_DISTANCE, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1, VK_SHADER_STAGE_FRAGMENT_BIT,
                 nullptr};
  bindings[7] = {BINDING_HEIGHT_LEVELS, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1,
                 VK_SHADER_STAGE_FRAGMENT_BIT, nullptr};
  bindings[8] = {BINDING_CONE_LEVELS, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1,
                 VK_SHADER_STAGE_FRAGMENT_BIT, nullptr};
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

  // one descriptor set per frame in flight
  const std::array<VkDescriptorPoolSize, 2> sizes = {
      VkDescriptorPoolSize{VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 7 * frames_in_flight},
      VkDescriptorPoolSize{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 2 * frames_in_flight}};
  VkDescriptorPoolCreateInfo pool_info{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
  pool_info.maxSets = frames_in_flight;
  pool_info.poolSizeCount = std::uint32_t(sizes.size());
  pool_info.pPoolSizes = sizes.data();
  VkDescriptorPool pool = VK_NULL_HANDLE;
  DISPLACE_VK_CHECK(vkCreateDescriptorPool(device, &pool_info, nullptr, &pool));
  descriptor_pool = OwnedDescriptorPool(device, pool);

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
  const VkSamplerAddressMode repeat = VK_SAMPLER_ADDRESS_MODE_REPEAT,
                             clamp = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE;
  linear_wrap = sampler(VK_FILTER_LINEAR, repeat, repeat);
  linear_clamp = sampler(VK_FILTER_LINEAR, clamp, clamp);
  nearest_wrap = sampler(VK_FILTER_NEAREST, repeat, repeat);
  nearest_clamp = sampler(VK_FILTER_NEAREST, clamp, clamp);
  linear_wrap_u = sampler(VK_FILTER_LINEAR, clamp, repeat);
  nearest_wrap_u = sampler(VK_FILTER_NEAREST, clamp, repeat);
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
                                 VK_PIPELINE_STAGE_EARLY_FRAGMENT_TESTS_BIT |
                                 VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT;
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

  relief_vertex = shader_module(context.device(), spirv_relief_vert);
  reference_vertex = shader_module(context.device(), spirv_reference_vert);
}

VkPipeline Renderer::Impl::pipeline(const MethodInfo& info, Surface surface, int features) {
  features &= FEATURE_FLAGS;
  if (surface != Surface::plane) features &= ~FLAG_SHADOWS;  // a uniform there (config.h)
  const int key = (info.shader_id * 8 + surface_id(surface)) * 256 + features;
  if (const auto found = pipelines.find(key); found != pipelines.end()) return found->second.get();
  const bool reference = info.family == MethodFamily::reference;
  const bool quadric = is_quadric(surface);
  const bool mesh = surface == Surface::mesh;

  // specialization constants 0 (METHOD), 1 (SURFACE) and 2 (FEATURES; the fragment shaders only),
  // frozen into the modules (alive until the pipeline is made)
  const std::array<std::int32_t, 3> constants = {info.shader_id, surface_id(surface), features};
  OwnedShaderModule vertex_module, fragment_module;
  std::array<VkPipelineShaderStageCreateInfo, 2> stages{};
  stages[0] = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
  stages[0].stage = VK_SHADER_STAGE_VERTEX_BIT;
  if (quadric) {
    vertex_module = reference ? specialised_shader(context.device(), spirv_quadric_reference_vert, constants)
                              : specialised_shader(context.device(), spirv_quadric_proxy_vert, constants);
    stages[0].module = vertex_module.get();
  } else if (mesh) {
    vertex_module = specialised_shader(context.device(), spirv_mesh_vert, constants);
    stages[0].module = vertex_module.get();
  } else {
    stages[0].module = reference ? reference_vertex.get() : relief_vertex.get();
  }
  stages[0].pName = "main";
  fragment_module = quadric ? specialised_shader(context.device(), spirv_surface_quadric_frag, constants)
                            : specialised_shader(context.device(), spirv_surface_planar_frag, constants);
  stages[1] = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
  stages[1].stage = VK_SHADER_STAGE_FRAGMENT_BIT;
  stages[1].module = fragment_module.get();
  stages[1].pName = "main";

  const VkVertexInputBindingDescription vertex_binding{0, sizeof(float) * 2, VK_VERTEX_INPUT_RATE_VERTEX};
  const VkVertexInputAttributeDescription vertex_attribute{0, 0, VK_FORMAT_R32G32_SFLOAT, 0};
  VkPipelineVertexInputStateCreateInfo vertex_input{
      VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO};
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
  VkPipelineInputAssemblyStateCreateInfo assembly{
      VK_STRUCTURE_TYPE_PIPELINE_INPUT_ASSEMBLY_STATE_CREATE_INFO};
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
    attachment.colorWriteMask = VK_COLOR_COMPONENT_R_BIT | VK_COLOR_COMPONENT_G_BIT |
                                VK_COLOR_COMPONENT_B_BIT | VK_COLOR_COMPONENT_A_BIT;
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
  DISPLACE_VK_CHECK(
      vkCreateGraphicsPipelines(context.device(), pipeline_cache.get(), 1, &create, nullptr, &handle));
  ++pipelines_created;
  return pipelines.emplace(key, OwnedPipeline(context.device(), handle)).first->second.get();
}

}  // namespace displace::render
