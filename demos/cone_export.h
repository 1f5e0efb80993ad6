// demos/cone_export.h - writes baked cone maps for tools (EXR) and for engines (PNG).
//
// Two kinds of cone map (displace:cones): "center" cones hold between texel centres (bake_exact's
// definition, and the relaxed cones); "bilinear" cones hold for the bilinear surface from anywhere in
// a texel's square and come with an apex height per texel (bake::bake_bilinear_cones' contract).
//
// EXR (lossless, for tools and tests): float32 channels `height` (the [0, 1] heights that were
// baked, 1 = top), for bilinear cones `apex` (H_c), and `cone0` .. `cone{n-1}` (the ratio of sector
// k, see bake/bake.h), with the attributes displace:sectors (int), displace:address ("wrap" |
// "clamp"), displace:cones ("center" | "bilinear"), displace:mode ("exact" | "original" |
// "paper-adaptive" | "budgeted" | "relaxed" | "full"), displace:height_scale = 1 and
// displace:height_bias = 0 (the height channel is already in [0, 1]).
//
// PNG layout (RGBA, 8 bits per channel, straight alpha; data, not colour: load it as a linear
// UNORM texture, never sRGB, and do not premultiply):
//   A W x H cone map with n sectors is stored as P = ceil(n / 4) cone panels followed by one
//   height panel, side by side: the image is (P + 1) * W wide and H tall, and texel (i, j) of
//   panel p is pixel (row i, column p * W + j).
//   - Cone panel p holds sectors 4p, 4p + 1, 4p + 2, 4p + 3 in R, G, B, A as q = the byte of
//     sqrt(ratio) (Dummer's encoding; it spends the precision on the small ratios that matter),
//     decoded as ratio = (q / 255)^2. Quantization rounds DOWNWARDS: q is the largest byte with
//     (q / 255)^2 <= ratio in float arithmetic, so a decoded ratio never exceeds the baked one
//     and the cone stays conservative; it is at most one step of sqrt(ratio) (1/255) below.
//   - Channels of a cone panel with no sector (n = 1: G, B, A) are 0, except alpha, which is 255.
//   - The height panel holds R = round(h * 255), G = B = 0, A = 255.
//   - Bilinear cones add an apex panel after the height panel (the image is (P + 2) * W wide):
//     R = the byte of H_c rounded UPWARDS (the smallest q with q / 255 >= H_c in float arithmetic),
//     G = B = 0, A = 255, decoded as q / 255. A higher apex keeps every cone conservative; it is at
//     most 1/255 above. Their heights must already be 8-bit values (checked), so the height panel
//     holds them exactly.
//   - Text chunks repeat displace:sectors, displace:address, displace:cones and displace:mode.
//   Because the heights are quantized to 8 bits, `displace bake` with a .png output quantizes the
//   heights first (h = round(h * 255) / 255) and bakes those, so the stored cones are
//   conservative for the stored heights, which are what an engine marches against.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <vector>

#include "bake/bake.h"
#include "demos/image_io.h"

namespace displace::app {

// Which baker made a cone map: for center cones the four conservative-ratio modes plus the relaxed
// baker; for bilinear cones budgeted (bake::BilinearBaker) or full (bake::bake_bilinear_cones).
enum class Baker { exact, original, paper_adaptive, budgeted, relaxed, full };
enum class ConeKind { center, bilinear };

// "exact", "original", "paper-adaptive", "budgeted", "relaxed", "full"
const char* baker_name(Baker baker);
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
