// bake/relaxed_search.h - bake_relaxed's search, row by row (internal to bake/): what a map needs
// made once, then any rows of its relaxed cone map, each row seeded by the row before it when both
// are done in the same call. Any split of the rows gives the same map, bit for bit (the seeds change
// the work only); bake_relaxed and RelaxedBaker share it.
#pragma once

#include <memory>

#include "bake/bake.h"

namespace displace::bake::detail {

class RelaxedSearch {
 public:
  // heights (validated by the caller) are read, not copied: they must outlive the search.
  // sector_count: 1 or 4.
  RelaxedSearch(HeightView heights, Address address, int sector_count);
  ~RelaxedSearch();

  // Rows [first, last) of the relaxed map into `out` (the whole map: W x H x sectors), in order.
  // Returns the work done (candidates followed and cells of their rays). Thread safe: calls on
  // disjoint rows may run at once.
  long long rows(int first, int last, float* out) const;
  // Texels [first, last) of one row, the same way.
  long long texels(int row, int first, int last, float* out) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace displace::bake::detail
