// OBJ meshes: load_obj / save_obj (io.hpp).
//
// Parsing is tinyobjloader's (polygons triangulated as fans). tinyobjloader reads a malformed
// number as 0 without complaint, so the `v` and `f` lines are checked first by a small scan
// that rejects anything that is not a finite number or an integer index, with its line number.
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <tiny_obj_loader.h>

#include "penumbra/error.hpp"
#include "penumbra/io.hpp"
#include "text.hpp"

namespace penumbra {
namespace {

// Joins tinyobjloader's multi-line messages into one line.
std::string one_line(const std::string& text) {
  std::string out;
  bool space = false;
  for (char c : text) {
    if (c == '\n' || c == '\r' || c == '\t' || c == ' ') {
      space = !out.empty();
      continue;
    }
    if (space) out += ' ';
    space = false;
    out += c;
  }
  return out;
}

std::vector<std::string> split_ws(const std::string& line) {
  std::vector<std::string> out;
  std::istringstream s(line);
  std::string tok;
  while (s >> tok) out.push_back(tok);
  return out;
}

bool parse_number(const std::string& tok, double* value) {
  const char* begin = tok.c_str();
  char* end = nullptr;
  errno = 0;
  *value = std::strtod(begin, &end);
  return end != begin && *end == '\0';
}

bool is_integer(const std::string& s) {
  size_t i = (!s.empty() && (s[0] == '-' || s[0] == '+')) ? 1 : 0;
  if (i == s.size()) return false;
  for (; i < s.size(); ++i)
    if (s[i] < '0' || s[i] > '9') return false;
  return true;
}

// A face corner: v, v/vt, v/vt/vn or v//vn, each an integer.
bool is_face_corner(const std::string& tok) {
  std::vector<std::string> parts;
  size_t start = 0;
  for (;;) {
    size_t slash = tok.find('/', start);
    parts.push_back(
        tok.substr(start, slash == std::string::npos ? std::string::npos : slash - start));
    if (slash == std::string::npos) break;
    start = slash + 1;
  }
  if (parts.size() > 3 || !is_integer(parts[0])) return false;
  if (parts.size() == 2) return is_integer(parts[1]);  // v/vt: "1/" has no vt
  if (parts.size() == 3) return (parts[1].empty() || is_integer(parts[1])) && is_integer(parts[2]);
  return true;
}

size_t count_vertices(const std::string& text) {
  std::istringstream in(text);
  std::string line;
  size_t n = 0;
  while (std::getline(in, line)) {
    std::istringstream s(line);
    std::string tok;
    if (s >> tok && tok == "v") ++n;
  }
  return n;
}

// Checks the `v` and `f` lines that tinyobjloader would otherwise accept silently (malformed
// numbers read as 0, out-of-range indices skipped or kept). Returns the number of `f` lines.
size_t prescan(const std::string& text, const std::string& path) {
  const long long total = static_cast<long long>(count_vertices(text));
  std::istringstream in(text);
  std::string line;
  size_t line_no = 0, faces = 0;
  long long seen = 0;  // vertices before the current line (for relative, negative indices)
  while (std::getline(in, line)) {
    ++line_no;
    std::vector<std::string> tok = split_ws(line);
    if (tok.empty()) continue;
    const std::string where =
        "file " + quoted_path(path) + " line " + std::to_string(line_no) + ": ";
    if (tok[0] == "v") {
      // x y z, x y z w, or x y z r g b (vertex colours).
      if (tok.size() != 4 && tok.size() != 5 && tok.size() != 7)
        throw Error("OBJ " + where + "vertex has " + std::to_string(tok.size() - 1) +
                    " values (expected x y z, x y z w, or x y z r g b)");
      for (size_t i = 1; i < tok.size(); ++i) {
        double value;
        if (!parse_number(tok[i], &value))
          throw Error("OBJ " + where + "vertex value '" + tok[i] + "' is not a number");
        if (!std::isfinite(value))
          throw Error("OBJ " + where + "vertex value '" + tok[i] + "' is non-finite");
      }
      ++seen;
    } else if (tok[0] == "f") {
      if (tok.size() < 4)
        throw Error("OBJ " + where + "face has " + std::to_string(tok.size() - 1) +
                    " corners (at least 3 needed)");
      for (size_t i = 1; i < tok.size(); ++i) {
        if (!is_face_corner(tok[i]))
          throw Error("OBJ " + where + "face corner '" + tok[i] +
                      "' is not v, v/vt, v/vt/vn or v//vn (integer indices)");
        const long long idx = std::atoll(tok[i].c_str());
        if (idx == 0)
          throw Error("OBJ " + where + "face corner '" + tok[i] +
                      "' has vertex index 0 (indices start at 1)");
        if (idx > total)
          throw Error("OBJ " + where + "face vertex index " + std::to_string(idx) +
                      " out of range [1, " + std::to_string(total) + "]");
        if (idx < -seen)
          throw Error("OBJ " + where + "relative face vertex index " + std::to_string(idx) +
                      " out of range (only " + std::to_string(seen) + " vertices before it)");
      }
      ++faces;
    }
  }
  return faces;
}

std::string read_file(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    throw Error("cannot read OBJ file " + quoted_path(path) + ": it is a directory");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error("cannot open OBJ file " + quoted_path(path) + ": " + std::strerror(errno));
  std::ostringstream s;
  s << in.rdbuf();
  if (in.bad()) throw Error("cannot read OBJ file " + quoted_path(path));
  return s.str();
}

}  // namespace

Mesh load_obj(const std::string& path, glm::dvec3 default_albedo) {
  const std::string text = read_file(path);
  if (prescan(text, path) == 0) throw Error("OBJ file " + quoted_path(path) + " contains no faces");

  tinyobj::ObjReaderConfig config;
  config.triangulate = true;
  config.vertex_color = false;  // keep colours only when every vertex has them
  tinyobj::ObjReader reader;
  // From a string: material libraries are not needed (albedo comes from vertex colours).
  if (!reader.ParseFromString(text, "", config)) {
    const std::string msg = one_line(reader.Error());
    throw Error("cannot parse OBJ file " + quoted_path(path) + ": " +
                (msg.empty() ? std::string("unknown error") : msg));
  }

  const tinyobj::attrib_t& attrib = reader.GetAttrib();
  Mesh mesh;
  mesh.name = std::filesystem::path(path).stem().string();
  const size_t nv = attrib.vertices.size() / 3;
  mesh.vertices.resize(nv);
  for (size_t i = 0; i < nv; ++i)
    mesh.vertices[i] =
        glm::dvec3(attrib.vertices[3 * i], attrib.vertices[3 * i + 1], attrib.vertices[3 * i + 2]);

  for (const tinyobj::shape_t& shape : reader.GetShapes()) {
    const tinyobj::mesh_t& m = shape.mesh;
    size_t offset = 0;
    for (size_t f = 0; f < m.num_face_vertices.size(); ++f) {
      const size_t n = m.num_face_vertices[f];
      if (n == 3)
        mesh.faces.emplace_back(m.indices[offset].vertex_index, m.indices[offset + 1].vertex_index,
                                m.indices[offset + 2].vertex_index);
      offset += n;
    }
  }
  if (mesh.faces.empty()) throw Error("OBJ file " + quoted_path(path) + " contains no faces");

  mesh.albedo_mode = AlbedoMode::PerVertex;
  if (!attrib.colors.empty() && attrib.colors.size() == attrib.vertices.size()) {
    mesh.albedo.resize(nv);
    for (size_t i = 0; i < nv; ++i)
      mesh.albedo[i] =
          glm::dvec3(attrib.colors[3 * i], attrib.colors[3 * i + 1], attrib.colors[3 * i + 2]);
  } else {
    mesh.albedo.assign(nv, default_albedo);
  }

  try {
    validate(mesh);
  } catch (const Error& e) {
    throw Error("OBJ file " + quoted_path(path) + ": " + e.what());
  }
  return mesh;
}

std::string obj_text(const Mesh& mesh) {
  std::string out;
  char line[256];
  auto put = [&](int n) { out.append(line, size_t(std::min<int>(n, sizeof line - 1))); };
  const bool colors =
      mesh.albedo_mode == AlbedoMode::PerVertex && mesh.albedo.size() == mesh.vertices.size();
  if (!mesh.name.empty()) out += "# " + mesh.name + "\n";
  put(std::snprintf(line, sizeof line, "# %zu vertices, %zu faces\n", mesh.vertices.size(),
                    mesh.faces.size()));
  for (size_t i = 0; i < mesh.vertices.size(); ++i) {
    const glm::dvec3& v = mesh.vertices[i];
    if (colors) {
      const glm::dvec3& c = mesh.albedo[i];
      put(std::snprintf(line, sizeof line, "v %.9g %.9g %.9g %.9g %.9g %.9g\n", v.x, v.y, v.z, c.x,
                        c.y, c.z));
    } else {
      put(std::snprintf(line, sizeof line, "v %.9g %.9g %.9g\n", v.x, v.y, v.z));
    }
  }
  for (const glm::ivec3& t : mesh.faces)
    put(std::snprintf(line, sizeof line, "f %d %d %d\n", t.x + 1, t.y + 1, t.z + 1));
  return out;
}

void save_obj(const Mesh& mesh, const std::string& path) {
  write_file(path, obj_text(mesh), "OBJ file");
}

}  // namespace penumbra
