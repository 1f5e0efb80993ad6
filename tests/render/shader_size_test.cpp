// tests/render/shader_size_test.cpp - the code each specialised pipeline of the surface shader holds
// (render/shaders/surface.frag.glsl, render/pipelines.cpp), counted without a clock.
//
// lavapipe runs both sides of every branch under a lane mask, so a pipeline's cost per pixel grows
// with every instruction it holds, taken or not: code of a feature its view does not use (levels of
// detail, the water material, shadows, the sky) made every frame up to 3.7x slower with no test
// noticing. Here each pipeline's fragment module is specialised as the renderer specialises it
// (METHOD, SURFACE, FEATURES), optimised by SPIRV-Tools as a driver would (constants folded, dead
// branches and functions removed, inlined), and its instructions counted against a stored count: a
// change that makes a pipeline carry more code than it needs fails here, not on a user's frame.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstdio>
#include <set>
#include <span>
#include <spirv-tools/optimizer.hpp>
#include <string>
#include <unordered_map>
#include <vector>

#include "render/render.h"
#include "render/shaders/config.h"
#include "spirv/surface_planar_frag.h"
#include "spirv/surface_quadric_frag.h"

namespace {

using displace::render::Method;

// SPIR-V opcodes read here (the SPIR-V specification, section 3.49)
constexpr std::uint32_t op_variable = 59, op_function = 54, op_function_end = 56, op_decorate = 71,
                        op_image_sample_first = 87, op_image_gather = 96, op_image_fetch = 95, op_label = 248,
                        op_loop_merge = 246, decoration_binding = 33;

struct Counts {
  int instructions = 0;                   // inside functions: what the pipeline executes, taken or not
  int in_loops = 0;                       // of those, inside a loop: what every iteration of a march executes
  int image_reads = 0;                    // OpImageSample*, OpImageFetch, OpImageGather
  std::set<std::uint32_t> bindings_read;  // the descriptor bindings an instruction in a function uses
};

// The fragment module specialised with the three constants and optimised, its instructions counted.
Counts specialised(std::span<const std::uint32_t> module, int method, int surface, int features) {
  spvtools::Optimizer optimizer(SPV_ENV_VULKAN_1_2);
  std::string failure;
  optimizer.SetMessageConsumer(
      [&](spv_message_level_t level, const char*, const spv_position_t&, const char* text) {
        if (level <= SPV_MSG_ERROR) failure += text;
      });
  const std::unordered_map<std::uint32_t, std::string> values = {
      {0, std::to_string(method)}, {1, std::to_string(surface)}, {2, std::to_string(features)}};
  optimizer.RegisterPass(spvtools::CreateSetSpecConstantDefaultValuePass(values));
  optimizer.RegisterPass(spvtools::CreateFreezeSpecConstantValuePass());
  optimizer.RegisterPass(spvtools::CreateFoldSpecConstantOpAndCompositePass());
  optimizer.RegisterPerformancePasses();
  std::vector<std::uint32_t> optimised;
  EXPECT_TRUE(optimizer.Run(module.data(), module.size(), &optimised)) << failure;

  Counts counts;
  std::unordered_map<std::uint32_t, std::uint32_t> binding_of;  // variable id -> binding
  bool in_function = false;
  std::vector<std::uint32_t> open_loops;  // the merge blocks of the loops the walk is inside
  for (std::size_t at = 5; at < optimised.size();) {
    const std::uint32_t words = optimised[at] >> 16, opcode = optimised[at] & 0xffffu;
    if (words == 0 || at + words > optimised.size()) {
      ADD_FAILURE() << "malformed optimised module";
      break;
    }
    const std::span<const std::uint32_t> operands(optimised.data() + at + 1, words - 1);
    if (opcode == op_decorate && operands.size() >= 3 && operands[1] == decoration_binding)
      binding_of[operands[0]] = operands[2];
    if (opcode == op_function) in_function = true;
    // a structured loop's blocks lie between its header (OpLoopMerge) and its merge block's label
    if (opcode == op_label && !open_loops.empty() && operands[0] == open_loops.back()) open_loops.pop_back();
    if (opcode == op_loop_merge) open_loops.push_back(operands[0]);
    if (in_function && opcode != op_variable) {
      ++counts.instructions;
      counts.in_loops += !open_loops.empty();
      if ((opcode >= op_image_sample_first && opcode <= op_image_gather) || opcode == op_image_fetch)
        ++counts.image_reads;
      for (const std::uint32_t operand : operands) {
        if (const auto found = binding_of.find(operand); found != binding_of.end())
          counts.bindings_read.insert(found->second);
      }
    }
    if (opcode == op_function_end) in_function = false;
    at += words;
  }
  return counts;
}

int shader_id(Method method) { return displace::render::method_info(method).shader_id; }

struct Stored {
  const char* view;  // what draws it
  Method method;
  int surface;
  int features;
  int instructions;  // counted when it was last made smaller or knowingly larger
  int in_loops;      // likewise, the instructions inside loops
};

// The pipelines the built-in scenes and the benchmarks draw. A count more than `growth` above its
// stored value fails (the pipeline carries code it did not); one more than `shrink` below fails too,
// so that the stored values stay tight: write the new count in then.
constexpr double growth = 1.10, shrink = 0.85;
constexpr int none = 0, water = FLAG_WATER, sea = FLAG_WATER | FLAG_UNBOUNDED, far_sea = sea | FLAG_LEVELS;
const Stored stored[] = {
    {"bricks", Method::acm4, SURFACE_PLANE, none, 750, 357},
    {"bricks", Method::csm, SURFACE_PLANE, none, 719, 357},
    {"bricks", Method::relief, SURFACE_PLANE, none, 501, 101},
    {"bricks", Method::relaxed, SURFACE_PLANE, none, 1107, 641},
    {"bricks", Method::pom, SURFACE_PLANE, none, 463, 67},
    {"bricks", Method::interval, SURFACE_PLANE, none, 554, 127},
    {"bricks", Method::acm8, SURFACE_PLANE, none, 750, 357},
    {"bricks", Method::acm4_interval, SURFACE_PLANE, none, 1005, 494},
    {"bricks", Method::maxmip, SURFACE_PLANE, none, 874, 472},
    {"bricks", Method::qdm, SURFACE_PLANE, none, 857, 455},
    {"bricks", Method::sphere, SURFACE_PLANE, none, 703, 336},
    {"bricks", Method::parallax_slope, SURFACE_PLANE, none, 462, 132},
    {"bricks", Method::reference, SURFACE_PLANE, none, 721, 371},
    {"bricks with shadows", Method::acm4, SURFACE_PLANE, FLAG_SHADOWS, 1256, 715},
    {"water patch", Method::acm4, SURFACE_PLANE, water, 759, 357},
    {"water patch", Method::relief, SURFACE_PLANE, water, 510, 101},
    {"water patch", Method::relaxed, SURFACE_PLANE, water, 1116, 641},
    {"water, level 0 and the sky", Method::acm4, SURFACE_PLANE, sea, 862, 357},
    {"water, the coarser levels", Method::acm4, SURFACE_PLANE, far_sea, 1223, 499},
    {"water, level 0 and the sky", Method::csm, SURFACE_PLANE, sea, 831, 357},
    {"water, the coarser levels", Method::csm, SURFACE_PLANE, far_sea, 1192, 499},
    {"water, the sea to the horizon", Method::relief, SURFACE_PLANE, sea, 616, 101},
    {"water, the sky", Method::acm4, SURFACE_PLANE, far_sea | FLAG_SKY, 69, 0},
    {"bricks on a mesh", Method::acm4, SURFACE_MESH, none, 1271, 714},
    {"bricks on a sphere", Method::acm4, SURFACE_SPHERE, none, 2610, 1846},
    {"bricks on a sphere", Method::relief, SURFACE_SPHERE, none, 1433, 492},
};

std::span<const std::uint32_t> module_for(int surface) {
  if (surface == SURFACE_PLANE || surface == SURFACE_MESH) return spirv_surface_planar_frag;
  return spirv_surface_quadric_frag;
}

TEST(ShaderSize, EachPipelineHoldsNoMoreCodeThanStored) {
  for (const Stored& row : stored) {
    const Counts counts =
        specialised(module_for(row.surface), shader_id(row.method), row.surface,
                    row.surface == SURFACE_PLANE ? row.features : row.features & ~FLAG_SHADOWS);
    const std::string what = std::string(row.view) + ", " + displace::render::method_info(row.method).name +
                             " (features " + std::to_string(row.features) + ")";
    std::printf("%-30s %-14s features %3d: %5d instructions, %5d in loops, %3d image reads\n", row.view,
                displace::render::method_info(row.method).name, row.features, counts.instructions,
                counts.in_loops, counts.image_reads);
    // a count within [shrink, growth] times its stored value; `grown` says what growing means
    auto within = [&](int count, int stored_count, const char* counted, const char* grown) {
      EXPECT_LE(count, stored_count * growth)
          << what << ": " << count << " " << counted << ", stored " << stored_count << ": " << grown;
      EXPECT_GE(count, stored_count * shrink) << what << ": " << count << " " << counted << ", stored "
                                              << stored_count << ": smaller than stored; store the new count";
    };
    within(counts.instructions, row.instructions, "instructions",
           "the pipeline holds code it did not (a feature or method it does not use?)");
    within(counts.in_loops, row.in_loops, "instructions in loops",
           "each step of its march does more work than it did (work that belongs before the loop?)");
  }
}

// No pipeline whose view traces no levels of detail reads the levels' atlases, and none but the
// water's the foam: every method on the plane, with no feature and with the others.
TEST(ShaderSize, APipelineReadsOnlyTheImagesItsFeaturesUse) {
  for (const displace::render::MethodInfo& info : displace::render::method_table()) {
    for (const int features : {0, FLAG_SHADOWS, FLAG_UNBOUNDED | FLAG_WATER | FLAG_SHADOWS}) {
      const Counts counts = specialised(spirv_surface_planar_frag, info.shader_id, SURFACE_PLANE, features);
      EXPECT_FALSE(counts.bindings_read.contains(BINDING_HEIGHT_LEVELS))
          << info.name << ", features " << features;
      EXPECT_FALSE(counts.bindings_read.contains(BINDING_CONE_LEVELS))
          << info.name << ", features " << features;
      if ((features & FLAG_WATER) == 0) {
        EXPECT_FALSE(counts.bindings_read.contains(BINDING_FOAM)) << info.name << ", features " << features;
      }
    }
  }
  // and the features that use them do read them
  const Counts far_sea_acm4 = specialised(spirv_surface_planar_frag, shader_id(Method::acm4), SURFACE_PLANE,
                                          FLAG_WATER | FLAG_UNBOUNDED | FLAG_LEVELS);
  EXPECT_TRUE(far_sea_acm4.bindings_read.contains(BINDING_HEIGHT_LEVELS));
  EXPECT_TRUE(far_sea_acm4.bindings_read.contains(BINDING_CONE_LEVELS));
  EXPECT_TRUE(far_sea_acm4.bindings_read.contains(BINDING_FOAM));
  // the coarser levels' pass reads no texel of level 0 (surface.frag.glsl discards its pixels)
  EXPECT_FALSE(far_sea_acm4.bindings_read.contains(BINDING_HEIGHT));
  EXPECT_FALSE(far_sea_acm4.bindings_read.contains(BINDING_CONES));
  // the sky's pass reads no image and holds no loop: the sky alone (config.h, FLAG_SKY)
  const Counts sky = specialised(spirv_surface_planar_frag, shader_id(Method::acm4), SURFACE_PLANE,
                                 FLAG_WATER | FLAG_UNBOUNDED | FLAG_LEVELS | FLAG_SKY);
  EXPECT_EQ(sky.image_reads, 0);
  EXPECT_EQ(sky.in_loops, 0);
}

}  // namespace
