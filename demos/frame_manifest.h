// demos/frame_manifest.h - what `sequence --resume` trusts: the files a run wrote, each with its size,
// modification time and checksum (files::WrittenFile).
//
// A run keeps its manifest next to its per-frame CSV (STEM.manifest, or STEM.shardIofN.manifest),
// saved by the checked writer together with the CSV. Names in it are relative to its directory. A
// resumed run reads every manifest of the sequence in that directory (any shard layout) and judges
// each present file:
//   1. its size and modification time are the manifest's: whole, without reading a byte (checking
//      10,000 frames costs 10,000 stats);
//   2. else its size and the FNV-1a checksum of its bytes are the manifest's: whole (a copy that lost
//      its time);
//   3. else it decodes whole (decodes_whole(): a frame of a run that kept no manifest, or a killed one);
//   4. else (empty, truncated, corrupt): not whole, and rendered again.
// A file judged whole joins this run's manifest, so the next resume finds it at step 1.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>

#include "render/files.h"

namespace displace::app {

// Whether `file` is STEM.EXTENSION or STEM.shard*.EXTENSION: a sequence's CSV or manifest, of any
// shard layout.
bool is_sequence_file(const std::filesystem::path& file, const std::string& stem,
                      const std::string& extension);

class FrameManifest {
 public:
  explicit FrameManifest(std::filesystem::path file);

  // Reads every manifest of the sequence STEM in this one's directory (STEM.manifest,
  // STEM.shard*.manifest); unreadable lines are skipped (a file they named is then judged by its bytes).
  void read_beside(const std::string& stem);
  // Whether `file` is present and whole, by the rules above.
  bool whole(const std::filesystem::path& file);
  void add(const std::filesystem::path& file, const files::WrittenFile& written);
  // Writes this run's entries (written or judged whole) through the checked writer.
  void save() const;

 private:
  std::string key(const std::filesystem::path& file) const;

  std::filesystem::path file_, directory_;
  std::multimap<std::string, files::WrittenFile> known_;  // from the manifests read
  std::map<std::string, files::WrittenFile> mine_;        // this run's
};

}  // namespace displace::app
