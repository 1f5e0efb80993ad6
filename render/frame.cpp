// render/frame.cpp - one frame: validate the view -> check the method's maps were given -> check
// that what the frame allocates fits (memory.cpp) -> the pipeline (made once) and, for `reference`,
// the tessellation -> frame uniforms and the slot's descriptor set -> record the draw and the copies
// of the outputs asked for -> submit (and wait only when something is read back) -> read back into
// the caller's Frame.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <string>

#include "render/pass_rows.h"
#include "render/quadric.h"
#include "render/renderer_impl.h"
#include "render/shaders/config.h"

namespace displace::render {

void Renderer::Impl::ensure_targets(int width, int height) {
  if (targets.width == width && targets.height == height) return;
  drain();  // frames in flight draw into the old targets
  targets = Targets{};
  const auto w = std::uint32_t(width), h = std::uint32_t(height);
  const VkImageUsageFlags color_usage = VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT;
  targets.color =
      Image(context, color_format, w, h, 1, color_usage, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_VIEW_TYPE_2D);
  targets.hit =
      Image(context, hit_format, w, h, 1, color_usage, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_VIEW_TYPE_2D);
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
  targets.width = width;
  targets.height = height;
}

void Renderer::Impl::ensure_reference(int tile) {
  const std::array<int, 3> key{tile, map_width, map_height};
  if (reference_key == key && reference_vertices.handle()) return;
  drain();  // an earlier frame may draw the old tessellation
  const PlaneReference reference = plane_reference(map_width, map_height, tile);
  reference_vertices = host_buffer(reference.uv, VK_BUFFER_USAGE_VERTEX_BUFFER_BIT);
  reference_indices = host_buffer(reference.indices, VK_BUFFER_USAGE_INDEX_BUFFER_BIT);
  reference_index_count = std::uint32_t(reference.indices.size());
  reference_key = key;
}

void Renderer::Impl::ensure_mesh_reference(int tile) {
  const std::array<int, 3> key{tile, map_width, map_height};
  if (mesh_reference_key == key && mesh_reference_vertices.handle()) return;
  drain();
  const MeshReference reference = mesh_reference(mesh_cpu, mesh_triangles, map_width, map_height, tile);
  mesh_reference_vertices = host_buffer(reference.vertices, VK_BUFFER_USAGE_VERTEX_BUFFER_BIT);
  mesh_reference_indices = host_buffer(reference.indices, VK_BUFFER_USAGE_INDEX_BUFFER_BIT);
  mesh_reference_index_count = std::uint32_t(reference.indices.size());
  mesh_reference_key = key;
}

void Renderer::Impl::write_descriptors(FrameSlot& frame_slot, const View& view, const MethodInfo& info) {
  const bool wrap = view.address == bake::Address::wrap;
  const bool quadric = is_quadric(view.surface);
  const std::size_t cone_index = info.cone_sectors > 0 ? std::size_t(cone_slot(info.cone_sectors)) : 0;
  const bool device_cone_map = info.cone_sectors > 0 && device_cones[cone_index];
  const VkImageView cone_view = device_cone_map         ? device_cones[cone_index]->image->view()
                                : info.cone_sectors > 0 ? cones[cone_index].image.view()
                                                        : dummy_cones.view();
  const VkBuffer pyramid_buffer =
      info.family == MethodFamily::pyramid ? max_pyramid.buffer.handle() : dummy_pyramid.handle();
  const VkImageView distance_view =
      info.family == MethodFamily::distance ? distance.image.view() : dummy_distance.view();
  const VkDescriptorBufferInfo uniform_info{frame_slot.uniforms.handle(), 0, sizeof(gpu::FrameUniforms)};
  const VkSampler linear = wrap ? linear_wrap.get() : (quadric ? linear_wrap_u.get() : linear_clamp.get());
  const VkSampler nearest =
      wrap ? nearest_wrap.get() : (quadric ? nearest_wrap_u.get() : nearest_clamp.get());
  const VkDescriptorImageInfo height_info =
      device_heights ? VkDescriptorImageInfo{linear, device_heights->heights->view(), VK_IMAGE_LAYOUT_GENERAL}
                     : VkDescriptorImageInfo{linear, heights.image.view(), heights.read_layout()};
  const VkDescriptorImageInfo cone_info{nearest, cone_view,
                                        device_cone_map         ? VK_IMAGE_LAYOUT_GENERAL
                                        : info.cone_sectors > 0 ? cones[cone_index].read_layout()
                                                                : VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
  const VkDescriptorImageInfo albedo_info{linear, has_albedo ? albedo_image.view() : dummy_albedo.view(),
                                          VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
  const VkDescriptorBufferInfo pyramid_info{pyramid_buffer, 0, VK_WHOLE_SIZE};
  const VkDescriptorImageInfo distance_info{wrap ? linear_wrap.get() : linear_clamp.get(), distance_view,
                                            VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
  const VkDescriptorImageInfo foam_info =
      device_heights && device_heights->foam
          ? VkDescriptorImageInfo{linear, device_heights->foam->view(), VK_IMAGE_LAYOUT_GENERAL}
          : VkDescriptorImageInfo{linear, foam.held ? foam.image.view() : dummy_foam.view(),
                                  foam.held ? foam.read_layout() : VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
  const bool levels = traced_levels(view, info) > 0;
  VkDescriptorImageInfo level_height_info{nearest, dummy_foam.view(),
                                          VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
  VkDescriptorImageInfo level_cone_info{nearest, dummy_cones.view(),
                                        VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
  if (levels && device_levels) {  // a DeviceLevels' atlases (device.h)
    level_height_info = {nearest, device_levels->heights->view(), VK_IMAGE_LAYOUT_GENERAL};
    level_cone_info = {nearest, device_levels->cones->view(), VK_IMAGE_LAYOUT_GENERAL};
  } else if (levels) {
    level_height_info = {nearest, level_heights.image.view(), level_heights.read_layout()};
    level_cone_info = {nearest, level_cones.image.view(), level_cones.read_layout()};
  }
  auto write = [&](std::uint32_t binding, VkDescriptorType type, const VkDescriptorImageInfo* image,
                   const VkDescriptorBufferInfo* buffer) {
    VkWriteDescriptorSet w{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
    w.dstSet = frame_slot.descriptor_set;
    w.dstBinding = binding;
    w.descriptorCount = 1;
    w.descriptorType = type;
    w.pImageInfo = image;
    w.pBufferInfo = buffer;
    return w;
  };
  constexpr VkDescriptorType sampled = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
  const std::array<VkWriteDescriptorSet, 9> writes = {
      write(BINDING_FRAME, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, nullptr, &uniform_info),
      write(BINDING_HEIGHT, sampled, &height_info, nullptr),
      write(BINDING_CONES, sampled, &cone_info, nullptr),
      write(BINDING_MAX_PYRAMID, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, nullptr, &pyramid_info),
      write(BINDING_ALBEDO, sampled, &albedo_info, nullptr),
      write(BINDING_DISTANCE, sampled, &distance_info, nullptr),
      write(BINDING_FOAM, sampled, &foam_info, nullptr),
      write(BINDING_HEIGHT_LEVELS, sampled, &level_height_info, nullptr),
      write(BINDING_CONE_LEVELS, sampled, &level_cone_info, nullptr)};
  vkUpdateDescriptorSets(context.device(), std::uint32_t(writes.size()), writes.data(), 0, nullptr);
}

namespace {

// The background: the sky's horizon over water, else the grid's dark grey.
std::array<float, 4> clear_colour(const View& view) {
  return view.material == Material::water
             ? std::array<float, 4>{float(SKY_HORIZON_R), float(SKY_HORIZON_G), float(SKY_HORIZON_B), 1.0f}
             : background;
}

std::string limits_text(const char* field, double low, double high, const char* unit) {
  char text[160];
  std::snprintf(text, sizeof text, "%s must be between %g and %g%s", field, low, high, unit);
  return text;
}

// the level every pixel traces (FrameUniforms::levels.y), or -1 where each pixel chooses its own
int pinned_level(const View& view, int levels) {
  return view.level == View::level_auto ? -1 : std::min(std::max(view.level, 0), levels);
}

}  // namespace

void Renderer::Impl::validate_frame(const View& view, const MethodSettings& method, unsigned outputs) const {
  view.camera.validate();
  if (view.tile < 1 || view.tile > max_tile)
    throw RenderError("View::tile must be between 1 and " + std::to_string(max_tile));
  if (view.tile > 1 && view.address != bake::Address::wrap)
    throw RenderError("View::tile above 1 needs View::address = Address::wrap");
  if (view.unbounded && (view.surface != Surface::plane || view.address != bake::Address::wrap ||
                         method.method == Method::reference)) {
    throw RenderError(
        "View::unbounded tiles the plane with Address::wrap, for a method other than the reference");
  }
  if (!(view.depth_scale >= min_depth_scale && view.depth_scale <= max_depth_scale)) {
    throw RenderError(
        limits_text("View::depth_scale", double(min_depth_scale), double(max_depth_scale), " world units"));
  }
  if (!std::isfinite(view.light_direction.x) || !std::isfinite(view.light_direction.y) ||
      !std::isfinite(view.light_direction.z) || glm::length(view.light_direction) < 1e-6f) {
    throw RenderError("View::light_direction must be finite and non-zero");
  }
  const glm::vec3 foam_colour = view.foam_color;
  if (!(foam_colour.r >= 0.0f && foam_colour.r <= 1.0f && foam_colour.g >= 0.0f && foam_colour.g <= 1.0f &&
        foam_colour.b >= 0.0f && foam_colour.b <= 1.0f && view.foam_intensity >= 0.0f &&
        view.foam_intensity <= 1.0f)) {
    throw RenderError("View::foam_color and View::foam_intensity must be in [0, 1]");
  }
  if (method.steps < 1 || method.steps > max_steps)
    throw RenderError("MethodSettings::steps must be between 1 and " + std::to_string(max_steps));
  if (method.refine < 0 || method.refine > max_refine)
    throw RenderError("MethodSettings::refine must be between 0 and " + std::to_string(max_refine));
  if (outputs > output_all) throw RenderError("render: unknown outputs requested");
  if (view.surface == Surface::mesh && mesh_index_count == 0)
    throw RenderError("View::surface mesh: no mesh was set (Renderer::set_mesh)");
  if (!supports_surface(method.method, view.surface)) {
    std::string supported;
    for (const MethodInfo& other : method_table()) {
      if (!supports_surface(other.method, view.surface)) continue;
      supported += (supported.empty() ? "" : ", ") + std::string(other.name);
    }
    throw RenderError(std::string("MethodSettings::method ") + method_info(method.method).name +
                      " does not support View::surface " + surface_name(view.surface) +
                      " (methods there: " + supported + ")");
  }
  if (is_quadric(view.surface)) quadric::validate(view);
}

int Renderer::Impl::frame_flags(const View& view) const {
  const bool water = view.material == Material::water;
  return (view.address == bake::Address::wrap ? FLAG_WRAP : 0) | (view.shadows ? FLAG_SHADOWS : 0) |
         (has_albedo ? FLAG_ALBEDO : 0) | (water ? FLAG_WATER : 0) |
         (water && (foam.held || (device_heights && device_heights->foam)) ? FLAG_FOAM : 0) |
         (view.unbounded ? FLAG_UNBOUNDED : 0);
}

// near and far planes enclose the relief box ([0,1]^2 x [-D, 0] on the plane)
void Renderer::Impl::write_uniforms(FrameSlot& frame_slot, const View& view, const MethodSettings& method,
                                    const MethodInfo& info) const {
  const Camera& camera = view.camera;
  const bool quadric = is_quadric(view.surface);
  glm::dvec3 box_lo(0.0, 0.0, -double(view.depth_scale)), box_hi(1.0, 1.0, 0.0);
  if (quadric) quadric::relief_box(quadric::shape_of(view), box_lo, box_hi);
  if (view.surface == Surface::mesh) {
    box_lo = mesh_lo - glm::dvec3(view.depth_scale);
    box_hi = mesh_hi + glm::dvec3(view.depth_scale);
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
  // a weight step above 1/16 (a device reporting fewer than the 4 bits Vulkan requires) counts as 1/16
  const int sub_texel_bits = std::max(context.info().sub_texel_precision_bits, 4);
  uniforms.surface = glm::vec4(float(view.tile), view.depth_scale, 1.0f / float(view.tile),
                               std::ldexp(1.0f, -sub_texel_bits));
  uniforms.map_size =
      glm::vec4(float(map_width), float(map_height), 1.0f / float(map_width), 1.0f / float(map_height));
  uniforms.counts = glm::ivec4(method.steps, method.refine, frame_flags(view), info.cone_sectors);
  const std::array<float, 4> clear = clear_colour(view);
  uniforms.background = glm::vec4(clear[0], clear[1], clear[2], clear[3]);
  uniforms.quadric = glm::vec4(quadric ? view.radius : 0.0f, 0.0f, 0.0f, 0.0f);
  uniforms.foam = glm::vec4(view.foam_color, view.foam_intensity);
  const Camera::PixelRays rays = camera.pixel_rays();
  uniforms.ray_corner = glm::vec4(glm::vec3(rays.corner), 0.0f);
  uniforms.ray_along_x = glm::vec4(glm::vec3(rays.along_x), 0.0f);
  uniforms.ray_along_y = glm::vec4(glm::vec3(rays.along_y), 0.0f);
  const int levels = traced_levels(view, info);
  const int pinned = pinned_level(view, levels);
  uniforms.levels = glm::vec4(float(levels), float(pinned), 0.0f, 0.0f);
  for (int level = 1; level <= levels; ++level)
    uniforms.level_tops[(level - 1) / 4][(level - 1) % 4] = level_tops[std::size_t(level - 1)];
  std::memcpy(frame_slot.uniforms.mapped(), &uniforms, sizeof uniforms);
}

// readback buffers of the outputs asked for (made per target size; the slot's frame has finished)
void Renderer::Impl::ensure_readbacks(FrameSlot& frame_slot, int width, int height, unsigned outputs) {
  const VkDeviceSize pixels = VkDeviceSize(std::uint32_t(width)) * std::uint32_t(height);
  if (frame_slot.readback_width != width || frame_slot.readback_height != height) {
    frame_slot.color_readback = Buffer{};
    frame_slot.hit_readback = Buffer{};
    frame_slot.counters_readback = Buffer{};
    frame_slot.readback_width = width;
    frame_slot.readback_height = height;
  }
  const VkMemoryPropertyFlags host =
      VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
  auto ensure_readback = [&](Buffer& buffer, VkDeviceSize bytes) {
    if (!buffer.handle()) buffer = Buffer(context, bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT, host);
  };
  if (outputs & output_color) ensure_readback(frame_slot.color_readback, pixels * 4);
  if (outputs & (output_uv | output_depth)) ensure_readback(frame_slot.hit_readback, pixels * 16);
  if (outputs & (output_iterations | output_fetches))
    ensure_readback(frame_slot.counters_readback, pixels * 8);
}

// the draw between two timestamps, then the copies of the outputs asked for
void Renderer::Impl::record_frame(FrameSlot& frame_slot, int slot_index, const View& view,
                                  const MethodInfo& info, VkPipeline pipeline_handle,
                                  VkPipeline levels_pipeline, VkPipeline sky_pipeline, unsigned outputs) {
  const auto width = std::uint32_t(view.camera.width), height = std::uint32_t(view.camera.height);
  const bool mesh = view.surface == Surface::mesh;
  const bool reference = info.family == MethodFamily::reference;
  const VkCommandBuffer commands = frames.begin();  // recording since begin_slot
  const VkQueryPool queries = timestamps.get();
  const auto first_query = std::uint32_t(2 * slot_index);
  if (queries) vkCmdResetQueryPool(commands, queries, first_query, 2);
  const std::array<float, 4> clear_color = clear_colour(view);
  std::array<VkClearValue, 4> clears{};
  std::memcpy(clears[0].color.float32, clear_color.data(), sizeof(float) * 4);
  clears[3].depthStencil = {1.0f, 0};
  VkRenderPassBeginInfo begin{VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO};
  begin.renderPass = render_pass.get();
  begin.framebuffer = targets.framebuffer.get();
  begin.renderArea = {{0, 0}, {width, height}};
  begin.clearValueCount = std::uint32_t(clears.size());
  begin.pClearValues = clears.data();
  if (queries) vkCmdWriteTimestamp(commands, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, queries, first_query);
  if (device_levels && traced_levels(view, info) > 0) {
    // the levels' highest heights, made on the device: over the host's values in the uniforms
    const VkBufferCopy tops{0, offsetof(gpu::FrameUniforms, level_tops),
                            sizeof(gpu::FrameUniforms::level_tops)};
    vkCmdCopyBuffer(commands, device_levels->tops, frame_slot.uniforms.handle(), 1, &tops);
    VkMemoryBarrier barrier{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    barrier.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
    barrier.dstAccessMask = VK_ACCESS_SHADER_READ_BIT;
    vkCmdPipelineBarrier(commands, VK_PIPELINE_STAGE_TRANSFER_BIT,
                         VK_PIPELINE_STAGE_VERTEX_SHADER_BIT | VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT, 0, 1,
                         &barrier, 0, nullptr, 0, nullptr);
  }
  vkCmdBeginRenderPass(commands, &begin, VK_SUBPASS_CONTENTS_INLINE);
  vkCmdBindPipeline(commands, VK_PIPELINE_BIND_POINT_GRAPHICS, pipeline_handle);
  const VkViewport viewport{0.0f, 0.0f, float(width), float(height), 0.0f, 1.0f};
  const VkRect2D scissor{{0, 0}, {width, height}};
  vkCmdSetViewport(commands, 0, 1, &viewport);
  vkCmdSetScissor(commands, 0, 1, &scissor);
  vkCmdBindDescriptorSets(commands, VK_PIPELINE_BIND_POINT_GRAPHICS, pipeline_layout.get(), 0, 1,
                          &frame_slot.descriptor_set, 0, nullptr);
  const VkDeviceSize offset = 0;
  if (mesh) {
    const VkBuffer vertex_buffer = reference ? mesh_reference_vertices.handle() : mesh_vertices.handle();
    vkCmdBindVertexBuffers(commands, 0, 1, &vertex_buffer, &offset);
    vkCmdBindIndexBuffer(commands, reference ? mesh_reference_indices.handle() : mesh_indices.handle(), 0,
                         VK_INDEX_TYPE_UINT32);
    vkCmdDrawIndexed(commands, reference ? mesh_reference_index_count : mesh_index_count, 1, 0, 0, 0);
  } else if (reference) {
    const VkBuffer vertex_buffer = reference_vertices.handle();
    vkCmdBindVertexBuffers(commands, 0, 1, &vertex_buffer, &offset);
    vkCmdBindIndexBuffer(commands, reference_indices.handle(), 0, VK_INDEX_TYPE_UINT32);
    vkCmdDrawIndexed(commands, reference_index_count, 1, 0, 0, 0);
  } else {
    // the proxy box, or the plane's two triangles
    if (!levels_pipeline) {
      vkCmdDraw(commands, is_quadric(view.surface) ? 36 : 6, 1, 0, 0);
    } else {
      // the plane three times, for the pixels of level 0, of the coarser levels and of the sky, each
      // pass over the rows where it has pixels (pass_rows.h)
      const int levels = traced_levels(view, info);
      const detail::PassRows rows =
          detail::level_pass_rows(view.camera, levels, pinned_level(view, levels),
                                  double(view.tile) * double(std::max(map_width, map_height)));
      const auto draw_rows = [&](detail::RowRange range) {
        if (range.empty()) return;
        const VkRect2D band{{0, range.begin}, {width, std::uint32_t(range.end - range.begin)}};
        vkCmdSetScissor(commands, 0, 1, &band);
        vkCmdDraw(commands, 6, 1, 0, 0);
      };
      draw_rows(rows.level_zero);
      vkCmdBindPipeline(commands, VK_PIPELINE_BIND_POINT_GRAPHICS, levels_pipeline);
      draw_rows(rows.coarser);
      if (!rows.sky.empty()) {
        vkCmdBindPipeline(commands, VK_PIPELINE_BIND_POINT_GRAPHICS, sky_pipeline);
        draw_rows(rows.sky);
      }
    }
  }
  vkCmdEndRenderPass(commands);
  if (queries) vkCmdWriteTimestamp(commands, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, queries, first_query + 1);
  VkBufferImageCopy region{};
  region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
  region.imageExtent = {width, height, 1};
  if (outputs & output_color) {
    vkCmdCopyImageToBuffer(commands, targets.color.handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                           frame_slot.color_readback.handle(), 1, &region);
  }
  if (outputs & (output_uv | output_depth)) {
    vkCmdCopyImageToBuffer(commands, targets.hit.handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                           frame_slot.hit_readback.handle(), 1, &region);
  }
  if (outputs & (output_iterations | output_fetches)) {
    vkCmdCopyImageToBuffer(commands, targets.counters.handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                           frame_slot.counters_readback.handle(), 1, &region);
  }
  if (outputs != output_none) {
    VkMemoryBarrier to_host{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    to_host.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
    to_host.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
    vkCmdPipelineBarrier(commands, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &to_host,
                         0, nullptr, 0, nullptr);
  }
}

// the caller's Frame from the slot's readback buffers (vectors keep their capacity)
void Renderer::Impl::read_back(const FrameSlot& frame_slot, int slot_index, unsigned outputs,
                               Frame& frame) const {
  const std::size_t pixels = std::size_t(std::uint32_t(frame.width)) * std::uint32_t(frame.height);
  auto keep = [](auto& values, bool wanted, std::size_t size) {
    if (wanted) {
      values.resize(size);
    } else {
      values.clear();
    }
  };
  keep(frame.color, outputs & output_color, pixels * 4);
  keep(frame.uv, outputs & output_uv, pixels * 3);
  keep(frame.depth, outputs & output_depth, pixels);
  keep(frame.iterations, outputs & output_iterations, pixels);
  keep(frame.fetches, outputs & output_fetches, pixels);
  if (outputs == output_none) return;
  if (outputs & output_color) std::memcpy(frame.color.data(), frame_slot.color_readback.mapped(), pixels * 4);
  if (outputs & (output_uv | output_depth)) {
    const auto* hit = static_cast<const float*>(frame_slot.hit_readback.mapped());
    const bool uv = outputs & output_uv, depth = outputs & output_depth;
    for (std::size_t p = 0; p < pixels; ++p) {
      if (uv) {
        frame.uv[p * 3 + 0] = hit[p * 4 + 0];
        frame.uv[p * 3 + 1] = hit[p * 4 + 1];
        frame.uv[p * 3 + 2] = hit[p * 4 + 2];
      }
      if (depth) frame.depth[p] = hit[p * 4 + 3];
    }
  }
  if (outputs & (output_iterations | output_fetches)) {
    const auto* counters = static_cast<const float*>(frame_slot.counters_readback.mapped());
    const bool iterations = outputs & output_iterations, fetches = outputs & output_fetches;
    for (std::size_t p = 0; p < pixels; ++p) {
      if (iterations) frame.iterations[p] = counters[p * 2 + 0];
      if (fetches) frame.fetches[p] = counters[p * 2 + 1];
    }
  }
  const VkQueryPool queries = timestamps.get();
  if (queries) {
    const auto first_query = std::uint32_t(2 * slot_index);
    std::array<std::uint64_t, 2> ticks{};
    if (vkGetQueryPoolResults(context.device(), queries, first_query, 2, sizeof ticks, ticks.data(),
                              sizeof(std::uint64_t), VK_QUERY_RESULT_64_BIT) == VK_SUCCESS) {
      frame.gpu_milliseconds = double(ticks[1] - ticks[0]) * context.timestamp_period_ns() * 1e-6;
    }
  }
}

void Renderer::Impl::render(const View& view, const MethodSettings& method, Frame& frame, unsigned outputs) {
  if (!heights.held && !device_heights)
    throw RenderError("render: no height map was given (Renderer::set_maps)");
  validate_frame(view, method, outputs);
  const MethodInfo& info = method_info(method.method);
  require_maps(map_needs(method.method, view), info);
  check_frame_memory(view, info, frame, outputs);

  // pipeline, geometry, targets (made once per key; each may wait for the frames in flight)
  const int features = frame_flags(view) & FEATURE_FLAGS;
  const VkPipeline pipeline_handle = pipeline(info, view.surface, features);
  // a view that traces levels of detail draws the pixels of the coarser levels and those of the sky with
  // pipelines of their own (config.h, FLAG_LEVELS, FLAG_SKY)
  const bool levels = traced_levels(view, info) > 0;
  const VkPipeline levels_handle =
      levels ? pipeline(info, view.surface, features | FLAG_LEVELS) : VK_NULL_HANDLE;
  const VkPipeline sky_handle =
      levels ? pipeline(info, view.surface, features | FLAG_LEVELS | FLAG_SKY) : VK_NULL_HANDLE;
  if (info.family == MethodFamily::reference) {
    if (view.surface == Surface::mesh) {
      ensure_mesh_reference(view.tile);
    } else {
      ensure_reference(view.tile);
    }
  }
  ensure_targets(view.camera.width, view.camera.height);

  FrameSlot& frame_slot = begin_slot();
  const int slot_index = frames.slot();
  write_uniforms(frame_slot, view, method, info);
  write_descriptors(frame_slot, view, info);
  ensure_readbacks(frame_slot, view.camera.width, view.camera.height, outputs);
  record_frame(frame_slot, slot_index, view, info, pipeline_handle, levels_handle, sky_handle, outputs);
  submit_slot(outputs != output_none);  // waits only for a frame that is read back
  frame.width = view.camera.width;
  frame.height = view.camera.height;
  frame.gpu_milliseconds = 0.0;
  read_back(frame_slot, slot_index, outputs, frame);
}

}  // namespace displace::render
