// Files in and out: OBJ, JSON scenes, PNG, .npy; scene validation and framing, and the meshes'
// shared arrays (io.hpp, scene.hpp, shared_array.hpp).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <fstream>
#include <functional>
#include <limits>
#include <sstream>
#include <string>

#include "penumbra/error.hpp"
#include "penumbra/image_io.hpp"
#include "penumbra/io.hpp"
#include "penumbra/scene.hpp"

namespace penumbra {
namespace {

const std::string kData = PENUMBRA_DATA_DIR;

std::string temp_path(const std::string& name) {
  return ::testing::TempDir() + "penumbra_io_" + name;
}

void write_text(const std::string& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary);
  f << text;
  ASSERT_TRUE(f.good()) << path;
}

std::string read_bytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::ostringstream s;
  s << f.rdbuf();
  return s.str();
}

// Runs `fn`, expects a penumbra::Error whose one-line message contains `needle`.
void expect_error(const std::function<void()>& fn, const std::string& needle) {
  try {
    fn();
    ADD_FAILURE() << "expected penumbra::Error containing \"" << needle << "\"";
  } catch (const Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(needle), std::string::npos)
        << "message \"" << msg << "\" lacks \"" << needle << "\"";
    EXPECT_EQ(msg.find('\n'), std::string::npos) << "message spans lines: " << msg;
  }
}

Mesh obj_mesh(const std::string& name, const std::string& text) {
  const std::string path = temp_path(name + ".obj");
  write_text(path, text);
  return load_obj(path);
}

// ---- OBJ ------------------------------------------------------------------------------------

TEST(IoObj, RoundTrip) {
  Mesh m;
  m.name = "tetra";
  // Values with short binary and decimal forms survive %.9g text and float parsing exactly.
  m.vertices = {{0.125, -1.5, 2.0}, {3.25, 0.5, -0.75}, {-2.0, 1.0, 0.0625}, {1.0, 2.5, 1.5}};
  m.faces = {{0, 1, 2}, {0, 3, 1}, {1, 3, 2}, {2, 3, 0}};
  m.albedo = {{0.5, 0.25, 0.125}, {1, 0, 0.75}, {0.375, 0.625, 0.875}, {0, 0, 0}};
  const std::string path = temp_path("roundtrip.obj");
  save_obj(m, path);
  const Mesh r = load_obj(path);
  ASSERT_EQ(r.vertices.size(), m.vertices.size());
  ASSERT_EQ(r.faces.size(), m.faces.size());
  ASSERT_EQ(r.albedo.size(), m.albedo.size());
  EXPECT_EQ(r.albedo_mode, AlbedoMode::PerVertex);
  for (size_t i = 0; i < m.vertices.size(); ++i)
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(r.vertices[i][k], m.vertices[i][k], 1e-9);
      EXPECT_NEAR(r.albedo[i][k], m.albedo[i][k], 1e-9);
    }
  for (size_t f = 0; f < m.faces.size(); ++f) EXPECT_EQ(r.faces[f], m.faces[f]);
}

TEST(IoObj, DefaultAlbedoWithoutVertexColours) {
  const Mesh m = obj_mesh("nocolour", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  ASSERT_EQ(m.albedo.size(), 3u);
  EXPECT_EQ(m.albedo[0], glm::dvec3(0.8));
  EXPECT_EQ(m.name, "penumbra_io_nocolour");
}

TEST(IoObj, QuadsAreTriangulated) {
  const Mesh m = obj_mesh("quad", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n");
  EXPECT_EQ(m.faces.size(), 2u);
}

TEST(IoObj, BundledIcosphere) {
  const Mesh m = load_obj(kData + "/meshes/icosphere.obj");
  EXPECT_EQ(m.vertices.size(), 642u);
  EXPECT_EQ(m.faces.size(), 1280u);
  for (const glm::dvec3& v : m.vertices) EXPECT_NEAR(glm::length(v), 1.0, 1e-6);
  // Outward, counter-clockwise winding.
  for (const glm::ivec3& f : m.faces) {
    const glm::dvec3 a = m.vertices[f.x], b = m.vertices[f.y], c = m.vertices[f.z];
    EXPECT_GT(glm::dot(glm::cross(b - a, c - a), a + b + c), 0.0);
  }
}

TEST(IoObj, BundledPlane) {
  const Mesh m = load_obj(kData + "/meshes/plane.obj");
  EXPECT_EQ(m.vertices.size(), 25u);
  EXPECT_EQ(m.faces.size(), 32u);
  for (const glm::ivec3& f : m.faces) {
    const glm::dvec3 a = m.vertices[f.x], b = m.vertices[f.y], c = m.vertices[f.z];
    EXPECT_GT(glm::cross(b - a, c - a).y, 0.0);
  }
}

TEST(IoObj, Errors) {
  expect_error([] { load_obj(temp_path("does_not_exist.obj")); }, "cannot open");
  expect_error([] { obj_mesh("malformed", "v 0 0 0\nv 1 zero 0\nv 0 1 0\nf 1 2 3\n"); },
               "not a number");
  expect_error([] { obj_mesh("badface", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n"); },
               "is not v, v/vt, v/vt/vn or v//vn");
  expect_error([] { obj_mesh("empty", "# nothing here\n"); }, "contains no faces");
  expect_error([] { obj_mesh("nofaces", "v 0 0 0\nv 1 0 0\nv 0 1 0\n"); }, "contains no faces");
  expect_error([] { obj_mesh("nan", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n"); }, "non-finite");
  expect_error([] { obj_mesh("range", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n"); }, "out of range");
  expect_error([] { obj_mesh("relrange", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n"); },
               "out of range");
  expect_error([] { obj_mesh("degenerate", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n"); },
               "degenerate");
  expect_error([] { obj_mesh("repeat", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 2\n"); },
               "repeat a vertex");
  expect_error([] { obj_mesh("zeroindex", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n"); },
               "vertex index 0");
}

// ---- validation -----------------------------------------------------------------------------

Mesh triangle() {
  Mesh m;
  m.name = "tri";
  m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  m.faces = {{0, 1, 2}};
  m.albedo.assign(3, glm::dvec3(0.5));
  return m;
}

Scene small_scene() {
  Scene s;
  s.meshes.push_back(triangle());
  s.cameras.emplace_back();
  s.lights.emplace_back();
  return s;
}

// Copies of a SharedArray share its values until one is written; a write gives the written
// array its own values, and the others keep theirs.
TEST(SharedArray, CopiesShareUntilOneIsWritten) {
  SharedArray<int> a = std::vector<int>{1, 2, 3};
  SharedArray<int> b = a;
  EXPECT_TRUE(b.shares(a));
  b.push_back(4);
  EXPECT_FALSE(b.shares(a));
  EXPECT_EQ(a, (std::vector<int>{1, 2, 3}));
  EXPECT_EQ(b, (std::vector<int>{1, 2, 3, 4}));
  SharedArray<int> c = a;
  c.edit([](std::vector<int>& v) { v[0] = 7; });
  EXPECT_EQ(a, (std::vector<int>{1, 2, 3}));
  EXPECT_EQ(c, (std::vector<int>{7, 2, 3}));
  SharedArray<int> alone = std::vector<int>{5};
  const int* values = alone.data();
  alone.edit([](std::vector<int>& v) { v[0] = 6; });  // shared with none: written in place
  EXPECT_EQ(alone.data(), values);
  EXPECT_EQ(SharedArray<int>(std::vector<int>{1, 2, 3}), a);  // equal values, not shared
  a.clear();
  EXPECT_TRUE(a.empty());
  EXPECT_EQ(b.size(), 4u);
}

TEST(IoValidate, Mesh) {
  EXPECT_NO_THROW(validate(triangle()));
  {
    Mesh m = triangle();
    m.vertices[1].y = std::numeric_limits<double>::quiet_NaN();
    expect_error([&] { validate(m); }, "mesh 'tri': vertex 1 has a non-finite coordinate");
  }
  {
    Mesh m = triangle();
    m.faces.edit([](std::vector<glm::ivec3>& f) { f[0].z = -1; });
    expect_error([&] { validate(m); }, "out of range");
  }
  {
    Mesh m = triangle();
    m.faces.clear();
    expect_error([&] { validate(m); }, "has no faces");
  }
  {
    Mesh m = triangle();
    m.albedo.pop_back();
    expect_error([&] { validate(m); }, "albedo count 2 does not match the vertex count 3");
  }
  {
    Mesh m = triangle();
    m.albedo_mode = AlbedoMode::PerFace;
    expect_error([&] { validate(m); }, "face count 1");
    m.albedo.resize(1);
    EXPECT_NO_THROW(validate(m));
  }
  {
    Mesh m = triangle();
    m.albedo.edit([](std::vector<glm::dvec3>& a) { a[2].x = -0.1; });
    expect_error([&] { validate(m); }, "albedo 2 is negative");
    m.albedo.edit(
        [](std::vector<glm::dvec3>& a) { a[2].x = std::numeric_limits<double>::quiet_NaN(); });
    expect_error([&] { validate(m); }, "albedo 2 is non-finite");
  }
  {
    // Zero area relative to the mesh size: a tiny but proper triangle is fine.
    Mesh m = triangle();
    for (auto& v : m.vertices) v *= 1e-5;
    EXPECT_NO_THROW(validate(m));
  }
}

TEST(IoValidate, Scene) {
  EXPECT_NO_THROW(validate(small_scene()));
  const double nan = std::numeric_limits<double>::quiet_NaN();
  auto check = [](const std::function<void(Scene&)>& edit, const std::string& needle) {
    Scene s = small_scene();
    edit(s);
    expect_error([&] { validate(s); }, needle);
  };
  check([](Scene& s) { s.meshes.clear(); }, "no meshes");
  check([](Scene& s) { s.cameras.clear(); }, "no cameras");
  check([](Scene& s) { s.cameras[0].width = 0; }, "image size");
  check([](Scene& s) { s.cameras[0].height = 20000; }, "image size");
  check([](Scene& s) { s.cameras[0].fov_deg = 180; }, "fov");
  check(
      [](Scene& s) {
        s.cameras[0].projection = Projection::Orthographic;
        s.cameras[0].half_height = 0;
      },
      "half_height");
  check([](Scene& s) { s.cameras[0].near = 0; }, "near");
  check([](Scene& s) { s.cameras[0].far = s.cameras[0].near; }, "far");
  check([](Scene& s) { s.cameras[0].target = s.cameras[0].eye; }, "same point");
  check([](Scene& s) { s.cameras[0].up = {0, 0, -2}; }, "parallel");
  check([nan](Scene& s) { s.lights[0].position.x = nan; }, "light 0: position");
  check(
      [](Scene& s) {
        s.lights[0].type = LightType::Directional;
        s.lights[0].direction = glm::dvec3(0);
      },
      "zero direction");
  check([](Scene& s) { s.lights[0].color.y = -1; }, "negative");
  check([](Scene& s) { s.lights[0].size = -0.5; }, "size");
  check([](Scene& s) { s.params.sigma = 0; }, "sigma");
  check([](Scene& s) { s.params.gamma = 1.5; }, "gamma");
  check([](Scene& s) { s.params.eps = -1e-3; }, "eps");
  check([](Scene& s) { s.params.dist_eps = 1; }, "dist_eps");
  check([](Scene& s) { s.params.sigma_s = 0; }, "sigma_s");
  check([](Scene& s) { s.params.lambda_eps = 0; }, "lambda_eps");
  check([](Scene& s) { s.params.gamma_s = -1; }, "gamma_s");
  check([nan](Scene& s) { s.params.beta = nan; }, "beta");
  check([](Scene& s) { s.params.gamma_p = std::numeric_limits<double>::infinity(); }, "gamma_p");
}

TEST(IoValidate, FramedScene) {
  Mesh m = load_obj(kData + "/meshes/icosphere.obj");
  for (auto& v : m.vertices) v = v * 3.0 + glm::dvec3(10, -2, 5);
  const Scene s = framed_scene(m, 320, 240);
  ASSERT_EQ(s.meshes.size(), 1u);
  ASSERT_EQ(s.cameras.size(), 1u);
  ASSERT_EQ(s.lights.size(), 1u);
  const Camera& c = s.cameras[0];
  EXPECT_EQ(c.width, 320);
  EXPECT_EQ(c.height, 240);
  EXPECT_NEAR(glm::length(c.target - glm::dvec3(10, -2, 5)), 0.0, 1e-6);
  const double dist = glm::length(c.eye - c.target);
  EXPECT_GT(c.near, 0.0);
  EXPECT_LT(c.near, dist - 3.0);  // the whole sphere lies between near and far
  EXPECT_GT(c.far, dist + 3.0);
  // Elevation ~25°.
  EXPECT_NEAR(std::asin((c.eye.y - c.target.y) / dist), glm::radians(25.0), 1e-9);
  // The sphere's angular radius is ~70% of the half field of view.
  const double half_fov = glm::radians(c.fov_deg) / 2;
  EXPECT_NEAR(std::tan(std::asin(3.0 / dist)) / std::tan(half_fov), 0.7, 0.01);
  EXPECT_GT(s.lights[0].position.y, c.target.y);
  EXPECT_EQ(s.ambient, glm::dvec3(0.2));
  EXPECT_EQ(s.background, glm::dvec3(1));
}

TEST(IoValidate, Bounds) {
  Scene s = small_scene();
  Mesh m = triangle();
  for (auto& v : m.vertices) v += glm::dvec3(0, 0, -4);
  s.meshes.push_back(m);
  const Bounds b = bounds(s);
  EXPECT_EQ(b.lo, glm::dvec3(0, 0, -4));
  EXPECT_EQ(b.hi, glm::dvec3(1, 1, 0));
  EXPECT_EQ(b.center(), glm::dvec3(0.5, 0.5, -2));
}

// ---- scene JSON -----------------------------------------------------------------------------

TEST(IoScene, BundledTurnaround) {
  const Scene s = load_scene(kData + "/scenes/turnaround.json");
  ASSERT_EQ(s.meshes.size(), 2u);
  EXPECT_EQ(s.meshes[0].name, "sphere");
  EXPECT_EQ(s.meshes[0].vertices.size(), 642u);
  EXPECT_EQ(s.meshes[0].faces.size(), 1280u);
  EXPECT_EQ(s.meshes[1].faces.size(), 32u);
  // The sphere rests on the plane.
  double lowest = 1e9;
  for (const auto& v : s.meshes[0].vertices) {
    EXPECT_NEAR(glm::length(v - glm::dvec3(0, 1, 0)), 1.0, 1e-6);
    lowest = std::min(lowest, v.y);
  }
  EXPECT_NEAR(lowest, 0.0, 1e-6);
  for (const auto& v : s.meshes[1].vertices) EXPECT_EQ(v.y, 0.0);
  for (const auto& a : s.meshes[0].albedo) EXPECT_EQ(a, glm::dvec3(0.85, 0.35, 0.3));
  for (const auto& a : s.meshes[1].albedo) EXPECT_EQ(a, glm::dvec3(0.8));

  ASSERT_EQ(s.cameras.size(), 1u);
  const Camera& c = s.cameras[0];
  EXPECT_EQ(c.projection, Projection::Perspective);
  EXPECT_EQ(c.fov_deg, 40.0);
  EXPECT_EQ(c.near, 0.5);
  EXPECT_EQ(c.far, 20.0);
  EXPECT_EQ(c.width, 256);
  EXPECT_EQ(c.height, 256);
  EXPECT_EQ(c.target, glm::dvec3(0, 0.6, 0));
  EXPECT_NEAR(glm::length(c.eye - c.target), 6.0, 1e-9);
  EXPECT_NEAR(glm::degrees(std::asin((c.eye.y - c.target.y) / 6.0)), 30.0, 1e-9);

  ASSERT_EQ(s.lights.size(), 1u);
  EXPECT_EQ(s.lights[0].type, LightType::Point);
  EXPECT_EQ(s.lights[0].color, glm::dvec3(1));
  EXPECT_EQ(s.lights[0].size, 0.5);
  const double light_dist = glm::length(s.lights[0].position - glm::dvec3(0, 1, 0));
  EXPECT_GT(light_dist, 6.0);
  EXPECT_LT(light_dist, 8.0);

  EXPECT_EQ(s.ambient, glm::dvec3(0.25));
  EXPECT_EQ(s.background, glm::dvec3(1));
  const RenderParams d;
  EXPECT_EQ(s.params.sigma, d.sigma);
  EXPECT_EQ(s.params.gamma, d.gamma);
  EXPECT_EQ(s.params.eps, d.eps);
  EXPECT_EQ(s.params.dist_eps, d.dist_eps);
  EXPECT_EQ(s.params.sigma_s, d.sigma_s);
  EXPECT_EQ(s.params.lambda_eps, d.lambda_eps);
  EXPECT_EQ(s.params.gamma_s, d.gamma_s);
  EXPECT_EQ(s.params.beta, d.beta);
  EXPECT_EQ(s.params.gamma_p, d.gamma_p);
  EXPECT_EQ(s.params.cull_backfaces, d.cull_backfaces);
}

const std::string kMeshes = kData + "/meshes";

TEST(IoScene, DefaultsAndOptions) {
  const Scene s = parse_scene(R"({
    "meshes": [{"file": "icosphere.obj", "scale": [2, 2, -2]}],
    "cameras": [{"projection": "orthographic", "half_height": 3}],
    "lights": [{"type": "directional", "direction": [0, -1, 0], "color": [1, 0.5, 0],
                "intensity": 2}],
    "render": {"cull_backfaces": true}
  })",
                              kMeshes);
  const Mesh& m = s.meshes[0];
  EXPECT_EQ(m.name, "icosphere");
  EXPECT_NEAR(glm::length(m.vertices[0]), 2.0, 1e-6);
  EXPECT_EQ(m.albedo[0], glm::dvec3(0.8));
  // A mirroring scale keeps the faces wound outward.
  for (const glm::ivec3& f : m.faces) {
    const glm::dvec3 a = m.vertices[f.x], b = m.vertices[f.y], c = m.vertices[f.z];
    EXPECT_GT(glm::dot(glm::cross(b - a, c - a), a + b + c), 0.0);
  }
  const Camera def;
  EXPECT_EQ(s.cameras[0].projection, Projection::Orthographic);
  EXPECT_EQ(s.cameras[0].half_height, 3.0);
  EXPECT_EQ(s.cameras[0].eye, def.eye);
  EXPECT_EQ(s.cameras[0].width, def.width);
  EXPECT_EQ(s.lights[0].type, LightType::Directional);
  EXPECT_EQ(s.lights[0].color, glm::dvec3(2, 1, 0));
  EXPECT_EQ(s.ambient, Scene().ambient);
  EXPECT_TRUE(s.params.cull_backfaces);
  EXPECT_EQ(s.params.sigma, RenderParams().sigma);
  // A map size left out follows the shadow model (docs/scene-format.md); a given one stays.
  RenderParams p = s.params;
  EXPECT_FALSE(p.shadow_map_size.has_value());
  EXPECT_EQ(shadow_map_side(p), 384);
  p.shadow_model = ShadowModel::Paper;
  EXPECT_EQ(shadow_map_side(p), 256);
  p.shadow_map_size = 100;
  EXPECT_EQ(shadow_map_side(p), 100);
}

// "sampling" and "exact_backend" are independent keys; "sampling": "gemm" stays a shorthand
// for exact sampling on CLBlast, and contradicting it is an error. The combinations the
// renderer cannot run are refused by validate (check_combination), named by both settings.
TEST(IoScene, SamplingAndExactBackend) {
  auto params = [](const std::string& render) {
    return parse_scene(R"({"meshes": [{"file": "icosphere.obj"}], "cameras": [{}], "render": )" +
                           render + "}",
                       kMeshes)
        .params;
  };
  EXPECT_EQ(params("{}").sampling, Sampling::Truncated);
  EXPECT_EQ(params("{}").exact_backend, ExactBackend::Auto);
  RenderParams p = params(R"({"sampling": "exact", "exact_backend": "kernels"})");
  EXPECT_EQ(p.sampling, Sampling::Exact);
  EXPECT_EQ(p.exact_backend, ExactBackend::Kernels);
  p = params(R"({"sampling": "gemm", "shadows": "hard", "shadow_model": "paper"})");
  EXPECT_EQ(p.sampling, Sampling::Exact);
  EXPECT_EQ(p.exact_backend, ExactBackend::CLBlast);
  p = params(R"({"sampling": "gemm", "exact_backend": "clblast"})");
  EXPECT_EQ(p.exact_backend, ExactBackend::CLBlast);
  auto parse = [&](const std::string& render) { return [=] { params(render); }; };
  expect_error(parse(R"({"sampling": "gemm", "exact_backend": "kernels"})"),
               "'render.exact_backend' is \"kernels\"");
  expect_error(parse(R"({"sampling": "gems"})"), "expected truncated, exact or gemm");
  expect_error(parse(R"({"exact_backend": "blas"})"), "expected auto, kernels or clblast");
  expect_error(parse(R"({"sampling": "truncated", "exact_backend": "clblast"})"),
               "needs sampling 'exact'");
  expect_error(parse(R"({"sampling": "gemm", "shadows": "soft", "shadow_model": "paper"})"),
               "soft shadows");
  expect_error(parse(R"({"sampling": "gemm", "shadows": "hard"})"), "accurate shadow model");
  EXPECT_NO_THROW(
      params(R"({"sampling": "exact", "exact_backend": "kernels", "shadows": "soft"})"));
}

// Values whose squares overflow are named as too large, not by what their overflow breaks
// later (a view direction of zero, a frustum of NaNs, every face degenerate).
TEST(IoScene, ValuesTooLargeToStayFiniteAreNamed) {
  auto parse = [](const std::string& mesh, const std::string& camera, const std::string& light) {
    return [=] {
      parse_scene(R"({"meshes": [{"file": "icosphere.obj")" + mesh + R"(}], "cameras": [{)" +
                      camera + R"(}], "lights": [{)" + light + "}]}",
                  kMeshes);
    };
  };
  const std::string too_large = "has a coordinate beyond ±1e+100, too large for its squared";
  expect_error(parse("", R"("eye": [1e308, 0, 0])", ""),
               "camera 0: eye (1e+308, 0, 0) " + too_large);
  expect_error(parse("", "", R"("position": [0, 1e200, 0])"), "light 0: position (0, 1e+200, 0)");
  expect_error(parse(R"(, "scale": 1e200)", "", ""), "vertex 0 (");
  expect_error(parse(R"(, "translate": [1e308, 0, 0])", "", ""), too_large);
  EXPECT_NO_THROW(parse(R"(, "scale": 1e90)", R"("eye": [0, 0, 1e95])", "")());
}

// Refused where the nesting passes 64 levels: at once, however deep the document goes.
TEST(IoScene, DeepNestingIsRefusedAtOnce) {
  const std::string deep = std::string(200000, '[') + std::string(200000, ']');
  expect_error([&] { parse_scene(deep, kMeshes); },
               "'[0][0][0][0][0][0][0][0][0][0][0][0][0][...' is nested deeper than 64 levels");
  const std::string cameras = R"({"cameras": )" + std::string(64, '[') + std::string(64, ']') + "}";
  expect_error([&] { parse_scene(cameras, kMeshes); },
               "'cameras[0][0][0][0][0][0][0][0][0][0][0]...' is nested");
  // 64 levels are read (and refused for what they hold).
  const std::string ok = R"({"cameras": )" + std::string(63, '[') + std::string(63, ']') + "}";
  expect_error([&] { parse_scene(ok, kMeshes); }, "the required key 'meshes' is missing");
}

TEST(IoScene, Errors) {
  auto parse = [](const std::string& text) { return [text] { parse_scene(text, kMeshes); }; };
  const std::string mesh = R"("meshes": [{"file": "icosphere.obj"}])";
  const std::string cam = R"("cameras": [{}])";
  expect_error(parse("{" + mesh + ", " + cam + R"(, "lihgts": []})"), "unknown key 'lihgts'");
  expect_error(parse(R"({"meshes": [{"file": "icosphere.obj", "scael": 2}], )" + cam + "}"),
               "unknown key 'meshes[0].scael'");
  expect_error(parse("{" + mesh + ", " + cam + R"(, "render": {"sigam": 1e-5}})"),
               "unknown key 'render.sigam'");
  expect_error(parse("{" + mesh + R"(, "cameras": [{"fov": "40"}]})"),
               "'cameras[0].fov' must be a number, got a string");
  expect_error(parse("{" + mesh + R"(, "cameras": [{"width": 25.5}]})"),
               "'cameras[0].width' must be an integer");
  expect_error(parse("{" + mesh + R"(, "cameras": [{"eye": [0, 1]}]})"),
               "'cameras[0].eye' must be an array of 3 numbers");
  expect_error(parse("{" + mesh + R"(, "cameras": [{"projection": "fisheye"}]})"), "fisheye");
  expect_error(parse("{" + mesh + ", " + cam + R"(, "render": {"cull_backfaces": 1}})"),
               "'render.cull_backfaces' must be true or false");
  expect_error(parse("{" + mesh + ", " + cam + R"(, "lights": {}})"), "'lights' must be an array");
  expect_error(parse("{" + cam + "}"), "the required key 'meshes' is missing");
  expect_error(parse("{" + mesh + ", " + cam + ", }"), "JSON syntax error");
  expect_error(parse(R"({"meshes": [{"file": "nope.obj"}], )" + cam + "}"), "nope.obj");
  // Validation runs at the end.
  expect_error(parse("{" + mesh + R"(, "cameras": [{"near": 5, "far": 1}]})"), "camera 0: far");
  expect_error(parse("{" + mesh + ", " + cam + R"(, "render": {"sigma": 0}})"), "sigma");

  const std::string bad = temp_path("syntax.json");
  write_text(bad, "{\"meshes\": [\n  {\"file\": \"x.obj\"\n]}\n");
  expect_error([&] { load_scene(bad); }, bad);
  expect_error([&] { load_scene(bad); }, "JSON syntax error");
  expect_error([] { load_scene(temp_path("missing.json")); }, "cannot open scene file");
}

// ---- .npy -----------------------------------------------------------------------------------

Image ramp(int w, int h, int c) {
  Image im(w, h, c);
  for (size_t i = 0; i < im.data.size(); ++i) im.data[i] = 0.1 * double(i) - 3.3;
  return im;
}

void check_npy_header(const std::string& path, const std::string& descr, const std::string& shape) {
  const std::string b = read_bytes(path);
  ASSERT_GE(b.size(), 10u);
  EXPECT_EQ(b.substr(0, 6), std::string("\x93NUMPY", 6));
  EXPECT_EQ(b[6], 1);
  EXPECT_EQ(b[7], 0);
  const size_t len = size_t(uint8_t(b[8])) | size_t(uint8_t(b[9])) << 8;
  EXPECT_EQ((10 + len) % 64, 0u);
  const std::string header = b.substr(10, len);
  EXPECT_EQ(header.back(), '\n');
  EXPECT_NE(header.find("'descr': '" + descr + "'"), std::string::npos) << header;
  EXPECT_NE(header.find("'fortran_order': False"), std::string::npos) << header;
  EXPECT_NE(header.find("'shape': " + shape), std::string::npos) << header;
}

TEST(IoNpy, RoundTrip) {
  for (bool f64 : {false, true}) {
    for (int c : {1, 3}) {
      const Image im = ramp(5, 4, c);
      const std::string path = temp_path("rt.npy");
      save_npy(im, path, f64);
      check_npy_header(path, f64 ? "<f8" : "<f4", c == 1 ? "(4, 5)" : "(4, 5, 3)");
      const Image r = load_npy(path);
      EXPECT_EQ(r.width, 5);
      EXPECT_EQ(r.height, 4);
      EXPECT_EQ(r.channels, c);
      ASSERT_EQ(r.data.size(), im.data.size());
      for (size_t i = 0; i < im.data.size(); ++i) {
        if (f64)
          EXPECT_EQ(r.data[i], im.data[i]);
        else
          EXPECT_EQ(r.data[i], double(float(im.data[i])));
      }
    }
  }
}

TEST(IoNpy, RowsCols) {
  std::vector<double> v(7 * 3);
  for (size_t i = 0; i < v.size(); ++i) v[i] = double(i) * 0.5;
  const std::string path = temp_path("rows.npy");
  save_npy(v, 7, 3, path, true);
  check_npy_header(path, "<f8", "(7, 3)");
  const Image r = load_npy(path);
  EXPECT_EQ(r.height, 7);
  EXPECT_EQ(r.width, 3);
  EXPECT_EQ(r.channels, 1);
  EXPECT_EQ(r.data, v);
  expect_error([&] { save_npy(v, 4, 3, path); }, "do not fill shape");
}

TEST(IoNpy, Errors) {
  const Image im = ramp(3, 2, 1);
  const std::string good = temp_path("good.npy");
  save_npy(im, good);
  const std::string bytes = read_bytes(good);
  const std::string path = temp_path("corrupt.npy");
  auto load = [&] { load_npy(path); };

  write_text(path, "PK\x03\x04 this is not numpy at all, not at all");
  expect_error(load, "bad magic");
  write_text(path, bytes.substr(0, bytes.size() - 3));
  expect_error(load, "truncated data");
  write_text(path, bytes.substr(0, 40));
  expect_error(load, "truncated header");

  auto with_header = [&](const std::string& from, const std::string& to) {
    std::string b = bytes;
    const size_t at = b.find(from);
    ASSERT_NE(at, std::string::npos);
    ASSERT_EQ(from.size(), to.size());
    b.replace(at, from.size(), to);
    write_text(path, b);
  };
  with_header("'fortran_order': False", "'fortran_order': True ");
  expect_error(load, "Fortran");
  with_header("<f4", ">f4");
  expect_error(load, "big-endian");
  with_header("<f4", "<i4");
  expect_error(load, "unsupported dtype '<i4'");
  with_header("(2, 3)", "(6,)  ");
  expect_error(load, "2-D");
  expect_error([] { load_npy(temp_path("missing.npy")); }, "cannot open");
  expect_error([] { save_npy(Image(), temp_path("empty.npy")); }, "empty");
}

// ---- PNG ------------------------------------------------------------------------------------

TEST(IoPng, RoundTrip) {
  for (int c : {1, 3, 4}) {
    Image im(7, 5, c);
    for (int y = 0; y < im.height; ++y)
      for (int x = 0; x < im.width; ++x)
        for (int k = 0; k < c; ++k) im.at(x, y, k) = std::fmod(0.137 * (x + 3 * y + 5 * k), 1.0);
    im.at(0, 0, 0) = -0.5;  // clamped to 0
    im.at(1, 0, 0) = 2.0;   // clamped to 1
    const std::string path = temp_path("rt.png");
    save_png(im, path);
    const Image r = load_image(path);
    ASSERT_EQ(r.width, 7);
    ASSERT_EQ(r.height, 5);
    ASSERT_EQ(r.channels, c);
    for (size_t i = 0; i < im.data.size(); ++i)
      EXPECT_NEAR(r.data[i], std::min(1.0, std::max(0.0, im.data[i])), 0.5 / 255 + 1e-12);
    const Image grey = load_image(path, 1);
    EXPECT_EQ(grey.channels, 1);
    EXPECT_EQ(grey.data.size(), 35u);
  }
}

TEST(IoPng, Errors) {
  expect_error([] { save_png(Image(), temp_path("empty.png")); }, "empty");
  expect_error([] { save_png(Image(2, 2, 1), "/nonexistent-dir/x.png"); }, "cannot write PNG");
  expect_error([] { load_image(temp_path("missing.png")); }, "cannot read image");
  const std::string junk = temp_path("junk.png");
  write_text(junk, "definitely not an image");
  expect_error([&] { load_image(junk); }, "cannot read image");
}

}  // namespace
}  // namespace penumbra
