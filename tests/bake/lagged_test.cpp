// tests/bake/lagged_test.cpp - the lagged maps' schedule and raise (bake/lagged.h), which both
// backends keep: checked here frame by frame against the schedule written out in full.
#include "bake/lagged.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cstdint>
#include <string>
#include <vector>

namespace displace::bake {
namespace {

using Lands = LagSchedule::Lands;

// What a backend sees on each frame when every map takes all its shares.
struct Frame {
  LagSchedule::Share share;
  bool served_now = false;  // finished() said this frame serves the map in progress
  long long age = -1;       // of the map the frame samples (-1: none)
  long long served_frame = -1;
};

std::vector<Frame> run(Lands lands, int lag, int frames) {
  LagSchedule schedule(lands);
  std::vector<Frame> out;
  for (long long f = 0; f < frames; ++f) {
    Frame frame;
    frame.share = schedule.next(f, lag);
    frame.served_now = schedule.finished(frame.share.last());
    frame.served_frame = schedule.served_frame();
    if (frame.served_frame >= 0) frame.age = f - frame.served_frame;
    out.push_back(frame);
  }
  return out;
}

// The schedule in full, by frame: frame 0 makes a whole map; then a map begins on frame 1 and one
// each S frames after it - S = N + 1 where a frame's share is done before its draw, N where after -
// and is served N frames after it began, so that frame f samples the map begun on begun(f).
long long begun_on(Lands lands, int lag, long long f) {
  const long long period = lands == Lands::before_draw ? lag + 1 : lag;
  if (f < 1 + lag) return 0;
  return 1 + period * ((f - 1 - lag) / period);
}

TEST(LagSchedule, ServesEachMapNFramesAfterItBeganOnBothBackends) {
  for (const Lands lands : {Lands::before_draw, Lands::after_draw}) {
    for (int lag = 1; lag <= 7; ++lag) {
      const int shares = lands == Lands::before_draw ? lag + 1 : lag;
      const std::vector<Frame> frames = run(lands, lag, 6 * lag + 5);
      long long oldest = 0;
      for (long long f = 0; f < static_cast<long long>(frames.size()); ++f) {
        const Frame& frame = frames[std::size_t(f)];
        const std::string at = std::string(lands == Lands::before_draw ? "before" : "after") + " lag " +
                               std::to_string(lag) + " frame " + std::to_string(f);
        ASSERT_EQ(frame.served_frame, begun_on(lands, lag, f)) << at;
        oldest = std::max(oldest, frame.age);
        // the first map whole; every other takes its shares one a frame, in order
        ASSERT_EQ(frame.share.whole, f == 0) << at;
        ASSERT_EQ(frame.share.count, f == 0 ? 1 : shares) << at;
        const long long shares_before = f == 0 ? 0 : (f - 1) % shares;
        ASSERT_EQ(frame.share.index, shares_before) << at;
        ASSERT_EQ(frame.share.begin, frame.share.index == 0) << at;
        // served on the frame of its last share (done before the draw) or the frame after it
        const bool last_before = f > 1 && frames[std::size_t(f - 1)].share.last();
        ASSERT_EQ(frame.share.serve, lands == Lands::after_draw && last_before) << at;
        ASSERT_EQ(frame.served_now, f == 0 || (lands == Lands::before_draw && frame.share.last())) << at;
      }
      EXPECT_EQ(oldest, lands == Lands::before_draw ? 2 * lag : 2 * lag - 1) << "lag " << lag;
    }
  }
}

// A CPU map done before its last share (the budget lasted) is served that frame, and the next one
// begins on the frame after; a device map never finishes before its last share lands.
TEST(LagSchedule, AMapDoneEarlyIsServedAtOnce) {
  LagSchedule schedule(Lands::before_draw);
  EXPECT_TRUE(schedule.next(0, 3).whole);
  EXPECT_TRUE(schedule.finished(true));
  const LagSchedule::Share first = schedule.next(1, 3);
  EXPECT_TRUE(first.begin);
  EXPECT_FALSE(schedule.finished(false));
  EXPECT_EQ(schedule.next(2, 3).index, 1);
  EXPECT_TRUE(schedule.finished(true));  // two of four shares, and done
  EXPECT_EQ(schedule.served_frame(), 1);
  EXPECT_FALSE(schedule.in_progress());
  const LagSchedule::Share next = schedule.next(3, 3);
  EXPECT_TRUE(next.begin);
  EXPECT_FALSE(next.serve);
  EXPECT_EQ(next.index, 0);

  LagSchedule device(Lands::after_draw);
  device.next(0, 2);
  EXPECT_TRUE(device.finished(true));  // the whole map: served in its frame
  device.next(1, 2);
  EXPECT_FALSE(device.finished(false));
  EXPECT_FALSE(device.next(2, 2).serve);
  EXPECT_FALSE(device.finished(true));  // its last band: served from the next frame on
  EXPECT_EQ(device.served_frame(), 0);
  const LagSchedule::Share served = device.next(3, 2);
  EXPECT_TRUE(served.serve);
  EXPECT_TRUE(served.begin);
  EXPECT_EQ(device.served_frame(), 1);
}

// A change of N keeps the map in progress: its shares count on under the new N (what is left done in
// one share where the new N has fewer than it had), and the maps after it follow the new N.
TEST(LagSchedule, AChangeOfLagKeepsTheMapInProgress) {
  for (const Lands lands : {Lands::before_draw, Lands::after_draw}) {
    LagSchedule schedule(lands);
    schedule.next(0, 5);
    schedule.finished(true);
    for (long long f = 1; f <= 3; ++f) {  // three shares of a map begun on frame 1 under N = 5
      const LagSchedule::Share share = schedule.next(f, 5);
      EXPECT_FALSE(share.last());
      schedule.finished(false);
    }
    const LagSchedule::Share cut = schedule.next(4, 2);  // N = 2: its fourth share is its last
    EXPECT_FALSE(cut.begin);
    EXPECT_EQ(cut.index, 3);
    EXPECT_TRUE(cut.last());
    EXPECT_EQ(schedule.finished(true), lands == Lands::before_draw);
    const LagSchedule::Share after = schedule.next(5, 2);
    EXPECT_TRUE(after.begin);
    EXPECT_EQ(after.serve, lands == Lands::after_draw);
    EXPECT_EQ(schedule.served_frame(), 1);
    EXPECT_EQ(after.count, lands == Lands::before_draw ? 3 : 2);
  }
}

// A map in progress dropped by its backend is begun again on the next frame; after a restart (heights
// of another size) nothing is served and the next map is whole.
TEST(LagSchedule, DroppedMapsBeginAgainAndARestartMakesAWholeOne) {
  LagSchedule schedule(Lands::after_draw);
  schedule.next(0, 3);
  schedule.finished(true);
  schedule.next(1, 3);
  schedule.finished(false);
  schedule.drop_in_progress();
  const LagSchedule::Share again = schedule.next(2, 3);
  EXPECT_TRUE(again.begin);
  EXPECT_FALSE(again.whole);
  EXPECT_EQ(schedule.served_frame(), 0);
  schedule.finished(false);
  schedule.restart();
  EXPECT_EQ(schedule.served_frame(), -1);
  const LagSchedule::Share whole = schedule.next(3, 3);
  EXPECT_TRUE(whole.begin && whole.whole);
  EXPECT_TRUE(schedule.finished(true));
  EXPECT_EQ(schedule.served_frame(), 3);
}

// The raise: the lift is the largest rise of any texel (none where every texel fell), each apex goes
// up by it and is rounded up past the sum's rounding, and none passes 1.
TEST(RaiseApexes, RaisesEveryApexByTheLargestRiseRoundedUp) {
  const std::size_t texels = 40000;  // more than one task's worth
  std::vector<float> made(texels), now(texels), apex(texels), raised(texels);
  for (std::size_t t = 0; t < texels; ++t) {
    made[t] = float(t % 97) / 97.0f;
    now[t] = made[t] - 0.01f;
    apex[t] = std::min(1.0f, made[t] + 0.02f);
  }
  EXPECT_EQ(raise_apexes(made, now, apex, raised), 0.0f);
  EXPECT_EQ(raised, apex);
  now[31415] = made[31415] + 0.125f;  // one texel rose most; the last (past the last whole eight) less
  now[texels - 1] = made[texels - 1] + 0.0625f;
  const float lift = raise_apexes(made, now, apex, raised);
  EXPECT_EQ(lift, now[31415] - made[31415]);
  for (std::size_t t = 0; t < texels; ++t) {
    const float sum = apex[t] + lift;
    if (sum >= 1.0f) {
      ASSERT_EQ(raised[t], 1.0f) << t;
    } else {
      ASSERT_GT(raised[t], sum) << t;
      ASSERT_EQ(raised[t], std::bit_cast<float>(std::bit_cast<std::uint32_t>(sum) + 1u)) << t;
      ASSERT_GE(double(raised[t]), double(apex[t]) + double(lift)) << t;
    }
  }
}

}  // namespace
}  // namespace displace::bake
