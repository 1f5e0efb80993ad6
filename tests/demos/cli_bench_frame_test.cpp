// tests/demos/cli_bench_frame_test.cpp - `displace bench-frame`, end to end.
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
#include "demos/progress.h"
#include "pipeline/frame_pipeline.h"
#include "pipeline/scene.h"
#include "render/render.h"
#include "tests/demos/demos_fixtures.h"

namespace {

namespace fs = std::filesystem;
using namespace displace::app;

// bench-frame: the per-stage table and its JSON, no Vulkan allocation after warm-up.
TEST(Cli, BenchFrameWritesTheTableAndItsJson) {
  TempDir dir;
  const std::string json = dir.operator/("bench.json").string();
  const RunResult run = run_displace(
      dir,
      "bench-frame --scene water --map-size 32 --size 32x32 --frames 6 --warm-up 2 --budget-ms 50 --json '" +
          json + "'");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_NE(run.out.find("p50 ms"), std::string::npos) << run.out;
  const nlohmann::json parsed = nlohmann::json::parse(read_text(json));
  EXPECT_EQ(parsed["frames"], 6);
  EXPECT_EQ(parsed["budget_ms"], 50.0);
  for (const char* stage : {"sim", "bake", "upload", "render", "frame"}) {
    for (const char* key : {"p50_ms", "p95_ms", "p99_ms"})
      EXPECT_TRUE(parsed["stages"][stage][key].is_number());
  }
  EXPECT_TRUE(parsed["within_budget"].is_number());
  EXPECT_EQ(parsed["ffts_per_frame"], 6.0);
  EXPECT_EQ(parsed["effects"], nlohmann::json({"heights", "choppy", "foam"}));
  EXPECT_EQ(parsed["vulkan_allocations_after_warmup"], 0);
  // every frame came back, and resident memory was sampled (the soak's figures, tests/soak.sh)
  EXPECT_EQ(parsed["frames_rendered"], 6);
  const nlohmann::json& rss = parsed["rss_kb"];
  ASSERT_TRUE(rss.is_object()) << parsed.dump();
  EXPECT_GT(rss["after_warmup"].get<long long>(), 0);
  EXPECT_GE(rss["max"].get<long long>(), rss["end"].get<long long>());
  EXPECT_GE(rss["max"].get<long long>(), rss["after_warmup"].get<long long>());
  EXPECT_EQ(rss["growth"].get<long long>(),
            rss["end"].get<long long>() - rss["after_warmup"].get<long long>());
  EXPECT_EQ(parsed["overlapped"], true);
  EXPECT_EQ(parsed["pinned_threads"], 0);
  // --serial: the same table from the stages run one after another; --pin-threads: with the main
  // thread, TBB's worker(s) and lavapipe's rasterizers each on one CPU (none pinned on one CPU)
  const RunResult serial = run_displace(dir,
                                        "bench-frame --scene water --map-size 32 --size 32x32 --frames 3 "
                                        "--warm-up 2 --serial --pin-threads --json '" +
                                            json + "'");
  ASSERT_EQ(serial.exit_code, 0) << serial.err;
  EXPECT_NE(serial.out.find("stages in series"), std::string::npos) << serial.out;
  const nlohmann::json in_series = nlohmann::json::parse(read_text(json));
  EXPECT_EQ(in_series["overlapped"], false);
  cpu_set_t cpus;
  if (sched_getaffinity(0, sizeof cpus, &cpus) == 0 && CPU_COUNT(&cpus) >= 2) {
    EXPECT_NE(serial.out.find("pinned one per CPU"), std::string::npos) << serial.out;
    EXPECT_GE(in_series["pinned_threads"].get<int>(), 2);
  }
  EXPECT_EQ(in_series["frames_rendered"], 3);
  EXPECT_EQ(in_series["ffts_per_frame"], 6.0);
  EXPECT_EQ(in_series["vulkan_allocations_after_warmup"], 0);
  EXPECT_GT(in_series["stages"]["render"]["p50_ms"].get<double>(), 0.0);
}

}  // namespace
