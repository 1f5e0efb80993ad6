// render/shaders/frame_block.inc.glsl - the frame's FrameUniforms (config.h) at BINDING_FRAME, for
// every stage. A read-only storage buffer and not a uniform block, because of lavapipe in Mesa 22.3
// (Debian 12's): it "inlines" uniform-block values that feed branches and loop bounds (steps,
// refine, flags) and compiles the shader again with LLVM every time a command buffer binds the
// pipeline, caching no variant and freeing none (lvp_execute.c, update_inline_shader_state; later
// Mesa keeps the variants in a set and inlines push constants only). Each frame then paid a JIT
// compile and kept its 0.6-2 MB for good. Storage-buffer loads are never inlined. std430 lays the
// block out as std140 does: every member is a vec4, ivec4 or mat4.
layout(std430, binding = BINDING_FRAME) readonly buffer FrameBlock { FrameUniforms frame; };
