// The paper model's soft shadows (--shadow-model paper --shadows soft; math.md §4.3 penumbra
// map, §6.3 eq. 11; paper_soft_map.cl, paper_lookups.cl): the penumbra map P of each light, the
// compare-then-filter lookup with the receiver-plane bias, and their gradients, on small scenes
// built here — occluders (an icosphere, two small icospheres at different heights, a flat
// square) above a ground grid, lit by point and directional lights of nonzero size D_L.
//
//   PaperSoftReference.*   the reference's map: P = 1 for D_L = 0, a penumbra for D_L > 0
//   PaperSoftMaps.*        Renderer::penumbra_maps() against reference::penumbra_map (double
//                          ~1e-9, float with a stated bound)
//   PaperSoftKernels.*     soft colours against the reference, truncated and exact sampling
//                          (double ~1e-9, float with a stated bound)
//   PaperSoftGemm.*        the renderer refuses gemm sampling for soft shadows
//   PaperSoftZeroSize.*    a light of size 0 casts no penumbra: P = 1 everywhere
//   PaperSoftOverlap.*     the two-occluder scene has ground texels in both penumbrae
//   PaperSoftGradCheck.*   backward vs finite differences (truncated, exact) on several scenes,
//                          and with a loss on the ground where two penumbrae overlap
//   PaperSoftLightSize.*   dL/dD_L against a central difference of render
//   PaperSoftWidth.*       the penumbra widens with D_L and with the occluder's height
//   PaperSoftDeterminism.* two backward calls give bit-identical gradients
//   PaperSoftFacing.*      soft_sample's skip of fragments facing away from the light changes no
//                          bit, and happens
// A missing OpenCL device fails these tests; it never skips them.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <iostream>
#include <limits>
#include <map>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "penumbra/context.hpp"
#include "penumbra/error.hpp"
#include "penumbra/gradcheck.hpp"
#include "penumbra/image.hpp"
#include "penumbra/reference.hpp"
#include "penumbra/renderer.hpp"
#include "penumbra/scene.hpp"
#include "scenes.hpp"

namespace {

using glm::dvec3;
using namespace penumbra;

// Shared device, builders and comparisons (scenes.hpp).
using namespace penumbra_tests;

// ---------------------------------------------------------------------------------------------
// Meshes and scenes.

// A horizontal square of half-size `half` at height h centred over (x, z), facing +y.
Mesh square(double half, double h, double x = 0.0, double z = 0.0) {
  Mesh mesh;
  mesh.name = "square";
  mesh.vertices = {{x - half, h, z - half},
                   {x + half, h, z - half},
                   {x - half, h, z + half},
                   {x + half, h, z + half}};
  mesh.faces = {{0, 2, 1}, {1, 2, 3}};
  mesh.albedo = {dvec3(0.5, 0.45, 0.4), dvec3(0.5, 0.45, 0.4)};
  mesh.albedo_mode = AlbedoMode::PerFace;
  return mesh;
}

// The parameters of every scene here: those of the hard-shadow scenes (shadow_params: σ = 3e-4,
// γ = 3e-3, 32² maps, β = 0.2, γ_s = 0.04) with soft shadows and γ_P = 10; an occluder 0.5 or
// more above the ground gives membership m ≈ 1.
void soft_params(Scene& s, Sampling sampling) {
  shadow_params(s, Shadows::Soft, sampling);
  s.params.gamma_p = 10.0;
}

enum class Layout { Point, Directional, Two, Overlap };

// Point / Directional / Two: an icosphere of radius 0.5 centred 1.0 above a 4×4 ground grid
// over [−2, 2]² (the Directional one seen by an orthographic camera), with lights of size
// comparable to the occluder's diameter (1).
// Overlap: two small icospheres (radius 0.25) at heights 0.6 and 1.5, either side of a point
// light of size 1.6 straight above, over a ground grid over [−1.6, 1.6]². The higher one's
// penumbra on the ground (≈ 0.9 wide) reaches into the lower one's (≈ 0.3 wide) in the gap
// between their shadows, so ground texels lie in both penumbrae (PaperSoftOverlap).
Scene soft_scene(Layout layout, Sampling sampling = Sampling::Truncated) {
  Scene s;
  switch (layout) {
    case Layout::Point:
      s.meshes = {icosphere({0.0, 1.0, 0.0}, 0.5), ground(2.0, 4)};
      s.cameras = {front_camera(false)};
      s.lights = {point_light({0.9, 5.0, 0.7}, {0.9, 0.85, 0.8}, 1.0)};
      break;
    case Layout::Directional:
      s.meshes = {icosphere({0.0, 1.0, 0.0}, 0.5), ground(2.0, 4)};
      s.cameras = {front_camera(true)};
      s.lights = {directional_light({-0.35, -1.0, -0.25}, {0.85, 0.9, 0.8}, 0.8)};
      break;
    case Layout::Two:
      s.meshes = {icosphere({0.0, 1.0, 0.0}, 0.5), ground(2.0, 4)};
      s.cameras = {front_camera(false)};
      s.lights = {point_light({-1.2, 4.5, 0.8}, {0.6, 0.55, 0.5}, 1.0),
                  directional_light({0.3, -1.0, -0.4}, {0.35, 0.4, 0.45}, 0.6)};
      break;
    case Layout::Overlap:
      s.meshes = {icosphere({-0.35, 0.6, 0.0}, 0.25, 1, "low"),
                  icosphere({0.4, 1.5, 0.1}, 0.25, 1, "high"), ground(1.6, 4)};
      s.cameras = {front_camera(false)};
      s.lights = {point_light({0.0, 5.0, 0.2}, {0.9, 0.9, 0.85}, 1.6)};
      break;
  }
  soft_params(s, sampling);
  penumbra::fit_light_frusta(s);
  return s;
}

std::vector<NamedScene> comparison_scenes(Sampling sampling) {
  return {{"point", soft_scene(Layout::Point, sampling)},
          {"directional (orthographic camera)", soft_scene(Layout::Directional, sampling)},
          {"two lights", soft_scene(Layout::Two, sampling)},
          {"two occluders", soft_scene(Layout::Overlap, sampling)}};
}

// ---------------------------------------------------------------------------------------------
// Comparisons.

// Double kernels: the same formulas in the same precision, summed in another order (and the
// raster leaves out fragments below 1e-10 of a pixel's largest weight): 1e-9.
constexpr double kDoubleTol = 1e-9;
// Float kernels, penumbra map. P depends on S (float map depths ≈ 3–9 carry ~5e-7 absolute
// rounding) and on the faces' float screen positions and depths, through the membership
// σ((S − β − z)/γ_s), which divides depth errors by γ_s = 0.04 (~1.3e-5 in the logit), and
// through τ = r/b with b ∝ S − z ≥ ~0.2 (~3e-6 relative); the soft minimum passes dv to P with
// a factor of order 1 (up to ~γ_P/4 where a weight is small). Bound: 2e-4 (PoCL measured
// ≈ 1e-5, printed).
constexpr double kFloatMapTol = 2e-4;
// Float kernels, colour: the raster alone gives ~1e-5 at σ = 3e-4, γ = 3e-3 (test_raster.cpp);
// the soft lookup adds the compare's float error (map and fragment depths ~5e-7 over γ_s = 0.04
// → ~1e-5 in each logit, scaled by front·(1 − front) ≤ 1/4) and the P error above, averaged by
// the window's weights, all times a light's colour ≤ 1. Bound: 1e-4, as for hard shadows
// (PoCL measured ≈ 3e-6, printed).
constexpr double kFloatColorTol = 1e-4;

// ---------------------------------------------------------------------------------------------
// (a) Penumbra maps and soft colours against the reference.

TEST(PaperSoftReference, ZeroSizeGivesOneAndGemmThrows) {
  Scene s = soft_scene(Layout::Point);
  s.lights[0].size = 0.0;
  const Image P = penumbra::reference::penumbra_map(s, 0);
  ASSERT_EQ(P.width, 32);
  ASSERT_EQ(P.height, 32);
  ASSERT_EQ(P.channels, 1);
  for (double v : P.data) ASSERT_EQ(v, 1.0);
  EXPECT_THROW(penumbra::reference::penumbra_map(s, 1), penumbra::Error);
  set_method(s.params, Method::Gemm);
  EXPECT_THROW(penumbra::reference::render(s, 0), penumbra::Error);
}

// The reference's map shows a penumbra: below 1 on the ground around the shadow, near 0 only
// where an occluder covers the texel's cone, and bounded to [0, 1].
TEST(PaperSoftReference, MapShowsPenumbra) {
  const Scene s = soft_scene(Layout::Point);
  const Image P = penumbra::reference::penumbra_map(s, 0);
  int partial = 0, dark = 0, lit = 0;
  for (double v : P.data) {
    EXPECT_GE(v, 0.0);
    EXPECT_LE(v, 1.0 + 1e-15);
    partial += v > 0.1 && v < 0.9;
    dark += v <= 0.1;
    lit += v >= 0.999;
  }
  std::cout << "[penumbra] reference map, point light D_L = 1: " << partial << " penumbra texels, "
            << dark << " dark, " << lit << " lit of " << P.data.size() << std::endl;
  EXPECT_GE(partial, 10);
  EXPECT_GE(lit, int(P.data.size() / 2));
}

TEST(PaperSoftMaps, MatchReference) {
  REQUIRE_CONTEXT(ctx);
  for (Precision precision : {Precision::Double, Precision::Float}) {
    Renderer& r = shared_renderer(*ctx, precision);
    const double tol = precision == Precision::Double ? kDoubleTol : kFloatMapTol;
    double worst = 0;
    for (const auto& [name, scene] : comparison_scenes(Sampling::Truncated)) {
      ASSERT_NO_THROW(r.render(scene)) << name;
      const std::vector<Image> maps = r.penumbra_maps();
      ASSERT_EQ(maps.size(), scene.lights.size()) << name;
      for (size_t l = 0; l < maps.size(); ++l) {
        const std::string tag =
            std::string(name_of(precision)) + " " + name + " light " + std::to_string(l);
        const Image want = penumbra::reference::penumbra_map(scene, l);
        ASSERT_EQ(maps[l].width, 32) << tag;
        ASSERT_EQ(maps[l].height, 32) << tag;
        // The map has a penumbra to compare: texels strictly between dark and lit.
        int partial = 0;
        for (double v : want.data) partial += v > 0.05 && v < 0.95;
        EXPECT_GE(partial, 4) << tag << ": the reference map shows no penumbra";
        worst = std::max(worst, expect_close(maps[l], want, tol, false, tag + " penumbra map"));
      }
    }
    std::cout << "[penumbra] maps " << name_of(precision) << ": max error " << worst
              << " (tolerance " << tol << ")" << std::endl;
  }
  // Hard shadows and no shadows have no penumbra maps.
  Renderer& r = shared_renderer(*ctx, Precision::Double);
  Scene hard = soft_scene(Layout::Point);
  hard.params.shadows = Shadows::Hard;
  ASSERT_NO_THROW(r.render(hard));
  EXPECT_TRUE(r.penumbra_maps().empty());
}

class PaperSoftKernels : public ::testing::TestWithParam<Sampling> {};

TEST_P(PaperSoftKernels, MatchReference) {
  REQUIRE_CONTEXT(ctx);
  // The reference once per scene, for both precisions.
  std::vector<std::pair<NamedScene, RenderOutput>> cases;
  for (auto& ns : comparison_scenes(GetParam())) {
    RenderOutput want = penumbra::reference::render(ns.scene, 0);
    ASSERT_EQ(count_non_finite(want.color), 0u) << ns.name;
    // Soft shadows show: the colour differs from a render without shadows.
    Scene none = ns.scene;
    none.params.shadows = Shadows::None;
    EXPECT_GT(max_error(want.color, penumbra::reference::render(none, 0).color), 0.2)
        << ns.name << ": the soft shadow does not show";
    cases.push_back({std::move(ns), std::move(want)});
  }
  for (Precision precision : {Precision::Double, Precision::Float}) {
    Renderer& r = shared_renderer(*ctx, precision);
    const double tol = precision == Precision::Double ? kDoubleTol : kFloatColorTol;
    double worst = 0, worst_sil = 0, worst_depth = 0;
    for (const auto& [ns, want] : cases) {
      const std::string tag =
          std::string(name_of(GetParam())) + " " + name_of(precision) + " " + ns.name;
      std::vector<RenderOutput> got;
      ASSERT_NO_THROW(got = r.render(ns.scene)) << tag;
      ASSERT_EQ(got.size(), 1u) << tag;
      worst = std::max(worst, expect_close(got[0].color, want.color, tol, false, tag + " colour"));
      worst_sil = std::max(worst_sil, max_error(got[0].silhouette, want.silhouette));
      worst_depth = std::max(worst_depth, max_error(got[0].depth, want.depth));
    }
    std::cout << "[penumbra] soft " << name_of(GetParam()) << " " << name_of(precision)
              << ": max colour error " << worst << " (tolerance " << tol << "), silhouette "
              << worst_sil << ", depth " << worst_depth << std::endl;
  }
}

INSTANTIATE_TEST_SUITE_P(PaperSoft, PaperSoftKernels,
                         ::testing::Values(Sampling::Truncated, Sampling::Exact),
                         [](const auto& info) { return std::string(name_of(info.param)); });

// The renderer refuses gemm sampling for soft shadows, with a message naming the alternatives.
TEST(PaperSoftGemm, IsRefused) {
  REQUIRE_CONTEXT(ctx);
  Renderer& r = shared_renderer(*ctx, Precision::Double);
  Scene s = soft_scene(Layout::Point);
  set_method(s.params, Method::Gemm);
  try {
    r.render(s);
    ADD_FAILURE() << "soft shadows with gemm sampling rendered";
  } catch (const penumbra::Error& e) {
    EXPECT_NE(std::string(e.what()).find("'kernels'"), std::string::npos) << e.what();
  }
}

// ---------------------------------------------------------------------------------------------
// (b) A light of size 0 casts no penumbra.

TEST(PaperSoftZeroSize, MapIsOneEverywhere) {
  REQUIRE_CONTEXT(ctx);
  for (Precision precision : {Precision::Double, Precision::Float}) {
    Renderer& r = shared_renderer(*ctx, precision);
    for (Layout layout : {Layout::Point, Layout::Two, Layout::Overlap}) {
      Scene s = soft_scene(layout);
      for (Light& l : s.lights) l.size = 0.0;
      ASSERT_NO_THROW(r.render(s));
      const std::vector<Image> maps = r.penumbra_maps();
      ASSERT_EQ(maps.size(), s.lights.size());
      for (size_t l = 0; l < maps.size(); ++l) {
        size_t not_one = 0;
        for (double v : maps[l].data) not_one += v != 1.0;
        EXPECT_EQ(not_one, 0u) << name_of(precision) << " light " << l;
        EXPECT_EQ(maps[l].data.size(), 32u * 32u);
      }
    }
  }
  // With P = 1, eq. 11 reduces to Σλ·front·(1 − at·0) = Σλ·front: the colour matches the
  // reference, and the shadow still shows (the umbra is the occluder's hard shadow).
  Renderer& r = shared_renderer(*ctx, Precision::Double);
  Scene s = soft_scene(Layout::Point);
  s.lights[0].size = 0.0;
  std::vector<RenderOutput> got;
  ASSERT_NO_THROW(got = r.render(s));
  expect_close(got[0].color, penumbra::reference::render(s, 0).color, kDoubleTol, false,
               "zero-size light colour");
}

// ---------------------------------------------------------------------------------------------
// Geometry helpers.

// The point of the ground plane y = 0 that the centre of texel `texel` (row-major index) of a
// point light's map of size n² looks at, through the light's fitted frustum.
dvec3 texel_on_ground(const Light& light, int n, int texel) {
  const auto& fr = light.frustum;
  const dvec3 f = glm::normalize(fr.target - light.position);
  const dvec3 r = glm::normalize(glm::cross(f, fr.up));
  const dvec3 u = glm::cross(r, f);
  const int i = texel % n, j = texel / n;
  const double t = std::tan(glm::radians(fr.fov_deg) / 2);
  const double x = double(2 * i + 1 - n) / n, y = double(n - 2 * j - 1) / n;
  const dvec3 dir = f + x * t * r + y * t * u;
  return light.position - (light.position.y / dir.y) * dir;
}

// ---------------------------------------------------------------------------------------------
// The two-occluder scene: some ground texels are in the penumbra of both occluders: each
// occluder alone darkens them (P < 0.95), and both enter the soft minimum there (removing
// either one changes P).

std::vector<int> overlap_texels(const Scene& scene, double* both_max = nullptr) {
  Scene low = scene, high = scene, bare = scene;
  low.meshes = {scene.meshes[0], scene.meshes[2]};
  high.meshes = {scene.meshes[1], scene.meshes[2]};
  bare.meshes = {scene.meshes[2]};
  const Image P = penumbra::reference::penumbra_map(scene, 0);
  const Image Pl = penumbra::reference::penumbra_map(low, 0);
  const Image Ph = penumbra::reference::penumbra_map(high, 0);
  const Image S = penumbra::reference::shadow_map(scene, 0);
  const Image Sg = penumbra::reference::shadow_map(bare, 0);  // the ground alone
  std::vector<int> texels;
  double m = 0;
  for (size_t i = 0; i < P.data.size(); ++i) {
    // Ground texels: neither occluder shows, nor the background (depth at the far plane).
    const bool on_ground =
        std::abs(S.data[i] - Sg.data[i]) < 1e-6 && Sg.data[i] < scene.lights[0].frustum.far - 1e-6;
    const bool in_both = Pl.data[i] < 0.95 && Ph.data[i] < 0.95;
    const double change =
        std::min(std::abs(P.data[i] - Pl.data[i]), std::abs(P.data[i] - Ph.data[i]));
    if (on_ground && in_both && change > 1e-3) {
      texels.push_back(int(i));
      m = std::max(m, change);
    }
  }
  if (both_max) *both_max = m;
  return texels;
}

TEST(PaperSoftOverlap, GroundTexelsInBothPenumbrae) {
  const Scene s = soft_scene(Layout::Overlap);
  double m = 0;
  const std::vector<int> texels = overlap_texels(s, &m);
  std::cout << "[penumbra] two occluders: " << texels.size()
            << " ground texels in both penumbrae (P changes by up to " << m
            << " without either occluder)" << std::endl;
  EXPECT_GE(texels.size(), 5u);
}

// ---------------------------------------------------------------------------------------------
// (c) Gradients.

// Every scene with truncated sampling; exact sampling (every texel whose weight is not 0 per
// fragment, slower here) on the directional light seen by an orthographic camera and on the two
// occluders under a point light.
std::vector<GradCase> gradient_cases(Sampling sampling) {
  if (sampling == Sampling::Exact)
    return {{"directional (orthographic camera)", soft_scene(Layout::Directional, sampling), 5},
            {"two occluders", soft_scene(Layout::Overlap, sampling), 9}};
  return {{"point", soft_scene(Layout::Point, sampling), 3},
          {"directional (orthographic camera)", soft_scene(Layout::Directional, sampling), 5},
          {"two lights", soft_scene(Layout::Two, sampling), 7},
          {"two occluders", soft_scene(Layout::Overlap, sampling), 9}};
}

// Occluder and receiver vertices, and every point light's position, are among the entries.
void expect_entries(const GradCheckResult& result, const Scene& scene, const std::string& tag) {
  for (size_t m = 0; m < scene.meshes.size(); ++m)
    EXPECT_TRUE(has_entry(result, "mesh" + std::to_string(m) + ".v"))
        << tag << ": no vertex of mesh " << m << "\n"
        << describe(result);
  for (size_t l = 0; l < scene.lights.size(); ++l)
    EXPECT_TRUE(has_entry(
        result, "light" + std::to_string(l) +
                    (scene.lights[l].type == LightType::Point ? ".position" : ".direction")))
        << tag << ": light " << l << " not checked\n"
        << describe(result);
}

class PaperSoftGradCheck : public ::testing::TestWithParam<Sampling> {};

TEST_P(PaperSoftGradCheck, Double) {
  REQUIRE_CONTEXT(ctx);
  Renderer& r = shared_renderer(*ctx, Precision::Double);
  for (auto& [name, scene, seed] : gradient_cases(GetParam())) {
    penumbra::fit_light_frusta(scene);  // fixed frusta: gradients and differences agree
    GradCheckOptions options;
    options.samples = GetParam() == Sampling::Exact ? 24 : 30;
    options.seed = seed;
    GradCheckResult result;
    ASSERT_NO_THROW(result = penumbra::gradcheck(r, scene, options)) << name;
    const std::string tag = std::string(name_of(GetParam())) + " " + name;
    std::cout << "[penumbra gradcheck] " << tag << ": checked=" << result.checked
              << " failed=" << result.failed << " failure_fraction=" << result.failure_fraction()
              << " max_rel_err=" << result.max_rel_err << std::endl;
    EXPECT_TRUE(result.passed()) << tag << "\n" << describe(result);
    EXPECT_EQ(result.checked, options.samples) << tag;
    expect_entries(result, scene, tag);
  }
}

// A loss on the ground pixels that see the texels in both penumbrae of the two-occluder scene
// (colour only): there the soft term depends on P, built from both occluders' faces, so their
// vertices reach the loss through P and S alone.
TEST_P(PaperSoftGradCheck, OverlappingPenumbraeOnly) {
  REQUIRE_CONTEXT(ctx);
  Renderer& r = shared_renderer(*ctx, Precision::Double);
  Scene scene = soft_scene(Layout::Overlap, GetParam());
  const std::string tag = std::string(name_of(GetParam())) + " two occluders, overlap only";
  const Camera& cam = scene.cameras[0];
  Scene ground_only = scene;
  ground_only.meshes = {scene.meshes[2]};
  ground_only.params.shadows = Shadows::None;
  const RenderOutput g = penumbra::reference::render(ground_only, 0);
  const RenderOutput soft = penumbra::reference::render(scene, 0);
  std::vector<OutputGrads> weights(1);
  weights[0].color = Image(cam.width, cam.height, 3);
  std::mt19937_64 rng(21);
  std::normal_distribution<double> normal;
  int pixels = 0;
  for (int texel : overlap_texels(scene)) {
    // The ground point the texel's centre sees, and the camera pixel that shows it.
    const dvec3 X = texel_on_ground(scene.lights[0], shadow_map_side(scene.params), texel);
    const auto [px, py] = pixel_of(cam, X);
    for (int y = py - 1; y <= py + 1; ++y)
      for (int x = px - 1; x <= px + 1; ++x) {
        if (x < 0 || y < 0 || x >= cam.width || y >= cam.height) continue;
        if (weights[0].color.at(x, y, 0) != 0) continue;  // already taken
        const bool on_ground =
            std::abs(soft.depth.at(x, y) - g.depth.at(x, y)) <= 1e-9 * g.depth.at(x, y);
        if (!on_ground) continue;
        ++pixels;
        for (int c = 0; c < 3; ++c) weights[0].color.at(x, y, c) = normal(rng);
      }
  }
  ASSERT_GE(pixels, 10) << tag << ": too few ground pixels in both penumbrae";
  penumbra::fit_light_frusta(scene);
  ASSERT_NO_THROW(r.render(scene)) << tag;
  SceneGrads analytic;
  ASSERT_NO_THROW(analytic = r.backward(scene, weights)) << tag;
  GradCheckOptions options;
  options.samples = 24;
  options.seed = 31;
  GradCheckResult result;
  ASSERT_NO_THROW(
      result = penumbra::compare_with_finite_differences(r, scene, weights, analytic, options))
      << tag;
  std::cout << "[penumbra gradcheck] " << tag << " (" << pixels
            << " px): checked=" << result.checked << " failed=" << result.failed
            << " failure_fraction=" << result.failure_fraction()
            << " max_rel_err=" << result.max_rel_err << std::endl;
  EXPECT_TRUE(result.passed()) << tag << "\n" << describe(result);
  expect_entries(result, scene, tag);
  // Both occluders matter to this loss, and some of their entries were compared well above the
  // absolute floor.
  const double scale = penumbra::max_abs_gradient(analytic);
  for (int m : {0, 1}) {
    double occluder = 0;
    for (const auto& v : analytic.vertices[size_t(m)])
      occluder = std::max({occluder, std::abs(v.x), std::abs(v.y), std::abs(v.z)});
    EXPECT_GT(occluder, 1e-2 * scale) << tag << " occluder " << m;
  }
  int occluder_entries = 0;
  for (const auto& e : result.entries)
    if ((e.name.compare(0, 7, "mesh0.v") == 0 || e.name.compare(0, 7, "mesh1.v") == 0) &&
        std::abs(e.numeric) > 10 * result.atol)
      ++occluder_entries;
  EXPECT_GE(occluder_entries, 1) << tag << "\n" << describe(result);
  EXPECT_NE(analytic.light_size.at(0), 0.0) << tag;
}

INSTANTIATE_TEST_SUITE_P(PaperSoft, PaperSoftGradCheck,
                         ::testing::Values(Sampling::Truncated, Sampling::Exact),
                         [](const auto& info) { return std::string(name_of(info.param)); });

// dL/dD_L (which the gradient check does not perturb) against the central difference
// (L(D_L + h) − L(D_L − h))/(2h) of render, for a random linear loss. The light size changes
// only P (never the frusta, the raster or which fragments are kept), so L is smooth in D_L away
// from the kinks τ = 1 and m = 0.
TEST(PaperSoftLightSize, GradientMatchesCentralDifference) {
  REQUIRE_CONTEXT(ctx);
  Renderer& r = shared_renderer(*ctx, Precision::Double);
  struct Case {
    std::string name;
    Scene scene;
  };
  std::vector<Case> cases = {
      {"truncated point", soft_scene(Layout::Point, Sampling::Truncated)},
      {"truncated two lights", soft_scene(Layout::Two, Sampling::Truncated)},
      {"truncated two occluders", soft_scene(Layout::Overlap, Sampling::Truncated)},
      {"exact directional", soft_scene(Layout::Directional, Sampling::Exact)},
      {"exact two occluders", soft_scene(Layout::Overlap, Sampling::Exact)}};
  const double h = 1e-6;
  for (auto& [name, scene] : cases) {
    penumbra::fit_light_frusta(scene);
    const auto weights = penumbra::random_loss_weights(scene, 17);
    ASSERT_NO_THROW(r.render(scene)) << name;
    SceneGrads grads;
    ASSERT_NO_THROW(grads = r.backward(scene, weights)) << name;
    ASSERT_EQ(grads.light_size.size(), scene.lights.size()) << name;
    for (size_t l = 0; l < scene.lights.size(); ++l) {
      Scene plus = scene, minus = scene;
      plus.lights[l].size += h;
      minus.lights[l].size -= h;
      double lp = 0, lm = 0;
      ASSERT_NO_THROW(lp = penumbra::linear_loss(r.render(plus), weights)) << name;
      ASSERT_NO_THROW(lm = penumbra::linear_loss(r.render(minus), weights)) << name;
      const double numeric = (lp - lm) / (2 * h);
      const double analytic = grads.light_size[l];
      std::cout << "[penumbra] dL/dD_L " << name << " light " << l << ": analytic " << analytic
                << ", numeric " << numeric << ", relative error "
                << std::abs(analytic - numeric) / std::max(std::abs(numeric), 1e-300) << std::endl;
      // The penumbra matters: the loss changes with the light's size.
      EXPECT_GT(std::abs(numeric), 1e-2) << name << " light " << l;
      EXPECT_TRUE(penumbra::gradients_agree(analytic, numeric, 1e-6, 1e-4))
          << name << " light " << l << ": analytic " << analytic << ", numeric " << numeric;
    }
  }
}

// ---------------------------------------------------------------------------------------------
// (d) The penumbra widens with the light's size and with the occluder–receiver distance.

// A flat square occluder (half-size 0.35) at height h over the middle of a uniform ground grid
// over [−1.6, 1.6]², a point light of size D_L straight above at height 5. The orthographic
// 40×32 camera looks down at 45° from +z, so its rows run along x and the square (seen above the
// shadow in the image) hides none of the ground along z = 0.
Scene width_scene(double light_size, double height) {
  Scene s;
  s.meshes = {square(0.35, height), ground(1.6, 8, 0.0)};
  Camera cam;
  cam.eye = {0.0, 4.0, 4.0};
  cam.target = {0.0, 0.0, 0.0};
  cam.up = {0, 1, 0};
  cam.projection = Projection::Orthographic;
  cam.half_height = 1.2;
  cam.near = 0.5;
  cam.far = 12.0;
  cam.width = 40;
  cam.height = 32;
  s.cameras = {cam};
  s.lights = {point_light({0.0, 5.0, 0.0}, {0.8, 0.8, 0.8}, light_size)};
  soft_params(s, Sampling::Truncated);
  penumbra::fit_light_frusta(s);
  return s;
}

// Width in pixels of the shadow's transition along the image row through the ground point
// (0, 0, 0), on its +x side. The ground's shadow level along the row is the fraction of the
// light it receives, t = (C − C_ambient)/(C_lit − C_ambient) per pixel (mean over channels),
// with C_lit rendered without shadows and C_ambient with the light off. With t_in at the
// shadow's centre and t_out at the row's end (lit), the width is the distance between where t
// first crosses t_in + 10% and t_in + 90% of (t_out − t_in), by linear interpolation.
double transition_width(Renderer& r, const Scene& scene, double* t_in, double* t_out) {
  Scene none = scene, dark = scene;
  none.params.shadows = dark.params.shadows = Shadows::None;
  dark.lights[0].color = dvec3(0.0);
  const Image soft = r.render(scene).at(0).color;
  const Image lit = r.render(none).at(0).color;
  const Image amb = r.render(dark).at(0).color;
  const Camera& cam = scene.cameras[0];
  const int y = cam.height / 2;  // the row through the target (0, 0, 0), half a pixel below
  const int x0 = cam.width / 2;  // the column through x ≈ 0
  std::vector<double> t;
  for (int x = x0; x < cam.width; ++x) {
    double num = 0, den = 0;
    for (int c = 0; c < 3; ++c) {
      num += soft.at(x, y, c) - amb.at(x, y, c);
      den += lit.at(x, y, c) - amb.at(x, y, c);
    }
    t.push_back(num / den);
  }
  *t_in = t.front();
  *t_out = t.back();
  auto crossing = [&](double level) {
    for (size_t i = 1; i < t.size(); ++i)
      if (t[i - 1] < level && t[i] >= level)
        return double(i - 1) + (level - t[i - 1]) / (t[i] - t[i - 1]);
    return std::numeric_limits<double>::quiet_NaN();
  };
  const double lo = *t_in + 0.1 * (*t_out - *t_in), hi = *t_in + 0.9 * (*t_out - *t_in);
  return crossing(hi) - crossing(lo);
}

TEST(PaperSoftWidth, GrowsWithLightSizeAndOccluderHeight) {
  REQUIRE_CONTEXT(ctx);
  Renderer& r = shared_renderer(*ctx, Precision::Double);
  auto measure = [&](double size, double height, const std::string& what) {
    double t_in = 0, t_out = 0;
    const double w = transition_width(r, width_scene(size, height), &t_in, &t_out);
    std::cout << "[penumbra] width, " << what << " (D_L = " << size << ", height " << height
              << "): " << w << " px (shadow level " << t_in << ", lit level " << t_out << ")"
              << std::endl;
    EXPECT_TRUE(std::isfinite(w)) << what;
    EXPECT_LT(t_in, 0.1) << what << ": the shadow's centre is not dark";
    EXPECT_GT(t_out, 0.95) << what << ": the row's end is not lit";
    return w;
  };
  // Light size small → medium → large at height 1 (predicted penumbra on the ground
  // ≈ D_L·h/(5 − h) = 0.075, 0.375, 0.75 world units; 13.3 px per unit), then occluder height
  // low → high at D_L = 1.5 (0.17, 0.375, 0.64 units).
  const double small = measure(0.3, 1.0, "small light");
  const double medium = measure(1.5, 1.0, "medium light");
  const double large = measure(3.0, 1.0, "large light");
  EXPECT_LT(small, medium);
  EXPECT_LT(medium, large);
  const double low = measure(1.5, 0.5, "low occluder");
  const double high = measure(1.5, 1.5, "high occluder");
  EXPECT_LT(low, medium);
  EXPECT_LT(medium, high);
  // The growth is substantial, not rounding. (The Gaussian filter alone spreads the edge over
  // ≈ 2.56·√σ_s texels ≈ 5 px here; the penumbra adds roughly in quadrature.)
  EXPECT_GT(large, 1.3 * small);
  EXPECT_GT(high, 1.3 * low);
}

// ---------------------------------------------------------------------------------------------
// (e) Determinism.

TEST(PaperSoftDeterminism, BackwardIsBitIdentical) {
  REQUIRE_CONTEXT(ctx);
  for (Precision precision : {Precision::Double, Precision::Float}) {
    Renderer& r = shared_renderer(*ctx, precision);
    for (Sampling sampling : {Sampling::Truncated, Sampling::Exact}) {
      // Two lights (point and directional) with truncated sampling, two occluders with exact.
      const Layout layout = sampling == Sampling::Truncated ? Layout::Two : Layout::Overlap;
      {
        const Scene scene = soft_scene(layout, sampling);
        const auto weights = penumbra::random_loss_weights(scene, 11);
        const std::string tag = std::string(name_of(sampling)) + " " + name_of(precision) +
                                (layout == Layout::Two ? " two lights" : " two occluders");
        ASSERT_NO_THROW(r.render(scene)) << tag;
        SceneGrads a, b, c;
        ASSERT_NO_THROW(a = r.backward(scene, weights)) << tag;
        ASSERT_NO_THROW(b = r.backward(scene, weights)) << tag;
        expect_identical(a, b, tag + " (two backward calls)", true);
        ASSERT_NO_THROW(r.render(scene)) << tag;
        ASSERT_NO_THROW(c = r.backward(scene, weights)) << tag;
        expect_identical(a, c, tag + " (render again)", true);
        // The gradient reaches the light's size.
        ASSERT_EQ(a.light_size.size(), scene.lights.size()) << tag;
        EXPECT_NE(a.light_size[0], 0.0) << tag;
      }
    }
  }
}

// soft_sample gives a fragment in the map that faces away from the light (n·l ≤ 0) s = 1
// without a lookup: kernels that look every fragment up give the same images and gradients bit
// for bit, truncated and exact; kernels that store NaN there give NaN colours (s·0), so the
// skip happens in these scenes.
constexpr const char* kFacingStore =
    "    rec_light[r * nl + light].w = 1;\n    return;\n  }\n  real2";

TEST(PaperSoftFacing, SkippedLookupsChangeNoBit) {
  REQUIRE_CONTEXT(ctx);
  const std::string always = kernels_looking_up_every_fragment("penumbra_soft_look_up_all");
  for (Precision p : {Precision::Float, Precision::Double})
    for (Sampling sampling : {Sampling::Truncated, Sampling::Exact})
      for (const NamedScene& named : comparison_scenes(sampling))
        expect_skip_changes_no_bit(always, named.scene, p,
                                   named.name + " " + name_of(sampling) + " " + name_of(p));
}

TEST(PaperSoftFacing, LookupsSkipped) {
  REQUIRE_CONTEXT(ctx);
  const std::string poisoned =
      patched_kernels("penumbra_soft_facing_nan", "paper_lookups.cl", kFacingStore,
                      "    rec_light[r * nl + light].w = NAN;\n    return;\n  }\n  real2");
  for (Sampling sampling : {Sampling::Truncated, Sampling::Exact})
    expect_skip_taken(poisoned, soft_scene(Layout::Point, sampling), name_of(sampling));
}

}  // namespace
