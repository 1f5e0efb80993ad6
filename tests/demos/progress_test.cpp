// tests/demos/progress_test.cpp - the progress line (demos/progress.cpp).
#include "demos/progress.h"

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>
#include <sched.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <span>
#include <sstream>
#include <string>
#include <vector>

#include "bake/bake.h"
#include "demos/cli/command.h"
#include "demos/commands/settings.h"
#include "demos/cone_export.h"
#include "demos/heights.h"
#include "demos/image_io.h"
#include "demos/obj_io.h"
#include "demos/play.h"
#include "pipeline/frame_pipeline.h"
#include "pipeline/scene.h"
#include "render/render.h"
#include "tests/demos/demos_fixtures.h"

namespace {

namespace fs = std::filesystem;
using namespace displace::app;

// A fake clock in seconds.
struct FakeClock {
  double now = 0.0;
  ProgressLine::Clock clock() {
    return [this] { return now; };
  }
};

TEST(ProgressLine, DrawsOnATerminalOnlyAfterASecondThenErasesItself) {
  std::ostringstream stream;
  FakeClock time;  // steps of binary fractions, so the printed tenths are not ties
  ProgressLine line(stream, true, "baking cones", time.clock());
  time.now += 0.25;
  line.update(0.1);
  time.now += 0.5;
  line.update(0.3);
  EXPECT_EQ(stream.str(), "") << "a bake under a second shows nothing";
  time.now += 0.75;  // 1.5 s
  line.callback()(0.42);
  EXPECT_EQ(stream.str(), "\rdisplace: baking cones  42% (1.5 s)");
  time.now += 0.0625;
  line.update(0.5);  // too soon after the last redraw
  EXPECT_EQ(stream.str(), "\rdisplace: baking cones  42% (1.5 s)");
  time.now += 8.8125;  // 10.375 s: the line grows by a character
  line.update(0.999);
  time.now += 0.0625;
  line.update(1.0);  // the last report is always drawn
  const std::string drawn = stream.str();
  EXPECT_NE(drawn.find("\rdisplace: baking cones  99% (10.4 s)"), std::string::npos) << drawn;
  const std::string last = "displace: baking cones 100% (10.4 s)";
  EXPECT_TRUE(drawn.ends_with("\r" + last)) << drawn;
  line.finish();
  const std::string erased = stream.str().substr(drawn.size());
  std::string blank = "\r";  // appended: GCC 12 warns (-Wrestrict) on "\r" + std::string here
  blank.append(last.size(), ' ').append("\r");
  EXPECT_EQ(erased, blank);
  EXPECT_EQ(stream.str().find('\n'), std::string::npos) << "one line, updated in place";
  line.update(1.0);
  line.finish();
  EXPECT_EQ(stream.str().size(), drawn.size() + erased.size()) << "nothing after finish";
}

TEST(ProgressLine, DrawsNothingWhenNotATerminalOrWhenQuick) {
  std::ostringstream stream;
  FakeClock time;
  {
    ProgressLine line(stream, false, "baking cones", time.clock());
    for (int k = 1; k <= 100; ++k) {
      time.now += 0.5;
      line.update(k / 100.0);
    }
  }
  {
    ProgressLine quick(stream, true, "baking cones", time.clock());
    time.now += 0.5;
    quick.update(1.0);
  }
  EXPECT_EQ(stream.str(), "");
}

// A quick command's stages print nothing; once one has run for a second, every stage so far and
// every later one prints one line as it ends, with its own time.
TEST(StageLines, PrintNothingWhileQuickThenALinePerStage) {
  std::ostringstream stream;
  FakeClock time;
  {
    StageLines quick(stream, "displace render", time.clock());
    time.now += 0.3;
    quick.done("heights made");
    time.now += 0.6;
    quick.done("cone maps baked");
  }
  EXPECT_EQ(stream.str(), "");
  StageLines slow(stream, "displace render", time.clock());
  time.now += 0.25;
  slow.done("heights made");
  EXPECT_EQ(stream.str(), "");
  time.now += 1.5;
  slow.done("cone maps baked");
  EXPECT_EQ(stream.str(),
            "displace render: heights made in 0.25 s\ndisplace render: cone maps baked in 1.50 s\n");
  time.now += 0.1;
  slow.done("drawn");
  EXPECT_EQ(stream.str(),
            "displace render: heights made in 0.25 s\ndisplace render: cone maps baked in 1.50 s\n"
            "displace render: drawn in 0.10 s\n");
}

// From many threads at once (as a bake's reports could come, were they not serialized): every draw
// is whole.
TEST(ProgressLine, UpdatesFromManyThreadsDrawWholeLines) {
  std::ostringstream stream;
  std::atomic<int> ticks{0};
  ProgressLine line(stream, true, "baking", [&] { return 10.0 * ticks.fetch_add(1); });
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&] {
      for (int k = 0; k < 200; ++k) line.update(k / 200.0);
    });
  for (std::thread& thread : threads) thread.join();
  line.finish();
  const std::string text = stream.str();
  std::size_t lines = 0;
  for (std::size_t at = text.find("\rdisplace: baking "); at != std::string::npos;
       at = text.find("\rdisplace: baking ", at + 1)) {
    ++lines;
    const std::size_t end = text.find('\r', at + 1);
    const std::string one = text.substr(at + 1, end - at - 1);
    EXPECT_NE(one.find("%"), std::string::npos) << one;
    EXPECT_NE(one.find(" s)"), std::string::npos) << one;
  }
  EXPECT_EQ(lines, 800u);
}

}  // namespace
