// Raster stage (math.md §2–§3 without shadows): the OpenCL renderer against the plain C++
// double-precision reference (host/reference/reference.cpp), on small scenes built here.
//
//   RasterReference.*  the reference itself against closed-form values (no device needed)
//   RasterDouble.*     double kernels vs reference, ~1e-9
//   RasterFloat.*      float kernels vs reference, ~1e-4
//   RasterTuning.*     brute force and every tile / pixels-per-item variant agree bit for bit
//   RasterDeterminism  rendering twice gives the same bits
//   RasterShadingSkip.*  raster_bwd's skip of the shading where a pixel has no colour gradient
//                      changes no bit, with and without shadows
// Every comparison also checks that no output holds NaN or inf.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <numeric>
#include <random>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "cli_run.hpp"
#include "ops/args.hpp"
#include "penumbra/context.hpp"
#include "penumbra/image.hpp"
#include "penumbra/reference.hpp"
#include "penumbra/renderer.hpp"
#include "penumbra/scene.hpp"
#include "scenes.hpp"

namespace {

using glm::dvec3;
using namespace penumbra;

// Shared device, builders and comparisons (scenes.hpp). A missing OpenCL device is a failure,
// not a skip: these tests are the kernels' correctness check.
using namespace penumbra_tests;

// ---------------------------------------------------------------------------------------------
// Geometry builders.

// The sphere of the raster scenes: brighter and more varied than the shadow tests' occluder.
const SphereAlbedo kSphereAlbedo{{0.55, 0.5, 0.45}, {0.35, 0.3, 0.3}};

// Horizontal n×n grid at height y over [x0,x1]×[z0,z1], facing +y, checkered per-face albedo.
Mesh ground(double y, double x0, double x1, double z0, double z1, int n) {
  Mesh mesh;
  mesh.name = "ground";
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i)
      mesh.vertices.push_back({x0 + (x1 - x0) * i / n, y, z0 + (z1 - z0) * j / n});
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i, b = a + 1, c = a + (n + 1), d = c + 1;
      const dvec3 col = (i + j) % 2 ? dvec3(0.7, 0.65, 0.6) : dvec3(0.4, 0.45, 0.5);
      mesh.faces.push_back({a, c, b});  // (c−a)×(b−a) points along +y
      mesh.albedo.push_back(col);
      mesh.faces.push_back({b, c, d});
      mesh.albedo.push_back(col * 0.9);
    }
  }
  mesh.albedo_mode = AlbedoMode::PerFace;
  return mesh;
}

Camera perspective_camera(dvec3 eye, dvec3 target, int w, int h, double fov, double near,
                          double far) {
  Camera c;
  c.eye = eye;
  c.target = target;
  c.up = {0, 1, 0};
  c.projection = Projection::Perspective;
  c.fov_deg = fov;
  c.near = near;
  c.far = far;
  c.width = w;
  c.height = h;
  return c;
}

Camera orthographic_camera(dvec3 eye, dvec3 target, int w, int h, double half_height, double near,
                           double far) {
  Camera c = perspective_camera(eye, target, w, h, 40.0, near, far);
  c.projection = Projection::Orthographic;
  c.half_height = half_height;
  return c;
}

// View depth of a world point for a camera (math.md §1), used to check that the scenes below
// really contain the cases they are meant to exercise.
double view_depth(const Camera& cam, dvec3 p) {
  return glm::dot(p - cam.eye, glm::normalize(cam.target - cam.eye));
}

// Number of faces with at least one vertex in front of the near plane (dropped by the
// renderer) and at least one vertex beyond it (so they would otherwise be visible).
int faces_straddling_near(const Scene& scene, const Camera& cam) {
  int count = 0;
  for (const Mesh& m : scene.meshes)
    for (const glm::ivec3& f : m.faces) {
      int behind = 0;
      for (int k = 0; k < 3; ++k) behind += view_depth(cam, m.vertices[size_t(f[k])]) < cam.near;
      count += behind > 0 && behind < 3;
    }
  return count;
}

// ---------------------------------------------------------------------------------------------
// Scenes.

// A handful of loose triangles, perspective, W > H: overlapping faces at different depths
// (two of them close enough in depth to blend), both windings on screen, a face running off
// the right edge of the image, a tilted face with per-vertex albedo (perspective-correct
// interpolation), a face with one vertex behind the eye and one with a vertex between the eye
// and the near plane (both dropped), a face entirely behind the camera, and a face crossing the
// far plane (silhouette only beyond it). One point light.
Scene triangles_scene() {
  Scene s;
  Mesh flat;
  flat.name = "flat";
  flat.albedo_mode = AlbedoMode::PerFace;
  auto add = [&flat](dvec3 a, dvec3 b, dvec3 c, dvec3 albedo) {
    const int base = int(flat.vertices.size());
    flat.vertices.insert(flat.vertices.end(), {a, b, c});
    flat.faces.push_back({base, base + 1, base + 2});
    flat.albedo.push_back(albedo);
  };
  add({-1.2, -0.8, 0.0}, {0.9, -0.7, 0.0}, {-0.2, 0.9, 0.0}, {0.8, 0.2, 0.2});    // back, CCW
  add({-0.3, -0.5, 0.4}, {0.2, 0.6, 0.4}, {0.8, -0.3, 0.4}, {0.2, 0.8, 0.2});     // front, CW
  add({-0.6, 0.0, 0.43}, {0.3, -0.9, 0.43}, {0.4, 0.3, 0.43}, {0.2, 0.3, 0.9});   // blends with ↑
  add({0.9, 0.2, -0.5}, {3.5, 0.6, -0.5}, {1.5, 1.4, -0.5}, {0.9, 0.8, 0.1});     // off the right
  add({-1.5, 0.6, -1.0}, {-0.6, 0.9, 5.0}, {-0.9, 1.2, -1.0}, {0.5, 0.5, 0.5});   // vertex behind
  add({-1.4, -1.0, 0.0}, {-0.5, -0.3, 3.8}, {-0.4, -1.2, 0.0}, {0.1, 0.9, 0.9});  // inside near
  add({-1.0, -1.0, 6.0}, {1.0, -1.0, 6.0}, {0.0, 1.0, 6.0}, {0.9, 0.9, 0.9});     // all behind
  add({0.2, -1.3, -2.0}, {1.6, -0.9, -9.0}, {1.4, -0.2, -2.0}, {0.6, 0.4, 0.8});  // crosses far
  s.meshes.push_back(flat);

  Mesh tilted;
  tilted.name = "tilted";
  tilted.vertices = {{-1.4, 0.2, -1.5}, {-0.2, 0.5, 1.2}, {-0.9, 1.3, 0.3}};
  tilted.faces = {{0, 1, 2}};
  tilted.albedo = {{0.9, 0.1, 0.1}, {0.1, 0.9, 0.1}, {0.1, 0.1, 0.9}};
  tilted.albedo_mode = AlbedoMode::PerVertex;
  s.meshes.push_back(tilted);

  s.cameras.push_back(perspective_camera({0.0, 0.0, 4.0}, {0.0, 0.0, 0.0}, 48, 32, 45.0, 0.5, 9.0));
  s.lights.push_back(point_light({1.5, 2.0, 3.0}, {0.9, 0.85, 0.8}));
  s.ambient = {0.15, 0.15, 0.2};
  s.background = {0.3, 0.5, 0.7};
  s.params.sigma = 5e-4;
  s.params.gamma = 3e-3;
  return s;
}

// An icosphere on a ground grid with two lights (point + directional). The ground reaches behind
// the perspective camera (faces straddling the near plane) and past its far plane. Two views:
// perspective with H > W and orthographic with W > H.
Scene sphere_scene(int levels = 1) {
  Scene s;
  s.meshes.push_back(icosphere({0.0, 0.0, 0.0}, 1.0, levels, "sphere", kSphereAlbedo));
  s.meshes.push_back(ground(-1.0, -4.0, 4.0, -14.0, 7.0, 6));
  s.cameras.push_back(
      perspective_camera({0.6, 1.2, 4.0}, {0.0, -0.2, 0.0}, 32, 48, 50.0, 0.3, 12.0));
  s.cameras.push_back(
      orthographic_camera({4.0, 3.0, 3.0}, {0.0, -0.3, 0.0}, 40, 24, 1.8, 0.1, 20.0));
  s.lights.push_back(point_light({2.0, 4.0, 3.0}, {0.7, 0.7, 0.6}));
  s.lights.push_back(directional_light({-0.3, -1.0, -0.5}, {0.3, 0.35, 0.4}));
  s.ambient = {0.1, 0.1, 0.1};
  s.background = {0.9, 0.95, 1.0};
  s.params.sigma = 1e-3;
  s.params.gamma = 1e-2;
  return s;
}

// ---------------------------------------------------------------------------------------------
// Comparison helpers.

// Double kernels: the same formulas in the same precision; only evaluation order differs.
constexpr Tolerance kDoubleTol{1e-9, 1e-9, 1e-9};
// Float kernels: screen positions and depths carry ~1e-7 relative error; the aggregation
// exponent (z̃ − m)/γ divides depth errors by γ (down to 3e-3 here) and the coverage exponent
// d²/σ divides squared-distance errors by σ, so colour and silhouette errors of ~1e-5 are
// expected (PoCL measured ≤ 8e-6 colour, ≤ 3e-6 silhouette, ≤ 8e-7 relative depth).
constexpr Tolerance kFloatTol{1e-4, 1e-4, 1e-5};

void expect_identical(const std::vector<RenderOutput>& a, const std::vector<RenderOutput>& b,
                      const std::string& what) {
  ASSERT_EQ(a.size(), b.size()) << what;
  for (size_t v = 0; v < a.size(); ++v) {
    EXPECT_EQ(a[v].color.data, b[v].color.data) << what << " view " << v << " colour";
    EXPECT_EQ(a[v].silhouette.data, b[v].silhouette.data) << what << " view " << v << " silhouette";
    EXPECT_EQ(a[v].depth.data, b[v].depth.data) << what << " view " << v << " depth";
    expect_finite(a[v].color, what + " colour");
    expect_finite(a[v].silhouette, what + " silhouette");
    expect_finite(a[v].depth, what + " depth");
  }
}

// ---------------------------------------------------------------------------------------------
// The reference against closed-form values.

// A large triangle in the plane z = 0 seen head-on: the centre pixel is fully covered, its
// depth is the plane's, its colour is albedo ⊙ (light · cosθ + ambient); a pixel of a small
// triangle's far corner shows the background at depth `far`.
TEST(RasterReference, HeadOnTriangle) {
  Scene s;
  Mesh m;
  m.vertices = {{-10, -10, 0}, {10, -10, 0}, {0, 10, 0}};
  m.faces = {{0, 1, 2}};
  m.albedo = {{0.5, 0.6, 0.7}};
  m.albedo_mode = AlbedoMode::PerFace;
  s.meshes.push_back(m);
  s.cameras.push_back(perspective_camera({0, 0, 5}, {0, 0, 0}, 33, 21, 40.0, 0.1, 20.0));
  s.lights.push_back(point_light({0, 0, 3}, {2, 2, 2}));
  s.ambient = {0.2, 0.2, 0.2};
  s.background = {0.1, 0.2, 0.3};
  s.params.sigma = 1e-3;
  s.params.gamma = 1e-2;

  RenderOutput out = penumbra::reference::render(s, 0);
  ASSERT_EQ(out.color.channels, 3);
  // Pixel (16, 10) is the image centre: X = (0,0,0), n·l = 1.
  EXPECT_NEAR(out.silhouette.at(16, 10), 1.0, 1e-12);
  EXPECT_NEAR(out.depth.at(16, 10), 5.0, 1e-12);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(out.color.at(16, 10, c), m.albedo[0][c] * 2.2, 1e-12);
  // A pixel off the centre: point light at distance, cosθ = 3/|X − L|.
  {
    const double tan_half = std::tan(20.0 * 3.14159265358979323846 / 180.0);
    const double x = (2.0 * 20 + 1 - 33) / 21.0, y = (21 - 2.0 * 4 - 1) / 21.0;
    const dvec3 X(x * tan_half * 5.0, y * tan_half * 5.0, 0.0);
    const double cos_theta = 3.0 / glm::length(dvec3(0, 0, 3) - X);
    EXPECT_NEAR(out.color.at(20, 4, 1), 0.6 * (2.0 * cos_theta + 0.2), 1e-12);
  }

  s.meshes[0].vertices = {{-0.1, -0.1, 0}, {0.1, -0.1, 0}, {0, 0.1, 0}};
  out = penumbra::reference::render(s, 0);
  EXPECT_EQ(out.silhouette.at(0, 0), 0.0);
  EXPECT_EQ(out.depth.at(0, 0), 20.0);
  for (int c = 0; c < 3; ++c) EXPECT_EQ(out.color.at(0, 0, c), s.background[c]);
  EXPECT_GT(out.silhouette.at(16, 10), 0.5);
}

// A tilted plane: inside the face, depth equals the ray–plane intersection (perspective-correct
// interpolation), and with albedo = position + const, no lights and ambient 1, the colour is
// the 3D point X hit by the pixel's ray. Orthographic: the same with parallel rays.
TEST(RasterReference, TiltedPlaneIsPerspectiveCorrect) {
  for (Projection proj : {Projection::Perspective, Projection::Orthographic}) {
    Scene s;
    Mesh m;
    m.vertices = {{-6, -4, -3}, {5, -5, 1}, {0, 6, -1}};
    m.faces = {{0, 1, 2}};
    const dvec3 offset(10, 10, 10);
    for (const dvec3& p : m.vertices) m.albedo.push_back(p + offset);
    s.meshes.push_back(m);
    Camera cam = perspective_camera({0.5, 0.3, 6}, {0, 0, 0}, 24, 30, 50.0, 0.1, 50.0);
    if (proj == Projection::Orthographic) {
      cam.projection = proj;
      cam.half_height = 2.0;
    }
    s.cameras.push_back(cam);
    s.ambient = {1, 1, 1};
    s.params.sigma = 1e-4;
    s.params.gamma = 1e-3;
    const RenderOutput out = penumbra::reference::render(s, 0);

    const dvec3 f = glm::normalize(cam.target - cam.eye);
    const dvec3 r = glm::normalize(glm::cross(f, cam.up));
    const dvec3 u = glm::cross(r, f);
    const dvec3 n = glm::cross(m.vertices[1] - m.vertices[0], m.vertices[2] - m.vertices[0]);
    const double tan_half = std::tan(25.0 * 3.14159265358979323846 / 180.0);
    for (int py = 6; py < 24; py += 5) {
      for (int px = 5; px < 20; px += 4) {
        const double x = (2.0 * px + 1 - cam.width) / cam.height;
        const double y = (cam.height - 2.0 * py - 1) / cam.height;
        dvec3 origin, dir;
        if (proj == Projection::Perspective) {
          origin = cam.eye;
          dir = f + x * tan_half * r + y * tan_half * u;  // view depth 1 per unit of t
        } else {
          origin = cam.eye + x * cam.half_height * r + y * cam.half_height * u;
          dir = f;
        }
        const double t = glm::dot(m.vertices[0] - origin, n) / glm::dot(dir, n);
        const dvec3 X = origin + t * dir;
        ASSERT_NEAR(out.silhouette.at(px, py), 1.0, 1e-9) << px << "," << py;
        EXPECT_NEAR(out.depth.at(px, py), t, 1e-9 * t) << px << "," << py;
        for (int c = 0; c < 3; ++c)
          EXPECT_NEAR(out.color.at(px, py, c), X[c] + offset[c], 1e-9) << px << "," << py;
      }
    }
  }
}

// Faces with a vertex in front of the near plane vanish entirely; a face crossing the far
// plane keeps its silhouette beyond it but adds no colour there; culling drops back faces.
TEST(RasterReference, NearFarAndCulling) {
  Scene s;
  Mesh m;
  m.vertices = {{-3, -3, 0}, {3, -3, 0}, {0, 3, 0}};
  m.faces = {{0, 1, 2}};
  m.albedo = {{0.5, 0.5, 0.5}};
  m.albedo_mode = AlbedoMode::PerFace;
  s.meshes.push_back(m);
  s.cameras.push_back(perspective_camera({0, 0, 5}, {0, 0, 0}, 16, 16, 60.0, 1.0, 20.0));
  s.params.sigma = 1e-3;
  s.params.gamma = 1e-2;
  s.background = {0.25, 0.25, 0.25};

  RenderOutput out = penumbra::reference::render(s, 0);
  EXPECT_NEAR(out.silhouette.at(8, 8), 1.0, 1e-12);

  s.meshes[0].vertices[2] = {0, 3, 4.5};  // view depth 0.5 < near
  out = penumbra::reference::render(s, 0);
  for (double v : out.silhouette.data) EXPECT_EQ(v, 0.0);
  for (double v : out.color.data) EXPECT_EQ(v, 0.25);

  s.meshes[0].vertices[2] = {0, 3, 0};
  s.cameras[0].far = 4.0;  // the whole face lies beyond far
  out = penumbra::reference::render(s, 0);
  EXPECT_NEAR(out.silhouette.at(8, 8), 1.0, 1e-12);
  EXPECT_EQ(out.depth.at(8, 8), 4.0);
  EXPECT_EQ(out.color.at(8, 8, 0), 0.25);

  s.cameras[0].far = 20.0;
  s.params.cull_backfaces = true;
  out = penumbra::reference::render(s, 0);
  EXPECT_NEAR(out.silhouette.at(8, 8), 1.0, 1e-12);  // CCW towards the camera: kept
  s.meshes[0].faces.edit([](std::vector<glm::ivec3>& f) { std::swap(f[0].y, f[0].z); });
  out = penumbra::reference::render(s, 0);
  for (double v : out.silhouette.data) EXPECT_EQ(v, 0.0);  // turned away: culled
}

// Huge |d²/σ| must not produce NaN or inf anywhere.
TEST(RasterReference, ExtremeSharpnessStaysFinite) {
  Scene s = sphere_scene();
  s.params.sigma = 1e-14;
  s.params.gamma = 1e-8;
  for (size_t v = 0; v < s.cameras.size(); ++v) {
    const RenderOutput out = penumbra::reference::render(s, v);
    expect_finite(out.color, "colour");
    expect_finite(out.silhouette, "silhouette");
    expect_finite(out.depth, "depth");
  }
}

// The scenes contain what their comments promise.
TEST(RasterReference, ScenesExerciseTheirCases) {
  const Scene tri = triangles_scene();
  EXPECT_GE(faces_straddling_near(tri, tri.cameras[0]), 2);
  const Scene sph = sphere_scene();
  EXPECT_GE(faces_straddling_near(sph, sph.cameras[0]), 1);
  // Some ground vertices lie beyond the far plane of the perspective view.
  int beyond_far = 0;
  for (const dvec3& p : sph.meshes[1].vertices)
    beyond_far += view_depth(sph.cameras[0], p) > sph.cameras[0].far;
  EXPECT_GT(beyond_far, 0);
  // Partly off-screen: the reference shows the right-edge face touching the image border.
  const RenderOutput out = penumbra::reference::render(tri, 0);
  double edge = 0.0;
  for (int y = 0; y < tri.cameras[0].height; ++y)
    edge = std::max(edge, out.silhouette.at(tri.cameras[0].width - 1, y));
  EXPECT_GT(edge, 0.99);
}

// ---------------------------------------------------------------------------------------------
// Kernels against the reference.

Scene ortho_triangles_scene() {
  Scene s = triangles_scene();
  s.cameras[0] = orthographic_camera({0.3, 0.2, 4.0}, {0.0, 0.0, 0.0}, 30, 40, 1.6, 0.5, 9.0);
  s.lights = {directional_light({0.4, -0.5, -1.0}, {0.8, 0.8, 0.8})};
  return s;
}

Scene culled_sphere_scene() {
  Scene s = sphere_scene();
  s.params.cull_backfaces = true;
  return s;
}

Scene one_light_sphere_scene() {
  Scene s = sphere_scene(2);
  s.lights = {directional_light({0.2, -1.0, -0.3}, {1.0, 0.9, 0.8})};
  s.cameras.resize(1);
  s.cameras[0].width = 40;
  s.cameras[0].height = 40;
  s.params.sigma = 3e-4;
  s.params.gamma = 5e-3;
  return s;
}

const std::vector<std::pair<std::string, Scene (*)()>>& all_scenes() {
  static const std::vector<std::pair<std::string, Scene (*)()>> scenes = {
      {"triangles", &triangles_scene},
      {"ortho_triangles", &ortho_triangles_scene},
      {"sphere", [] { return sphere_scene(); }},
      {"culled_sphere", &culled_sphere_scene},
      {"one_light_sphere", &one_light_sphere_scene},
  };
  return scenes;
}

TEST(RasterDouble, MatchesReference) {
  REQUIRE_CONTEXT(ctx);
  Renderer renderer(*ctx, Precision::Double);
  for (const auto& [name, make] : all_scenes())
    expect_matches_reference(renderer, make(), kDoubleTol, name);
}

TEST(RasterFloat, MatchesReference) {
  REQUIRE_CONTEXT(ctx);
  Renderer renderer(*ctx, Precision::Float);
  for (const auto& [name, make] : all_scenes())
    expect_matches_reference(renderer, make(), kFloatTol, name);
}

// The brute-force path (no bins) against the reference as well.
TEST(RasterDouble, BruteForceMatchesReference) {
  REQUIRE_CONTEXT(ctx);
  RasterTuning tuning;
  tuning.brute_force = true;
  Renderer renderer(*ctx, Precision::Double, tuning);
  expect_matches_reference(renderer, triangles_scene(), kDoubleTol, "triangles brute force");
  expect_matches_reference(renderer, sphere_scene(), kDoubleTol, "sphere brute force");
}

// ---------------------------------------------------------------------------------------------
// Schedules: brute force and every binned variant give the same bits.

std::vector<RasterTuning> all_tunings() {
  std::vector<RasterTuning> tunings;
  RasterTuning brute;
  brute.brute_force = true;
  tunings.push_back(brute);
  for (int tile : {8, 16, 32})
    for (int ppi : {1, 4, 8, 16}) {
      RasterTuning t;
      t.tile = tile;
      t.pixels_per_item = ppi;
      tunings.push_back(t);
    }
  return tunings;
}

std::string describe(const RasterTuning& t) {
  std::ostringstream os;
  if (t.brute_force)
    os << "brute force";
  else
    os << "tile " << t.tile << ", pixels/item " << t.pixels_per_item;
  return os.str();
}

// Sizes that no tile or pixels-per-item value divides, W > H and H > W, many faces per tile.
Scene tuning_scene() {
  Scene s = sphere_scene(2);
  s.cameras[0].width = 37;
  s.cameras[0].height = 53;
  s.cameras[1].width = 61;
  s.cameras[1].height = 43;
  s.params.sigma = 3e-4;
  s.params.gamma = 5e-3;
  return s;
}

void expect_all_tunings_identical(Precision precision) {
  REQUIRE_CONTEXT(ctx);
  const Scene scene = tuning_scene();
  const std::vector<RasterTuning> tunings = all_tunings();
  std::vector<RenderOutput> first;
  {
    Renderer renderer(*ctx, precision, tunings[0]);
    ASSERT_NO_THROW(first = renderer.render(scene));
  }
  for (size_t i = 1; i < tunings.size(); ++i) {
    Renderer renderer(*ctx, precision, tunings[i]);
    std::vector<RenderOutput> out;
    ASSERT_NO_THROW(out = renderer.render(scene)) << describe(tunings[i]);
    expect_identical(out, first, describe(tunings[i]) + " vs " + describe(tunings[0]));
  }
}

TEST(RasterTuning, AllSchedulesBitIdenticalDouble) {
  expect_all_tunings_identical(Precision::Double);
}

TEST(RasterTuning, AllSchedulesBitIdenticalFloat) {
  expect_all_tunings_identical(Precision::Float);
}

// ---------------------------------------------------------------------------------------------
// Rendering twice, with the same renderer or a fresh one, gives the same bits.

TEST(RasterDeterminism, RepeatedRendersIdentical) {
  REQUIRE_CONTEXT(ctx);
  const Scene scene = tuning_scene();
  for (Precision precision : {Precision::Float, Precision::Double}) {
    const std::string p = precision == Precision::Float ? "float" : "double";
    Renderer renderer(*ctx, precision);
    std::vector<RenderOutput> a, b, c;
    ASSERT_NO_THROW(a = renderer.render(scene));
    ASSERT_NO_THROW(b = renderer.render(scene));
    expect_identical(a, b, p + " same renderer");
    Renderer other(*ctx, precision);
    ASSERT_NO_THROW(c = other.render(scene));
    expect_identical(a, c, p + " fresh renderer");
  }
}

// One renderer through `scenes` in turn renders and differentiates each as a fresh one does.
void expect_reused_renderer_as_fresh(Context& ctx, std::initializer_list<const Scene*> scenes) {
  Renderer reused(ctx, Precision::Float);
  int step = 0;
  for (const Scene* s : scenes) {
    const std::string what = "scene " + std::to_string(step++);
    const auto weights = random_loss_weights(*s, 5);
    std::vector<RenderOutput> a, b;
    ASSERT_NO_THROW(a = reused.render(*s)) << what;
    const SceneGrads ga = reused.backward(*s, weights);
    Renderer fresh(ctx, Precision::Float);
    ASSERT_NO_THROW(b = fresh.render(*s)) << what;
    expect_identical(a, b, what);
    penumbra_tests::expect_identical(ga, fresh.backward(*s, weights), what);
  }
}

// A renderer rasters into its last render's fragment buffers where they fit (reuse_or_alloc):
// after scenes of other sizes, with shadows, it renders and differentiates as a fresh one does.
TEST(RasterDeterminism, ReusedBuffersGiveAFreshRenderersBits) {
  REQUIRE_CONTEXT(ctx);
  Scene base = tuning_scene();
  base.params.shadows = Shadows::Hard;
  Scene shrunk = base;  // fewer fragments
  for (Mesh& m : shrunk.meshes)
    for (dvec3& v : m.vertices) v *= 0.8;
  Scene small = base;  // far fewer
  for (Camera& c : small.cameras) c.width = c.height = 9;
  expect_reused_renderer_as_fresh(*ctx, {&base, &shrunk, &small, &base, &shrunk});
}

// A renderer keeps the last render's faces and the backward's groupings of their corners on the
// device while the faces stay (as in an optimisation), and its albedo while that stays too, and
// uploads them again when they change: through scenes whose faces, albedo or vertex counts
// change, whose albedo changes as the vertices move, and whose vertices then move (with
// everything but the faces and albedo, once), it renders and differentiates as a fresh one does.
TEST(RasterDeterminism, ChangedFacesAndAlbedoAreUploadedAgain) {
  REQUIRE_CONTEXT(ctx);
  Scene base = tuning_scene();
  base.params.shadows = Shadows::Hard;
  Mesh& sphere = base.meshes[0];  // albedo per face, so that its count is not the vertices'
  sphere.albedo_mode = AlbedoMode::PerFace;
  sphere.albedo.clear();
  for (const glm::ivec3& face : sphere.faces)
    sphere.albedo.push_back(dvec3(0.3, 0.5, 0.7) + 0.1 * (face.x % 3));
  Scene faces = base;  // the sphere's first half of faces replaced by copies of its second
  faces.meshes[0].faces.edit([](std::vector<glm::ivec3>& f) {
    std::copy(f.begin() + f.size() / 2, f.begin() + f.size() / 2 * 2, f.begin());
  });
  Scene albedo = base;
  albedo.meshes[0].albedo.edit([](std::vector<dvec3>& all) {
    for (dvec3& a : all) a *= 0.5;
  });
  Scene recoloured_moved = albedo;
  recoloured_moved.meshes[0].albedo.edit([](std::vector<dvec3>& all) {
    for (dvec3& a : all) a.x = 0.9;
  });
  for (dvec3& v : recoloured_moved.meshes[0].vertices) v *= 0.95;
  Scene more_vertices = base;  // one vertex more, unused: the ground's indices shift when packed
  more_vertices.meshes[0].vertices.push_back({0, 0, 0});
  Scene moved = more_vertices;
  for (dvec3& v : moved.meshes[0].vertices) v *= 0.8;
  Scene seen_anew = moved;  // its faces and albedo too as the last render's, all else changed
  for (dvec3& v : seen_anew.meshes[0].vertices) v *= 0.9;
  seen_anew.meshes[0].name = "renamed";
  seen_anew.cameras[0].eye += dvec3(0.3, 0.2, 0);
  seen_anew.lights[0].position += dvec3(0.2, 0, 0.1);
  seen_anew.ambient *= 0.5;
  seen_anew.background = dvec3(0.2, 0.3, 0.4);
  seen_anew.params.gamma *= 2;
  expect_reused_renderer_as_fresh(*ctx, {&base, &faces, &base, &albedo, &recoloured_moved, &base,
                                         &more_vertices, &moved, &seen_anew, &base});
}

// Unless PENUMBRA_TRANSFERS chooses, a context copies where the device's memory is not the
// host's (a discrete GPU's driver transfers copies faster, docs/gpu.md) and maps where it is
// (the test device of CI: PoCL on the CPU, whose maps copy nothing).
TEST(Transfers, CopiedOnlyWhereTheDeviceMemoryIsNotTheHosts) {
  REQUIRE_CONTEXT(ctx);
  ScopedEnv unset("PENUMBRA_TRANSFERS", nullptr);
  for (const DeviceInfo& d : list_devices()) {
    const Context context(std::to_string(d.index));
    EXPECT_EQ(context.copy_transfers(), !d.shares_host_memory) << d.name;
    if (d.device.getInfo<CL_DEVICE_TYPE>() == CL_DEVICE_TYPE_CPU) {
      EXPECT_TRUE(d.shares_host_memory)
          << d.name << ": a CPU device whose memory is not the host's";
    }
  }
}

// Reading results and writing inputs through reused host memory and copies
// (PENUMBRA_TRANSFERS=copy) gives the bits of mapped buffers (the default on PoCL): the outputs,
// the shadow and penumbra maps, and the gradients, in both precisions, of the accurate and the
// paper model's soft shadows (their host reads of records and texels), then of the scene with
// its vertices moved (written into the last render's buffer).
TEST(RasterDeterminism, CopiedTransfersGiveTheMappedBits) {
  REQUIRE_CONTEXT(ctx);
  std::unique_ptr<Context> mapped, copied;
  {
    ScopedEnv map("PENUMBRA_TRANSFERS", "map");
    mapped = std::make_unique<Context>(std::to_string(ctx->info().index));
  }
  {
    ScopedEnv copy("PENUMBRA_TRANSFERS", "copy");
    copied = std::make_unique<Context>(std::to_string(ctx->info().index));
  }
  ASSERT_FALSE(mapped->copy_transfers());
  ASSERT_TRUE(copied->copy_transfers());
  Scene base = tuning_scene();
  base.params.shadows = Shadows::Soft;
  Scene moved = base;
  for (dvec3& v : moved.meshes[0].vertices) v *= 0.9;
  for (Precision precision : {Precision::Float, Precision::Double})
    for (ShadowModel model : {ShadowModel::Accurate, ShadowModel::Paper}) {
      Renderer a(*mapped, precision), b(*copied, precision);
      for (Scene* s : {&base, &moved}) {
        s->params.shadow_model = model;
        const std::string what = std::string(precision == Precision::Float ? "float" : "double") +
                                 (model == ShadowModel::Paper ? " paper" : " accurate") +
                                 (s == &base ? "" : ", moved");
        const auto weights = random_loss_weights(*s, 5);
        std::vector<RenderOutput> ra, rb;
        ASSERT_NO_THROW(ra = a.render(*s)) << what;
        ASSERT_NO_THROW(rb = b.render(*s)) << what;
        expect_identical(ra, rb, what);
        for (auto maps : {&Renderer::shadow_maps, &Renderer::penumbra_maps}) {
          const std::vector<Image> ma = (a.*maps)(), mb = (b.*maps)();
          ASSERT_EQ(ma.size(), mb.size()) << what;
          for (size_t i = 0; i < ma.size(); ++i) EXPECT_EQ(ma[i].data, mb[i].data) << what;
        }
        penumbra_tests::expect_identical(a.backward(*s, weights), b.backward(*s, weights), what);
      }
    }
}

// Renderer::fragment_counts counts the kept fragments, not raster_count's bound on them: over a
// head-on view, two coincident triangles (faces 1 and 2) keep one fragment each per pixel, and
// a triangle behind them (face 0, visited first, so that the running maximum counts it) keeps
// none, its weight e^{−Δz̃/γ} far below weight_eps.
TEST(RasterFragments, CountsTheKeptFragments) {
  REQUIRE_CONTEXT(ctx);
  Scene s;
  Mesh m;
  m.vertices = {{-40, -40, -2}, {40, -40, -2}, {0, 40, -2},
                {-40, -40, 0},  {40, -40, 0},  {0, 40, 0}};
  m.faces = {{0, 1, 2}, {3, 4, 5}, {3, 4, 5}};
  m.albedo.assign(m.vertices.size(), {0.5, 0.5, 0.5});
  s.meshes.push_back(m);
  const int W = 24, H = 16;
  s.cameras.push_back(perspective_camera({0, 0, 5}, {0, 0, 0}, W, H, 40.0, 0.1, 20.0));
  s.lights.push_back(point_light({0, 0, 3}, {1, 1, 1}));
  s.params.sigma = 1e-3;
  s.params.gamma = 1e-3;
  for (Precision precision : {Precision::Float, Precision::Double}) {
    Renderer renderer(*ctx, precision);
    EXPECT_TRUE(renderer.fragment_counts().empty());
    ASSERT_NO_THROW(renderer.render(s));
    EXPECT_EQ(renderer.fragment_counts(), std::vector<size_t>{size_t(2 * W * H)});
  }
}

// Both raster passes skip a face hidden behind the block's nearest surface (lanes_may_weigh),
// but not one that still weighs ε_w of it: a plane 0.3 e-folds short of ε_w behind a front one
// keeps its fragments, one 0.3 e-folds beyond keeps none, in either face order (the count skips
// against its running maxima, raster_fragments against the final ones).
TEST(RasterFragments, KeepsAHiddenFaceThatStillWeighs) {
  REQUIRE_CONTEXT(ctx);
  const int W = 24, H = 16;
  const double near = 0.1, far = 20.0, gamma = 1e-3;
  for (double beyond : {-0.3, 0.3})
    for (bool back_first : {true, false}) {
      // Planes far larger than the view (log D = 0 at every pixel), Δz̃/γ = ln(1/ε_w) + beyond.
      const double dz = (std::log(1 / RenderParams{}.weight_eps) + beyond) * gamma * (far - near);
      Mesh m;
      m.vertices = {{-40, -40, 0},   {40, -40, 0},   {0, 40, 0},
                    {-40, -40, -dz}, {40, -40, -dz}, {0, 40, -dz}};
      m.faces = back_first ? std::vector<glm::ivec3>{{3, 4, 5}, {0, 1, 2}}
                           : std::vector<glm::ivec3>{{0, 1, 2}, {3, 4, 5}};
      m.albedo.assign(m.vertices.size(), {0.5, 0.5, 0.5});
      Scene s;
      s.meshes.push_back(m);
      s.cameras.push_back(perspective_camera({0, 0, 5}, {0, 0, 0}, W, H, 40.0, near, far));
      s.lights.push_back(point_light({0, 0, 3}, {1, 1, 1}));
      s.params.sigma = 1e-3;
      s.params.gamma = gamma;
      for (Precision precision : {Precision::Float, Precision::Double}) {
        Renderer renderer(*ctx, precision);
        ASSERT_NO_THROW(renderer.render(s));
        EXPECT_EQ(renderer.fragment_counts(),
                  std::vector<size_t>{size_t((beyond < 0 ? 2 : 1) * W * H)})
            << "beyond " << beyond << ", back face first " << back_first;
      }
    }
}

// ---------------------------------------------------------------------------------------------
// raster_bwd passes a fragment's gradient through its shading only where the pixel has a colour
// gradient (never in a light's view): kernels that always do give the same images and gradients
// bit for bit, with hard and soft shadows of both models, without shadows and without lights,
// under a loss whose colour part leaves the image's left half out (its silhouette and depth
// parts cover it all). And the skip happens: kernels that poison the normal's gradient where it
// would skip give NaN gradients.
constexpr const char* kShadingTest = "    if (gimg.x != 0 || gimg.y != 0 || gimg.z != 0)\n";

Scene shading_scene(Shadows shadows, ShadowModel model) {
  Scene s;
  s.meshes = {icosphere({0.0, 1.0, 0.0}, 0.5), penumbra_tests::ground(2.0, 4)};
  s.cameras = {front_camera(false)};
  s.lights = {point_light({0.9, 5.0, 0.7}, {0.9, 0.85, 0.8}, 1.0)};
  shadow_params(s, shadows, Sampling::Truncated, model);
  fit_light_frusta(s);
  return s;
}

std::vector<OutputGrads> colour_loss_on_right_half(const Scene& scene) {
  std::vector<OutputGrads> weights = random_loss_weights(scene, 13);
  for (OutputGrads& w : weights) clear_left_half(w.color);
  return weights;
}

TEST(RasterShadingSkip, ChangesNoBit) {
  REQUIRE_CONTEXT(ctx);
  const std::string always =
      patched_kernels("penumbra_raster_shade_always", "raster.cl", kShadingTest, "");
  std::vector<NamedScene> scenes;
  for (Shadows sh : {Shadows::Hard, Shadows::Soft})
    for (ShadowModel model : {ShadowModel::Paper, ShadowModel::Accurate})
      scenes.push_back({std::string(sh == Shadows::Hard ? "hard" : "soft") +
                            (model == ShadowModel::Paper ? " paper" : " accurate"),
                        shading_scene(sh, model)});
  scenes.push_back({"no shadows", shading_scene(Shadows::None, ShadowModel::Accurate)});
  scenes.push_back({"no lights (ambient only)", scenes.back().scene});
  scenes.back().scene.lights.clear();
  for (Precision p : {Precision::Float, Precision::Double})
    for (const auto& [name, scene] : scenes) {
      const std::string what = name + " " + name_of(p);
      const auto weights = colour_loss_on_right_half(scene);
      const Results a = results_with("", scene, p, weights),
                    b = results_with(always, scene, p, weights);
      EXPECT_TRUE(same_images(a.images, b.images)) << what;
      penumbra_tests::expect_identical(a.grads, b.grads, what + ": shading skipped or not", true);
    }
}

TEST(RasterShadingSkip, Taken) {
  REQUIRE_CONTEXT(ctx);
  const std::string poisoned =
      patched_kernels("penumbra_raster_shade_nan", "raster.cl", kShadingTest,
                      "    if (gimg.x == 0 && gimg.y == 0 && gimg.z == 0) s->gn = (real3)(NAN);\n");
  const Scene scene = shading_scene(Shadows::None, ShadowModel::Accurate);
  const auto weights = colour_loss_on_right_half(scene);
  EXPECT_TRUE(all_finite(grads_with("", scene, Precision::Float, weights)));
  EXPECT_FALSE(all_finite(grads_with(poisoned, scene, Precision::Float, weights)))
      << "no fragment's pixel lacked a colour gradient";
}

// ---------------------------------------------------------------------------------------------
// bin_sort puts each tile's list into face order whatever order bin_fill wrote it in (a CPU
// writes nearly sorted lists, a GPU any order): lists given here reversed, shuffled, as
// interleaved runs, of length 0 and 1, and longer than a work-group sorts in local memory
// (SORT_LOCAL), through the renderer's sort_lists (this device's SORT_GROUP) and with
// bin.cl built for work-groups of 64 and 256 (a GPU's) per list.

TEST(Binning, SortsListsInAnyOrder) {
  REQUIRE_CONTEXT(ctx);
  std::mt19937 rng(7);
  std::vector<std::vector<int>> lists(7);
  for (int n : {0, 1}) lists[n].resize(n, 42);
  lists[2].resize(777);
  std::iota(lists[2].rbegin(), lists[2].rend(), 0);  // reversed
  lists[3].resize(1500);
  std::iota(lists[3].begin(), lists[3].end(), 100);
  std::shuffle(lists[3].begin(), lists[3].end(), rng);
  for (int i = 0; i < 1000; ++i)  // two ascending runs interleaved at random
    lists[4].push_back(rng() % 2 ? i : 5000 + i);
  for (int i = 0; i < 300; ++i) lists[5].push_back(i % 3 * 1000 + i);  // three, in turn
  lists[6].resize(5000);  // past SORT_LOCAL (4096): merged by one work-item
  std::iota(lists[6].begin(), lists[6].end(), 0);
  std::shuffle(lists[6].begin(), lists[6].end(), rng);
  std::vector<int> offsets, counts, items;
  for (const auto& l : lists) {
    offsets.push_back(int(items.size()));
    counts.push_back(int(l.size()));
    items.insert(items.end(), l.begin(), l.end());
  }
  namespace d = penumbra::detail;
  d::Bins bins;  // one row of tiles, one list each
  bins.tiles_x = int(lists.size());
  bins.tiles_y = 1;
  bins.total = items.size();
  bins.offsets = d::upload_ints(*ctx, offsets);
  bins.counts = d::upload_ints(*ctx, counts);
  auto expect_sorted = [&](const std::string& how) {
    const std::vector<int> sorted = d::download_ints(*ctx, bins.items, items.size());
    for (size_t t = 0; t < lists.size(); ++t) {
      std::vector<int> want = lists[t];
      std::sort(want.begin(), want.end());
      const std::vector<int> got(sorted.begin() + offsets[t],
                                 sorted.begin() + offsets[t] + counts[t]);
      EXPECT_EQ(got, want) << how << ", list " << t;
    }
  };
  d::Kernels kernels(*ctx, Precision::Float, {});
  bins.items = d::upload_ints(*ctx, items);
  d::sort_lists(kernels, bins);
  expect_sorted("sort_lists");
  for (int group : {64, 256}) {
    cl::Program program(ctx->cl_context(), penumbra::Context::kernel_source("bin.cl"));
    program.build(
        penumbra::Context::build_options("-DSORT_GROUP=" + std::to_string(group)).c_str());
    cl::Kernel sort(program, "bin_sort");
    bins.items = d::upload_ints(*ctx, items);
    const cl::Buffer scratch = d::alloc_ints(*ctx, items.size());
    sort.setArg(0, bins.offsets);
    sort.setArg(1, bins.counts);
    sort.setArg(2, int(lists.size()));
    sort.setArg(3, bins.items);
    sort.setArg(4, scratch);
    ctx->queue().enqueueNDRangeKernel(sort, cl::NullRange, cl::NDRange(lists.size() * group),
                                      cl::NDRange(group));
    expect_sorted("work-groups of " + std::to_string(group));
  }
}

}  // namespace
