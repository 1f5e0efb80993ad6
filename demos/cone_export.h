// demos/cone_export.h - writes baked cone maps for tools (EXR) and for engines (PNG).
//
// Two kinds of cone map (displace:cones): "center" cones hold between texel centres (bake_exact's
// definition, and the relaxed cones); "bilinear" cones hold for the bilinear surface from anywhere in
// a texel's square and come with an apex height per texel (bake::bake_bilinear_cones' contract).
//
// EXR (lossless, for tools and tests): float32 channels height, apex (bilinear cones only) and cone0
// .. cone{n-1}, with displace:* attributes. PNG (RGBA8; data: load as linear UNORM, straight alpha):
// ceil(n / 4) cone panels of sqrt(ratio) bytes, one height panel and, for bilinear cones, an apex
// panel, side by side. The one fact: a PNG stays conservative - ratios are quantized downwards,
// apexes upwards, and the heights to 8 bits before the bake, so its cones hold for its heights.
//
// Layouts in full: docs/design/conventions.md#demoscone_exporth-the-export-layouts
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <vector>

#include "bake/bake.h"
#include "demos/image_io.h"
#include "pipeline/cone_bake.h"

namespace displace::app {

// Which baker made a cone map (pipeline/cone_bake.h) and which kind of cones it made.
using pipeline::Baker;
using pipeline::baker_name;
enum class ConeKind { center, bilinear };

const char* cone_kind_name(ConeKind kind);        // "center", "bilinear"
const char* address_name(bake::Address address);  // "wrap", "clamp"

// A baked cone map and what made it; views into the caller's memory.
struct ConeMapExport {
  int width = 0;
  int height = 0;
  int sector_count = 0;
  std::span<const float> heights;  // width * height, [0, 1]
  std::span<const float> ratios;   // width * height * sector_count, interleaved as in bake/bake.h
  bake::Address address = bake::Address::wrap;
  Baker baker = Baker::exact;
  ConeKind kind = ConeKind::center;
  std::span<const float> apex = {};  // bilinear: width * height apex heights H_c in [0, 1]; center: empty
};

void write_cone_exr(const std::filesystem::path& file, const ConeMapExport& cones,
                    const Metadata& extra = {});
void write_cone_png(const std::filesystem::path& file, const ConeMapExport& cones,
                    const Metadata& extra = {});

// The PNG layout above, in memory: ((P + 1) * width) x height RGBA bytes, ((P + 2) * width) x
// height for bilinear cones.
std::vector<std::uint8_t> encode_cone_png_pixels(const ConeMapExport& cones);

// Downward sqrt quantization of one ratio in [0, 1] and its decoding.
std::uint8_t encode_ratio(float ratio);
float decode_ratio(std::uint8_t byte);

// Upward quantization of a height in [0, 1] (the apex panel) and its decoding, q / 255.
std::uint8_t encode_height_up(float height);
float decode_height(std::uint8_t byte);

// Rounds heights to the 8 bits the PNG height panel stores: h = round(h * 255) / 255.
void quantize_heights_8bit(std::span<float> heights);

// The heights, ratios and apex heights a PNG cone map decodes to (heights = R / 255 of the height
// panel, apex = R / 255 of the apex panel).
struct DecodedConeMap {
  int width = 0;
  int height = 0;
  int sector_count = 0;
  ConeKind kind = ConeKind::center;
  std::vector<float> heights;
  std::vector<float> ratios;
  std::vector<float> apex;  // bilinear only
};
DecodedConeMap decode_cone_pixels(std::span<const std::uint8_t> rgba, int image_width, int image_height,
                                  int sector_count, ConeKind kind = ConeKind::center);
// Reads the sector count from the displace:sectors text chunk and the kind from displace:cones
// (center when absent).
DecodedConeMap read_cone_png(const std::filesystem::path& file);

}  // namespace displace::app
