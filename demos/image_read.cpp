// demos/image_read.cpp - whole images in, through OpenImageIO (demos/image_oiio.h).
//
// Whole images only: a read that fails, or succeeds with an error left behind (libjpeg fills the
// rows of a truncated JPEG and leaves "Premature end of JPEG file"; libtiff fills missing strips and
// leaves one message per strip), is refused as truncated or corrupt, with the libraries' messages
// folded into one line (one_line()).
//
// Library noise: libpng, as OpenImageIO 2.4 sets it up (libpng's default error handler), prints
// "libpng error: ..." on the process's stderr before OpenImageIO records the same error, and
// OpenImageIO has no setting that stops it. So opens and reads run with file descriptor 2 pointed
// at an anonymous temporary file (StderrCapture); afterwards fd 2 is put back and what the
// libraries wrote is folded into the error, or dropped when the read succeeded. A file rather than
// a pipe: a pipe nobody drains during the read would fill up and block the library's write.
#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>
#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <memory>
#include <mutex>
#include <string_view>
#include <vector>

#include "demos/error.h"
#include "demos/image_oiio.h"

namespace displace::app {
namespace {

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

}  // namespace

std::string channel_list(const oiio::ImageSpec& spec) {
  std::string list;
  for (int c = 0; c < spec.nchannels; ++c) {
    if (c > 0) list += ", ";
    list += spec.channel_name(c);
  }
  return list;
}

// Opens `file`, or the bytes of `memory` (then `file` only names the image and its extension
// picks the format).
std::unique_ptr<oiio::ImageInput> open_input(const std::filesystem::path& file, const ImageUse& use,
                                             oiio::Filesystem::IOProxy* memory) {
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

}  // namespace displace::app

namespace displace::app {

bool decodes_whole(const std::filesystem::path& file) {
  try {
    const ImageUse frame_use{"a frame", 1};
    std::unique_ptr<oiio::ImageInput> input = open_input(file, frame_use, nullptr);
    const oiio::ImageSpec& spec = input->spec();
    std::vector<float> pixels(std::size_t(spec.width) * std::size_t(spec.height) *
                              std::size_t(spec.nchannels));
    read_pixels(*input, 0, spec.nchannels, oiio::TypeDesc::FLOAT, pixels.data(), file);
    return true;
  } catch (const AppError&) {
    return false;
  }
}

}  // namespace displace::app
