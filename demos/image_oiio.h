// demos/image_oiio.h - what the image readers and writers of demos/ share about OpenImageIO: a file
// named in messages, and the library's pending error taken as one line.
#pragma once

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <filesystem>
#include <memory>
#include <string>

#include "demos/image_io.h"

namespace displace::app {

namespace oiio = OIIO;

// (appended: GCC 12 warns, -Wrestrict, on "'" + std::string once this is inlined)
inline std::string quoted(const std::filesystem::path& file) {
  std::string text = "'";
  text.append(file.string()).append("'");
  return text;
}

// Takes the pending error of an ImageOutput (or the global one) so that none is left unretrieved,
// and makes it one line.
template <typename Io>
inline std::string take_error(Io* io) {
  std::string message = io ? io->geterror() : oiio::geterror();
  if (io) {
    std::string global = oiio::geterror();
    if (message.empty()) message = global;
  }
  while (!message.empty() && (message.back() == '\n' || message.back() == ' ')) message.pop_back();
  std::replace(message.begin(), message.end(), '\n', ' ');
  return message.empty() ? std::string("unknown error") : message;
}

// The channels of `spec`, "R, G, B".
std::string channel_list(const oiio::ImageSpec& spec);

// What an image is read for: the smallest side it may have and the words of the errors.
struct ImageUse {
  const char* noun;  // "a height map"
  int min_side;      // pixels
  int max_side = max_image_side;
};
inline constexpr ImageUse height_map_use{"a height map",
                                         2};  // a single texel (or row) has no relief to displace
inline constexpr ImageUse albedo_use{"an albedo image", 1};
inline constexpr ImageUse data_use{"an image", 1};  // cone maps and float images read back

// Opens `file`, or the bytes of `memory` (then `file` only names the image and its extension picks the
// format), refusing what `use` cannot take; throws AppError naming the file.
std::unique_ptr<oiio::ImageInput> open_input(const std::filesystem::path& file, const ImageUse& use,
                                             oiio::Filesystem::IOProxy* memory = nullptr);
// Reads channels [first, end) of every pixel as `type`; a file that is not whole is refused.
void read_pixels(oiio::ImageInput& input, int first, int end, oiio::TypeDesc type, void* pixels,
                 const std::filesystem::path& file);

}  // namespace displace::app
