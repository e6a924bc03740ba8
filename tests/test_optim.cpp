// The optimisation library (penumbra/optim.hpp): losses, regularisers, Adam, mesh refinement,
// targets, visual hull and the wall scenes of the applications.
//
//   OptimLoss.*           soft IoU and MSE gradients against central differences (double)
//   OptimRegulariser.*    Laplacian, edge length (both kinds), normal consistency: gradients
//                         against central differences on a jittered mesh (double)
//   OptimAdam.*           Adam on a quadratic; the first step's size
//   OptimMesh.*           topology, midpoint subdivision, visual hull, surface nets
//   OptimTargets.*        reading targets (dark = shape) and their errors; helpers
//   OptimScenes.*         the bundled targets are the silhouettes / shadows of their meshes;
//                         the wall cameras never see the shape, so gradients come only through
//                         shadows; a short silhouette fit improves the IoU
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "penumbra/context.hpp"
#include "penumbra/error.hpp"
#include "penumbra/image_io.hpp"
#include "penumbra/io.hpp"
#include "penumbra/optim.hpp"
#include "penumbra/renderer.hpp"
#include "scenes.hpp"

using namespace penumbra;
using namespace penumbra::optim;
using penumbra_tests::error_of;

namespace {

const std::string kData = PENUMBRA_DATA_DIR;

Image random_image(int w, int h, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0.02, 0.98);
  Image im(w, h, 1);
  for (double& v : im.data) v = u(rng);
  return im;
}

// Central difference of f at x[i] with step h.
double central(const std::function<double()>& f, double& x, double h) {
  const double x0 = x;
  x = x0 + h;
  const double fp = f();
  x = x0 - h;
  const double fm = f();
  x = x0;
  return (fp - fm) / (2 * h);
}

void expect_close(double analytic, double numeric, double rtol, double atol,
                  const std::string& what) {
  EXPECT_NEAR(analytic, numeric, atol + rtol * std::max(std::abs(analytic), std::abs(numeric)))
      << what;
}

// The icosahedron, jittered so that no two edges have the same length.
Mesh jittered_icosahedron(unsigned seed) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  Mesh m;
  m.vertices = {{-1, t, 0},  {1, t, 0},  {-1, -t, 0}, {1, -t, 0}, {0, -1, t},  {0, 1, t},
                {0, -1, -t}, {0, 1, -t}, {t, 0, -1},  {t, 0, 1},  {-t, 0, -1}, {-t, 0, 1}};
  m.faces = {{0, 11, 5},  {0, 5, 1},  {0, 1, 7},  {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
             {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
             {3, 8, 9},   {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-0.15, 0.15);
  for (glm::dvec3& v : m.vertices) v = glm::normalize(v) + glm::dvec3(u(rng), u(rng), u(rng));
  m.albedo.assign(m.vertices.size(), glm::dvec3(0.8));
  return m;
}

// Checks the gradient of a vertex function against central differences at every coordinate.
void check_vertex_gradient(Mesh mesh,
                           const std::function<double(const Mesh&, std::vector<glm::dvec3>*)>& term,
                           const std::string& name) {
  std::vector<glm::dvec3> grad;
  term(mesh, &grad);
  ASSERT_EQ(grad.size(), mesh.vertices.size()) << name;
  double largest = 0;
  for (const glm::dvec3& g : grad)
    largest = std::max({largest, std::abs(g.x), std::abs(g.y), std::abs(g.z)});
  ASSERT_GT(largest, 0) << name << ": zero gradient";
  for (size_t v = 0; v < mesh.vertices.size(); ++v)
    for (int k = 0; k < 3; ++k) {
      const double numeric =
          central([&] { return term(mesh, nullptr); }, mesh.vertices[v][k], 1e-6);
      expect_close(grad[v][k], numeric, 1e-6, 1e-8 * largest,
                   name + " vertex " + std::to_string(v) + " axis " + std::to_string(k));
    }
}

std::string temp(const std::string& name) {
  return ::testing::TempDir() + "penumbra_optim_" + name;
}

Context& context() {
  static Context ctx;
  return ctx;
}

Renderer& renderer() {
  static Renderer r(context(), Precision::Float);
  return r;
}

Mesh sphere(double radius) {
  Mesh m = load_obj(kData + "/meshes/icosphere.obj");
  for (glm::dvec3& v : m.vertices) v *= radius;
  return m;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Losses.

TEST(OptimLoss, SoftIouGradient) {
  std::mt19937 rng(1);
  Image a = random_image(7, 5, rng);
  const Image t = random_image(7, 5, rng);
  Image grad;
  const double value = soft_iou_loss(a, t, &grad, 1.7);
  ASSERT_EQ(grad.data.size(), a.data.size());
  double inter = 0, uni = 0;
  for (size_t i = 0; i < a.data.size(); ++i) {
    inter += a.data[i] * t.data[i];
    uni += a.data[i] + t.data[i] - a.data[i] * t.data[i];
  }
  EXPECT_NEAR(value, 1.7 * (1 - inter / uni), 1e-14);
  for (size_t i = 0; i < a.data.size(); ++i) {
    const double numeric =
        central([&] { return soft_iou_loss(a, t, nullptr, 1.7); }, a.data[i], 1e-6);
    expect_close(grad.data[i], numeric, 1e-6, 1e-12, "pixel " + std::to_string(i));
  }
}

TEST(OptimLoss, SoftIouEdgeCases) {
  Image zero(4, 4, 1, 0.0), one(4, 4, 1, 1.0);
  EXPECT_EQ(soft_iou_loss(zero, zero), 0.0);
  EXPECT_NEAR(soft_iou_loss(one, one), 0.0, 1e-15);
  EXPECT_NEAR(soft_iou_loss(zero, one), 1.0, 1e-15);
  // Gradients accumulate into a given image.
  Image grad(4, 4, 1, 0.25);
  soft_iou_loss(zero, one, &grad);
  for (double g : grad.data) EXPECT_LT(g, 0.25);  // more coverage would lower the loss
  Image wrong(3, 4, 1);
  EXPECT_NE(error_of([&] { soft_iou_loss(zero, wrong); }).find("same size"), std::string::npos);
}

TEST(OptimLoss, MseGradient) {
  std::mt19937 rng(2);
  Image a = random_image(6, 6, rng);
  const Image t = random_image(6, 6, rng);
  Image grad;
  const double value = mse_loss(a, t, &grad, 0.5);
  double sum = 0;
  for (size_t i = 0; i < a.data.size(); ++i)
    sum += (a.data[i] - t.data[i]) * (a.data[i] - t.data[i]);
  EXPECT_NEAR(value, 0.5 * sum / 36, 1e-15);
  for (size_t i = 0; i < a.data.size(); ++i) {
    const double numeric = central([&] { return mse_loss(a, t, nullptr, 0.5); }, a.data[i], 1e-6);
    expect_close(grad.data[i], numeric, 1e-6, 1e-12, "pixel " + std::to_string(i));
  }
}

TEST(OptimLoss, BinaryIou) {
  Image a(4, 1, 1), b(4, 1, 1);
  a.data = {1, 1, 0, 0};
  b.data = {0.9, 0.2, 0.7, 0};
  EXPECT_DOUBLE_EQ(binary_iou(a, b), 1.0 / 3.0);  // ∩ = {0}, ∪ = {0, 1, 2}
  Image zero(4, 1, 1, 0.0);
  EXPECT_DOUBLE_EQ(binary_iou(zero, zero), 1.0);
}

// ---------------------------------------------------------------------------------------------
// Regularisers.

TEST(OptimRegulariser, LaplacianGradient) {
  const Mesh m = jittered_icosahedron(3);
  const Topology topo = topology(m.faces, m.vertices.size());
  check_vertex_gradient(
      m,
      [&](const Mesh& x, std::vector<glm::dvec3>* g) {
        return laplacian_loss(x.vertices, topo, g, 1.3);
      },
      "laplacian");
  // Its value by definition, at one vertex of a flat fan: a vertex at the mean of its
  // neighbours costs nothing.
  Mesh fan;
  fan.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {-1, 0, 0}, {0, -1, 0}};
  fan.faces = {{0, 1, 2}, {0, 2, 3}, {0, 3, 4}, {0, 4, 1}};
  const Topology ft = topology(fan.faces, fan.vertices.size());
  // Vertex 1's neighbours are 0, 2, 4 (mean (0, 0, 0)): ‖(1, 0, 0)‖² = 1; likewise 2, 3, 4.
  EXPECT_NEAR(laplacian_loss(fan.vertices, ft), 4.0, 1e-15);
}

TEST(OptimRegulariser, EdgeLengthGradients) {
  const Mesh m = jittered_icosahedron(4);
  const Topology topo = topology(m.faces, m.vertices.size());
  for (EdgeLoss kind : {EdgeLoss::Variance, EdgeLoss::SquaredLength})
    check_vertex_gradient(
        m,
        [&](const Mesh& x, std::vector<glm::dvec3>* g) {
          return edge_loss(x.vertices, topo, kind, g, 0.7);
        },
        kind == EdgeLoss::Variance ? "edge variance" : "edge squared length");
  // A regular tetrahedron's edges all have the same length: no variance.
  const std::vector<glm::dvec3> tet = {{1, 1, 1}, {1, -1, -1}, {-1, 1, -1}, {-1, -1, 1}};
  const Topology tt = topology({{0, 1, 2}, {0, 3, 1}, {0, 2, 3}, {1, 3, 2}}, 4);
  EXPECT_NEAR(edge_loss(tet, tt, EdgeLoss::Variance), 0.0, 1e-15);
  EXPECT_NEAR(edge_loss(tet, tt, EdgeLoss::SquaredLength), 8.0, 1e-13);
}

TEST(OptimRegulariser, NormalConsistencyGradient) {
  const Mesh m = jittered_icosahedron(5);
  const Topology topo = topology(m.faces, m.vertices.size());
  check_vertex_gradient(
      m,
      [&](const Mesh& x, std::vector<glm::dvec3>* g) {
        return normal_consistency_loss(x.vertices, x.faces, topo, g, 2.0);
      },
      "normal consistency");
  // A flat square of two triangles costs nothing; folded by 90° it costs 1 − cos 90° = 1.
  const std::vector<glm::ivec3> faces = {{0, 1, 2}, {0, 2, 3}};
  const Topology st = topology(faces, 4);
  ASSERT_EQ(st.hinges.size(), 1u);
  EXPECT_NEAR(normal_consistency_loss({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}}, faces, st), 0.0,
              1e-15);
  EXPECT_NEAR(normal_consistency_loss({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 0, 1}}, faces, st), 1.0,
              1e-12);
}

TEST(OptimRegulariser, CombinedAddsTheTerms) {
  const Mesh m = jittered_icosahedron(6);
  const Topology topo = topology(m.faces, m.vertices.size());
  const RegulariserWeights w{0.3, 0.2, 0.1, EdgeLoss::SquaredLength};
  std::vector<glm::dvec3> g_all, g_sep;
  const double all = regularise(m, topo, w, &g_all);
  double sep = laplacian_loss(m.vertices, topo, &g_sep, 0.3);
  sep += edge_loss(m.vertices, topo, EdgeLoss::SquaredLength, &g_sep, 0.2);
  sep += normal_consistency_loss(m.vertices, m.faces, topo, &g_sep, 0.1);
  EXPECT_NEAR(all, sep, 1e-14);
  for (size_t i = 0; i < g_all.size(); ++i)
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(g_all[i][k], g_sep[i][k], 1e-14);
}

// ---------------------------------------------------------------------------------------------
// Adam.

TEST(OptimAdam, ConvergesOnAQuadratic) {
  // f(x) = Σ a_i (x_i − c_i)², badly scaled (a from 0.01 to 100): Adam's per-coordinate steps
  // do not care.
  const std::vector<double> a = {0.01, 1.0, 100.0, 3.0}, c = {1.5, -2.0, 0.25, 4.0};
  std::vector<double> x(4, 0.0), g(4);
  Adam adam(4, AdamOptions{0.05});
  for (int it = 0; it < 3000; ++it) {
    for (size_t i = 0; i < 4; ++i) g[i] = 2 * a[i] * (x[i] - c[i]);
    adam.step(x, g);
  }
  EXPECT_EQ(adam.steps(), 3000);
  for (size_t i = 0; i < 4; ++i) EXPECT_NEAR(x[i], c[i], 1e-3) << "coordinate " << i;
}

TEST(OptimAdam, FirstStepIsTheLearningRate) {
  // With bias correction the first step is lr · g/|g| (up to eps), whatever |g|.
  std::vector<glm::dvec3> x = {{0, 0, 0}, {1, 1, 1}};
  const std::vector<glm::dvec3> g = {{1e-3, -5.0, 0.0}, {2.0, 1e4, -1e-6}};
  Adam adam(6, AdamOptions{0.1});
  adam.step(x, g);
  EXPECT_NEAR(x[0].x, -0.1, 1e-6);
  EXPECT_NEAR(x[0].y, 0.1, 1e-9);
  EXPECT_EQ(x[0].z, 0.0);
  EXPECT_NEAR(x[1].x, 0.9, 1e-9);
  EXPECT_NEAR(x[1].y, 0.9, 1e-9);
  EXPECT_NEAR(x[1].z, 1.0 + 0.1 * 1e-6 / (1e-6 + 1e-8), 1e-9);
  std::vector<glm::dvec3> wrong(3);
  EXPECT_NE(error_of([&] { adam.step(wrong, wrong); }).find("size"), std::string::npos);
}

// ---------------------------------------------------------------------------------------------
// Mesh refinement, visual hull, surface nets.

namespace {

// Σ over faces of the signed volume of the tetrahedron (origin, face): the enclosed volume of
// a closed mesh, positive when its faces wind outwards.
double signed_volume(const Mesh& m) {
  double v = 0;
  for (const glm::ivec3& f : m.faces)
    v += glm::dot(m.vertices[size_t(f.x)],
                  glm::cross(m.vertices[size_t(f.y)], m.vertices[size_t(f.z)])) /
         6.0;
  return v;
}

bool closed(const Mesh& m) {
  const Topology t = topology(m.faces, m.vertices.size());
  return t.hinges.size() == t.edges.size();
}

}  // namespace

TEST(OptimMesh, TopologyOfTheIcosahedron) {
  const Mesh m = jittered_icosahedron(7);
  const Topology t = topology(m.faces, m.vertices.size());
  EXPECT_EQ(t.edges.size(), 30u);
  EXPECT_EQ(t.hinges.size(), 30u);
  for (const auto& n : t.neighbours) EXPECT_EQ(n.size(), 5u);
  for (const glm::ivec2& e : t.edges) EXPECT_LT(e.x, e.y);
}

TEST(OptimMesh, SubdivideKeepsTheShape) {
  const Mesh m = sphere(1.0);
  const Mesh s = subdivide(m);
  const Topology t = topology(m.faces, m.vertices.size());
  EXPECT_EQ(s.faces.size(), 4 * m.faces.size());
  EXPECT_EQ(s.vertices.size(), m.vertices.size() + t.edges.size());
  EXPECT_EQ(s.albedo.size(), s.vertices.size());
  EXPECT_TRUE(closed(s));
  EXPECT_NEAR(signed_volume(s), signed_volume(m), 1e-9);  // midpoints lie on the old faces
  EXPECT_NEAR(mean_edge_length(s), 0.5 * mean_edge_length(m), 1e-12);
  EXPECT_NO_THROW(validate(s));
}

TEST(OptimMesh, SurfaceNetsOfABox) {
  // A 3 × 2 × 2 block of voxels inside an 8³ grid over [−1, 1]³.
  const int n = 8;
  std::vector<unsigned char> occ(size_t(n) * n * n, 0);
  for (int z = 3; z < 5; ++z)
    for (int y = 3; y < 5; ++y)
      for (int x = 2; x < 5; ++x) occ[(size_t(z) * n + y) * n + x] = 1;
  const Mesh m = surface_nets(occ, n, 1.0, 0);
  EXPECT_TRUE(closed(m));
  EXPECT_GT(signed_volume(m), 0.0);  // outward winding
  EXPECT_NO_THROW(validate(m));
  // Vertices sit between the voxel centres inside and outside: within the block's box.
  for (const glm::dvec3& v : m.vertices) {
    EXPECT_GE(v.x, -1 + 2 * 0.25 - 1e-12);
    EXPECT_LE(v.x, -1 + 5 * 0.25 + 1e-12);
  }
  std::vector<unsigned char> empty(size_t(n) * n * n, 0);
  EXPECT_NE(error_of([&] { surface_nets(empty, n, 1.0); }).find("empty"), std::string::npos);
}

TEST(OptimMesh, VisualHullOfADiscAndASquare) {
  // Front: a disc of radius 0.5; side: a square of half-size 0.5. The hull is a cylinder
  // along z clipped to |z| ≤ 0.5: its front view is the disc, its side view the square, and
  // its top view (not constrained) a square too.
  const int size = 32;
  Image disc(size, size, 1, 0.0), square(size, size, 1, 0.0);
  for (int y = 0; y < size; ++y)
    for (int x = 0; x < size; ++x) {
      const double u = (2 * x + 1 - size) / double(size), v = (size - 2 * y - 1) / double(size);
      disc.at(x, y) = u * u + v * v <= 0.25 ? 1 : 0;
      square.at(x, y) = std::abs(u) <= 0.5 && std::abs(v) <= 0.5 ? 1 : 0;
    }
  const int n = 32;
  const auto occ =
      visual_hull({disc, square}, {named_view("front"), named_view("side")}, 1.0, n, 1.0);
  auto voxel = [&](double x, double y, double z) {
    auto idx = [&](double c) { return std::clamp(int(std::floor((c + 1) / 2 * n)), 0, n - 1); };
    return occ[(size_t(idx(z)) * n + idx(y)) * n + idx(x)] != 0;
  };
  EXPECT_TRUE(voxel(0, 0, 0));
  EXPECT_TRUE(voxel(0.3, 0.3, 0.45));
  EXPECT_FALSE(voxel(0.4, 0.4, 0));  // outside the disc
  EXPECT_FALSE(voxel(0, 0, 0.6));    // outside the square (|z| > 0.5)
  const Mesh m = surface_nets(occ, n, 1.0, 2);
  const auto hs =
      hard_silhouettes(renderer(), m, {named_view("front"), named_view("side")}, 1.0, size);
  EXPECT_GT(binary_iou(hs[0], disc), 0.8);
  EXPECT_GT(binary_iou(hs[1], square), 0.8);
}

// ---------------------------------------------------------------------------------------------
// Targets and helpers.

TEST(OptimTargets, DarkIsTheShape) {
  Image im(8, 8, 3, 1.0);
  for (int y = 2; y < 5; ++y)
    for (int x = 1; x < 4; ++x)
      for (int c = 0; c < 3; ++c) im.at(x, y, c) = 0.1;
  const std::string path = temp("dark.png");
  save_png(im, path);
  const Image t = load_target(path);
  EXPECT_EQ(t.channels, 1);
  double sum = 0;
  for (double v : t.data) sum += v;
  EXPECT_EQ(sum, 9.0);
  EXPECT_EQ(t.at(1, 2), 1.0);
  EXPECT_EQ(t.at(0, 0), 0.0);
}

TEST(OptimTargets, Errors) {
  EXPECT_NE(error_of([] { load_target(temp("no_such_file.png")); }).find("no_such_file.png"),
            std::string::npos);
  save_png(Image(8, 6, 1, 1.0), temp("wide.png"));
  EXPECT_NE(error_of([] { load_target(temp("wide.png")); }).find("square"), std::string::npos);
  save_png(Image(8, 8, 1, 1.0), temp("white.png"));
  EXPECT_NE(error_of([] { load_target(temp("white.png")); }).find("no shape"), std::string::npos);
  save_png(Image(8, 8, 1, 0.0), temp("black.png"));
  EXPECT_NE(error_of([] { load_target(temp("black.png")); }).find("no background"),
            std::string::npos);
  const std::string msg = error_of([] {
    check_targets({Image(8, 8, 1), Image(16, 16, 1)}, {"a.png", "b.png"});
  });
  EXPECT_NE(msg.find("a.png is 8x8"), std::string::npos) << msg;
  EXPECT_NE(msg.find("b.png is 16x16"), std::string::npos) << msg;
  EXPECT_NE(error_of([] { parse_direction("1,2"); }).find("three numbers"), std::string::npos);
  EXPECT_NE(error_of([] { parse_direction("0,0,0"); }).find("zero"), std::string::npos);
  EXPECT_NE(error_of([] { named_view("back"); }).find("front, side or top"), std::string::npos);
}

TEST(OptimTargets, Helpers) {
  EXPECT_EQ(stage_resolution(128, 32), 32);
  EXPECT_EQ(stage_resolution(96, 64), 48);
  EXPECT_EQ(stage_resolution(30, 32), 30);
  EXPECT_EQ(stage_resolution(97, 32), 97);  // a prime: no coarser size divides it
  const glm::dvec3 d = parse_direction("0, 0,-2");
  EXPECT_NEAR(glm::length(d - glm::dvec3(0, 0, -1)), 0.0, 1e-15);
  Image m(4, 4, 1, 0.0);
  m.at(0, 0) = m.at(1, 0) = m.at(0, 1) = 1;
  const Image d2 = downsample(m, 2);
  EXPECT_DOUBLE_EQ(d2.at(0, 0), 0.75);
  EXPECT_DOUBLE_EQ(d2.at(1, 1), 0.0);
  const Image row = side_by_side({Image(3, 2, 1, 0.0), Image(2, 4, 3, 1.0)}, 1, 0.5);
  EXPECT_EQ(row.width, 6);
  EXPECT_EQ(row.height, 4);
  EXPECT_EQ(row.channels, 3);
  EXPECT_EQ(upscale(m, 3).width, 12);
  // The named views' orientation (the convention the bundled targets are drawn in).
  EXPECT_EQ(view_up(named_view("front")), glm::dvec3(0, 1, 0));
  EXPECT_EQ(view_up(named_view("top")), glm::dvec3(0, 0, -1));
}

// ---------------------------------------------------------------------------------------------
// Scenes: the bundled targets, the walls.

TEST(OptimScenes, BundledSilhouettesAreThoseOfTheirMesh) {
  const Mesh shape = load_obj(kData + "/targets/silhouette_shape.obj");
  const std::vector<std::string> views = {"front", "side", "top"};
  std::vector<glm::dvec3> dirs;
  dirs.reserve(views.size());
  for (const std::string& v : views) dirs.push_back(named_view(v));
  const auto sil = hard_silhouettes(renderer(), shape, dirs, 1.0, 128);
  for (size_t v = 0; v < views.size(); ++v) {
    const Image t = load_target(kData + "/targets/silhouette_" + views[v] + ".png");
    EXPECT_GT(binary_iou(sil[v], t), 0.99) << views[v];
  }
}

TEST(OptimScenes, BundledShadowsAreThoseOfTheirMesh) {
  const Mesh shape = load_obj(kData + "/targets/shadow_shape.obj");
  const auto shadows = hard_shadows(renderer(), shape, {{0, 0, -1}, {-1, 0, 0}}, 96);
  EXPECT_GT(binary_iou(shadows[0], load_target(kData + "/targets/shadow_back.png")), 0.98);
  EXPECT_GT(binary_iou(shadows[1], load_target(kData + "/targets/shadow_side.png")), 0.98);
}

TEST(OptimScenes, BundledLettersAreNearlyConsistent) {
  // The visual hull of G, E, B (front, side, top) at the targets' resolution reproduces each
  // letter almost entirely: one object can cast all three.
  std::vector<Image> letters;
  for (const char* l : {"g", "e", "b"})
    letters.push_back(load_target(kData + "/targets/letter_" + l + ".png"));
  const std::vector<glm::dvec3> dirs = {named_view("front"), named_view("side"), named_view("top")};
  const int n = 64;
  std::vector<Image> coarse;
  coarse.reserve(letters.size());
  for (const Image& t : letters) coarse.push_back(binarize(downsample(t, 128 / n)));
  const Mesh hull = surface_nets(visual_hull(coarse, dirs, 1.0, n, 1.0), n, 1.0, 0);
  const auto sil = hard_silhouettes(renderer(), hull, dirs, 1.0, 128);
  for (size_t k = 0; k < 3; ++k) EXPECT_GT(binary_iou(sil[k], letters[k]), 0.9) << "letter " << k;
}

TEST(OptimScenes, WallCamerasNeverSeeTheShape) {
  // The fit-shadows scene: remove the wall, and the camera's silhouette is empty (the shape is
  // behind it); without shadows the loss has no gradient with respect to the shape at all,
  // with shadows it has one — every gradient reaches the shape through its shadow.
  const Mesh shape = sphere(0.75);
  for (const glm::dvec3 d : {glm::dvec3(0, 0, -1), glm::dvec3(-1, 0, 0), glm::dvec3(0, -1, 0)}) {
    RenderParams p = ShadowProblem::default_shadow_fit_params();
    p.shadow_map_size = 64;
    p.light_sigma = 3e-4;
    Scene alone = wall_scene(shape, d, 32, p);
    alone.meshes.pop_back();  // the wall
    const Image sil = renderer().render(alone).front().silhouette;
    for (double v : sil.data) ASSERT_EQ(v, 0.0);

    for (Shadows mode : {Shadows::None, Shadows::Hard, Shadows::Soft}) {
      p.shadows = mode;
      Scene scene = wall_scene(shape, d, 32, p);
      scene.lights.front().size = 0.05;
      const RenderOutput out = renderer().render(scene).front();
      OutputGrads g;
      g.color = Image(32, 32, 3, 1.0);  // L = Σ colour
      const SceneGrads sg = renderer().backward(scene, {g});
      double largest = 0;
      for (const glm::dvec3& v : sg.vertices.front()) largest = std::max(largest, glm::length(v));
      if (mode == Shadows::None)
        EXPECT_EQ(largest, 0.0);
      else
        EXPECT_GT(largest, 1e-3) << "shadows " << int(mode);
      // The wall is white and lit head-on, with no ambient light: where lit its colour is the
      // shadow term (near 1), in the shadow near 0.
      if (mode == Shadows::None) {
        for (double v : out.color.data) EXPECT_NEAR(v, 1.0, 1e-5);
      }
    }
  }
}

TEST(OptimScenes, ShadowIsTheSilhouetteFromTheLight) {
  const Mesh shape = load_obj(kData + "/targets/silhouette_shape.obj");
  const std::vector<glm::dvec3> dirs = {named_view("front"), named_view("side"), named_view("top"),
                                        parse_direction("-1,-1,-1")};
  const auto shadows = hard_shadows(renderer(), shape, dirs, 64);
  const auto sil = hard_silhouettes(renderer(), shape, dirs, 1.0, 64);
  for (size_t k = 0; k < dirs.size(); ++k) EXPECT_GT(binary_iou(shadows[k], sil[k]), 0.97) << k;
}

TEST(OptimScenes, ShortSilhouetteFitImproves) {
  // 80 iterations at 32 pixels: a sphere moves towards the rounded square and the triangle.
  SilhouetteProblem problem;
  problem.half_height = 1.0;
  for (const char* v : {"front", "side"}) {
    problem.targets.push_back(
        downsample(load_target(kData + "/targets/silhouette_" + std::string(v) + ".png"), 4));
    problem.targets.back() = binarize(problem.targets.back());
    problem.directions.push_back(named_view(v));
  }
  SilhouetteStage stage;
  stage.resolution = 32;
  stage.iterations = 80;
  stage.sigma = 1e-3;
  stage.lr = 0.01;
  stage.weights = {1.0, 0.0, 0.01, EdgeLoss::Variance};
  std::vector<double> first, last;
  int calls = 0;
  const Mesh out =
      fit_silhouettes(renderer(), sphere(0.75), problem, {stage}, [&](const FitProgress& p) {
        ++calls;
        EXPECT_EQ(p.total, 80);
        EXPECT_EQ(p.images->size(), 2u);
        if (p.iteration == 1) first = p.ious;
        last = p.ious;
      });
  EXPECT_EQ(calls, 80);
  EXPECT_EQ(out.vertices.size(), 642u);
  for (size_t v = 0; v < 2; ++v) {
    EXPECT_GT(last[v], first[v] + 0.05) << "view " << v;
    EXPECT_GT(last[v], 0.7) << "view " << v << " first " << first[v];
  }
}

TEST(OptimScenes, FitResumedFromAnyCheckpointEndsBitIdentical) {
  // Two stages (the second subdivides): a checkpoint after every iteration, then a fit resumed
  // from each of them (through the checkpoint's text, as a file would hold it) must end with
  // the very mesh of the fit that was never stopped, stage boundaries included.
  SilhouetteProblem problem;
  problem.half_height = 1.0;
  for (const char* v : {"front", "side"}) {
    problem.targets.push_back(binarize(
        downsample(load_target(kData + "/targets/silhouette_" + std::string(v) + ".png"), 8)));
    problem.directions.push_back(named_view(v));
  }
  std::vector<SilhouetteStage> stages(2);
  stages[0] = {8, 3, 2e-2, 0.01, 0, {1.0, 0.0, 0.01, EdgeLoss::Variance}};
  stages[1] = {16, 3, 1e-2, 0.005, 1, {0.2, 0.0, 5e-4, EdgeLoss::Variance}};
  std::vector<std::string> saved;
  FitCheckpoints every;
  every.every = 1;
  every.save = [&](const FitState& s) { saved.push_back(checkpoint_text(s, "test run")); };
  const Mesh whole = fit_silhouettes(renderer(), sphere(0.75), problem, stages, nullptr, every);
  ASSERT_EQ(saved.size(), 6u);
  for (size_t k = 0; k < saved.size(); ++k) {
    const FitState state =
        parse_checkpoint(saved[k], "checkpoint " + std::to_string(k), "test run");
    EXPECT_EQ(state.iteration, int(k) + 1);
    FitCheckpoints resume;
    resume.resume = &state;
    int observed = 0;
    const Mesh out = fit_silhouettes(
        renderer(), sphere(0.75), problem, stages,
        [&](const FitProgress& p) { observed = p.iteration; }, resume);
    EXPECT_EQ(out.vertices, whole.vertices) << "resumed after iteration " << k + 1;
    EXPECT_EQ(out.faces, whole.faces);
    EXPECT_EQ(observed, k + 1 < saved.size() ? 6 : 0) << k;
  }
  EXPECT_NE(error_of([&] {
              parse_checkpoint(saved[0], "c.json", "another run");
            }).find("checkpoint c.json was written by another run (test run)"),
            std::string::npos);
}
