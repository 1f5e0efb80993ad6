// render/files.cpp - the checked writer (render/files.h): temporary, every write checked, fsync,
// rename, fsync of the directory.
#include "render/files.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <cerrno>
#include <climits>
#include <cstring>

namespace displace::files {
namespace {

// The temporaries being written now, for remove_partial_files() (a signal handler). A slot is free
// (0), being filled (1) or holds a path (2); with every slot taken a write goes on unregistered.
constexpr std::size_t partial_slots = 16;
struct PartialSlot {
  std::atomic<int> state{0};
  char path[PATH_MAX] = {};
};
std::array<PartialSlot, partial_slots> partials;
std::atomic<unsigned long> temporaries_made{0};

class PartialRegistration {
 public:
  explicit PartialRegistration(const std::string& path) {
    if (path.size() >= PATH_MAX) return;
    for (PartialSlot& candidate : partials) {
      int free = 0;
      if (!candidate.state.compare_exchange_strong(free, 1)) continue;
      std::memcpy(candidate.path, path.c_str(), path.size() + 1);
      candidate.state.store(2);
      slot_ = &candidate;
      return;
    }
  }
  ~PartialRegistration() {
    if (slot_) slot_->state.store(0);
  }
  PartialRegistration(const PartialRegistration&) = delete;
  PartialRegistration& operator=(const PartialRegistration&) = delete;

 private:
  PartialSlot* slot_ = nullptr;
};

std::string system_reason(int error_number) { return std::strerror(error_number); }

// Closes the descriptor and removes the temporary unless released.
class Temporary {
 public:
  Temporary(std::string path, int descriptor) : path_(std::move(path)), descriptor_(descriptor) {}
  ~Temporary() {
    if (descriptor_ >= 0) ::close(descriptor_);
    if (!path_.empty()) ::unlink(path_.c_str());
  }
  Temporary(const Temporary&) = delete;
  Temporary& operator=(const Temporary&) = delete;
  int descriptor() const { return descriptor_; }
  const std::string& path() const { return path_; }
  // closes the descriptor; false with errno set when the close reported an error
  bool close() {
    const int descriptor = descriptor_;
    descriptor_ = -1;
    return ::close(descriptor) == 0;
  }
  void renamed() { path_.clear(); }

 private:
  std::string path_;
  int descriptor_ = -1;
};

void write_all(const std::filesystem::path& file, int descriptor, std::span<const std::byte> bytes) {
  std::size_t written = 0;
  while (written < bytes.size()) {
    const ::ssize_t count = ::write(descriptor, bytes.data() + written, bytes.size() - written);
    if (count < 0) {
      if (errno == EINTR) continue;
      throw WriteError(file, system_reason(errno));
    }
    if (count == 0) throw WriteError(file, "the file system took no more bytes");
    written += std::size_t(count);
  }
}

// The directory holding `file`, fsynced so that the rename survives a crash. Some file systems
// cannot sync a directory (EINVAL): the rename stands there as the system keeps it.
void sync_directory(const std::filesystem::path& file, const std::filesystem::path& directory) {
  const int descriptor = ::open(directory.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (descriptor < 0) throw WriteError(file, "its directory: " + system_reason(errno));
  const bool synced = ::fsync(descriptor) == 0 || errno == EINVAL;
  const int error_number = errno;
  ::close(descriptor);
  if (!synced) throw WriteError(file, "its directory: " + system_reason(error_number));
}

}  // namespace

WriteError::WriteError(const std::filesystem::path& target, const std::string& why)
    : std::runtime_error(std::string("cannot write '").append(target.string()).append("': ").append(why)),
      file(target),
      reason(why) {}

std::uint64_t checksum(std::span<const std::byte> bytes) {
  std::uint64_t hash = 14695981039346656037ull;
  for (const std::byte byte : bytes) {
    hash ^= std::uint64_t(byte);
    hash *= 1099511628211ull;
  }
  return hash;
}

WrittenFile write_file(const std::filesystem::path& requested, std::span<const std::byte> bytes) {
  // the target: a regular file (through a link) or nothing yet
  std::filesystem::path file = requested;
  struct ::stat existing {};
  mode_t mode = 0666;
  bool replaces = false;
  if (::lstat(file.c_str(), &existing) == 0 && S_ISLNK(existing.st_mode)) {
    std::error_code error;
    const std::filesystem::path target = std::filesystem::canonical(file, error);
    if (error) throw WriteError(requested, "a link to nowhere that can be written");
    file = target;
  }
  if (::stat(file.c_str(), &existing) == 0) {
    if (!S_ISREG(existing.st_mode)) throw WriteError(requested, "not a regular file");
    mode = existing.st_mode & 07777;
    replaces = true;
  } else if (errno != ENOENT) {
    throw WriteError(requested, system_reason(errno));
  }
  const std::filesystem::path directory = file.has_parent_path() ? file.parent_path() : ".";
  if (file.filename().empty()) throw WriteError(requested, "no file name");

  // the temporary: same directory, so that the rename is atomic
  // (appended: GCC 12 warns, -Wrestrict, on "." + std::string)
  std::string temporary_name(".");
  temporary_name.append(file.filename().string())
      .append(".partial-")
      .append(std::to_string(::getpid()))
      .append("-")
      .append(std::to_string(temporaries_made.fetch_add(1)));
  const std::string temporary_path = (directory / temporary_name).string();
  const PartialRegistration registration(temporary_path);
  const int descriptor = ::open(temporary_path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
  if (descriptor < 0) throw WriteError(requested, system_reason(errno));
  Temporary temporary(temporary_path, descriptor);
  if (replaces && ::fchmod(descriptor, mode) != 0) throw WriteError(requested, system_reason(errno));

  // every byte, then to the disk
  write_all(requested, descriptor, bytes);
  if (::fsync(descriptor) != 0) throw WriteError(requested, system_reason(errno));
  struct ::stat written {};
  if (::fstat(descriptor, &written) != 0) throw WriteError(requested, system_reason(errno));
  if (std::uint64_t(written.st_size) != bytes.size()) {
    throw WriteError(requested, std::to_string(written.st_size) + " of " + std::to_string(bytes.size()) +
                                    " bytes reached the disk");
  }
  if (!temporary.close()) throw WriteError(requested, system_reason(errno));

  // into place
  if (::rename(temporary.path().c_str(), file.c_str()) != 0)
    throw WriteError(requested, system_reason(errno));
  temporary.renamed();
  sync_directory(requested, directory);

  WrittenFile facts;
  facts.bytes = bytes.size();
  facts.modified_ns = std::int64_t(written.st_mtim.tv_sec) * 1000000000 + written.st_mtim.tv_nsec;
  facts.checksum = checksum(bytes);
  return facts;
}

WrittenFile write_file(const std::filesystem::path& file, std::string_view text) {
  return write_file(file, std::as_bytes(std::span(text.data(), text.size())));
}

void remove_partial_files() noexcept {
  for (PartialSlot& slot : partials) {
    if (slot.state.load() == 2) ::unlink(slot.path);
  }
}

}  // namespace displace::files
