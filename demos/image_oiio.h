// demos/image_oiio.h - what the image readers and writers of demos/ share about OpenImageIO: a file
// named in messages, and the library's pending error taken as one line.
#pragma once

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <filesystem>
#include <string>

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

}  // namespace displace::app
