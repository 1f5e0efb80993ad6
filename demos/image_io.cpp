// demos/image_io.cpp - height images in, EXR and PNG out, through OpenImageIO.
//
// PNG alpha: OpenImageIO associates (premultiplies) alpha on read and un-associates on write unless
// told the data is straight; cone maps use alpha as a data channel, so every open passes
// oiio:UnassociatedAlpha = 1 and the bytes go through untouched.
//
// Whole images only: a read that fails, or succeeds with an error left behind (libjpeg fills the
// rows of a truncated JPEG and leaves "Premature end of JPEG file"; libtiff fills missing strips and
// leaves one message per strip), is refused as truncated or corrupt, with the libraries' messages
// folded into one line (read_failure()).
//
// Library noise: what libpng prints on stderr during opens and reads is captured in a temporary
// file (StderrCapture) and folded into the error; why a file, and why at all:
// docs/design/reliability.md#library-noise-on-stderr-demosimage_iocpp
#include "demos/image_io.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>
#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <mutex>
#include <string_view>

#include "demos/image_oiio.h"

namespace displace::app {
namespace {

namespace oiio = OIIO;

std::string channel_list(const oiio::ImageSpec& spec) {
  std::string list;
  for (int c = 0; c < spec.nchannels; ++c) {
    if (c > 0) list += ", ";
    list += spec.channel_name(c);
  }
  return list;
}

// File descriptor 2 pointed at an anonymous temporary file for as long as the object lives (or
// until finish()), one capture at a time in the process. When no temporary file can be made, nothing
// is captured and the libraries write to stderr as before.
class StderrCapture {
 public:
  StderrCapture() : lock_(capture_mutex()) {
    std::fflush(stderr);
    file_ = std::tmpfile();
    if (!file_) return;
    saved_ = ::dup(STDERR_FILENO);
    if (saved_ >= 0 && ::dup2(::fileno(file_), STDERR_FILENO) >= 0) return;
    if (saved_ >= 0) ::close(saved_);
    saved_ = -1;
  }
  ~StderrCapture() {
    restore();
    if (file_) std::fclose(file_);
  }
  StderrCapture(const StderrCapture&) = delete;
  StderrCapture& operator=(const StderrCapture&) = delete;

  // Puts fd 2 back and returns the lines the libraries wrote meanwhile. Lines this program writes
  // (they start with "displace", or '\r' for a progress line) come from other threads: they go on
  // to stderr.
  std::vector<std::string> finish() {
    const bool captured = saved_ >= 0;
    restore();
    std::vector<std::string> library;
    if (!captured) return library;
    std::rewind(file_);
    std::string line;
    for (int c = std::fgetc(file_);; c = std::fgetc(file_)) {
      if (c != EOF && c != '\n') {
        line += char(c);
        continue;
      }
      if (line.starts_with("displace") || line.starts_with("\r")) {
        std::fputs((line + (c == '\n' ? "\n" : "")).c_str(), stderr);
      } else if (!line.empty()) {
        library.push_back(line);
      }
      line.clear();
      if (c == EOF) break;
    }
    return library;
  }

 private:
  static std::mutex& capture_mutex() {
    static std::mutex mutex;
    return mutex;
  }
  void restore() {
    if (saved_ < 0) return;
    std::fflush(stderr);
    ::dup2(saved_, STDERR_FILENO);
    ::close(saved_);
    saved_ = -1;
  }

  std::unique_lock<std::mutex> lock_;
  std::FILE* file_ = nullptr;
  int saved_ = -1;  // the real stderr while captured
};

// `text` with each run of digits replaced by '#': messages of one shape differ only in their numbers.
std::string shape_of(std::string_view text) {
  std::string shape;
  for (const char c : text) {
    const bool digit = std::isdigit(static_cast<unsigned char>(c));
    if (!digit) {
      shape += c;
    } else if (shape.empty() || shape.back() != '#') {
      shape += '#';
    }
  }
  return shape;
}

// The libraries' account of a failure as one line: OpenImageIO's error text and the lines the
// libraries wrote on stderr, split into messages, without repeats. A message contained in another
// is dropped (libpng's "IDAT: Read error: hit end of file" inside OpenImageIO's "PNG read error:
// IDAT: Read error: hit end of file"); messages that differ only in their numbers (libtiff's one
// per missing strip) are counted, not repeated.
std::string one_line(std::string_view error, const std::vector<std::string>& library) {
  constexpr std::size_t most_messages = 3;  // distinct messages shown; the rest are counted
  std::vector<std::string> messages;
  auto add = [&](std::string_view text) {
    for (std::string_view prefix : {"libpng error: ", "libpng warning: "}) {
      if (text.starts_with(prefix)) text.remove_prefix(prefix.size());
    }
    while (!text.empty() && std::isspace(static_cast<unsigned char>(text.front()))) text.remove_prefix(1);
    while (!text.empty() && std::isspace(static_cast<unsigned char>(text.back()))) text.remove_suffix(1);
    if (!text.empty()) messages.emplace_back(text);
  };
  for (std::size_t start = 0; start < error.size();) {
    const std::size_t end = std::min(error.find('\n', start), error.size());
    add(error.substr(start, end - start));
    start = end + 1;
  }
  for (const std::string& line : library) add(line);

  // drop repeats and messages inside longer ones
  std::vector<std::string> kept;
  for (std::size_t m = 0; m < messages.size(); ++m) {
    bool inside = false;
    for (std::size_t other = 0; other < messages.size() && !inside; ++other) {
      if (other == m || messages[other].find(messages[m]) == std::string::npos) continue;
      inside = messages[other].size() > messages[m].size() || other < m;  // of equal ones the first stays
    }
    if (!inside) kept.push_back(messages[m]);
  }

  // one message per shape, with a count of the others
  std::vector<std::pair<std::string, int>> shapes;  // first message, how many more of its shape
  std::vector<std::string> shape_keys;
  for (const std::string& message : kept) {
    const std::string shape = shape_of(message);
    const auto found = std::find(shape_keys.begin(), shape_keys.end(), shape);
    if (found != shape_keys.end()) {
      ++shapes[std::size_t(found - shape_keys.begin())].second;
      continue;
    }
    shape_keys.push_back(shape);
    shapes.emplace_back(message, 0);
  }
  std::string line;
  for (std::size_t s = 0; s < shapes.size() && s < most_messages; ++s) {
    line += (line.empty() ? "" : "; ") + shapes[s].first;
    if (shapes[s].second > 0) line += fmt::format(" (and {} more like it)", shapes[s].second);
  }
  if (shapes.size() > most_messages) line += fmt::format("; and {} more", shapes.size() - most_messages);
  return line.empty() ? std::string("no reason given") : line;
}

// What an image is read for: the smallest side it may have and the words of the errors.
struct ImageUse {
  const char* noun;  // "a height map"
  int min_side;      // pixels
  int max_side = max_image_side;
};
constexpr ImageUse height_map_use{"a height map", 2};  // a single texel (or row) has no relief to displace
constexpr ImageUse albedo_use{"an albedo image", 1};
constexpr ImageUse data_use{"an image", 1};  // cone maps and float images read back

// Opens `file`, or the bytes of `memory` (then `file` only names the image and its extension
// picks the format).
std::unique_ptr<oiio::ImageInput> open_input(const std::filesystem::path& file, const ImageUse& use,
                                             oiio::Filesystem::IOProxy* memory = nullptr) {
  std::error_code error;
  if (!memory && !std::filesystem::exists(file, error))
    throw runtime_error("cannot read " + quoted(file) + ": no such file");
  if (!memory && std::filesystem::is_directory(file, error))
    throw runtime_error("cannot read " + quoted(file) + ": it is a directory");
  oiio::ImageSpec config;
  config.attribute("oiio:UnassociatedAlpha", 1);
  // the readers of OpenImageIO 2.4 take the proxy from the configuration hints (a proxy passed only
  // as open()'s argument is dropped when hints are given)
  if (memory) config.attribute("oiio:ioproxy", oiio::TypeDesc::PTR, &memory);
  StderrCapture capture;
  auto input = oiio::ImageInput::open(file.string(), &config, memory);
  const std::vector<std::string> library = capture.finish();
  if (!input) {
    throw runtime_error("cannot read " + quoted(file) +
                        " as an image: " + one_line(oiio::geterror(), library));
  }
  const oiio::ImageSpec& spec = input->spec();
  const std::string size = std::to_string(spec.width) + " x " + std::to_string(spec.height);
  if (spec.width <= 0 || spec.height <= 0)
    throw runtime_error(quoted(file) + " is an empty image (" + size + ")");
  if (spec.width < use.min_side || spec.height < use.min_side) {
    throw runtime_error(fmt::format("{} is {}: {} needs at least {} x {} texels to displace anything",
                                    quoted(file), size, use.noun, use.min_side, use.min_side));
  }
  if (spec.width > use.max_side || spec.height > use.max_side) {
    throw runtime_error(fmt::format("{} is {} pixels; {} may have at most {} a side", quoted(file), size,
                                    use.noun, use.max_side));
  }
  if (spec.depth > 1) throw runtime_error(quoted(file) + " is a volume image; " + use.noun + " is 2D");
  if (spec.deep) throw runtime_error(quoted(file) + " is a deep image; " + use.noun + " is flat");
  if (spec.nchannels <= 0) throw runtime_error(quoted(file) + " has no channels");
  return input;
}

// Reads channels [first, end) of every pixel as `type`. A read that fails, or that succeeds with an
// error left behind (a truncated JPEG or TIFF read "successfully" with its missing rows filled), is
// refused: a file that is not whole is never read as a silently wrong image.
void read_pixels(oiio::ImageInput& input, int first, int end, oiio::TypeDesc type, void* pixels,
                 const std::filesystem::path& file) {
  StderrCapture capture;
  const bool read = input.read_image(0, 0, first, end, type, pixels);
  const std::vector<std::string> library = capture.finish();
  const std::string left = input.geterror();
  if (read && left.empty()) return;  // what the libraries wrote on the way was warnings only
  throw runtime_error("cannot read the pixels of " + quoted(file) + ": the file is truncated or corrupt (" +
                      one_line(left, library) + ")");
}

int choose_channel(const oiio::ImageSpec& spec, const ChannelChoice& choice,
                   const std::filesystem::path& file) {
  if (choice.index >= 0) {
    if (choice.index >= spec.nchannels) {
      throw usage_error("--channel " + std::to_string(choice.index) + ": " + quoted(file) + " has " +
                        std::to_string(spec.nchannels) + " channel(s) (" + channel_list(spec) +
                        "); there is no channel index " + std::to_string(choice.index));
    }
    return choice.index;
  }
  if (!choice.name.empty()) {
    for (int c = 0; c < spec.nchannels; ++c)
      if (spec.channel_name(c) == choice.name) return c;
    throw usage_error("--channel " + choice.name + ": " + quoted(file) + " has no channel named '" +
                      choice.name + "' (channels: " + channel_list(spec) + ")");
  }
  for (int c = 0; c < spec.nchannels; ++c)
    if (spec.channel_name(c) == "height") return c;
  if (spec.nchannels == 1) return 0;
  if (spec.nchannels == 2 && spec.alpha_channel == 1) return 0;
  throw runtime_error(quoted(file) + " has " + std::to_string(spec.nchannels) + " channels (" +
                      channel_list(spec) +
                      "), which is not a greyscale height map; choose the height channel with --channel");
}

SampleFormat sample_format(oiio::TypeDesc type, const std::filesystem::path& file) {
  switch (type.basetype) {
    case oiio::TypeDesc::UINT8: return SampleFormat::uint8;
    case oiio::TypeDesc::UINT16: return SampleFormat::uint16;
    case oiio::TypeDesc::HALF:
    case oiio::TypeDesc::FLOAT:
    case oiio::TypeDesc::DOUBLE: return SampleFormat::floating;
    default:
      throw runtime_error(quoted(file) + " stores " + std::string(type.c_str()) +
                          " samples; supported are 8-bit and 16-bit unsigned integers and floats");
  }
}

template <typename Sample>
std::vector<float> read_channel_as(oiio::ImageInput& input, int channel, oiio::TypeDesc type,
                                   const std::filesystem::path& file) {
  const oiio::ImageSpec& spec = input.spec();
  std::vector<Sample> samples(std::size_t(spec.width) * std::size_t(spec.height));
  read_pixels(input, channel, channel + 1, type, samples.data(), file);
  return std::vector<float>(samples.begin(), samples.end());
}

// The float attribute `name`, if the spec holds one (float, or an int stored for it).
std::optional<float> float_attribute(const oiio::ImageSpec& spec, std::string_view name) {
  const oiio::ParamValue* value = spec.find_attribute(name);
  if (!value) return std::nullopt;
  if (value->type() == oiio::TypeDesc::FLOAT) return value->get_float();
  if (value->type() == oiio::TypeDesc::DOUBLE) return value->get_float();
  if (value->type() == oiio::TypeDesc::INT) return float(value->get_int());
  return std::nullopt;
}

Metadata read_metadata(const oiio::ImageSpec& spec) {
  Metadata metadata;
  for (const oiio::ParamValue& value : spec.extra_attribs) {
    if (value.nvalues() != 1) continue;
    if (value.type() == oiio::TypeDesc::STRING) {
      metadata.push_back({value.name().string(), value.get_string()});
    } else if (value.type() == oiio::TypeDesc::FLOAT) {
      metadata.push_back({value.name().string(), value.get_float()});
    } else if (value.type() == oiio::TypeDesc::INT) {
      metadata.push_back({value.name().string(), value.get_int()});
    }
  }
  return metadata;
}

// The heights of an opened image (load_heights from a file or from memory).
LoadedHeights read_heights(std::unique_ptr<oiio::ImageInput> input, const std::filesystem::path& file,
                           const HeightLoadSettings& settings) {
  const oiio::ImageSpec& spec = input->spec();

  LoadedHeights loaded;
  loaded.width = spec.width;
  loaded.height = spec.height;
  loaded.inverted = settings.invert;
  loaded.channel_index = choose_channel(spec, settings.channel, file);
  loaded.channel_name = spec.channel_name(loaded.channel_index);
  loaded.format = sample_format(spec.channelformat(loaded.channel_index), file);
  if (settings.range && loaded.format != SampleFormat::floating) {
    throw usage_error("--height-range applies to float images only; " + quoted(file) + " stores " +
                      (loaded.format == SampleFormat::uint8 ? "8" : "16") +
                      "-bit integers, mapped as value / maximum");
  }

  // read the raw samples in their own format
  std::vector<float> raw;
  switch (loaded.format) {
    case SampleFormat::uint8:
      raw = read_channel_as<std::uint8_t>(*input, loaded.channel_index, oiio::TypeDesc::UINT8, file);
      break;
    case SampleFormat::uint16:
      raw = read_channel_as<std::uint16_t>(*input, loaded.channel_index, oiio::TypeDesc::UINT16, file);
      break;
    case SampleFormat::floating:
      raw = read_channel_as<float>(*input, loaded.channel_index, oiio::TypeDesc::FLOAT, file);
      break;
  }
  input->close();

  // reject non-finite heights, naming the first one
  for (std::size_t k = 0; k < raw.size(); ++k) {
    if (!std::isfinite(raw[k])) {
      throw runtime_error(quoted(file) + " holds a non-finite height (" + std::to_string(raw[k]) +
                          ") at row " + std::to_string(k / std::size_t(loaded.width)) + ", column " +
                          std::to_string(k % std::size_t(loaded.width)) + " of channel '" +
                          loaded.channel_name + "'");
    }
  }

  // choose the mapping to [0, 1]
  if (loaded.format != SampleFormat::floating) {
    const float maximum = loaded.format == SampleFormat::uint8 ? 255.0f : 65535.0f;
    loaded.mapping = {1.0f / maximum, 0.0f};
    loaded.mapping_origin = MappingOrigin::integer_max;
  } else if (settings.range) {
    const float span = settings.range->high - settings.range->low;
    loaded.mapping = {1.0f / span, -settings.range->low / span};
    loaded.mapping_origin = MappingOrigin::user_range;
  } else if (auto scale = float_attribute(spec, "displace:height_scale"),
             bias = float_attribute(spec, "displace:height_bias");
             loaded.channel_name == "height" && scale && bias && std::isfinite(*scale) &&
             std::isfinite(*bias) && *scale != 0.0f) {
    loaded.mapping = {*scale, *bias};
    loaded.mapping_origin = MappingOrigin::file_metadata;
  } else {
    const auto [low, high] = std::minmax_element(raw.begin(), raw.end());
    const float span = *high - *low;
    if (span > 0.0f && std::isfinite(span)) {
      loaded.mapping = {1.0f / span, -*low / span};
    } else {
      loaded.mapping = {1.0f, -*low};
    }
    loaded.mapping_origin = MappingOrigin::image_min_max;
  }
  if (!std::isfinite(loaded.mapping.scale) || !std::isfinite(loaded.mapping.bias)) {
    throw runtime_error("the heights of " + quoted(file) + " span too wide a range to map to [0, 1]");
  }

  // apply it
  loaded.heights.resize(raw.size());
  for (std::size_t k = 0; k < raw.size(); ++k) {
    const float mapped = raw[k] * loaded.mapping.scale + loaded.mapping.bias;
    float h01 = std::clamp(mapped, 0.0f, 1.0f);
    if (h01 != mapped) ++loaded.clamped;
    loaded.heights[k] = settings.invert ? 1.0f - h01 : h01;
  }
  return loaded;
}

ImageUse height_use(const HeightLoadSettings& settings) {
  ImageUse use = height_map_use;
  use.max_side = std::min(settings.max_side, max_image_side);
  return use;
}

}  // namespace

LoadedHeights load_heights(const std::filesystem::path& file, const HeightLoadSettings& settings) {
  return read_heights(open_input(file, height_use(settings)), file, settings);
}

LoadedHeights load_heights(std::span<const std::uint8_t> bytes, const std::filesystem::path& name,
                           const HeightLoadSettings& settings) {
  oiio::Filesystem::IOMemReader memory(bytes.data(), bytes.size());
  return read_heights(open_input(name, height_use(settings), &memory), name, settings);
}

const Attribute* find_attribute(const Metadata& metadata, std::string_view name) {
  for (const Attribute& attribute : metadata)
    if (attribute.name == name) return &attribute;
  return nullptr;
}

std::vector<float> FloatImage::channel(std::string_view name) const {
  const auto found = std::find(channel_names.begin(), channel_names.end(), name);
  if (found == channel_names.end())
    throw runtime_error("the image has no channel named '" + std::string(name) + "'");
  const std::size_t index = std::size_t(found - channel_names.begin());
  const std::size_t count = channel_names.size();
  std::vector<float> samples(std::size_t(width) * std::size_t(height));
  for (std::size_t k = 0; k < samples.size(); ++k) samples[k] = pixels[k * count + index];
  return samples;
}

FloatImage read_float_image(const std::filesystem::path& file) {
  auto input = open_input(file, data_use);
  const oiio::ImageSpec& spec = input->spec();
  FloatImage image;
  image.width = spec.width;
  image.height = spec.height;
  for (int c = 0; c < spec.nchannels; ++c) image.channel_names.push_back(spec.channel_name(c));
  image.metadata = read_metadata(spec);
  image.pixels.resize(std::size_t(spec.width) * std::size_t(spec.height) * std::size_t(spec.nchannels));
  read_pixels(*input, 0, spec.nchannels, oiio::TypeDesc::FLOAT, image.pixels.data(), file);
  input->close();
  return image;
}

Rgba8Image read_color_image(const std::filesystem::path& file) {
  auto input = open_input(file, albedo_use);
  const oiio::ImageSpec& spec = input->spec();
  const int channels = spec.nchannels;
  if (channels < 1 || channels > 4) {
    throw runtime_error(quoted(file) + " has " + std::to_string(channels) +
                        " channels; a colour image has 1 to 4");
  }
  std::vector<std::uint8_t> stored(std::size_t(spec.width) * std::size_t(spec.height) *
                                   std::size_t(channels));
  read_pixels(*input, 0, channels, oiio::TypeDesc::UINT8, stored.data(), file);
  input->close();
  Rgba8Image image;
  image.width = spec.width;
  image.height = spec.height;
  image.metadata = read_metadata(spec);
  const std::size_t pixels = std::size_t(spec.width) * std::size_t(spec.height);
  image.pixels.resize(pixels * 4);
  for (std::size_t p = 0; p < pixels; ++p) {
    const std::uint8_t* in = &stored[p * std::size_t(channels)];
    std::uint8_t* rgba = &image.pixels[p * 4];
    const bool grey = channels <= 2;
    rgba[0] = in[0];
    rgba[1] = grey ? in[0] : in[1];
    rgba[2] = grey ? in[0] : in[2];
    rgba[3] = channels == 2 ? in[1] : channels == 4 ? in[3] : 255;
  }
  return image;
}

Rgba8Image read_rgba8_image(const std::filesystem::path& file) {
  auto input = open_input(file, data_use);
  const oiio::ImageSpec& spec = input->spec();
  if (spec.nchannels != 4 || spec.format != oiio::TypeDesc::UINT8) {
    throw runtime_error(quoted(file) + " is not an 8-bit RGBA image (" + std::to_string(spec.nchannels) +
                        " channels of " + std::string(spec.format.c_str()) + ")");
  }
  Rgba8Image image;
  image.width = spec.width;
  image.height = spec.height;
  image.metadata = read_metadata(spec);
  image.pixels.resize(std::size_t(spec.width) * std::size_t(spec.height) * 4);
  read_pixels(*input, 0, 4, oiio::TypeDesc::UINT8, image.pixels.data(), file);
  input->close();
  return image;
}

}  // namespace displace::app
