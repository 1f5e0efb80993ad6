// bake/lagged.cpp - lagged cone maps on the CPU (lagged.h): the raise and the schedule.
#include "bake/lagged.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <bit>
#include <cstdint>

namespace displace::bake {
namespace {

constexpr std::size_t lift_grain = 1 << 15;  // texels per task of the lift's passes

}  // namespace

// The lift and the raise. Conservative: the bilinear surface rose by at most lift = max over texels
// of (h - h_made) anywhere (it interpolates the texels' differences), so s(x) <= s_made(x) + lift <=
// (H_c + lift) + |x - p| / r_k for every p in Q_c and x in sector k - the same ratios hold from the
// raised apex. apex + lift is rounded up past both roundings by taking the next float above the
// rounded sum (both positive, so its bits plus one); 1 is above every height. The largest rise is
// taken in eight independent maxima per task (a vector's worth).
float raise_apexes(std::span<const float> made_from, std::span<const float> now, std::span<const float> apex,
                   std::span<float> raised) {
  const float lift = tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, now.size(), lift_grain), 0.0f,
      [&](const tbb::blocked_range<std::size_t>& range, float largest) {
        float rise[8] = {};
        const std::size_t first = range.begin(), whole = first + (range.size() / 8) * 8;
        for (std::size_t t = first; t < whole; t += 8) {
          for (int k = 0; k < 8; ++k) {
            const float d = now[t + k] - made_from[t + k];
            rise[k] = d > rise[k] ? d : rise[k];
          }
        }
        for (std::size_t t = whole; t < range.end(); ++t) rise[0] = std::max(rise[0], now[t] - made_from[t]);
        return std::max(largest, *std::max_element(std::begin(rise), std::end(rise)));
      },
      [](float a, float b) { return std::max(a, b); });
  if (!(lift > 0.0f)) {
    std::copy(apex.begin(), apex.end(), raised.begin());
    return 0.0f;
  }
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, apex.size(), lift_grain),
                    [&](const tbb::blocked_range<std::size_t>& range) {
                      for (std::size_t t = range.begin(); t < range.end(); ++t) {
                        raised[t] = std::min(
                            1.0f, std::bit_cast<float>(std::bit_cast<std::uint32_t>(apex[t] + lift) + 1u));
                      }
                    });
  return lift;
}

LaggedCones::Served LaggedCones::advance(BilinearBaker& baker, HeightView heights, int sector_count,
                                         const Budget& budget, int lag_frames, long long frame,
                                         std::vector<float>& raised) {
  const std::size_t texels = std::size_t(heights.width) * std::size_t(heights.height);
  if (served_ >= 0 && maps_[std::size_t(served_)].heights.size() != texels) served_ = -1;  // a new size
  if (!baker.in_progress()) {
    building_ = served_ < 0 ? 0 : 1 - served_;
    Map& next = maps_[std::size_t(building_)];
    next.heights.assign(heights.data, heights.data + texels);
    next.frame = frame;
    next.ratios.resize(texels * std::size_t(sector_count));
    next.apex.resize(texels);
    baker.begin(heights);
    build_frames_ = 0;
  }
  Map& next = maps_[std::size_t(building_)];
  const ConeView out{next.ratios.data(), heights.width, heights.height, sector_count};
  // an even share of the stage a frame (made by its begin frame + lag frames), more while the budget
  // lasts; with no map to serve yet the first is made whole
  const double due = served_ < 0 ? 1.0 : double(build_frames_ + 1) / double(lag_frames + 1);
  const bool made = baker.advance(budget, out, next.apex, next.stats, std::min(due, 1.0));
  ++build_frames_;
  if (made) served_ = building_;
  const Map& served = maps_[std::size_t(served_)];
  raised.resize(texels);
  Served result;
  result.lift =
      raise_apexes(served.heights, std::span<const float>(heights.data, texels), served.apex, raised);
  result.ratios = served.ratios;
  result.stats = served.stats;
  result.age = frame - served.frame;
  return result;
}

}  // namespace displace::bake
