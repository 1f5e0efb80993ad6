// demos/image_io.h - height images in, float EXR and RGBA8 PNG out (OpenImageIO).
//
// The one fact to know: a loaded height map is in [0, 1] with 1 = top, and the mapping from the
// file's samples to that range is always explicit and recorded (LoadedHeights::mapping):
//   h01 = clamp(raw * scale + bias, 0, 1), then h01 = 1 - h01 when `invert` is set.
// - 8-bit and 16-bit integer samples: raw is the integer, scale = 1 / (2^bits - 1), bias = 0.
// - float samples (half, float, double): an explicit range [lo, hi] maps to [0, 1]; it is, in order
//   of preference, the user's --height-range, the mapping recorded by `displace sim` in the file
//   (attributes displace:height_scale / displace:height_bias, for a channel named `height`), or the
//   image's own min / max (a flat image maps to 0).
// Every failure throws AppError naming the file: of kind usage when a flag does not fit the image
// (--height-range on integer samples, --channel naming no channel of it), of kind runtime for the
// file itself: missing, not an image, of a size outside the limits, or not whole (truncated or
// corrupt: refused, never read with rows filled in), with the decoders' messages in one line.
// The writers encode in memory and write through render/files.h: a file is whole under its name or
// absent, and a failed write throws files::WriteError naming the file and the system's reason.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <variant>
#include <vector>

#include "demos/error.h"
#include "render/files.h"
#include "sim/sim.h"

namespace displace::app {

// The largest width or height the application layer accepts (texels, pixels); a height map needs at
// least 2 x 2 texels, other images 1 x 1.
inline constexpr int max_image_side = 16384;

// Which channel holds the heights. Neither set: the channel named `height` if there is one, else
// the only channel (or the grey channel of grey + alpha).
struct ChannelChoice {
  int index = -1;    // >= 0: this channel index
  std::string name;  // non-empty: the channel with this name
};

// Raw float values [low, high] that map to [0, 1].
struct HeightRange {
  float low = 0.0f;
  float high = 1.0f;
};

struct HeightLoadSettings {
  ChannelChoice channel;
  bool invert = false;               // the file stores depth: 1 = deepest
  std::optional<HeightRange> range;  // float images only
  int max_side = max_image_side;     // a larger image is refused before its pixels are read
};

enum class SampleFormat { uint8, uint16, floating };

// Where LoadedHeights::mapping came from.
enum class MappingOrigin { integer_max, user_range, file_metadata, image_min_max };

struct LoadedHeights {
  int width = 0;
  int height = 0;
  std::vector<float> heights;  // width * height, row-major, in [0, 1], 1 = top
  sim::HeightMapping mapping;  // h01 = raw * scale + bias before inversion
  MappingOrigin mapping_origin = MappingOrigin::integer_max;
  bool inverted = false;
  SampleFormat format = SampleFormat::uint8;
  int channel_index = 0;
  std::string channel_name;
  std::size_t clamped = 0;  // samples outside the mapped range, clamped to 0 or 1
};

LoadedHeights load_heights(const std::filesystem::path& file, const HeightLoadSettings& settings);
// The same from an image in memory: `name` stands for the file in messages, and its extension picks
// the decoder (PNG, JPEG, OpenEXR, TIFF, ... as OpenImageIO reads them from memory).
LoadedHeights load_heights(std::span<const std::uint8_t> bytes, const std::filesystem::path& name,
                           const HeightLoadSettings& settings);

// True when `file` opens as an image and every pixel of it decodes (not truncated, not corrupt):
// what --resume asks of a frame its manifest does not vouch for.
bool decodes_whole(const std::filesystem::path& file);

// Image attributes: EXR header attributes or PNG text chunks.
using AttributeValue = std::variant<std::string, float, int>;
struct Attribute {
  std::string name;
  AttributeValue value;
};
using Metadata = std::vector<Attribute>;

const Attribute* find_attribute(const Metadata& metadata, std::string_view name);

// One planar float channel of width * height samples.
struct ExrChannel {
  std::string name;
  std::span<const float> samples;
};

// Writes a float32 EXR (zip compressed) with the named channels and attributes.
files::WrittenFile write_exr(const std::filesystem::path& file, int width, int height,
                             std::span<const ExrChannel> channels, const Metadata& metadata);

// Writes an 8-bit RGBA PNG from interleaved, unassociated (straight) RGBA samples; the attributes
// become text chunks (numbers in decimal). No colour conversion and no colour chunk: the bytes are
// stored as given.
files::WrittenFile write_png_rgba8(const std::filesystem::path& file, int width, int height,
                                   std::span<const std::uint8_t> rgba, const Metadata& metadata);
// Writes a 16-bit grey PNG of raw values (data for plots: iteration counts, not a picture).
files::WrittenFile write_png_gray16(const std::filesystem::path& file, int width, int height,
                                    std::span<const std::uint16_t> values);

// An animated GIF of RGBA8 frames of one size (the first frame's), `fps` frames a second; for
// previews (GIF's 256 colours a frame).
files::WrittenFile write_animated_gif(const std::filesystem::path& file, int width, int height,
                                      const std::vector<std::vector<std::uint8_t>>& frames, int fps);

// Any image, every channel converted to float, interleaved.
struct FloatImage {
  int width = 0;
  int height = 0;
  std::vector<std::string> channel_names;
  std::vector<float> pixels;
  Metadata metadata;

  // The planar samples of one channel; throws AppError when there is no such channel.
  std::vector<float> channel(std::string_view name) const;
};
FloatImage read_float_image(const std::filesystem::path& file);

// An 8-bit, 4-channel image exactly as stored (alpha is not applied to the colour channels).
struct Rgba8Image {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> pixels;  // interleaved RGBA
  Metadata metadata;
};
Rgba8Image read_rgba8_image(const std::filesystem::path& file);

// Any image OpenImageIO reads (1 to 4 channels, any bit depth, 1 to max_image_side pixels a side),
// converted to 8 bits per channel and expanded to RGBA: grey to grey, grey + alpha, RGB with alpha
// 255. For albedo textures.
Rgba8Image read_color_image(const std::filesystem::path& file);

}  // namespace displace::app
