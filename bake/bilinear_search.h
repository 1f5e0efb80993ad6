// bake/bilinear_search.h - bake_bilinear_cones' per-texel search, for the budgeted bilinear baker's
// refinement (internal to bake/; the method and its proof are in cone_bilinear.cpp).
#pragma once

#include <memory>

#include "bake/bake.h"

namespace displace::bake::detail {

// The search of bake_bilinear_cones for single texels. Made once per height map (cell maxima, slopes
// and their max pyramid, O(N)); `heights` must outlive it. texel() is thread-safe.
class BilinearSearch {
 public:
  BilinearSearch(HeightView heights, Address address, int sector_count, int slope_window);
  ~BilinearSearch();
  // New heights of the same size (they must outlive it): the same as a new search, without
  // allocating.
  void update(HeightView heights);
  // Texel (i, j): its apex and its sector ratios, exactly as bake_bilinear_cones stores them.
  // Returns the work done (cells and pyramid nodes examined).
  long long texel(int i, int j, float& apex, float* ratios) const;

  struct Context;

 private:
  std::unique_ptr<Context> context_;
};

}  // namespace displace::bake::detail
