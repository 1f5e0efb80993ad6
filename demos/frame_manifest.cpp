// demos/frame_manifest.cpp - the manifest `sequence --resume` trusts (demos/frame_manifest.h).
#include "demos/frame_manifest.h"

#include <fmt/format.h>
#include <sys/stat.h>

#include <cstring>
#include <fstream>
#include <iterator>
#include <sstream>
#include <vector>

#include "demos/image_io.h"

namespace displace::app {
namespace {

constexpr const char* manifest_header = "displace-manifest 1: bytes modified_ns fnv1a64 name";

std::filesystem::path absolute_normal(const std::filesystem::path& path) {
  std::error_code error;
  const std::filesystem::path absolute = std::filesystem::absolute(path, error);
  return (error ? path : absolute).lexically_normal();
}

bool read_bytes(const std::filesystem::path& file, std::vector<std::byte>& bytes) {
  std::ifstream stream(file, std::ios::binary);
  if (!stream) return false;
  std::vector<char> text((std::istreambuf_iterator<char>(stream)), std::istreambuf_iterator<char>());
  if (stream.bad()) return false;
  bytes.resize(text.size());
  std::memcpy(bytes.data(), text.data(), text.size());
  return true;
}

}  // namespace

FrameManifest::FrameManifest(std::filesystem::path file)
    : file_(std::move(file)), directory_(absolute_normal(file_).parent_path()) {}

std::string FrameManifest::key(const std::filesystem::path& file) const {
  return absolute_normal(file).lexically_relative(directory_).string();
}

bool is_sequence_file(const std::filesystem::path& file, const std::string& stem,
                      const std::string& extension) {
  const std::string name = file.filename().string();
  return file.extension() == extension && (name == stem + extension || name.rfind(stem + ".shard", 0) == 0);
}

void FrameManifest::read_beside(const std::string& stem) {
  std::error_code error;
  for (const auto& entry : std::filesystem::directory_iterator(directory_, error)) {
    if (!is_sequence_file(entry.path(), stem, ".manifest")) continue;
    std::ifstream stream(entry.path());
    std::string line;
    if (!std::getline(stream, line) || line != manifest_header) continue;
    while (std::getline(stream, line)) {
      std::istringstream fields(line);
      files::WrittenFile known;
      std::string checksum, file;
      if (!(fields >> known.bytes >> known.modified_ns >> checksum) || checksum.size() != 16) continue;
      fields.get();  // the one space before the name, which may hold spaces itself
      std::getline(fields, file);
      if (file.empty()) continue;
      try {
        known.checksum = std::stoull(checksum, nullptr, 16);
      } catch (const std::exception&) {
        continue;
      }
      known_.emplace(file, known);
    }
  }
}

bool FrameManifest::whole(const std::filesystem::path& file) {
  struct ::stat status {};
  if (::stat(file.c_str(), &status) != 0 || !S_ISREG(status.st_mode) || status.st_size == 0) return false;
  const std::string name = key(file);
  const auto [first, last] = known_.equal_range(name);
  files::WrittenFile present;
  present.bytes = std::uint64_t(status.st_size);
  present.modified_ns = std::int64_t(status.st_mtim.tv_sec) * 1000000000 + status.st_mtim.tv_nsec;
  // 1. size and time
  for (auto entry = first; entry != last; ++entry) {
    if (entry->second.bytes == present.bytes && entry->second.modified_ns == present.modified_ns) {
      mine_[name] = entry->second;
      return true;
    }
  }
  // 2. size and checksum
  std::vector<std::byte> bytes;
  if (!read_bytes(file, bytes) || bytes.size() != present.bytes) return false;
  present.checksum = files::checksum(bytes);
  for (auto entry = first; entry != last; ++entry) {
    if (entry->second.bytes == present.bytes && entry->second.checksum == present.checksum) {
      mine_[name] = present;
      return true;
    }
  }
  // 3. every pixel decodes
  if (!decodes_whole(file)) return false;
  mine_[name] = present;
  return true;
}

void FrameManifest::add(const std::filesystem::path& file, const files::WrittenFile& written) {
  mine_[key(file)] = written;
}

void FrameManifest::save() const {
  std::string text = std::string(manifest_header) + '\n';
  for (const auto& [name, entry] : mine_) {
    text += fmt::format("{} {} {:016x} {}\n", entry.bytes, entry.modified_ns, entry.checksum, name);
  }
  files::write_file(file_, text);
}

}  // namespace displace::app
