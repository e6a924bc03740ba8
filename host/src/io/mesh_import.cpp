// Mesh files: load_mesh (io.hpp) picks the reader by extension; every format but OBJ is read
// through Assimp.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <assimp/config.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <assimp/Importer.hpp>

#include "mesh_files.hpp"
#include "penumbra/error.hpp"
#include "penumbra/io.hpp"
#include "text.hpp"

namespace penumbra {
namespace {

struct MeshFormat {
  const char* extension;
  const char* name;
};
constexpr MeshFormat kMeshFormats[] = {{".obj", "OBJ"},   {".ply", "PLY"},  {".stl", "STL"},
                                       {".gltf", "glTF"}, {".glb", "glTF"}, {".off", "OFF"}};

const MeshFormat& format_of(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  for (const MeshFormat& f : kMeshFormats)
    if (ext == f.extension) return f;
  std::string known;
  for (const MeshFormat& f : kMeshFormats)
    known += std::string(known.empty() ? "" : ", ") + f.extension;
  throw Error("mesh file " + quoted_path(path) + " is not of a known format (" +
              (ext.empty() ? std::string("no extension") : "'" + printable(ext) + "'") +
              "): penumbra reads " + known);
}

// A face with a non-finite corner is not called degenerate: validate() names that corner.
bool degenerate(const Mesh& mesh, const glm::ivec3& f) {
  const glm::dvec3 &a = mesh.vertices[f.x], &b = mesh.vertices[f.y], &c = mesh.vertices[f.z];
  const glm::dvec3 sum = a + b + c;
  const bool finite = std::isfinite(sum.x) && std::isfinite(sum.y) && std::isfinite(sum.z);
  return finite && (f.x == f.y || f.y == f.z || f.z == f.x || degenerate_triangle(a, b, c));
}

// The element counts an OFF or PLY header declares (none where it declares none): Assimp
// reserves memory for them before reading them, so a file of a few bytes declaring billions of
// vertices would take minutes and gigabytes before its error.
std::vector<unsigned long long> declared_counts(const std::string& bytes,
                                                const std::string& format) {
  std::istringstream in(bytes.substr(0, 4096));
  std::vector<unsigned long long> counts;
  std::string word;
  if (format == "OFF") {
    if (!(in >> word) || word.find("OFF") == std::string::npos) return counts;
    for (unsigned long long n = 0; counts.size() < 2 && in >> n;) counts.push_back(n);
  } else if (format == "PLY") {
    for (std::string line; std::getline(in, line) && line.rfind("end_header", 0) != 0;) {
      std::istringstream s(line);
      unsigned long long n = 0;
      if (s >> word && word == "element" && s >> word >> n) counts.push_back(n);
    }
  }
  return counts;
}

// Refuses a header that declares more elements than the file has bytes (each takes two at least).
void check_declared_counts(const std::string& bytes, const std::string& format,
                           const std::string& file) {
  unsigned long long total = 0;
  for (unsigned long long n : declared_counts(bytes, format)) total += std::min(n, 1ull << 60);
  if (total > bytes.size() / 2)
    throw Error(file + " declares " + std::to_string(total) +
                " elements (vertices, faces) in its "
                "header, more than its " +
                std::to_string(bytes.size()) + " bytes can hold");
}

// Every triangle of the scene's meshes in one Mesh; the vertices' colours where all have one.
Mesh mesh_of(const aiScene& s, glm::dvec3 default_albedo) {
  Mesh mesh;
  bool coloured = true;
  for (unsigned m = 0; m < s.mNumMeshes; ++m)
    coloured = coloured && s.mMeshes[m]->HasVertexColors(0);
  for (unsigned m = 0; m < s.mNumMeshes; ++m) {
    const aiMesh& a = *s.mMeshes[m];
    const int offset = static_cast<int>(mesh.vertices.size());
    for (unsigned v = 0; v < a.mNumVertices; ++v) {
      mesh.vertices.emplace_back(a.mVertices[v].x, a.mVertices[v].y, a.mVertices[v].z);
      const aiColor4D c = coloured ? a.mColors[0][v] : aiColor4D();
      mesh.albedo.push_back(coloured ? glm::dvec3(c.r, c.g, c.b) : default_albedo);
    }
    for (unsigned f = 0; f < a.mNumFaces; ++f) {
      const aiFace& face = a.mFaces[f];
      if (face.mNumIndices != 3) continue;  // points and lines: nothing to render
      mesh.faces.emplace_back(offset + static_cast<int>(face.mIndices[0]),
                              offset + static_cast<int>(face.mIndices[1]),
                              offset + static_cast<int>(face.mIndices[2]));
    }
  }
  mesh.albedo_mode = AlbedoMode::PerVertex;
  return mesh;
}

Mesh load_with_assimp(const std::string& path, const MeshFormat& format, glm::dvec3 albedo,
                      DegenerateFacePolicy policy) {
  const std::string file = std::string(format.name) + " file " + quoted_path(path);
  // Read here too for the same messages as OBJ's where it cannot be read.
  check_declared_counts(read_whole_file(path, std::string(format.name) + " file"), format.name,
                        file);
  Assimp::Importer importer;
  // Normals and texture coordinates would keep the corners of a sharp edge apart.
  importer.SetPropertyInteger(AI_CONFIG_PP_RVC_FLAGS,
                              aiComponent_NORMALS | aiComponent_TANGENTS_AND_BITANGENTS |
                                  aiComponent_TEXCOORDS | aiComponent_BONEWEIGHTS);
  const unsigned steps = aiProcess_RemoveComponent | aiProcess_Triangulate |
                         aiProcess_JoinIdenticalVertices | aiProcess_PreTransformVertices |
                         aiProcess_ValidateDataStructure;
  const aiScene* scene = importer.ReadFile(path, steps);
  if (scene == nullptr)
    throw Error("cannot read " + file + ": " + one_line(importer.GetErrorString()));
  Mesh mesh = mesh_of(*scene, albedo);
  if (mesh.faces.empty()) throw Error(file + " contains no faces");
  mesh.name = std::filesystem::path(path).stem().string();
  drop_degenerate_faces(mesh, policy, file,
                        [](size_t f) { return "triangle " + std::to_string(f + 1); });
  try {
    validate(mesh, DegenerateFaces::Allow);  // drop_degenerate_faces judged those
  } catch (const Error& e) {
    throw Error(file + ": " + e.what());
  }
  return mesh;
}

}  // namespace

void drop_degenerate_faces(Mesh& mesh, DegenerateFacePolicy policy, const std::string& file,
                           const std::function<std::string(size_t)>& place) {
  std::vector<glm::ivec3> kept;
  size_t dropped = 0, first = 0;
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    if (!degenerate(mesh, mesh.faces[f])) {
      kept.push_back(mesh.faces[f]);
      continue;
    }
    if (dropped++ == 0) first = f;
    if (policy == DegenerateFacePolicy::Refuse)
      throw Error(file + ": the face at " + place(f) +
                  " is degenerate (its corners are on one line or repeat a vertex)");
  }
  if (dropped == 0) return;
  if (kept.empty())
    throw Error(file + " contains no faces: all " + std::to_string(dropped) +
                " are degenerate (their corners are on one line or repeat a vertex)");
  std::fprintf(stderr,
               "penumbra: warning: %s: dropped %zu of %zu faces, degenerate (corners on one line "
               "or a vertex repeated), the first at %s\n",
               file.c_str(), dropped, mesh.faces.size(), place(first).c_str());
  mesh.faces = std::move(kept);
}

Mesh load_mesh(const std::string& path, glm::dvec3 default_albedo, DegenerateFacePolicy policy) {
  const MeshFormat& format = format_of(path);
  if (std::string(format.name) == "OBJ") return load_obj(path, default_albedo, policy);
  return load_with_assimp(path, format, default_albedo, policy);
}

}  // namespace penumbra
