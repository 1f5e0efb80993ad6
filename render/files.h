// render/files.h - the one way the project writes a file: whole under its final name, or not at all.
//
// write_file(path, bytes) writes a temporary in the target's directory (".NAME.partial-PID-N"), checks
// every write, fsyncs and closes it, renames it over `path` and fsyncs the directory. On any failure
// it removes the temporary and throws WriteError, whose what() is one line naming the file and the
// system's reason: "cannot write 'out/w_0009.png': No space left on device". A target that exists and
// is not a regular file (a directory, /dev/full) is refused, never replaced; a symbolic link to a
// regular file is written through (the link stays). Directories are not made.
//
// remove_partial_files() unlinks the temporaries being written at that moment and is async-signal-safe:
// a signal handler that ends the process at once calls it, and no half file is left under any name.
//
// It lives in render/, the lowest library that writes a file (the pipeline cache); everything above
// (pipeline/, the app's frames, maps, tables and reports) writes through it too.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>

namespace displace::files {

struct WriteError : std::runtime_error {
  WriteError(const std::filesystem::path& target, const std::string& reason);
  std::filesystem::path file;
  std::string reason;  // the system's words ("No space left on device"), or what was refused
};

// What reached the disk: its size, its modification time (ns since the epoch, as stat gives it) and
// the FNV-1a checksum of its bytes (checksum()).
struct WrittenFile {
  std::uint64_t bytes = 0;
  std::int64_t modified_ns = 0;
  std::uint64_t checksum = 0;
};

WrittenFile write_file(const std::filesystem::path& file, std::span<const std::byte> bytes);
WrittenFile write_file(const std::filesystem::path& file, std::string_view text);

// 64-bit FNV-1a over bytes: what WrittenFile::checksum holds.
std::uint64_t checksum(std::span<const std::byte> bytes);

// Async-signal-safe: unlinks every temporary a write_file in this process is writing now.
void remove_partial_files() noexcept;

}  // namespace displace::files
