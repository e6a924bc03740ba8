// Gradients (math.md §8): Renderer::backward against central finite differences of
// Renderer::render, in double precision (penumbra/gradcheck.hpp).
//
//   GradCheckCompare.*   the comparison itself flags a 10% error, honours the absolute floor
//   GradCheckScene.*     random_scene() is valid, reproducible and in view
//   GradCheck.Turnaround        the bundled scene at 64×64
//   GradCheck.RandomScenes      six random scenes (prints the failure fraction of each)
//   GradCheck.Float             float gradients against double differences
//   GradCheck.ColoursAtZero     colours at 0 (which may not go negative) are still checked
//   GradCheck.Deterministic     two backward calls give bit-identical gradients
//   GradCheck.WrongGradientIsCaught  a gradient off by 10% (or zero) fails the check
//   GradCheck.HardShadows*      hard shadows (truncated, exact, gemm sampling): the sampled
//                               entries cover a vertex of every mesh and every light's position
//                               or direction, on scenes whose frusta are fitted by the check
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <glm/gtc/matrix_transform.hpp>
#include <iostream>
#include <limits>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "penumbra/context.hpp"
#include "penumbra/gradcheck.hpp"
#include "penumbra/io.hpp"
#include "penumbra/renderer.hpp"
#include "penumbra/scene.hpp"
#include "scenes.hpp"

namespace {

using namespace penumbra;

// Shared device and gradient-check helpers (scenes.hpp). A missing OpenCL device is a
// failure, not a skip.
using namespace penumbra_tests;

Scene small_turnaround(int size = 64) {
  Scene scene = penumbra::load_scene(std::string(PENUMBRA_DATA_DIR) + "/scenes/turnaround.json");
  for (auto& cam : scene.cameras) cam.width = cam.height = size;
  scene.params.shadow_map_size = 64;  // the bundled scene has hard shadows; a small map is quick
  return scene;
}

void report(const std::string& what, const GradCheckResult& r) {
  std::cout << "[gradcheck] " << what << ": checked=" << r.checked << " failed=" << r.failed
            << " failure_fraction=" << r.failure_fraction() << " max_rel_err=" << r.max_rel_err
            << std::endl;
}

bool bit_identical(const glm::dvec3& a, const glm::dvec3& b) {
  return std::memcmp(&a[0], &b[0], 3 * sizeof(double)) == 0;
}

// Counts entries of `a` and `b` that differ in any bit; -1 if the layouts differ.
long differing_entries(const SceneGrads& a, const SceneGrads& b) {
  auto list = [](const std::vector<glm::dvec3>& x, const std::vector<glm::dvec3>& y, long& n) {
    if (x.size() != y.size()) return false;
    for (size_t i = 0; i < x.size(); ++i) n += bit_identical(x[i], y[i]) ? 0 : 1;
    return true;
  };
  long n = 0;
  if (a.vertices.size() != b.vertices.size() || a.albedo.size() != b.albedo.size()) return -1;
  for (size_t m = 0; m < a.vertices.size(); ++m)
    if (!list(a.vertices[m], b.vertices[m], n)) return -1;
  for (size_t m = 0; m < a.albedo.size(); ++m)
    if (!list(a.albedo[m], b.albedo[m], n)) return -1;
  if (!list(a.light_position, b.light_position, n)) return -1;
  if (!list(a.light_color, b.light_color, n)) return -1;
  n += bit_identical(a.ambient, b.ambient) ? 0 : 1;
  return n;
}

SceneGrads scaled(SceneGrads g, double factor) {
  for (auto& mesh : g.vertices)
    for (auto& v : mesh) v *= factor;
  for (auto& mesh : g.albedo)
    for (auto& v : mesh) v *= factor;
  for (auto& v : g.light_position) v *= factor;
  for (auto& v : g.light_color) v *= factor;
  g.ambient *= factor;
  return g;
}

// ---------------------------------------------------------------------------------------------

TEST(GradCheckCompare, FlagsTenPercentError) {
  const double rtol = 1e-3;
  for (double a : {1.0, -3.5, 2e-3, 1e4}) {
    EXPECT_TRUE(penumbra::gradients_agree(a, a, 0.0, rtol)) << a;
    EXPECT_TRUE(penumbra::gradients_agree(a, a * (1 + 1e-5), 0.0, rtol)) << a;
    EXPECT_FALSE(penumbra::gradients_agree(1.1 * a, a, 0.0, rtol)) << a;
    EXPECT_FALSE(penumbra::gradients_agree(a, 1.1 * a, 0.0, rtol)) << a;
    EXPECT_FALSE(penumbra::gradients_agree(0.0, a, 0.0, rtol)) << a;
    EXPECT_FALSE(penumbra::gradients_agree(-a, a, 0.0, rtol)) << a;
    EXPECT_NEAR(penumbra::gradient_relative_error(1.1 * a, a, 0.0), 0.1 / 1.1, 1e-12);
  }
  // Float tolerance still flags 10%.
  EXPECT_FALSE(penumbra::gradients_agree(1.1, 1.0, 0.0, 5e-2));
}

TEST(GradCheckCompare, AbsoluteFloorAndNonFinite) {
  // Below the floor, tiny values agree whatever their ratio; above it they must not.
  EXPECT_TRUE(penumbra::gradients_agree(1e-9, -1e-9, 1e-6, 1e-3));
  EXPECT_FALSE(penumbra::gradients_agree(1e-3, -1e-3, 1e-6, 1e-3));
  EXPECT_LE(penumbra::gradient_relative_error(1e-9, -1e-9, 1e-6), 2e-3);
  EXPECT_EQ(penumbra::gradient_relative_error(0.0, 0.0, 0.0), 0.0);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(penumbra::gradients_agree(nan, 1.0, 1.0, 1.0));
  EXPECT_FALSE(penumbra::gradients_agree(1.0, inf, 1.0, 1.0));
}

TEST(GradCheckCompare, PassedHonoursFailureFraction) {
  GradCheckResult r;
  r.checked = 40;
  r.max_failure_fraction = 0.05;
  r.failed = 2;
  EXPECT_TRUE(r.passed());
  r.failed = 3;
  EXPECT_FALSE(r.passed());
}

TEST(GradCheckScene, RandomScenesAreValidReproducibleAndInView) {
  for (uint64_t seed = 1; seed <= 50; ++seed) {
    const Scene s = penumbra::random_scene(seed);
    ASSERT_NO_THROW(penumbra::validate(s)) << "seed " << seed;
    ASSERT_EQ(s.cameras.size(), 1u);
    ASSERT_GE(s.meshes.size(), 2u);
    ASSERT_GE(s.lights.size(), 1u);
    ASSERT_LE(s.lights.size(), 2u);
    const auto& cam = s.cameras[0];
    EXPECT_GE(cam.width, 32);
    EXPECT_LE(cam.width, 64);
    // The occluder's centre projects inside the image, in front of the camera.
    glm::dvec3 centre(0.0);
    for (const auto& v : s.meshes[0].vertices) centre += v;
    centre /= double(s.meshes[0].vertices.size());
    const glm::dvec4 q = glm::lookAt(cam.eye, cam.target, cam.up) * glm::dvec4(centre, 1.0);
    const double z = -q.z;
    ASSERT_GT(z, cam.near);
    const double scale = cam.projection == penumbra::Projection::Perspective
                             ? z * std::tan(glm::radians(cam.fov_deg) / 2)
                             : cam.half_height;
    EXPECT_LT(std::abs(q.y / scale), 1.0) << "seed " << seed;
    EXPECT_LT(std::abs(q.x / scale), double(cam.width) / cam.height) << "seed " << seed;

    const Scene again = penumbra::random_scene(seed);
    EXPECT_EQ(again.meshes[0].vertices, s.meshes[0].vertices);
    EXPECT_EQ(again.cameras[0].eye, s.cameras[0].eye);
  }
  EXPECT_NE(penumbra::random_scene(1).meshes[0].vertices,
            penumbra::random_scene(2).meshes[0].vertices);
}

TEST(GradCheckScene, LossIsLinearInTheOutputs) {
  const Scene s = penumbra::random_scene(7);
  const auto w = penumbra::random_loss_weights(s, 3);
  ASSERT_EQ(w.size(), 1u);
  EXPECT_EQ(w[0].color.size(), size_t(s.cameras[0].width) * s.cameras[0].height * 3);
  std::vector<penumbra::RenderOutput> out(1);
  out[0].color = penumbra::Image(s.cameras[0].width, s.cameras[0].height, 3, 0.0);
  out[0].silhouette = penumbra::Image(s.cameras[0].width, s.cameras[0].height, 1, 0.0);
  out[0].depth = penumbra::Image(s.cameras[0].width, s.cameras[0].height, 1, 0.0);
  out[0].color.data[5] = 2.0;
  out[0].depth.data[7] = 3.0;
  EXPECT_DOUBLE_EQ(penumbra::linear_loss(out, w),
                   2.0 * w[0].color.data[5] + 3.0 * w[0].depth.data[7]);
  // Depth weights are scaled by 1/far.
  double depth_sq = 0;
  for (double v : w[0].depth.data) depth_sq += v * v;
  const double rms = std::sqrt(depth_sq / w[0].depth.size());
  EXPECT_NEAR(rms * s.cameras[0].far, 1.0, 0.2);
}

// ---------------------------------------------------------------------------------------------

TEST(GradCheck, Turnaround) {
  REQUIRE_CONTEXT(ctx);
  const Scene scene = small_turnaround(64);
  GradCheckOptions options;
  options.samples = 40;
  options.seed = 1;
  const GradCheckResult r = penumbra::gradcheck(*ctx, scene, options);
  report("turnaround 64x64", r);
  EXPECT_EQ(r.checked, 40);
  EXPECT_GT(r.atol, 0.0) << "the analytic gradient is identically zero";
  EXPECT_TRUE(r.passed()) << describe(r);
}

TEST(GradCheck, RandomScenes) {
  REQUIRE_CONTEXT(ctx);
  int failed_scenes = 0;
  for (uint64_t seed = 1; seed <= 6; ++seed) {
    const Scene scene = penumbra::random_scene(seed);
    GradCheckOptions options;
    options.samples = 40;
    options.seed = seed;
    const GradCheckResult r = penumbra::gradcheck(*ctx, scene, options);
    report("random scene " + std::to_string(seed), r);
    EXPECT_EQ(r.checked, 40);
    EXPECT_GT(r.atol, 0.0) << "seed " << seed << ": the analytic gradient is identically zero";
    EXPECT_TRUE(r.passed()) << "seed " << seed << "\n" << describe(r);
    failed_scenes += r.passed() ? 0 : 1;
  }
  EXPECT_EQ(failed_scenes, 0);
}

TEST(GradCheck, Float) {
  REQUIRE_CONTEXT(ctx);
  std::vector<std::pair<std::string, Scene>> scenes = {{"turnaround 64x64", small_turnaround(64)}};
  for (uint64_t seed = 1; seed <= 3; ++seed)
    scenes.emplace_back("random scene " + std::to_string(seed), penumbra::random_scene(seed));
  for (const auto& [name, scene] : scenes) {
    GradCheckOptions options;
    options.precision = Precision::Float;
    options.samples = 40;
    const GradCheckResult r = penumbra::gradcheck(*ctx, scene, options);
    report(name + " (float)", r);
    EXPECT_DOUBLE_EQ(r.rtol, 5e-2);
    EXPECT_TRUE(r.passed()) << name << "\n" << describe(r);
  }
}

TEST(GradCheck, ColoursAtZero) {
  // Colours cannot go negative: entries at 0 are differenced one-sided, not rejected.
  REQUIRE_CONTEXT(ctx);
  Scene scene = penumbra::random_scene(4);
  scene.ambient = glm::dvec3(0.0);
  for (auto& light : scene.lights) light.color.g = 0.0;
  scene.meshes[0].albedo.edit([](std::vector<glm::dvec3>& all) {
    for (auto& a : all) a.b = 0.0;
  });
  GradCheckOptions options;
  options.samples = 40;
  GradCheckResult r;
  ASSERT_NO_THROW(r = penumbra::gradcheck(*ctx, scene, options));
  report("random scene 4, zero colours", r);
  int ambient_entries = 0;
  for (const auto& e : r.entries) ambient_entries += e.name.rfind("ambient.", 0) == 0 ? 1 : 0;
  EXPECT_GT(ambient_entries, 0);
  EXPECT_TRUE(r.passed()) << describe(r);
}

TEST(GradCheck, Deterministic) {
  REQUIRE_CONTEXT(ctx);
  for (const Scene& scene : {penumbra::random_scene(3), small_turnaround(48)}) {
    for (Precision precision : {Precision::Double, Precision::Float}) {
      Renderer renderer(*ctx, precision);
      const auto weights = penumbra::random_loss_weights(scene, 11);
      renderer.render(scene);
      const SceneGrads a = renderer.backward(scene, weights);
      const SceneGrads b = renderer.backward(scene, weights);
      renderer.render(scene);
      const SceneGrads c = renderer.backward(scene, weights);
      EXPECT_EQ(differing_entries(a, b), 0);
      EXPECT_EQ(differing_entries(a, c), 0);
      EXPECT_GT(penumbra::max_abs_gradient(a), 0.0);
    }
  }
}

TEST(GradCheck, WrongGradientIsCaught) {
  REQUIRE_CONTEXT(ctx);
  const Scene scene = penumbra::random_scene(2);
  Renderer renderer(*ctx, Precision::Double);
  const auto weights = penumbra::random_loss_weights(scene, 5);
  renderer.render(scene);
  const SceneGrads analytic = renderer.backward(scene, weights);
  GradCheckOptions options;
  options.samples = 20;
  options.seed = 5;

  const GradCheckResult right =
      penumbra::compare_with_finite_differences(renderer, scene, weights, analytic, options);
  EXPECT_TRUE(right.passed()) << describe(right);

  const GradCheckResult off = penumbra::compare_with_finite_differences(
      renderer, scene, weights, scaled(analytic, 1.1), options);
  EXPECT_FALSE(off.passed()) << describe(off);
  // Every entry clearly above the absolute floor must be flagged.
  for (const auto& e : off.entries) {
    if (std::abs(e.numeric) > 100 * off.atol) {
      EXPECT_FALSE(e.ok) << e.name << " analytic=" << e.analytic << " numeric=" << e.numeric;
    }
  }

  // A gradient with one whole kind missing (all zero) is caught too.
  SceneGrads no_vertices = analytic;
  for (auto& mesh : no_vertices.vertices)
    for (auto& v : mesh) v = glm::dvec3(0.0);
  const GradCheckResult missing =
      penumbra::compare_with_finite_differences(renderer, scene, weights, no_vertices, options);
  EXPECT_FALSE(missing.passed()) << describe(missing);
}

// --- hard shadows -----------------------------------------------------------------------

// Every mesh has a vertex entry and every light its position / direction entry.
void expect_shadow_coverage(const Scene& scene, const GradCheckResult& r, const std::string& what) {
  for (size_t m = 0; m < scene.meshes.size(); ++m) {
    bool vertex = false;
    for (const auto& e : r.entries)
      vertex = vertex || e.name.rfind("mesh" + std::to_string(m) + ".v", 0) == 0;
    EXPECT_TRUE(vertex) << what << ": no vertex of mesh " << m << "\n" << describe(r);
  }
  for (size_t l = 0; l < scene.lights.size(); ++l) {
    const bool point = scene.lights[l].type == penumbra::LightType::Point;
    const std::string prefix = "light" + std::to_string(l) + (point ? ".position." : ".direction.");
    EXPECT_TRUE(has_entry(r, prefix)) << what << ": no " << prefix << " entry\n" << describe(r);
  }
}

TEST(GradCheck, HardShadowsBundledScene) {
  REQUIRE_CONTEXT(ctx);
  Scene scene = small_turnaround(40);
  scene.params.shadows = penumbra::Shadows::Hard;
  scene.params.shadow_map_size = 32;
  for (auto model : {penumbra::ShadowModel::Accurate, penumbra::ShadowModel::Paper})
    for (auto sampling : {Method::Truncated, Method::Exact, Method::Gemm}) {
      if (model == penumbra::ShadowModel::Accurate && sampling == Method::Gemm) continue;
      set_method(scene.params, sampling);
      scene.params.shadow_model = model;
      penumbra::refit_light_frusta(scene);
      GradCheckOptions options;
      options.samples = 12;
      options.seed = 2;
      const GradCheckResult r = penumbra::gradcheck(*ctx, scene, options);
      const std::string what =
          "turnaround 40x40 hard, " + penumbra::word(model) + ", sampling " + name_of(sampling);
      report(what, r);
      EXPECT_EQ(r.checked, 12);
      EXPECT_TRUE(r.passed()) << what << "\n" << describe(r);
      expect_shadow_coverage(scene, r, what);
    }
}

// The paper model's exact sum on a 40² map: no multiple of paper_hard_exact.cl's column blocks, so
// the products' ragged edges (matmul_nn_rowdots, matmul_tn) are in the gradients checked. (Twelve
// sampled entries need not touch every texel column: ExactEqualsGemmGradients compares all of
// dL/dS's effect with CLBlast's on the same map.)
TEST(GradCheck, HardExactShadowsRaggedMap) {
  REQUIRE_CONTEXT(ctx);
  Scene scene = small_turnaround(40);
  scene.params.shadows = penumbra::Shadows::Hard;
  scene.params.shadow_model = penumbra::ShadowModel::Paper;
  scene.params.shadow_map_size = 40;
  set_method(scene.params, Method::Exact);
  penumbra::refit_light_frusta(scene);
  GradCheckOptions options;
  options.samples = 12;
  options.seed = 3;
  const GradCheckResult r = penumbra::gradcheck(*ctx, scene, options);
  const std::string what = "turnaround 40x40 hard, paper, exact, 40² map";
  report(what, r);
  EXPECT_EQ(r.checked, 12);
  EXPECT_TRUE(r.passed()) << what << "\n" << describe(r);
  expect_shadow_coverage(scene, r, what);
}

TEST(GradCheck, HardShadowsRandomScenesWithUnfittedFrusta) {
  // Random scenes with point and directional lights; the frusta are left unfitted, so the
  // check must fit them once itself (a frustum refitted to every perturbed copy would follow
  // the vertices and the differences would not match the gradient of the fixed-frustum render).
  REQUIRE_CONTEXT(ctx);
  int directional = 0;
  for (uint64_t seed : {2, 3, 6, 8}) {
    Scene scene = penumbra::random_scene(seed);
    for (auto& light : scene.lights) {
      light.frustum = penumbra::LightFrustum();
      directional += light.type == penumbra::LightType::Directional ? 1 : 0;
    }
    scene.params.shadows = penumbra::Shadows::Hard;
    scene.params.shadow_map_size = 48;
    GradCheckOptions options;
    options.samples = 20;
    options.seed = seed;
    const GradCheckResult r = penumbra::gradcheck(*ctx, scene, options);
    const std::string what = "random scene " + std::to_string(seed) + " hard";
    report(what, r);
    EXPECT_EQ(r.checked, 20);
    EXPECT_TRUE(r.passed()) << what << "\n" << describe(r);
    expect_shadow_coverage(scene, r, what);
  }
  EXPECT_GT(directional, 0) << "the scenes should include a directional light";
}

TEST(GradCheck, HardShadowsFewSamples) {
  // Fewer samples than meshes + lights: exactly `samples` entries, the required ones first.
  REQUIRE_CONTEXT(ctx);
  Scene scene = small_turnaround(32);
  scene.params.shadows = penumbra::Shadows::Hard;
  scene.params.shadow_map_size = 32;
  GradCheckOptions options;
  options.samples = 2;
  const GradCheckResult r = penumbra::gradcheck(*ctx, scene, options);
  ASSERT_EQ(r.checked, 2);
  EXPECT_EQ(r.entries[0].name.rfind("mesh0.v", 0), 0u) << describe(r);
  EXPECT_EQ(r.entries[1].name.rfind("mesh1.v", 0), 0u) << describe(r);
}

}  // namespace
