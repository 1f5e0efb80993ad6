// demos/obj_io.cpp - a reader for the Wavefront OBJ subset of base meshes: positions, texture
// coordinates, normals and polygonal faces. Corners that share position, texture and normal indices
// become one vertex of the unified render::Mesh.
#include "demos/obj_io.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <map>
#include <sstream>
#include <string_view>
#include <tuple>
#include <vector>

#include "demos/error.h"

namespace displace::app {
namespace {

constexpr std::string_view skipped_records[] = {"o", "g", "s", "usemtl", "mtllib"};

struct LineContext {
  const std::string& source;
  int line;
  std::string where() const { return source + " line " + std::to_string(line); }
};

float parse_number(std::string_view text, const LineContext& at) {
  float value = 0.0f;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error != std::errc() || end != text.data() + text.size() || !std::isfinite(value)) {
    throw runtime_error(at.where() + ": '" + std::string(text) + "' is not a finite number");
  }
  return value;
}

// A 1-based or negative (relative to the end) OBJ index into a list of `count` items; 0 for absent.
int parse_index(std::string_view text, std::size_t count, const LineContext& at, const char* what) {
  if (text.empty()) return 0;
  int value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error != std::errc() || end != text.data() + text.size() || value == 0) {
    throw runtime_error(at.where() + ": '" + std::string(text) + "' is not a " + what + " index");
  }
  const long long resolved = value > 0 ? value : (long long)count + value + 1;
  if (resolved < 1 || resolved > (long long)count) {
    throw runtime_error(at.where() + ": " + what + " index " + std::to_string(value) + " is out of range (" +
                        std::to_string(count) + " defined so far)");
  }
  return int(resolved);
}

}  // namespace

render::Mesh parse_obj(std::istream& in, const std::string& source) {
  std::vector<glm::vec3> positions, normals;
  std::vector<glm::vec2> uvs;
  render::Mesh mesh;
  std::map<std::tuple<int, int, int>, std::uint32_t> corners;  // (v, vt, vn) -> unified vertex
  bool any_normal = false, any_without_normal = false;
  std::string text;
  int number = 0;
  while (std::getline(in, text)) {
    ++number;
    const LineContext at{source, number};
    if (const auto hash = text.find('#'); hash != std::string::npos) text.resize(hash);
    std::istringstream words(text);
    std::string record;
    if (!(words >> record)) continue;
    std::vector<std::string> fields;
    for (std::string field; words >> field;) fields.push_back(field);
    auto numbers = [&](std::size_t least, std::size_t most) {
      if (fields.size() < least || fields.size() > most) {
        throw runtime_error(at.where() + ": '" + record + "' expects " + std::to_string(least) +
                            (least == most ? "" : " to " + std::to_string(most)) + " numbers");
      }
      std::vector<float> values;
      for (const std::string& field : fields) values.push_back(parse_number(field, at));
      return values;
    };
    if (record == "v") {
      const auto xyz = numbers(3, 4);  // a 4th (w) is allowed and ignored
      positions.emplace_back(xyz[0], xyz[1], xyz[2]);
    } else if (record == "vt") {
      const auto uv = numbers(2, 3);
      uvs.emplace_back(uv[0], uv[1]);
    } else if (record == "vn") {
      const auto n = numbers(3, 3);
      normals.emplace_back(n[0], n[1], n[2]);
    } else if (record == "f") {
      if (fields.size() < 3) throw runtime_error(at.where() + ": a face needs at least 3 corners");
      std::vector<std::uint32_t> face;
      for (const std::string& corner : fields) {
        const auto slash = corner.find('/');
        const auto second = slash == std::string::npos ? std::string::npos : corner.find('/', slash + 1);
        const std::string_view whole(corner);
        const int v = parse_index(whole.substr(0, slash), positions.size(), at, "vertex");
        if (v == 0) throw runtime_error(at.where() + ": a face corner without a vertex index");
        const int vt =
            slash == std::string::npos
                ? 0
                : parse_index(whole.substr(slash + 1, second == std::string::npos ? std::string::npos
                                                                                  : second - slash - 1),
                              uvs.size(), at, "texture coordinate");
        const int vn = second == std::string::npos
                           ? 0
                           : parse_index(whole.substr(second + 1), normals.size(), at, "normal");
        if (vt == 0) {
          throw runtime_error(at.where() + ": face corner '" + corner +
                              "' has no texture coordinates; relief needs a uv mapping");
        }
        (vn != 0 ? any_normal : any_without_normal) = true;
        const auto key = std::make_tuple(v, vt, vn);
        auto [found, inserted] = corners.try_emplace(key, std::uint32_t(mesh.positions.size()));
        if (inserted) {
          mesh.positions.push_back(positions[std::size_t(v - 1)]);
          mesh.uvs.push_back(uvs[std::size_t(vt - 1)]);
          mesh.normals.push_back(vn != 0 ? normals[std::size_t(vn - 1)] : glm::vec3(0.0f));
        }
        face.push_back(found->second);
      }
      for (std::size_t k = 1; k + 1 < face.size(); ++k) {
        mesh.triangles.insert(mesh.triangles.end(), {face[0], face[k], face[k + 1]});
      }
    } else if (std::find(std::begin(skipped_records), std::end(skipped_records), record) ==
               std::end(skipped_records)) {
      throw runtime_error(at.where() + ": unsupported OBJ record '" + record + "'");
    }
  }
  if (mesh.triangles.empty()) throw runtime_error(source + ": no faces");
  if (!any_normal || any_without_normal) mesh.normals.clear();  // all or none: else face normals everywhere
  return mesh;
}

render::Mesh read_obj(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw runtime_error("cannot read mesh " + file.string());
  return parse_obj(in, file.string());
}

}  // namespace displace::app
