// Mesh files (load_mesh, load_obj): every format on Assimp's own test models
// (/usr/share/assimp/models, Debian's assimp-testmodels), polygons, degenerate faces, text
// encodings, and the tool's --mesh.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

#include "cli_run.hpp"
#include "penumbra/error.hpp"
#include "penumbra/io.hpp"
#include "scenes.hpp"

using namespace penumbra;
using penumbra_tests::error_of;
using penumbra_tests::expect_clean_error;
using penumbra_tests::fresh_temp_dir;
using penumbra_tests::lines;
using penumbra_tests::quote;
using penumbra_tests::run_cli_to;

namespace {
namespace fs = std::filesystem;

const std::string kModels = "/usr/share/assimp/models/";

#define REQUIRE_MODELS()                 \
  ASSERT_TRUE(fs::is_directory(kModels)) \
      << kModels << " is missing: install assimp-testmodels (scripts/setup.sh)"

double area(const Mesh& m) {
  double sum = 0;
  for (const glm::ivec3& f : m.faces)
    sum += 0.5 * glm::length(glm::cross(m.vertices[f.y] - m.vertices[f.x],
                                        m.vertices[f.z] - m.vertices[f.x]));
  return sum;
}

std::string written(const std::string& dir, const std::string& name, const std::string& text) {
  std::string path = dir + "/" + name;
  std::ofstream(path, std::ios::binary) << text;
  return path;
}

// The polygon of the one `f` line of an OBJ file, its area by Newell's formula (exact for a
// planar polygon, concave or not), independent of any triangulation.
double polygon_area(const std::string& path) {
  std::ifstream in(path);
  std::vector<glm::dvec3> v, corners;
  std::string tag;
  for (std::string line; std::getline(in, line);) {
    std::istringstream s(line);
    if (!(s >> tag)) continue;
    glm::dvec3 p;
    if (tag == "v" && s >> p.x >> p.y >> p.z) v.push_back(p);
    for (std::string c; tag == "f" && s >> c;) corners.push_back(v[std::stoul(c) - 1]);
  }
  glm::dvec3 n(0);
  for (size_t i = 0; i < corners.size(); ++i)
    n += glm::cross(corners[i], corners[(i + 1) % corners.size()]);
  return 0.5 * glm::length(n);
}

// Every file of the formats penumbra reads, under the models' folders for them.
std::vector<std::string> model_files() {
  const std::vector<std::string> extensions{".obj", ".ply", ".stl", ".gltf", ".glb", ".off"};
  std::vector<std::string> files;
  for (const char* dir : {"OBJ", "PLY", "STL", "OFF", "glTF", "glTF2", "invalid"})
    for (const auto& e : fs::recursive_directory_iterator(kModels + dir)) {
      std::string ext = e.path().extension().string();
      std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
      if (e.is_regular_file() && std::count(extensions.begin(), extensions.end(), ext) > 0)
        files.push_back(e.path().string());
    }
  std::sort(files.begin(), files.end());
  return files;
}

}  // namespace

TEST(MeshFiles, EveryTestModelLoadsOrIsRefusedInOneLine) {
  REQUIRE_MODELS();
  const std::vector<std::string> files = model_files();
  EXPECT_GT(files.size(), 80u);
  size_t loaded = 0;
  for (const std::string& path : files) {
    SCOPED_TRACE(path);
    testing::internal::CaptureStderr();
    const std::string error = error_of([&] {
      const Mesh m = load_mesh(path);
      EXPECT_FALSE(m.faces.empty());
      EXPECT_TRUE(std::isfinite(area(m)) && area(m) > 0);
      ++loaded;
    });
    testing::internal::GetCapturedStderr();
    if (error.empty()) continue;
    EXPECT_NE(error.find(path), std::string::npos) << error;  // names the file
    EXPECT_EQ(error.find('\n'), std::string::npos) << error;
  }
  EXPECT_GT(loaded, 50u);
}

// The same models in several formats, read by tinyobjloader (OBJ) and by Assimp's readers
// of the others, give the same faces and area.
TEST(MeshFiles, OneModelInEveryFormatGivesOneMesh) {
  REQUIRE_MODELS();
  for (const char* file : {"OBJ/WusonOBJ.obj", "PLY/Wuson.ply", "STL/Wuson.stl", "OFF/Wuson.off"}) {
    const Mesh m = load_mesh(kModels + file);
    EXPECT_EQ(m.faces.size(), 3732u) << file;
    EXPECT_NEAR(area(m), 9.0258, 1e-3) << file;
  }
  // Unit cubes: 6 square faces of area 1.
  for (const char* file :
       {"OBJ/box.obj", "OBJ/box_UTF16BE.obj", "PLY/cube.ply", "PLY/cube_binary.ply", "OFF/Cube.off",
        "glTF/BoxTextured-glTF/BoxTextured.gltf",
        "glTF2/BoxTextured-glTF-Binary/BoxTextured.glb"}) {
    const Mesh m = load_mesh(kModels + file);
    EXPECT_EQ(m.faces.size(), 12u) << file;
    EXPECT_EQ(m.vertices.size(), 8u) << file;  // the corners of each face joined
    EXPECT_NEAR(area(m), 6.0, 1e-6) << file;
  }
}

TEST(MeshFiles, ConcavePolygonKeepsItsArea) {
  REQUIRE_MODELS();
  // A thin ring as one 66-corner outline through a doubled bridge edge: a fan covered 7.4
  // times its area.
  const std::string path = kModels + "OBJ/concave_polygon.obj";
  const Mesh m = load_mesh(path);
  EXPECT_EQ(m.faces.size(), 64u);
  EXPECT_NEAR(area(m), polygon_area(path), 1e-9 * polygon_area(path));
}

TEST(MeshFiles, ConcavePolygonWindingKept) {
  const std::string dir = fresh_temp_dir("mesh_files_winding");
  // An L in the z = 0 plane, counter-clockwise seen from +z, starting at its reflex corner.
  const Mesh m = load_mesh(written(dir, "l.obj",
                                   "v 1 1 0\nv 0 2 0\nv 0 0 0\nv 2 0 0\nv 2 1 0\nv 1 2 0\n"
                                   "f 1 6 2 3 4 5\n"));
  ASSERT_EQ(m.faces.size(), 4u);
  EXPECT_NEAR(area(m), 3.0, 1e-12);
  for (const glm::ivec3& f : m.faces) {
    const glm::dvec3 n =
        glm::cross(m.vertices[f.y] - m.vertices[f.x], m.vertices[f.z] - m.vertices[f.x]);
    EXPECT_GT(n.z, 0);
  }
}

TEST(MeshFiles, DegenerateFacesDroppedWithOneWarningOrRefused) {
  REQUIRE_MODELS();
  const std::string path = kModels + "OBJ/spider.obj";
  testing::internal::CaptureStderr();
  const Mesh m = load_mesh(path);
  const std::vector<std::string> warning = lines(testing::internal::GetCapturedStderr());
  EXPECT_EQ(m.faces.size(), 1368u - 56u);
  ASSERT_EQ(warning.size(), 1u);
  EXPECT_NE(warning[0].find("penumbra: warning: OBJ file '" + path + "': dropped 56 of 1368"),
            std::string::npos)
      << warning[0];
  EXPECT_NE(warning[0].find("the first at line 2902"), std::string::npos) << warning[0];
  const std::string refused = error_of([&] {
    load_mesh(path, {0.8, 0.8, 0.8}, DegenerateFacePolicy::Refuse);
  });
  EXPECT_NE(refused.find("the face at line 2902 is degenerate"), std::string::npos) << refused;
  // STL has no lines: a face is named by its place among the file's triangles.
  const std::string stl = error_of([&] {
    load_mesh(kModels + "STL/Spider_binary.stl", {0.8, 0.8, 0.8}, DegenerateFacePolicy::Refuse);
  });
  EXPECT_NE(stl.find("the face at triangle 925 is degenerate"), std::string::npos) << stl;
}

TEST(MeshFiles, MessagesNameTheFormatProblem) {
  const std::string dir = fresh_temp_dir("mesh_files_messages");
  EXPECT_NE(
      error_of([] { load_mesh("/dev/zero"); }).find("is not of a known format (no extension)"),
      std::string::npos);
  EXPECT_NE(error_of([&] {
              load_mesh(written(dir, "a.dae", "<xml/>"));
            }).find("not of a known format ('.dae'): penumbra reads .obj, .ply, .stl"),
            std::string::npos);
  EXPECT_NE(error_of([&] {
              load_mesh(written(dir, "b.ply", "ply\nformat nonsense\n"));
            }).find("cannot read PLY file"),
            std::string::npos);
  // UTF-16 text beyond ASCII: a byte-order mark, then "é".
  EXPECT_NE(error_of([&] {
              load_mesh(written(dir, "c.obj", std::string("\xFF\xFE\xE9\x00", 4)));
            }).find("UTF-16 text with characters beyond ASCII"),
            std::string::npos);
  // "v" then a vertical tab: a vertex to the scan, none to tinyobjloader (found by fuzz_obj).
  EXPECT_NE(
      error_of([&] {
        load_mesh(written(dir, "tab.obj", "v 0 0 0\nv 1 0 0\nv\v1 0 0\nv 0 1 0\nf -3 -2 -4\n"));
      }).find("line 5: face vertex index out of range (tinyobjloader read 3 vertices)"),
      std::string::npos);
  std::string polygon = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf";
  for (int i = 0; i < 300; ++i) polygon += " " + std::to_string(i % 3 + 1);
  EXPECT_NE(error_of([&] {
              load_mesh(written(dir, "d.obj", polygon + "\n"));
            }).find("line 4: face has 300 corners (at most 255)"),
            std::string::npos);
}

TEST(MeshFiles, SceneFilesAndTheToolReadEveryFormat) {
  REQUIRE_MODELS();
  const std::string dir = fresh_temp_dir("mesh_files_tool");
  const std::string ply = kModels + "PLY/cube.ply";
  const std::string rest = R"(, "cameras": [{"eye": [0, 0, 3]}], "lights": [{}]})";
  const Scene s = parse_scene(R"({"meshes": [{"file": ")" + ply + R"("}])" + rest, dir);
  EXPECT_EQ(s.meshes.at(0).faces.size(), 12u);
  EXPECT_NE(error_of([&] {
              parse_scene(R"({"meshes": [{"file": ")" + kModels +
                              R"(OBJ/spider.obj", "refuse_degenerate": true}])" + rest,
                          dir);
            }).find("the face at line 2902 is degenerate"),
            std::string::npos);

  const std::string spider = quote(kModels + "OBJ/spider.obj");
  const auto ok = run_cli_to(
      "render --mesh " + spider + " --width 32 --height 32 -o " + quote(dir + "/spider.png"),
      dir + "/out", dir + "/err");
  EXPECT_EQ(ok.exit_code, 0) << penumbra_tests::show(ok);
  ASSERT_EQ(lines(ok.err).size(), 1u) << penumbra_tests::show(ok);
  EXPECT_NE(ok.err.find("dropped 56 of 1368 faces"), std::string::npos);
  expect_clean_error(run_cli_to("render --refuse-degenerate --mesh " + spider + " -o " +
                                    quote(dir + "/refused.png"),
                                dir + "/out", dir + "/err"),
                     "the face at line 2902 is degenerate");
  EXPECT_FALSE(fs::exists(dir + "/refused.png"));
}
