// tests/demos/cli_output_style_test.cpp - the outputs meant for tools (bench-frame --json, query
// --json, bake --stats, the sequence CSV) share one style (docs/cli.md): snake_case keys, and every
// key they write is named in its command's --help, where docs/cli.md has it.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <set>
#include <sstream>
#include <string>

#include "tests/demos/demos_fixtures.h"

namespace {

namespace fs = std::filesystem;

// Every key of a JSON document, objects inside arrays included.
void collect_keys(const nlohmann::json& value, std::set<std::string>& keys) {
  if (value.is_object()) {
    for (const auto& [key, child] : value.items()) {
      keys.insert(key);
      collect_keys(child, keys);
    }
  } else if (value.is_array()) {
    for (const nlohmann::json& child : value) collect_keys(child, keys);
  }
}

std::string whole_text(const fs::path& file) {
  std::ifstream stream(file);
  std::ostringstream text;
  text << stream.rdbuf();
  return text.str();
}

// Each key is snake_case and appears, as a word, in the command's help.
void expect_style(const std::set<std::string>& keys, const std::string& command, const TempDir& dir) {
  const RunResult help = run_displace(dir, command + " --help");
  ASSERT_EQ(help.exit_code, 0) << help.err;
  const std::regex snake_case("[a-z][a-z0-9]*(_[a-z0-9]+)*");
  ASSERT_FALSE(keys.empty()) << command;
  for (const std::string& key : keys) {
    EXPECT_TRUE(std::regex_match(key, snake_case)) << command << ": key '" << key << "' is not snake_case";
    const std::regex word("(^|[^a-z0-9_])" + key + "([^a-z0-9_]|$)");
    EXPECT_TRUE(std::regex_search(help.out, word)) << command << ": key '" << key << "' is not in its --help";
  }
}

TEST(Cli, OutputsForToolsShareOneStyleAndTheirHelpNamesEveryKey) {
  TempDir dir;
  {  // bench-frame --json
    const fs::path json = dir / "bench.json";
    const RunResult run = run_displace(dir,
                                       "bench-frame --scene water --map-size 32 --size 32x32 --frames 2 "
                                       "--warm-up 2 --budget-ms 50 --json '" +
                                           json.string() + "'");
    ASSERT_EQ(run.exit_code, 0) << run.err;
    std::set<std::string> keys;
    collect_keys(nlohmann::json::parse(whole_text(json)), keys);
    EXPECT_TRUE(keys.count("device_p50_ms")) << "the device column";
    expect_style(keys, "bench-frame", dir);
  }
  {  // query --json
    std::ofstream(dir / "points.csv") << "x,y\n0,0\n10.5,-3\n";
    const fs::path json = dir / "query.json";
    const RunResult run =
        run_displace(dir, "query --scene water --map-size 32 --time 1 --points '" +
                              (dir / "points.csv").string() + "' --json --output '" + json.string() + "'");
    ASSERT_EQ(run.exit_code, 0) << run.err;
    std::set<std::string> keys;
    collect_keys(nlohmann::json::parse(whole_text(json)), keys);
    expect_style(keys, "query", dir);
  }
  {  // bake --stats: one JSON line on standard output
    const RunResult run =
        run_displace(dir, "bake --scene ocean --map-size 32 --mode budgeted --sectors 4 --stats --output '" +
                              (dir / "cones.exr").string() + "'");
    ASSERT_EQ(run.exit_code, 0) << run.err;
    std::set<std::string> keys;
    collect_keys(nlohmann::json::parse(run.out), keys);
    expect_style(keys, "bake", dir);
  }
  {  // the sequence CSV's columns
    const RunResult run = run_displace(dir,
                                       "sequence --scene calm --map-size 32 --size 32x32 --frames 0:1 "
                                       "--output '" +
                                           (dir / "calm_#.png").string() + "'");
    ASSERT_EQ(run.exit_code, 0) << run.err;
    std::istringstream csv(whole_text(dir / "calm.csv"));
    std::string header, column;
    std::getline(csv, header);
    std::set<std::string> keys;
    std::istringstream columns(header);
    while (std::getline(columns, column, ',')) keys.insert(column);
    EXPECT_TRUE(keys.count("time_s") && keys.count("bake_budget_ms")) << header;
    expect_style(keys, "sequence", dir);
  }
}

}  // namespace
