// demos/cone_export.h - writes baked cone maps for tools (EXR) and for engines (PNG).
//
// EXR (lossless, for tools and tests): float32 channels `height` (the [0, 1] heights that were
// baked, 1 = top) and `cone0` .. `cone{n-1}` (the ratio of sector k, see bake/bake.h), with the
// attributes displace:sectors (int), displace:address ("wrap" | "clamp"), displace:mode
// ("exact" | "original" | "paper-adaptive" | "budgeted" | "relaxed"), displace:height_scale = 1 and
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
//   - Text chunks repeat displace:sectors, displace:address and displace:mode.
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

// Which baker made a cone map: the four conservative-ratio modes plus the relaxed baker.
enum class Baker { exact, original, paper_adaptive, budgeted, relaxed };

const char* baker_name(Baker baker);  // "exact", "original", "paper-adaptive", "budgeted", "relaxed"
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
};

void write_cone_exr(const std::filesystem::path& file, const ConeMapExport& cones,
                    const Metadata& extra = {});
void write_cone_png(const std::filesystem::path& file, const ConeMapExport& cones,
                    const Metadata& extra = {});

// The PNG layout above, in memory: ((P + 1) * width) x height RGBA bytes.
std::vector<std::uint8_t> encode_cone_png_pixels(const ConeMapExport& cones);

// Downward sqrt quantization of one ratio in [0, 1] and its decoding.
std::uint8_t encode_ratio(float ratio);
float decode_ratio(std::uint8_t byte);

// Rounds heights to the 8 bits the PNG height panel stores: h = round(h * 255) / 255.
void quantize_heights_8bit(std::span<float> heights);

// The heights and ratios a PNG cone map decodes to (heights = R / 255 of the height panel).
struct DecodedConeMap {
  int width = 0;
  int height = 0;
  int sector_count = 0;
  std::vector<float> heights;
  std::vector<float> ratios;
};
DecodedConeMap decode_cone_pixels(std::span<const std::uint8_t> rgba, int image_width, int image_height,
                                  int sector_count);
// Reads the sector count from the displace:sectors text chunk.
DecodedConeMap read_cone_png(const std::filesystem::path& file);

}  // namespace displace::app
