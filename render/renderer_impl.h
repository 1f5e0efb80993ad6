// render/renderer_impl.h - what the renderer's files share (internal to render/): the state behind
// Renderer, split by job across
//   renderer.cpp       the renderer object: device, per-frame slots, albedo, mesh, counters
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

#include "render/compute.h"
#include "render/device.h"
#include "render/mesh.h"
#include "render/render.h"
#include "render/vulkan_context.h"

namespace displace::render {

using OwnedFence = Owned<VkFence, vkDestroyFence>;
using OwnedPipelineCache = Owned<VkPipelineCache, vkDestroyPipelineCache>;

inline constexpr VkFormat color_format = VK_FORMAT_R8G8B8A8_UNORM;
inline constexpr VkFormat hit_format = VK_FORMAT_R32G32B32A32_SFLOAT;
inline constexpr VkFormat counters_format = VK_FORMAT_R32G32_SFLOAT;
inline constexpr VkFormat depth_format = VK_FORMAT_D32_SFLOAT;
inline constexpr std::array<float, 4> background = {0.08f, 0.08f, 0.10f, 1.0f};

// Layers of the cone image (BINDING_CONES, cone_format): layer k < n holds (r_k, H_c); with n > 1 sectors
// layer n holds (min over k of r_k, H_c), the isotropic bound the quadric cone march needs near a
// step's start; with relaxed ratios one more layer holds (relaxed ratio, H_c).
inline int cone_layer_count(int sectors, bool relaxed) {
  return (sectors > 1 ? sectors + 1 : 1) + (relaxed ? 1 : 0);
}
// The cone image: per layer and texel (the ratio as a half float rounded down, the apex in 1 / 65535
// rounded up) in 16 bits each (map_pack.h), read back by the shaders' cone_value
constexpr VkFormat cone_format = VK_FORMAT_R16G16_UINT;
constexpr std::size_t cone_texel_bytes = 4;

// The levels of detail's atlases (shaders/config.h): level 1 from (0, 0), level l >= 2 from
// (W / 2, H / 2 - (H >> (l - 1))), (W / 2 + W / 4) x (H / 2) texels in all (W / 2 wide with one level).
inline glm::ivec2 level_atlas_origin(int width, int height, int level) {
  return level == 1 ? glm::ivec2(0) : glm::ivec2(width / 2, height / 2 - (height >> (level - 1)));
}
inline glm::ivec2 level_atlas_size(int width, int height, int level_count) {
  return {width / 2 + (level_count >= 2 ? width / 4 : 0), height / 2};
}

// device_cones.cpp, for DeviceLevels: what it copies from a level's DeviceCones after a bake - the
// cone image (GENERAL layout) and where the max pyramid's top node lies (the largest height, a float).

// memory.cpp: the items of frame_memory, one kind at a time, for the renderer's own checks
void add_target_memory(std::vector<Allocation>& list, int width, int height);
void add_readback_memory(std::vector<Allocation>& list, int width, int height, unsigned outputs);
void add_frame_vector_memory(std::vector<Allocation>& list, int width, int height, unsigned outputs);
void add_reference_memory(std::vector<Allocation>& list, const View& view, int map_width, int map_height);

void image_barrier(VkCommandBuffer commands, VkImage image, std::uint32_t layers, VkImageLayout from,
                   VkImageLayout to, VkAccessFlags src_access, VkAccessFlags dst_access,
                   VkPipelineStageFlags src_stage, VkPipelineStageFlags dst_stage);

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

// Per frame in flight: its command buffer, fence, descriptor set, uniforms, staging part of the
// ring, and readback buffers. A slot is reused once its fence says the frame finished.
struct FrameSlot {
  VkCommandBuffer commands = VK_NULL_HANDLE;  // the one recording (flush_slot swaps in `spare`)
  VkCommandBuffer spare = VK_NULL_HANDLE;
  std::uint64_t flushed = 0;  // the frame_timeline value of this recording's flush_slot (0: none)
  OwnedFence fence;           // signalled: nothing of this slot is in flight
  bool recording = false;     // commands begun (map copies or a frame), not yet submitted
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

// The maps a device stage wrote (map_set.h's handles; device.h): images in the GENERAL layout on this
// renderer's device, each named with the renderer that owns them. A stage clears its images' pointers
// when it goes, so that a stage still holding the handle sees that they are gone.
struct DeviceHeightImages {
  const Renderer::Impl* owner = nullptr;
  const Image* heights = nullptr;
  const Image* foam = nullptr;  // null: no foam
};
struct DeviceConeImage {  // cone_format, a layer per sector
  const Renderer::Impl* owner = nullptr;
  const Image* image = nullptr;
  int width = 0, height = 0, sectors = 0;
  bake::Address address = bake::Address::wrap;
  // the bake's max pyramid and the byte offset of its top (the map's highest height): what
  // DeviceLevels copies into a frame's level tops
  VkBuffer pyramid = VK_NULL_HANDLE;
  VkDeviceSize top_offset = 0;
};
// Atlases laid out as level_heights' and level_cones', and each level's highest height at level_tops'
// place in FrameUniforms (`tops`, 16 floats, copied into a frame's uniforms on the device).
struct DeviceLevelImages {
  const Renderer::Impl* owner = nullptr;
  const Image* heights = nullptr;
  const Image* cones = nullptr;
  VkBuffer tops = VK_NULL_HANDLE;
  int width = 0, height = 0;  // level 0's
  int count = 0, sectors = 0;
  bake::Address address = bake::Address::wrap;
};

struct Renderer::Impl {
  explicit Impl(const RendererOptions& options)
      : context(options),
        memory_limit(options.memory_limit),
        memory_limit_source(options.memory_limit_source),
        host_written_maps(options.host_written_maps) {}

  Context context;
  std::uint64_t memory_limit = 0;  // RendererOptions::memory_limit
  std::string memory_limit_source;
  bool host_written_maps = true;  // RendererOptions::host_written_maps
  bool hold_async_work = false;   // render/testing.h
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
  int slot = 0;  // the slot the next frame records into
  Image dummy_cones, dummy_albedo, dummy_distance, dummy_foam;
  Buffer dummy_pyramid;
  Image albedo_image;
  bool has_albedo = false;
  void create_frame_slots();
  FrameSlot& begin_slot();      // the current slot, recording (waits for its previous frame)
  void submit_slot(bool wait);  // ends, submits the current slot; moves on to the next slot
  void drain();                 // submits what is recorded, waits for every slot
  // Whether the frame last submitted from `slot` has finished (and nothing is being recorded there).
  bool slot_finished(int index) const {
    const FrameSlot& frame_slot = slots[std::size_t(index)];
    return !frame_slot.recording && vkGetFenceStatus(context.device(), frame_slot.fence.get()) == VK_SUCCESS;
  }
  void wait_submitted();  // waits for every frame submitted and every async submission
  // Work beside the frame's (Context::async_queue): a timeline semaphore per queue; every submission
  // of the frame's queue signals the next value of `frame_timeline`, every async one of `async_timeline`.
  OwnedSemaphore frame_timeline, async_timeline;
  std::uint64_t frame_signalled = 0, async_signalled = 0;
  std::uint64_t frame_waits_for = 0;  // the async value the frame queue's next submission waits for
  std::uint64_t frame_waited = 0;     // the largest one a submission waited for already
  // Ends and submits what the current slot recorded so far (no fence: the slot's frame submission
  // still follows) and goes on recording in the slot's other command buffer; returns the
  // frame_timeline value that submission signals.
  std::uint64_t flush_slot();
  // Submits `commands` to the async queue, after the frame queue's value `after_frame` (0: nothing);
  // returns the async_timeline value it signals.
  std::uint64_t submit_async(VkCommandBuffer commands, std::uint64_t after_frame);
  // The frame queue's next submission (and every later one) waits for async `value`.
  void frame_waits_for_async(std::uint64_t value) { frame_waits_for = std::max(frame_waits_for, value); }
  // hold_async_work (render/testing.h) where the async queue is the frame's own: an async submission
  // is held on the host until a frame submission or a host wait needs it (then it and those before
  // it go in), so that it runs as late as a GPU's other queue may run it.
  struct DeferredAsync {
    VkCommandBuffer commands;
    std::uint64_t after_frame, value;
  };
  std::vector<DeferredAsync> deferred_async;  // in submission order
  void release_async(std::uint64_t value);    // submits the deferred ones up to `value`
  bool async_finished(std::uint64_t value) const;
  void wait_async(std::uint64_t value) {  // on the host
    release_async(value);
    wait_timeline(async_timeline.get(), value);
  }
  void wait_timeline(VkSemaphore timeline, std::uint64_t value) const;
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
  std::shared_ptr<struct DeviceConeKernels> cone_kernels;  // device_cones.cpp: compiled once
  std::vector<VkBufferImageCopy> copy_regions;             // reused: cleared, never shrunk
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

// A device stage's milliseconds (StageTimer), the timestamps of its last frame read first when that
// frame has finished.
inline double finished_milliseconds(StageTimer& timer, const Renderer::Impl& impl) {
  if (timer.last_slot() >= 0 && impl.slot_finished(timer.last_slot())) timer.read(timer.last_slot());
  return timer.milliseconds();
}

}  // namespace displace::render
