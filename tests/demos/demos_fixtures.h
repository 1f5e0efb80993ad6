// tests/demos/demos_fixtures.h - what the application layer's tests share: temporary directories, files
// written independently of image_io, and running the `displace` binary.
// Moved from tests/app_test.cpp; functions are inline, in the anonymous namespace the tests use.
#pragma once

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>
#include <sched.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <span>
#include <sstream>
#include <string>
#include <vector>

#include "bake/bake.h"
#include "demos/cli/command.h"
#include "demos/commands/settings.h"
#include "demos/cone_export.h"
#include "demos/heights.h"
#include "demos/image_io.h"
#include "demos/obj_io.h"
#include "demos/play.h"
#include "demos/progress.h"
#include "pipeline/frame_pipeline.h"
#include "pipeline/scene.h"
#include "render/render.h"

namespace {

namespace fs = std::filesystem;
using namespace displace::app;

// A fresh directory under the system temp directory, removed with everything in it.
class TempDir {
 public:
  TempDir() {
    static std::atomic<int> counter{0};
    path_ = fs::temp_directory_path() /
            ("displace_app_test_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ignored;
    fs::remove_all(path_, ignored);
  }
  fs::path operator/(const std::string& name) const { return path_ / name; }

 private:
  fs::path path_;
};

// Writes an image with OpenImageIO directly, independently of image_io.
inline void write_with_oiio(const fs::path& file, int width, int height, int channels, OIIO::TypeDesc type,
                            const void* pixels, const std::vector<std::string>& names = {},
                            const std::vector<std::pair<std::string, float>>& attributes = {}) {
  OIIO::ImageSpec spec(width, height, channels, type);
  if (!names.empty()) spec.channelnames = names;
  for (const auto& [name, value] : attributes) spec.attribute(name, value);
  auto output = OIIO::ImageOutput::create(file.string());
  ASSERT_TRUE(output) << OIIO::geterror();
  ASSERT_TRUE(output->open(file.string(), spec)) << output->geterror();
  ASSERT_TRUE(output->write_image(type, pixels)) << output->geterror();
  ASSERT_TRUE(output->close());
}

inline void write_bytes(const fs::path& file, const std::string& bytes) {
  std::ofstream stream(file, std::ios::binary);
  stream << bytes;
}

inline std::string read_text(const fs::path& file) {
  std::ifstream stream(file);
  std::stringstream text;
  text << stream.rdbuf();
  return text.str();
}

// Random 8-bit samples: they do not compress, so half the file is about half the pixels.
inline std::vector<std::uint8_t> noise_pixels(int width, int height, int channels, unsigned seed) {
  std::mt19937 random(seed);
  std::vector<std::uint8_t> pixels(std::size_t(width) * height * channels);
  for (auto& p : pixels) p = std::uint8_t(random() >> 24);
  return pixels;
}

// `file`'s first `fraction` of bytes, written as `cut`.
inline void write_first_part(const fs::path& file, const fs::path& cut, double fraction) {
  const std::string bytes = read_text(file);
  write_bytes(cut, bytes.substr(0, std::size_t(double(bytes.size()) * fraction)));
}

// ---------------------------------------------------------------------------------------------
// the binary

struct RunResult {
  bool exited = false;  // exited normally (not killed by a signal)
  int exit_code = -1;
  std::string out, err;
};

// `prefix` goes before the binary (a wrapper such as "xvfb-run -a ", or "env -u DISPLAY ").
inline RunResult run_displace(const TempDir& dir, const std::string& arguments,
                              const std::string& prefix = "") {
  const fs::path out = dir / "stdout.txt", err = dir / "stderr.txt";
  const std::string command = prefix + "'" + std::string(DISPLACE_BINARY) + "' " + arguments + " >'" +
                              out.string() + "' 2>'" + err.string() + "'";
  const int status = std::system(command.c_str());
  RunResult result;
  result.exited = status != -1 && WIFEXITED(status);
  result.exit_code = result.exited ? WEXITSTATUS(status) : -1;
  result.out = read_text(out);
  result.err = read_text(err);
  return result;
}

}  // namespace
