// tests/fuzz/fuzz_scene.cpp - libFuzzer target: the TOML scene reader (pipeline::parse_scene).
// Any input either parses into a Scene or throws SceneError with a message; anything else (another
// exception, a crash, a sanitizer report, a hang) is a finding.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "pipeline/scene.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  try {
    const displace::pipeline::Scene scene = displace::pipeline::parse_scene(text, "fuzz.toml");
    // what parses must print and parse back
    (void)displace::pipeline::parse_scene(displace::pipeline::scene_toml(scene), "printed.toml");
  } catch (const displace::pipeline::SceneError& error) {
    if (std::string_view(error.what()).empty()) __builtin_trap();  // an error says what is wrong
  }
  return 0;
}
