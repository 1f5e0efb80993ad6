// tests/fuzz/fuzz_obj.cpp - libFuzzer target: the OBJ reader (app::parse_obj) and what the renderer
// checks of its mesh on the CPU (render::mesh_vertices). Any input either gives a mesh or throws
// AppError (the reader) or MeshError (a mesh that cannot carry a relief) with a message; anything
// else is a finding.
#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>

#include "demos/error.h"
#include "demos/obj_io.h"
#include "render/mesh.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
  try {
    const displace::render::Mesh mesh = displace::app::parse_obj(in, "fuzz.obj");
    (void)displace::render::mesh_vertices(mesh);
  } catch (const displace::app::AppError& error) {
    if (std::string(error.what()).empty()) __builtin_trap();
  } catch (const displace::render::MeshError& error) {
    if (std::string(error.what()).empty()) __builtin_trap();
  }
  return 0;
}
