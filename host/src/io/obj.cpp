// OBJ meshes: load_obj / save_obj (io.hpp).
//
// Parsing is tinyobjloader's; polygons are ear-clipped here (polygon.hpp). tinyobjloader reads a
// malformed number as 0 without complaint, so the `v` and `f` lines are checked first by a small
// scan that rejects anything that is not a finite number or an integer index, with its line number.
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

#include "mesh_files.hpp"
#include "penumbra/error.hpp"
#include "penumbra/io.hpp"
#include "polygon.hpp"
#include "text.hpp"

namespace penumbra {
namespace {

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
// numbers read as 0, out-of-range indices skipped or kept). Returns the `f` lines' numbers.
std::vector<size_t> prescan(const std::string& text, const std::string& path) {
  const long long total = static_cast<long long>(count_vertices(text));
  std::istringstream in(text);
  std::string line;
  size_t line_no = 0;
  std::vector<size_t> faces;
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
      if (tok.size() > 256)  // tinyobjloader counts a polygon's corners in a byte
        throw Error("OBJ " + where + "face has " + std::to_string(tok.size() - 1) +
                    " corners (at most 255)");
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
      faces.push_back(line_no);
    }
  }
  return faces;
}

// The text of an OBJ file as UTF-8: a UTF-8 byte-order mark dropped; UTF-16 (with its mark)
// converted where it holds ASCII alone, as OBJ files do outside comments and names.
std::string utf8_text(const std::string& bytes, const std::string& path) {
  if (bytes.rfind("\xEF\xBB\xBF", 0) == 0) return bytes.substr(3);
  const bool le = bytes.rfind("\xFF\xFE", 0) == 0, be = bytes.rfind("\xFE\xFF", 0) == 0;
  if (!le && !be) return bytes;
  std::string text;
  for (size_t i = 2; i + 1 < bytes.size(); i += 2) {
    const unsigned lo = static_cast<unsigned char>(bytes[le ? i : i + 1]);
    const unsigned hi = static_cast<unsigned char>(bytes[le ? i + 1 : i]);
    if (hi != 0 || lo >= 0x80)
      throw Error("OBJ file " + quoted_path(path) +
                  " is UTF-16 text with characters beyond ASCII: save it as UTF-8");
    text += static_cast<char>(lo);
  }
  return text;
}

// The faces of every shape, each polygon by ear clipping; `lines[f]` is the line of the
// polygon that triangle f comes from.
void add_faces(const tinyobj::ObjReader& reader, const std::vector<size_t>& polygon_lines,
               const std::string& file, Mesh& mesh, std::vector<size_t>& lines) {
  size_t polygon = 0;
  const auto nv = static_cast<int>(mesh.vertices.size());
  for (const tinyobj::shape_t& shape : reader.GetShapes()) {
    const tinyobj::mesh_t& m = shape.mesh;
    size_t offset = 0;
    for (const unsigned char n : m.num_face_vertices) {
      const size_t line = polygon < polygon_lines.size() ? polygon_lines[polygon] : 0;
      std::vector<int> index;
      std::vector<glm::dvec3> corners;
      for (size_t k = 0; k < n; ++k) {
        index.push_back(m.indices[offset + k].vertex_index);
        // The scan checked the indices; tinyobjloader may still count vertices otherwise (a
        // `v` followed by a vertical tab is one for the scan alone).
        if (index.back() < 0 || index.back() >= nv)
          throw Error(file + " line " + std::to_string(line) +
                      ": face vertex index out of range (tinyobjloader read " + std::to_string(nv) +
                      " vertices)");
        corners.push_back(mesh.vertices[static_cast<size_t>(index.back())]);
      }
      for (const glm::ivec3& t : triangulate_polygon(corners)) {
        mesh.faces.emplace_back(index[t.x], index[t.y], index[t.z]);
        lines.push_back(line);
      }
      offset += n;
      ++polygon;
    }
  }
}

void set_albedo(const tinyobj::attrib_t& attrib, glm::dvec3 default_albedo, Mesh& mesh) {
  const size_t nv = mesh.vertices.size();
  mesh.albedo_mode = AlbedoMode::PerVertex;
  std::vector<glm::dvec3> albedo(nv, default_albedo);
  if (!attrib.colors.empty() && attrib.colors.size() == attrib.vertices.size())
    for (size_t i = 0; i < nv; ++i)
      albedo[i] =
          glm::dvec3(attrib.colors[3 * i], attrib.colors[3 * i + 1], attrib.colors[3 * i + 2]);
  mesh.albedo = std::move(albedo);
}

}  // namespace

Mesh load_obj(const std::string& path, glm::dvec3 default_albedo, DegenerateFacePolicy policy) {
  const std::string file = "OBJ file " + quoted_path(path);
  const std::string text = utf8_text(read_whole_file(path, "OBJ file"), path);
  const std::vector<size_t> polygon_lines = prescan(text, path);
  if (polygon_lines.empty()) throw Error(file + " contains no faces");

  tinyobj::ObjReaderConfig config;
  config.triangulate = false;   // its fans cover more than a concave polygon: add_faces clips
  config.vertex_color = false;  // keep colours only when every vertex has them
  tinyobj::ObjReader reader;
  // From a string: material libraries are not needed (albedo comes from vertex colours).
  if (!reader.ParseFromString(text, "", config)) {
    const std::string msg = one_line(reader.Error());
    throw Error("cannot parse " + file + ": " + (msg.empty() ? std::string("unknown error") : msg));
  }

  const tinyobj::attrib_t& attrib = reader.GetAttrib();
  Mesh mesh;
  mesh.name = std::filesystem::path(path).stem().string();
  for (size_t i = 0; i + 2 < attrib.vertices.size(); i += 3)
    mesh.vertices.emplace_back(attrib.vertices[i], attrib.vertices[i + 1], attrib.vertices[i + 2]);
  std::vector<size_t> lines;
  add_faces(reader, polygon_lines, file, mesh, lines);
  if (mesh.faces.empty()) throw Error(file + " contains no faces");
  set_albedo(attrib, default_albedo, mesh);
  drop_degenerate_faces(mesh, policy, file,
                        [&](size_t f) { return "line " + std::to_string(lines[f]); });
  try {
    validate(mesh, DegenerateFaces::Allow);  // drop_degenerate_faces judged those
  } catch (const Error& e) {
    throw Error(file + ": " + e.what());
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
