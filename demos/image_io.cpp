// demos/image_io.cpp - height images and colour images in, through OpenImageIO; image_read.cpp opens
// and reads whole images (a truncated or corrupt file is refused, the libraries' stderr folded into
// the error: docs/design/reliability.md#library-noise-on-stderr-demosimage_readcpp), and
// image_write.cpp writes.
//
// PNG alpha: OpenImageIO associates (premultiplies) alpha on read and un-associates on write unless
// told the data is straight; cone maps use alpha as a data channel, so every open passes
// oiio:UnassociatedAlpha = 1 and the bytes go through untouched.
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
