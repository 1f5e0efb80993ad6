// render/renderer_impl.h - what the renderer's files share (internal to render/): the state behind
// Renderer, split by job across
//   renderer.cpp       the renderer object: its part of the frame slots, albedo, mesh, counters
//   map_upload.cpp     maps handed over by the caller -> persistent device images through the staging ring
//   pipelines.cpp      descriptor and pipeline layouts, render pass, samplers, pipelines, pipeline cache
//   frame.cpp          one frame: validate, bind, record, submit, read back what was asked
//   reference_mesh.cpp the reference's tessellation (CPU only, render/mesh.h)
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstring>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "render/mesh.h"
#include "render/render.h"
#include "vulkan/compute.h"
#include "vulkan/device_maps.h"
#include "vulkan/frames.h"

namespace displace::render {

// the Vulkan base (vulkan/) by the names render/ has always used
using vulkan::Buffer;
using vulkan::compute_barrier;
using vulkan::ComputeKernel;
using vulkan::cone_format;
using vulkan::cone_layer_count;
using vulkan::cone_texel_bytes;
using vulkan::Context;
using vulkan::DeviceConeImage;
using vulkan::DeviceHeightImages;
using vulkan::DeviceLevelImages;
using vulkan::host_read_barrier;
using vulkan::Image;
using vulkan::image_barrier;
using vulkan::level_atlas_origin;
using vulkan::level_atlas_size;
using vulkan::Owned;
using vulkan::OwnedDescriptorPool;
using vulkan::OwnedDescriptorSetLayout;
using vulkan::OwnedFence;
using vulkan::OwnedFramebuffer;
using vulkan::OwnedPipeline;
using vulkan::OwnedPipelineLayout;
using vulkan::OwnedQueryPool;
using vulkan::OwnedRenderPass;
using vulkan::OwnedSampler;
using vulkan::OwnedSemaphore;
using vulkan::OwnedShaderModule;
using vulkan::OwnedSwapchain;
using vulkan::rewrite_barrier;
using vulkan::shader_module;
using vulkan::specialised_shader;
using vulkan::StageTimer;
using vulkan::submit_commands;
using OwnedPipelineCache = Owned<VkPipelineCache, vkDestroyPipelineCache>;
static_assert(frames_in_flight == vulkan::frames_in_flight);

inline constexpr VkFormat color_format = VK_FORMAT_R8G8B8A8_UNORM;
inline constexpr VkFormat hit_format = VK_FORMAT_R32G32B32A32_SFLOAT;
inline constexpr VkFormat counters_format = VK_FORMAT_R32G32_SFLOAT;
inline constexpr VkFormat depth_format = VK_FORMAT_D32_SFLOAT;
inline constexpr std::array<float, 4> background = {0.08f, 0.08f, 0.10f, 1.0f};

// memory.cpp: the items of frame_memory, one kind at a time, for the renderer's own checks
void add_target_memory(std::vector<Allocation>& list, int width, int height);
void add_readback_memory(std::vector<Allocation>& list, int width, int height, unsigned outputs);
void add_frame_vector_memory(std::vector<Allocation>& list, int width, int height, unsigned outputs);
void add_reference_memory(std::vector<Allocation>& list, const View& view, int map_width, int map_height);

// A map kept on the device between frames: made again only when its shape changes.
struct DeviceMap {
  Image image;        // heights, cones, distance
  Buffer buffer;      // the max pyramid
  bool held = false;  // holds the caller's map of `version`
  std::uint64_t version = 0;
  int width = 0, height = 0, layers = 0;  // the shape it was made for
  bake::Address address = bake::Address::wrap;
  int sectors = 0;
  bool relaxed = false;
  bool host_written = false;  // Image::host_written: the host writes it, shaders read it in GENERAL layout
  bool general = false;       // host_written: its move to GENERAL layout is recorded
  VkImageLayout read_layout() const {
    return host_written ? VK_IMAGE_LAYOUT_GENERAL : VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL;
  }
};

// The renderer's own part of a frame in flight (vulkan::Frames holds its command buffers and fence):
// its descriptor set, uniforms, staging part of the ring, and readback buffers. A slot is reused once
// its frame finished.
struct FrameSlot {
  VkDescriptorSet descriptor_set = VK_NULL_HANDLE;
  Buffer uniforms;
  Buffer staging;
  VkDeviceSize staging_used = 0;
  Buffer color_readback, hit_readback, counters_readback;  // made when first asked for, per target size
  int readback_width = 0, readback_height = 0;
};

struct Targets {
  int width = 0, height = 0;
  Image color, hit, counters, depth;
  OwnedFramebuffer framebuffer;
};

struct Renderer::Impl {
  explicit Impl(const RendererOptions& options)
      : frames(vulkan::DeviceOptions{options.device, options.validate, options.instance_extensions,
                                     options.can_present, options.async_compute}),
        context(frames.context()),
        memory_limit(options.memory_limit),
        memory_limit_source(options.memory_limit_source),
        host_written_maps(options.host_written_maps) {}

  vulkan::Frames frames;  // the device and its frames in flight, shared with the device stages
  Context& context;
  std::uint64_t memory_limit = 0;  // RendererOptions::memory_limit
  std::string memory_limit_source;
  bool host_written_maps = true;  // RendererOptions::host_written_maps
  MemoryLimits memory_limits() const { return context.memory_limits(memory_limit, memory_limit_source); }

  // pipelines.cpp
  OwnedDescriptorSetLayout set_layout;
  OwnedPipelineLayout pipeline_layout;
  OwnedDescriptorPool descriptor_pool;
  OwnedRenderPass render_pass;
  // the plane's vertex shaders; the specialised ones (the fragment shaders, the quadrics' and meshes'
  // vertex shaders) are made per pipeline (specialised_shader)
  OwnedShaderModule relief_vertex, reference_vertex;
  OwnedSampler linear_wrap, linear_clamp, nearest_wrap, nearest_clamp;
  OwnedSampler linear_wrap_u, nearest_wrap_u;  // quadrics with Address::clamp: u wraps, v clamps
  // by (shader id * 8 + surface id) * 128 + features (config.h, FEATURE_FLAGS)
  std::map<int, OwnedPipeline> pipelines;
  std::string pipeline_cache_file;  // empty: the cache is off
  OwnedPipelineCache pipeline_cache;
  long long pipelines_created = 0;
  void create_layouts();
  void create_render_pass();
  void load_pipeline_cache(const std::string& directory);
  void save_pipeline_cache() noexcept;
  // the pipeline of a method on a surface with the features (FEATURE_FLAGS) its view uses
  VkPipeline pipeline(const MethodInfo& info, Surface surface, int features);

  // renderer.cpp: per-frame slots and set-up resources
  OwnedQueryPool timestamps;  // 2 per slot
  std::array<FrameSlot, frames_in_flight> slots;
  Image dummy_cones, dummy_albedo, dummy_distance, dummy_foam;
  Buffer dummy_pyramid;
  Image albedo_image;
  bool has_albedo = false;
  void create_frame_slots();
  // The current slot, recording (frames.begin(): waits for its previous frame).
  FrameSlot& begin_slot();
  void submit_slot(bool wait) { frames.submit(wait); }  // ends, submits the current slot; moves on
  void drain() { frames.drain(); }                      // submits what is recorded, waits for every slot
  Image upload_image_now(VkFormat format, int width, int height, int layers, VkImageViewType view_type,
                         const void* data, std::size_t bytes);
  template <typename T>
  Buffer host_buffer(const std::vector<T>& data, VkBufferUsageFlags usage);

  // map_upload.cpp
  int map_width = 0, map_height = 0;
  DeviceMap heights;
  std::array<DeviceMap, 3> cones;  // by cone_slot
  DeviceMap max_pyramid;
  DeviceMap distance;
  DeviceMap foam;
  // the levels of detail (MapSet::levels): heights and cones of levels 1 .. level_count in one atlas
  // each (config.h, BINDING_HEIGHT_LEVELS); `sectors` and `address` on level_cones
  DeviceMap level_heights, level_cones;
  int level_count = 0;                                      // levels held (0: none)
  std::array<float, bake::max_detail_levels> level_tops{};  // each level's highest height
  // the device stages' maps the last MapSet named (device.h; null: the host's maps above)
  std::shared_ptr<const DeviceHeightImages> device_heights;
  std::array<std::shared_ptr<const DeviceConeImage>, 3> device_cones;  // by cone_slot
  std::shared_ptr<const DeviceLevelImages> device_levels;
  std::vector<VkBufferImageCopy> copy_regions;  // reused: cleared, never shrunk
  void take_maps(const MapSet& maps);
  void check_map_memory(const MapSet& maps) const;  // before any map is made again
  void require_maps(const MapNeeds& needs, const MethodInfo& info) const;
  void check_device_maps_alive() const;  // the device stages the last MapSet named are not gone
  // The coarser levels a frame of this view and method traces: the levels held when it traces levels
  // (traces_levels) with cones of its sector count on the host's heights, else 0 (level 0 only).
  int traced_levels(const View& view, const MethodInfo& info) const;

  // frame.cpp: render targets and the reference geometry
  Targets targets;
  Buffer reference_vertices, reference_indices;
  std::uint32_t reference_index_count = 0;
  std::array<int, 3> reference_key{0, 0, 0};  // tile, map width, map height
  std::vector<MeshVertex> mesh_cpu;
  std::vector<std::uint32_t> mesh_triangles;
  glm::dvec3 mesh_lo{0.0}, mesh_hi{0.0};
  Buffer mesh_vertices, mesh_indices;
  std::uint32_t mesh_index_count = 0;
  Buffer mesh_reference_vertices, mesh_reference_indices;
  std::uint32_t mesh_reference_index_count = 0;
  std::array<int, 3> mesh_reference_key{0, 0, 0};  // tile, map width, map height
  // before a frame allocates anything (targets, readback, tessellation, the caller's Frame)
  void check_frame_memory(const View& view, const MethodInfo& info, const Frame& frame,
                          unsigned outputs) const;
  void ensure_targets(int width, int height);
  void ensure_reference(int tile);
  void ensure_mesh_reference(int tile);
  // one frame (render), by its stages: validate, write the uniforms and descriptors, record, read back
  void validate_frame(const View& view, const MethodSettings& method, unsigned outputs) const;
  // FrameUniforms::counts.z of a frame of this view (config.h's FLAG_*)
  int frame_flags(const View& view) const;
  void write_uniforms(FrameSlot& frame_slot, const View& view, const MethodSettings& method,
                      const MethodInfo& info) const;
  void write_descriptors(FrameSlot& frame_slot, const View& view, const MethodInfo& info);
  void ensure_readbacks(FrameSlot& frame_slot, int width, int height, unsigned outputs);
  // levels_pipeline, sky_pipeline: the coarser levels' and the sky's passes of a view that traces
  // levels (config.h), else null
  void record_frame(FrameSlot& frame_slot, int slot_index, const View& view, const MethodInfo& info,
                    VkPipeline pipeline_handle, VkPipeline levels_pipeline, VkPipeline sky_pipeline,
                    unsigned outputs);
  void read_back(const FrameSlot& frame_slot, int slot_index, unsigned outputs, Frame& frame) const;
  void render(const View& view, const MethodSettings& method, Frame& frame, unsigned outputs);
};

template <typename T>
Buffer Renderer::Impl::host_buffer(const std::vector<T>& data, VkBufferUsageFlags usage) {
  const VkMemoryPropertyFlags host =
      VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
  Buffer buffer(context, std::max<std::size_t>(data.size() * sizeof(T), 4), usage, host);
  std::memcpy(buffer.mapped(), data.data(), data.size() * sizeof(T));
  return buffer;
}

}  // namespace displace::render
