// demos/text_file.h - a text file (a CSV table, a JSON document) built in memory and written whole by
// the checked writer (render/files.h) at each save(): a table that grows row by row is on disk as of
// its last save, never with half a row, and a failed save throws files::WriteError.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <utility>

#include "render/files.h"

namespace displace::app {

class TextFile {
 public:
  explicit TextFile(std::filesystem::path file, std::string_view first_line = {})
      : file_(std::move(file)), text_(first_line) {
    if (!text_.empty()) text_ += '\n';
  }
  TextFile& operator<<(std::string_view text) {
    text_ += text;
    return *this;
  }
  void save() const { files::write_file(file_, text_); }

 private:
  std::filesystem::path file_;
  std::string text_;
};

}  // namespace displace::app
