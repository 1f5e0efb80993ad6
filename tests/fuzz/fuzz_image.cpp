// tests/fuzz/fuzz_image.cpp - libFuzzer target: the height-image loader (app::load_heights) reading
// an image from memory through OpenImageIO's IOMemReader, with every decoder the CLI meets in
// practice. The first byte picks the decoder (its value modulo the number of formats, through the
// name's extension), the second the load settings (channel, inversion, a float range); the rest is
// the file. Any input either gives heights in [0, 1] of the size the image declares, or throws
// AppError with a message; anything else (a crash, a sanitizer report, a height outside [0, 1], an
// exception of another type) is a finding.
//
// Only the decoder the name picks reads the bytes (OpenImageIO's try_all_readers off): by default a
// failed open goes on to every other reader OpenImageIO has, which fuzzes its plugins rather than
// our loader, at a tenth of the speed.
//
// Images are limited to 256 texels a side here (HeightLoadSettings::max_side, which the loader
// checks before it reads a pixel): a 40-byte header can declare 16384 x 16384, and reading such an
// image is a memory test, not a parser test - the CLI's memory guard covers it.
#include <OpenImageIO/imageio.h>

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

#include "demos/error.h"
#include "demos/image_io.h"

namespace {

constexpr std::array<const char*, 6> names = {"fuzz.png", "fuzz.jpg", "fuzz.exr",
                                              "fuzz.tif", "fuzz.bmp", "fuzz.hdr"};

const bool one_reader = OIIO::attribute("try_all_readers", 0);

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 2) return 0;
  const char* name = names[data[0] % names.size()];
  displace::app::HeightLoadSettings settings;
  settings.max_side = 256;
  const std::uint8_t choice = data[1];
  settings.invert = (choice & 1) != 0;
  if (choice & 2) settings.channel.index = (choice >> 2) & 3;
  if (choice & 16) settings.range = displace::app::HeightRange{-1.0f, 2.0f};
  try {
    const displace::app::LoadedHeights loaded =
        displace::app::load_heights(std::span<const std::uint8_t>(data + 2, size - 2), name, settings);
    if (loaded.width < 2 || loaded.height < 2 || loaded.width > 256 || loaded.height > 256) __builtin_trap();
    if (loaded.heights.size() != std::size_t(loaded.width) * std::size_t(loaded.height)) __builtin_trap();
    for (const float h : loaded.heights)
      if (!(h >= 0.0f && h <= 1.0f)) __builtin_trap();
  } catch (const displace::app::AppError& error) {
    if (std::string(error.what()).empty()) __builtin_trap();
  }
  return 0;
}
