// demos/image_io.cpp - height images in, EXR and PNG out, through OpenImageIO.
//
// PNG alpha: OpenImageIO associates (premultiplies) alpha on read and un-associates on write unless
// told the data is straight; cone maps use alpha as a data channel, so every open passes
// oiio:UnassociatedAlpha = 1 and the bytes go through untouched.
#include "demos/image_io.h"

#include <OpenImageIO/imageio.h>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

namespace displace::app {
namespace {

namespace oiio = OIIO;

std::string quoted(const std::filesystem::path& file) { return "'" + file.string() + "'"; }

std::string channel_list(const oiio::ImageSpec& spec) {
  std::string list;
  for (int c = 0; c < spec.nchannels; ++c) {
    if (c > 0) list += ", ";
    list += spec.channel_name(c);
  }
  return list;
}

// Takes the pending error of an ImageInput/ImageOutput (or the global one) so that none is left
// unretrieved, and makes it one line.
template <typename Io>
std::string take_error(Io* io) {
  std::string message = io ? io->geterror() : oiio::geterror();
  if (io) {
    std::string global = oiio::geterror();
    if (message.empty()) message = global;
  }
  while (!message.empty() && (message.back() == '\n' || message.back() == ' ')) message.pop_back();
  std::replace(message.begin(), message.end(), '\n', ' ');
  return message.empty() ? std::string("unknown error") : message;
}

// A read that succeeded can still have met a truncated or corrupt file: libjpeg, for one, fills the
// missing rows and only leaves a warning ("Premature end of JPEG file") in the reader's error text.
// Such a file is refused, not read as a silently wrong image.
void check_complete(oiio::ImageInput& input, const std::filesystem::path& file) {
  std::string warning = input.geterror();
  if (warning.empty()) return;
  while (!warning.empty() && (warning.back() == '\n' || warning.back() == ' ')) warning.pop_back();
  std::replace(warning.begin(), warning.end(), '\n', ' ');
  throw runtime_error("cannot read the pixels of " + quoted(file) + ": the file is truncated or corrupt (" + warning + ")");
}

std::unique_ptr<oiio::ImageInput> open_input(const std::filesystem::path& file) {
  std::error_code error;
  if (!std::filesystem::exists(file, error))
    throw runtime_error("cannot read " + quoted(file) + ": no such file");
  if (std::filesystem::is_directory(file, error))
    throw runtime_error("cannot read " + quoted(file) + ": it is a directory");
  oiio::ImageSpec config;
  config.attribute("oiio:UnassociatedAlpha", 1);
  auto input = oiio::ImageInput::open(file.string(), &config);
  if (!input) {
    throw runtime_error("cannot read " + quoted(file) +
                        " as an image: " + take_error<oiio::ImageInput>(nullptr));
  }
  const oiio::ImageSpec& spec = input->spec();
  if (spec.width <= 0 || spec.height <= 0) {
    throw runtime_error(quoted(file) + " is an empty image (" + std::to_string(spec.width) + " x " +
                        std::to_string(spec.height) + ")");
  }
  if (spec.width < 2 || spec.height < 2) {
    throw runtime_error(quoted(file) + " is " + std::to_string(spec.width) + " x " + std::to_string(spec.height) +
                        ": a height map needs at least 2 x 2 texels to displace anything");
  }
  if (spec.width > max_image_side || spec.height > max_image_side) {
    throw runtime_error(quoted(file) + " is " + std::to_string(spec.width) + " x " +
                        std::to_string(spec.height) + "; the largest supported side is " +
                        std::to_string(max_image_side));
  }
  if (spec.depth > 1) throw runtime_error(quoted(file) + " is a volume image; a 2D height map is needed");
  if (spec.deep) throw runtime_error(quoted(file) + " is a deep image; a flat 2D height map is needed");
  if (spec.nchannels <= 0) throw runtime_error(quoted(file) + " has no channels");
  return input;
}

int choose_channel(const oiio::ImageSpec& spec, const ChannelChoice& choice,
                   const std::filesystem::path& file) {
  if (choice.index >= 0) {
    if (choice.index >= spec.nchannels) {
      throw runtime_error(quoted(file) + " has " + std::to_string(spec.nchannels) + " channel(s) (" +
                          channel_list(spec) + "); there is no channel index " +
                          std::to_string(choice.index));
    }
    return choice.index;
  }
  if (!choice.name.empty()) {
    for (int c = 0; c < spec.nchannels; ++c)
      if (spec.channel_name(c) == choice.name) return c;
    throw runtime_error(quoted(file) + " has no channel named '" + choice.name +
                        "' (channels: " + channel_list(spec) + ")");
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
    case oiio::TypeDesc::UINT8:
      return SampleFormat::uint8;
    case oiio::TypeDesc::UINT16:
      return SampleFormat::uint16;
    case oiio::TypeDesc::HALF:
    case oiio::TypeDesc::FLOAT:
    case oiio::TypeDesc::DOUBLE:
      return SampleFormat::floating;
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
  if (!input.read_image(0, 0, channel, channel + 1, type, samples.data())) {
    throw runtime_error("cannot read the pixels of " + quoted(file) + ": " + take_error(&input));
  }
  check_complete(input, file);
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

void add_metadata(oiio::ImageSpec& spec, const Metadata& metadata) {
  for (const Attribute& attribute : metadata) {
    if (const auto* text = std::get_if<std::string>(&attribute.value)) {
      spec.attribute(attribute.name, *text);
    } else if (const auto* real = std::get_if<float>(&attribute.value)) {
      spec.attribute(attribute.name, *real);
    } else {
      spec.attribute(attribute.name, std::get<int>(attribute.value));
    }
  }
}

// PNG text chunks hold only text: numbers are written in decimal (floats round-trip exactly).
Metadata as_text(const Metadata& metadata) {
  Metadata text;
  for (const Attribute& attribute : metadata) {
    if (const auto* real = std::get_if<float>(&attribute.value)) {
      text.push_back({attribute.name, fmt::format("{:.9g}", double(*real))});
    } else if (const auto* number = std::get_if<int>(&attribute.value)) {
      text.push_back({attribute.name, std::to_string(*number)});
    } else {
      text.push_back(attribute);
    }
  }
  return text;
}

void write_image(const std::filesystem::path& file, const oiio::ImageSpec& spec, oiio::TypeDesc type,
                 const void* pixels) {
  auto output = oiio::ImageOutput::create(file.string());
  if (!output) {
    throw runtime_error("cannot write " + quoted(file) + ": " + take_error<oiio::ImageOutput>(nullptr));
  }
  if (!output->open(file.string(), spec)) {
    throw runtime_error("cannot write " + quoted(file) + ": " + take_error(output.get()));
  }
  if (!output->write_image(type, pixels)) {
    std::string message = take_error(output.get());
    output->close();
    throw runtime_error("cannot write " + quoted(file) + ": " + message);
  }
  if (!output->close()) {
    throw runtime_error("cannot write " + quoted(file) + ": " + take_error(output.get()));
  }
}

void check_size(const std::filesystem::path& file, int width, int height) {
  if (width <= 0 || height <= 0 || width > max_image_side || height > max_image_side) {
    throw runtime_error("cannot write " + quoted(file) + ": bad size " + std::to_string(width) + " x " +
                        std::to_string(height));
  }
}

}  // namespace

LoadedHeights load_heights(const std::filesystem::path& file, const HeightLoadSettings& settings) {
  auto input = open_input(file);
  const oiio::ImageSpec& spec = input->spec();

  LoadedHeights loaded;
  loaded.width = spec.width;
  loaded.height = spec.height;
  loaded.inverted = settings.invert;
  loaded.channel_index = choose_channel(spec, settings.channel, file);
  loaded.channel_name = spec.channel_name(loaded.channel_index);
  loaded.format = sample_format(spec.channelformat(loaded.channel_index), file);

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
    if (settings.range) {
      throw runtime_error("--height-range applies to float images only; " + quoted(file) + " stores " +
                          (loaded.format == SampleFormat::uint8 ? "8" : "16") +
                          "-bit integers, mapped as value / maximum");
    }
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

const Attribute* find_attribute(const Metadata& metadata, std::string_view name) {
  for (const Attribute& attribute : metadata)
    if (attribute.name == name) return &attribute;
  return nullptr;
}

void write_exr(const std::filesystem::path& file, int width, int height, std::span<const ExrChannel> channels,
               const Metadata& metadata) {
  check_size(file, width, height);
  const std::size_t texels = std::size_t(width) * std::size_t(height);
  if (channels.empty()) throw runtime_error("cannot write " + quoted(file) + ": no channels");
  for (const ExrChannel& channel : channels) {
    if (channel.samples.size() != texels) {
      throw runtime_error("cannot write " + quoted(file) + ": channel '" + channel.name + "' holds " +
                          std::to_string(channel.samples.size()) + " samples, not " + std::to_string(texels));
    }
  }

  // interleave
  const std::size_t count = channels.size();
  std::vector<float> pixels(texels * count);
  for (std::size_t c = 0; c < count; ++c)
    for (std::size_t k = 0; k < texels; ++k) pixels[k * count + c] = channels[c].samples[k];

  oiio::ImageSpec spec(width, height, int(count), oiio::TypeDesc::FLOAT);
  spec.channelnames.clear();
  for (const ExrChannel& channel : channels) spec.channelnames.push_back(channel.name);
  spec.alpha_channel = -1;
  spec.attribute("compression", "zip");
  // no capture date (OpenImageIO writes the current time otherwise): the same content gives the
  // same bytes, so that re-rendered frames and shards of a sequence compare equal
  spec.attribute("DateTime", "");
  add_metadata(spec, metadata);
  write_image(file, spec, oiio::TypeDesc::FLOAT, pixels.data());
}

void write_png_rgba8(const std::filesystem::path& file, int width, int height,
                     std::span<const std::uint8_t> rgba, const Metadata& metadata) {
  check_size(file, width, height);
  if (rgba.size() != std::size_t(width) * std::size_t(height) * 4) {
    throw runtime_error("cannot write " + quoted(file) + ": " + std::to_string(rgba.size()) +
                        " bytes do not make a " + std::to_string(width) + " x " + std::to_string(height) +
                        " RGBA image");
  }
  oiio::ImageSpec spec(width, height, 4, oiio::TypeDesc::UINT8);
  spec.attribute("oiio:UnassociatedAlpha", 1);
  add_metadata(spec, as_text(metadata));
  write_image(file, spec, oiio::TypeDesc::UINT8, rgba.data());
}

void write_png_gray16(const std::filesystem::path& file, int width, int height,
                      std::span<const std::uint16_t> values) {
  check_size(file, width, height);
  if (values.size() != std::size_t(width) * std::size_t(height)) {
    throw runtime_error("cannot write " + quoted(file) + ": " + std::to_string(values.size()) +
                        " samples do not make a " + std::to_string(width) + " x " + std::to_string(height) +
                        " image");
  }
  const oiio::ImageSpec spec(width, height, 1, oiio::TypeDesc::UINT16);
  write_image(file, spec, oiio::TypeDesc::UINT16, values.data());
}

void write_animated_gif(const std::filesystem::path& file, int width, int height,
                        const std::vector<std::vector<std::uint8_t>>& frames, int fps) {
  check_size(file, width, height);
  if (frames.empty()) throw runtime_error("cannot write " + quoted(file) + ": no frames");
  auto output = oiio::ImageOutput::create(file.string());
  if (!output || !output->supports("multiimage")) {
    throw runtime_error("cannot write " + quoted(file) + ": this OpenImageIO writes no animated GIF");
  }
  std::vector<oiio::ImageSpec> specs(frames.size(), oiio::ImageSpec(width, height, 4, oiio::TypeDesc::UINT8));
  const int rate[2] = {std::max(fps, 1), 1};
  for (oiio::ImageSpec& spec : specs) spec.attribute("FramesPerSecond", oiio::TypeRational, rate);
  if (!output->open(file.string(), int(specs.size()), specs.data())) {
    throw runtime_error("cannot write " + quoted(file) + ": " + take_error(output.get()));
  }
  for (std::size_t n = 0; n < frames.size(); ++n) {
    if (frames[n].size() != std::size_t(width) * std::size_t(height) * 4) {
      output->close();
      throw runtime_error("cannot write " + quoted(file) + ": frames of different sizes");
    }
    if ((n > 0 && !output->open(file.string(), specs[n], oiio::ImageOutput::AppendSubimage)) ||
        !output->write_image(oiio::TypeDesc::UINT8, frames[n].data())) {
      const std::string message = take_error(output.get());
      output->close();
      throw runtime_error("cannot write " + quoted(file) + ": " + message);
    }
  }
  if (!output->close()) throw runtime_error("cannot write " + quoted(file) + ": " + take_error(output.get()));
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
  auto input = open_input(file);
  const oiio::ImageSpec& spec = input->spec();
  FloatImage image;
  image.width = spec.width;
  image.height = spec.height;
  for (int c = 0; c < spec.nchannels; ++c) image.channel_names.push_back(spec.channel_name(c));
  image.metadata = read_metadata(spec);
  image.pixels.resize(std::size_t(spec.width) * std::size_t(spec.height) * std::size_t(spec.nchannels));
  if (!input->read_image(0, 0, 0, spec.nchannels, oiio::TypeDesc::FLOAT, image.pixels.data())) {
    throw runtime_error("cannot read the pixels of " + quoted(file) + ": " + take_error(input.get()));
  }
  check_complete(*input, file);
  input->close();
  return image;
}

Rgba8Image read_color_image(const std::filesystem::path& file) {
  auto input = open_input(file);
  const oiio::ImageSpec& spec = input->spec();
  const int channels = spec.nchannels;
  if (channels < 1 || channels > 4) {
    throw runtime_error(quoted(file) + " has " + std::to_string(channels) + " channels; a colour image has 1 to 4");
  }
  std::vector<std::uint8_t> stored(std::size_t(spec.width) * std::size_t(spec.height) * std::size_t(channels));
  if (!input->read_image(0, 0, 0, channels, oiio::TypeDesc::UINT8, stored.data())) {
    throw runtime_error("cannot read the pixels of " + quoted(file) + ": " + take_error(input.get()));
  }
  check_complete(*input, file);
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
  auto input = open_input(file);
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
  if (!input->read_image(0, 0, 0, 4, oiio::TypeDesc::UINT8, image.pixels.data())) {
    throw runtime_error("cannot read the pixels of " + quoted(file) + ": " + take_error(input.get()));
  }
  check_complete(*input, file);
  input->close();
  return image;
}

}  // namespace displace::app
