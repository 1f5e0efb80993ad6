// The checked writer (render/files.h) under real faults: a full file system (a tmpfs this test mounts
// where the machine lets it), a file size limit (RLIMIT_FSIZE, in a child process), a device that is
// always full, a read-only directory, a directory that is gone. Each time: one WriteError naming the
// file and the system's reason, nothing under the final name, no temporary left.
#include "render/files.h"

#include <gtest/gtest.h>
#include <sys/mount.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

namespace displace::files {
namespace {

namespace fs = std::filesystem;

class FilesTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (fs::temp_directory_path() / "displace-files-XXXXXX").string();
    ASSERT_NE(::mkdtemp(pattern.data()), nullptr);
    directory_ = pattern;
  }
  void TearDown() override {
    if (mounted_) ::umount2(mounted_path_.c_str(), MNT_DETACH);
    std::error_code error;
    fs::permissions(directory_, fs::perms::owner_all, fs::perm_options::add, error);
    fs::remove_all(directory_, error);
  }
  // A tmpfs of `kilobytes` at directory_/name; empty when the machine does not allow mounting.
  fs::path mount_tmpfs(const std::string& name, int kilobytes, bool read_only = false) {
    const fs::path at = directory_ / name;
    fs::create_directories(at);
    const std::string options = "size=" + std::to_string(kilobytes) + "k";
    if (::mount("tmpfs", at.c_str(), "tmpfs", read_only ? MS_RDONLY : 0, options.c_str()) != 0) return {};
    mounted_ = true;
    mounted_path_ = at;
    return at;
  }
  // The names in `at`, hidden ones included.
  static std::vector<std::string> names_in(const fs::path& at) {
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(at)) names.push_back(entry.path().filename().string());
    return names;
  }
  static std::string read_text(const fs::path& file) {
    std::ifstream stream(file, std::ios::binary);
    return {std::istreambuf_iterator<char>(stream), std::istreambuf_iterator<char>()};
  }

  fs::path directory_;
  bool mounted_ = false;
  fs::path mounted_path_;
};

TEST_F(FilesTest, WritesTheBytesAndSaysWhatReachedTheDisk) {
  const fs::path file = directory_ / "a.txt";
  const WrittenFile written = write_file(file, std::string_view("hello"));
  EXPECT_EQ(read_text(file), "hello");
  struct ::stat status {};
  ASSERT_EQ(::stat(file.c_str(), &status), 0);
  EXPECT_EQ(written.bytes, 5u);
  EXPECT_EQ(written.modified_ns, std::int64_t(status.st_mtim.tv_sec) * 1000000000 + status.st_mtim.tv_nsec);
  // FNV-1a 64 of "hello", computed by its definition elsewhere
  EXPECT_EQ(written.checksum, 0xa430d84680aabd0bull);
  EXPECT_EQ(names_in(directory_), std::vector<std::string>{"a.txt"});
}

TEST_F(FilesTest, ReplacesAFileWholeAndKeepsItsMode) {
  const fs::path file = directory_ / "b.csv";
  write_file(file, std::string_view("old and longer"));
  ASSERT_EQ(::chmod(file.c_str(), 0640), 0);
  write_file(file, std::string_view("new"));
  EXPECT_EQ(read_text(file), "new");
  struct ::stat status {};
  ASSERT_EQ(::stat(file.c_str(), &status), 0);
  EXPECT_EQ(status.st_mode & 07777, 0640u);
}

TEST_F(FilesTest, WritesThroughALinkAndKeepsTheLink) {
  const fs::path target = directory_ / "target.txt", link = directory_ / "link.txt";
  write_file(target, std::string_view("1"));
  fs::create_symlink(target, link);
  write_file(link, std::string_view("2"));
  EXPECT_TRUE(fs::is_symlink(link));
  EXPECT_EQ(read_text(target), "2");
}

TEST_F(FilesTest, RefusesWhatIsNotARegularFile) {
  // /dev/full is never replaced (a rename over a device node would be the worst write of all)
  try {
    write_file("/dev/full", std::string_view("x"));
    FAIL() << "wrote /dev/full";
  } catch (const WriteError& error) {
    EXPECT_EQ(std::string(error.what()), "cannot write '/dev/full': not a regular file");
  }
  struct ::stat status {};
  ASSERT_EQ(::stat("/dev/full", &status), 0);
  EXPECT_TRUE(S_ISCHR(status.st_mode));
  EXPECT_THROW(write_file(directory_, std::string_view("x")), WriteError);
}

TEST_F(FilesTest, AFullFileSystemLeavesNothing) {
  const fs::path small = mount_tmpfs("small", 64);
  if (small.empty()) GTEST_SKIP() << "this machine does not let the test mount a tmpfs (not root?)";
  write_file(small / "fits.bin", std::string(16 * 1024, 'a'));
  const std::string big(128 * 1024, 'b');
  try {
    write_file(small / "big.bin", big);
    FAIL() << "128 kB went into what was left of 64 kB";
  } catch (const WriteError& error) {
    EXPECT_EQ(std::string(error.what()),
              "cannot write '" + (small / "big.bin").string() + "': No space left on device");
    EXPECT_EQ(error.file, small / "big.bin");
  }
  EXPECT_EQ(names_in(small), std::vector<std::string>{"fits.bin"});
  // replacing a file that is there: the old one stays whole
  EXPECT_THROW(write_file(small / "fits.bin", big), WriteError);
  EXPECT_EQ(read_text(small / "fits.bin"), std::string(16 * 1024, 'a'));
  EXPECT_EQ(names_in(small), std::vector<std::string>{"fits.bin"});
}

TEST_F(FilesTest, AFileSizeLimitLeavesNothing) {
  // in a child: the limit and SIGXFSZ ignored (a write past the limit then fails with EFBIG)
  const fs::path file = directory_ / "limited.bin";
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    std::signal(SIGXFSZ, SIG_IGN);
    const struct rlimit limit = {4096, 4096};
    if (::setrlimit(RLIMIT_FSIZE, &limit) != 0) ::_exit(3);
    try {
      write_file(file, std::string(10000, 'c'));
    } catch (const WriteError& error) {
      ::_exit(std::string(error.what()) == "cannot write '" + file.string() + "': File too large" ? 0 : 2);
    }
    ::_exit(1);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0) << "1: wrote past the limit, 2: another message, 3: no limit";
  EXPECT_TRUE(names_in(directory_).empty());
}

TEST_F(FilesTest, AReadOnlyDirectoryLeavesNothing) {
  fs::path read_only;
  if (::geteuid() != 0) {
    read_only = directory_ / "read-only";
    fs::create_directories(read_only);
    fs::permissions(read_only, fs::perms::owner_read | fs::perms::owner_exec);
  } else {
    read_only = mount_tmpfs("read-only", 64, true);  // root writes into a mode 0555 directory
    if (read_only.empty()) GTEST_SKIP() << "root, and no read-only tmpfs can be mounted";
  }
  try {
    write_file(read_only / "c.txt", std::string_view("x"));
    FAIL() << "wrote into a read-only directory";
  } catch (const WriteError& error) {
    const std::string reason = error.reason;
    EXPECT_TRUE(reason == "Read-only file system" || reason == "Permission denied") << reason;
  }
  EXPECT_TRUE(names_in(read_only).empty());
}

TEST_F(FilesTest, ADirectoryThatIsGoneLeavesNothing) {
  const fs::path gone = directory_ / "gone";
  fs::create_directories(gone);
  fs::remove(gone);
  try {
    write_file(gone / "d.txt", std::string_view("x"));
    FAIL() << "wrote into a directory that is gone";
  } catch (const WriteError& error) {
    EXPECT_EQ(error.reason, "No such file or directory");
  }
  EXPECT_FALSE(fs::exists(gone));
}

}  // namespace
}  // namespace displace::files
