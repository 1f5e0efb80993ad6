// demos/image_write.cpp - float EXR, RGBA8 and 16-bit grey PNG, and animated GIF out: encoded in
// memory by OpenImageIO, written by the checked writer (demos/image_io.h, render/files.h). PNG alpha
// is written straight (oiio:UnassociatedAlpha = 1): cone maps use it as a data channel. A PNG's
// attributes are text chunks: numbers are written in decimal.
#include <fmt/format.h>

#include <cstdint>
#include <span>
#include <vector>

#include "demos/image_io.h"
#include "demos/image_oiio.h"
#include "render/files.h"

namespace displace::app {
namespace {

void check_size(const std::filesystem::path& file, int width, int height) {
  if (width <= 0 || height <= 0 || width > max_image_side || height > max_image_side) {
    throw runtime_error("cannot write " + quoted(file) + ": bad size " + std::to_string(width) + " x " +
                        std::to_string(height));
  }
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

// Encodes into memory (OpenImageIO's I/O proxy): the image library never touches the disk, and the
// bytes go through the checked writer, which sees every failed write (render/files.h).
std::vector<unsigned char> encode(const std::filesystem::path& file, std::span<const oiio::ImageSpec> specs,
                                  oiio::TypeDesc type, std::span<const void* const> pixels) {
  auto output = oiio::ImageOutput::create(file.string());
  if (!output) {
    throw runtime_error("cannot write " + quoted(file) + ": " + take_error<oiio::ImageOutput>(nullptr));
  }
  if (specs.size() > 1 && !output->supports("multiimage")) {
    throw runtime_error("cannot write " + quoted(file) + ": this OpenImageIO writes one image to it, not " +
                        std::to_string(specs.size()));
  }
  std::vector<unsigned char> bytes;
  oiio::Filesystem::IOVecOutput memory(bytes);
  if (!output->set_ioproxy(&memory)) {
    throw runtime_error("cannot write " + quoted(file) + ": " + take_error(output.get()));
  }
  const bool opened = specs.size() > 1 ? output->open(file.string(), int(specs.size()), specs.data())
                                       : output->open(file.string(), specs[0]);
  if (!opened) throw runtime_error("cannot write " + quoted(file) + ": " + take_error(output.get()));
  for (std::size_t n = 0; n < specs.size(); ++n) {
    if ((n > 0 && !output->open(file.string(), specs[n], oiio::ImageOutput::AppendSubimage)) ||
        !output->write_image(type, pixels[n])) {
      const std::string message = take_error(output.get());
      output->close();
      throw runtime_error("cannot write " + quoted(file) + ": " + message);
    }
  }
  if (!output->close()) throw runtime_error("cannot write " + quoted(file) + ": " + take_error(output.get()));
  return bytes;
}

files::WrittenFile write_image(const std::filesystem::path& file, const oiio::ImageSpec& spec,
                               oiio::TypeDesc type, const void* pixels) {
  const std::vector<unsigned char> bytes = encode(file, std::span(&spec, 1), type, std::span(&pixels, 1));
  return files::write_file(file, std::as_bytes(std::span(bytes)));
}

}  // namespace

files::WrittenFile write_exr(const std::filesystem::path& file, int width, int height,
                             std::span<const ExrChannel> channels, const Metadata& metadata) {
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
  return write_image(file, spec, oiio::TypeDesc::FLOAT, pixels.data());
}

files::WrittenFile write_png_rgba8(const std::filesystem::path& file, int width, int height,
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
  return write_image(file, spec, oiio::TypeDesc::UINT8, rgba.data());
}

files::WrittenFile write_png_gray16(const std::filesystem::path& file, int width, int height,
                                    std::span<const std::uint16_t> values) {
  check_size(file, width, height);
  if (values.size() != std::size_t(width) * std::size_t(height)) {
    throw runtime_error("cannot write " + quoted(file) + ": " + std::to_string(values.size()) +
                        " samples do not make a " + std::to_string(width) + " x " + std::to_string(height) +
                        " image");
  }
  const oiio::ImageSpec spec(width, height, 1, oiio::TypeDesc::UINT16);
  return write_image(file, spec, oiio::TypeDesc::UINT16, values.data());
}

files::WrittenFile write_animated_gif(const std::filesystem::path& file, int width, int height,
                                      const std::vector<std::vector<std::uint8_t>>& frames, int fps) {
  check_size(file, width, height);
  if (frames.empty()) throw runtime_error("cannot write " + quoted(file) + ": no frames");
  std::vector<oiio::ImageSpec> specs(frames.size(), oiio::ImageSpec(width, height, 4, oiio::TypeDesc::UINT8));
  const int rate[2] = {std::max(fps, 1), 1};
  for (oiio::ImageSpec& spec : specs) spec.attribute("FramesPerSecond", oiio::TypeRational, rate);
  std::vector<const void*> pixels;
  for (const std::vector<std::uint8_t>& frame : frames) {
    if (frame.size() != std::size_t(width) * std::size_t(height) * 4) {
      throw runtime_error("cannot write " + quoted(file) + ": frames of different sizes");
    }
    pixels.push_back(frame.data());
  }
  const std::vector<unsigned char> bytes = encode(file, specs, oiio::TypeDesc::UINT8, pixels);
  return files::write_file(file, std::as_bytes(std::span(bytes)));
}

}  // namespace displace::app
