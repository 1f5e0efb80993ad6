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

LagSchedule::Share LagSchedule::next(long long frame, int lag_frames) {
  Share share;
  if (complete_) {  // its last share landed after the frame before's draw
    served_ = begun_;
    begun_ = -1;
    complete_ = false;
    share.serve = true;
  }
  if (begun_ < 0) {
    begun_ = frame;
    shares_ = 0;
    whole_ = served_ < 0;
    share.begin = true;
  }
  share.whole = whole_;
  share.index = shares_++;
  share.count = whole_ ? 1 : lands_ == Lands::before_draw ? lag_frames + 1 : lag_frames;
  return share;
}

bool LagSchedule::finished(bool complete) {
  if (!complete || begun_ < 0) return false;
  if (whole_ || lands_ == Lands::before_draw) {
    served_ = begun_;
    begun_ = -1;
    return true;
  }
  complete_ = true;  // served from the next frame on
  return false;
}

void LagSchedule::drop_in_progress() {
  begun_ = -1;
  complete_ = false;
}

void LagSchedule::restart() {
  drop_in_progress();
  served_ = -1;
}

LaggedCones::Served LaggedCones::advance(BilinearBaker& baker, HeightView heights, int sector_count,
                                         const Budget& budget, int lag_frames, long long frame,
                                         std::vector<float>& raised) {
  const std::size_t texels = std::size_t(heights.width) * std::size_t(heights.height);
  if (served_ >= 0 && maps_[std::size_t(served_)].heights.size() != texels) {  // a new size
    served_ = -1;
    schedule_.restart();
  }
  if (!baker.in_progress()) schedule_.drop_in_progress();  // (a bake of the baker's own dropped it)
  const LagSchedule::Share share = schedule_.next(frame, lag_frames);
  if (share.begin) {
    building_ = served_ < 0 ? 0 : 1 - served_;
    Map& next = maps_[std::size_t(building_)];
    next.heights.assign(heights.data, heights.data + texels);
    next.ratios.resize(texels * std::size_t(sector_count));
    next.apex.resize(texels);
    baker.begin(heights);
  }
  Map& next = maps_[std::size_t(building_)];
  const ConeView out{next.ratios.data(), heights.width, heights.height, sector_count};
  // the share due by the end of this frame, more while the budget lasts
  const double due = double(share.index + 1) / double(share.count);
  const bool made = baker.advance(budget, out, next.apex, next.stats, std::min(due, 1.0));
  if (schedule_.finished(made)) served_ = building_;
  const Map& served = maps_[std::size_t(served_)];
  raised.resize(texels);
  Served result;
  result.lift =
      raise_apexes(served.heights, std::span<const float>(heights.data, texels), served.apex, raised);
  result.ratios = served.ratios;
  result.stats = served.stats;
  result.age = frame - schedule_.served_frame();
  return result;
}

}  // namespace displace::bake
