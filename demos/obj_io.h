// demos/obj_io.h - Wavefront OBJ meshes (the subset a base surface needs) into render::Mesh.
#pragma once

#include <filesystem>
#include <istream>
#include <string>

#include "render/mesh.h"

namespace displace::app {

// Reads `v`, `vt` and `vn` records and `f` faces (polygons become triangle fans; 1-based or negative
// indices; every face corner needs texture coordinates). Object, group, smoothing and material
// records are skipped; any other record, a malformed number or an index out of range is an AppError
// naming the source and line.
render::Mesh parse_obj(std::istream& in, const std::string& source);
render::Mesh read_obj(const std::filesystem::path& file);

}  // namespace displace::app
