// The paper model's hard shadows (--shadow-model paper --shadows hard; math.md §4–§6): the
// light pass, the shadow-map lookup (paper_lookups.cl, paper_hard_exact.cl) and their gradients, on
// small scenes built here — an icosphere occluder above a ground grid, lit by one point light, one
// directional light, or both.
//
//   ShadowReference.*  the reference's light pass against closed-form depths (no device needed)
//   ShadowMaps.*       Renderer::shadow_maps() against the reference's light pass
//   ShadowKernels.*    double (~1e-9) and float kernels vs the reference, with truncated, exact
//                      and gemm (exact on CLBlast) sampling (test names
//                      Shadow/ShadowKernels.*/<sampling>)
//   ShadowDouble.*     the shadows show: hard differs from none in every comparison scene
//   ShadowSampling.*   exact on penumbra's kernels and on CLBlast (gemm) compute the same number
//                      (and gradient), in one batch of fragments or several; truncated → exact
//                      as ε_λ → 0; the exact sums leave out only weights that are exactly 0
//   ShadowGradCheck.*  backward vs finite differences for every sampling method, with entries on
//                      occluder vertices, receiver vertices and light positions; and with a loss
//                      on the shadowed ground only (occluder vertices act through S alone)
//   ShadowVisible.*    a ground pixel in the occluder's shadow is dark, one outside it is lit
//   ShadowDeterminism.*  two backward calls give bit-identical gradients
//   ShadowFacing.*     the lookups' skip of fragments facing away from the light changes no bit
//   ShadowBuckets.*    the gathers' buckets leave out the fragments without a gradient: no bit
//                      changes, paper and accurate model, hard and soft shadows
// A missing OpenCL device fails these tests; it never skips them.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <iostream>
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
#include "penumbra/io.hpp"
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
// Scenes.

enum class Lighting { Point, Directional, Two, Overhead };

// Mesh 0: an icosphere of radius 0.5 centred 1.0 above the ground (a gap of 0.5 below it);
// mesh 1: a 4×4 ground grid over [−2, 2]². A 48×40 camera sees both from the front and above
// (orthographic with `ortho`). The fitted light frusta span the ground, so a 32² map has
// ≈ 0.13–0.2 world units per texel; β = 0.2 and γ_s = 0.04 (depth units) give lit ground
// s ≈ sigmoid(5) and shadowed ground s ≈ sigmoid(−7) or darker.
Scene shadow_scene(Lighting lighting, Method sampling = Method::Truncated, bool ortho = false) {
  Scene s;
  s.meshes = {icosphere({0.0, 1.0, 0.0}, 0.5), ground(2.0, 4)};
  s.cameras = {front_camera(ortho)};
  switch (lighting) {
    case Lighting::Point:
      s.lights = {point_light({0.9, 5.0, 0.7}, {0.9, 0.85, 0.8})};
      break;
    case Lighting::Directional:
      s.lights = {directional_light({-0.35, -1.0, -0.25}, {0.85, 0.9, 0.8})};
      break;
    case Lighting::Two:
      s.lights = {point_light({-1.2, 4.5, 0.8}, {0.6, 0.55, 0.5}),
                  directional_light({0.3, -1.0, -0.4}, {0.35, 0.4, 0.45})};
      break;
    case Lighting::Overhead:
      s.lights = {point_light({0.0, 6.0, 0.0}, {1.0, 1.0, 1.0})};
      break;
  }
  shadow_params(s, Shadows::Hard, sampling);
  penumbra::fit_light_frusta(s);
  return s;
}

// The scenes every comparison runs on.
std::vector<NamedScene> comparison_scenes(Method sampling) {
  return {
      {"point", shadow_scene(Lighting::Point, sampling)},
      {"directional (orthographic camera)", shadow_scene(Lighting::Directional, sampling, true)},
      {"two lights", shadow_scene(Lighting::Two, sampling)}};
}

// ---------------------------------------------------------------------------------------------
// Comparisons.

// Double kernels: the same formulas in the same precision; only the order of the sums differs
// (and the kernels leave out fragments whose weight is below 1e-10 of the pixel's largest).
constexpr Tolerance kDoubleTol{1e-9, 1e-9, 1e-9};
// Float kernels: the raster alone gives colour errors ~1e-5 at σ = 3e-4, γ = 3e-3 (see
// test_raster.cpp). The shadow term adds: map depths and the fragment's light depth d (≈ 5)
// carry ~5e-7 absolute error, divided by γ_s = 0.04 in the compare → ~1e-5 in the logit, and
// μ carries ~1e-5 texels of error, moving the filtered depth by up to slope·1e-5. At most
// s(1 − s)·logit error ≤ 1e-5 of the light's colour. Stated bound: 1e-4 colour, as for the
// raster alone (PoCL measured ≤ 1e-5).
constexpr Tolerance kFloatTol{1e-4, 1e-4, 1e-5};

// Largest |a − b| over every colour value of every view.
double max_colour_difference(const std::vector<RenderOutput>& a,
                             const std::vector<RenderOutput>& b) {
  double m = 0;
  for (size_t v = 0; v < a.size() && v < b.size(); ++v)
    m = std::max(m, max_error(a[v].color, b[v].color, false, nullptr));
  return m;
}

double luminance(const Image& color, std::pair<int, int> p) {
  return (color.at(p.first, p.second, 0) + color.at(p.first, p.second, 1) +
          color.at(p.first, p.second, 2)) /
         3;
}

// ---------------------------------------------------------------------------------------------
// The reference's light pass against closed-form depths.

// A directional light straight down onto a ground (flat unless `variation`), with a frustum
// given (not fitted): the orthographic light looks from 4 above the origin over [−3, 3]².
Scene ground_from_above(ShadowModel model, double variation = 0.05) {
  Scene s;
  s.meshes = {ground(2.0, 2, variation)};
  s.cameras = {Camera{}};
  s.lights = {directional_light({0, -1, 0}, {1, 1, 1})};
  s.params.sigma = 3e-4;
  s.params.gamma = 3e-3;
  s.params.shadow_map_size = 24;
  s.params.shadow_model = model;
  auto& fr = s.lights[0].frustum;
  fr.fitted = true;
  fr.target = {0, 0, 0};
  fr.up = {0, 0, 1};
  fr.half_size = 3.0;
  fr.distance = 4.0;
  fr.near = 1.0;
  fr.far = 8.0;
  return s;
}

// The paper model's map holds every face: texels over the ground ([−2, 2]²) see it at depth 4
// and the corner texels see the background at the far plane.
TEST(ShadowReference, FlatGroundDepthFromAbove) {
  const Image S = penumbra::reference::shadow_map(ground_from_above(ShadowModel::Paper), 0);
  ASSERT_EQ(S.width, 24);
  ASSERT_EQ(S.height, 24);
  ASSERT_EQ(S.channels, 1);
  EXPECT_NEAR(S.at(11, 11), 4.0, 1e-9);
  EXPECT_NEAR(S.at(12, 13), 4.0, 1e-9);
  EXPECT_NEAR(S.at(5, 18), 4.0, 1e-9);  // centre 1.625 off both axes: on the ground
  EXPECT_NEAR(S.at(0, 0), 8.0, 1e-9);   // centre 2.875 off both axes: beyond it
  EXPECT_NEAR(S.at(23, 23), 8.0, 1e-9);
}

// The accurate model's map holds only what can cast a shadow: a flat ground with the whole
// scene above it casts none and is left out (the far plane everywhere); a card 1 above it, whose
// plane has the ground beyond it, stays (depth 3 over [−1, 1]²), in the reference and kernels.
TEST(ShadowReference, AccurateMapLeavesOutWhatCastsNoShadow) {
  Scene s = ground_from_above(ShadowModel::Accurate, 0.0);
  EXPECT_NEAR(penumbra::reference::shadow_map(s, 0).at(11, 11), 8.0, 1e-9);
  Mesh card = ground(1.0, 1, 0.0);
  for (auto& v : card.vertices) v.y += 1;
  s.meshes.push_back(card);
  const Image S = penumbra::reference::shadow_map(s, 0);
  EXPECT_NEAR(S.at(11, 11), 3.0, 1e-9);
  EXPECT_NEAR(S.at(5, 18), 8.0, 1e-9);  // over the ground, beyond the card
  REQUIRE_CONTEXT(ctx);
  Renderer& r = shared_renderer(*ctx, Precision::Double);
  s.params.shadows = Shadows::Hard;
  ASSERT_NO_THROW(r.render(s));
  expect_close(r.shadow_maps().at(0), S, 1e-9, true, "accurate map");
  s.params.shadow_model = ShadowModel::Paper;
  EXPECT_NEAR(penumbra::reference::shadow_map(s, 0).at(5, 18), 4.0, 1e-9);
}

// A point light straight above a ground quad: the texel at the map centre looks straight down
// and sees the ground at depth = the light's height; an unfitted frustum is fitted by the
// reference as by the renderer.
TEST(ShadowReference, PointLightCentreTexelAndFitting) {
  Scene s;
  s.meshes = {ground(2.0, 2)};
  s.cameras = {Camera{}};
  s.lights = {point_light({0, 5, 0}, {1, 1, 1})};
  s.params.sigma = 3e-4;
  s.params.gamma = 3e-3;
  s.params.shadow_map_size = 25;               // odd: texel (12, 12) is the centre
  s.params.shadow_model = ShadowModel::Paper;  // whose map holds the ground (see below)
  ASSERT_FALSE(s.lights[0].frustum.fitted);
  const Image S = penumbra::reference::shadow_map(s, 0);
  EXPECT_NEAR(S.at(12, 12), 5.0, 1e-9);
  Scene f = s;
  penumbra::fit_light_frusta(f);
  EXPECT_EQ(penumbra::reference::shadow_map(f, 0).data, S.data);
  EXPECT_THROW(penumbra::reference::shadow_map(s, 1), penumbra::Error);
}

// With shadows on, a lit receiver far from any occluder keeps almost all its light
// (s ≈ sigmoid(β/γ_s)). The reference renders soft shadows (test_paper_soft.cpp compares them)
// but, like the renderer, rejects them with gemm sampling.
TEST(ShadowReference, NoneAndHardAgreeAwayFromShadowsSoftGemmThrows) {
  Scene hard = shadow_scene(Lighting::Overhead);
  Scene none = hard;
  none.params.shadows = Shadows::None;
  const RenderOutput a = penumbra::reference::render(hard, 0),
                     b = penumbra::reference::render(none, 0);
  const auto lit = pixel_of(hard.cameras[0], {1.3, 0.0, 1.1});
  const double s = 1 / (1 + std::exp(-*hard.params.beta / *hard.params.gamma_s));
  // colour = a·I_a + s·a·I_L·cos, so None − Hard = (1 − s)·(direct part) ≤ (1 − s)·None; the
  // filtered depth on flat lit ground is within a little of the receiver's own (slack 1%).
  for (int c = 0; c < 3; ++c) {
    const double full = b.color.at(lit.first, lit.second, c);
    EXPECT_LE(a.color.at(lit.first, lit.second, c), full + 1e-12) << c;
    EXPECT_GE(a.color.at(lit.first, lit.second, c), full * (s - 0.01)) << c;
  }
  Scene soft = hard;
  soft.params.shadows = Shadows::Soft;
  RenderOutput c;
  ASSERT_NO_THROW(c = penumbra::reference::render(soft, 0));
  expect_finite(c.color, "soft reference colour");
  set_method(soft.params, Method::Gemm);
  EXPECT_THROW(penumbra::reference::render(soft, 0), penumbra::Error);
}

// ---------------------------------------------------------------------------------------------
// (a) Shadow maps.

TEST(ShadowMaps, MatchReference) {
  REQUIRE_CONTEXT(ctx);
  for (Precision precision : {Precision::Double, Precision::Float}) {
    Renderer& r = shared_renderer(*ctx, precision);
    // Float: map depths ≈ 3–9 carry ~1e-7 relative rounding; the soft aggregation divides depth
    // errors by γ_L·(far − near), which at silhouettes mixes occluder and ground depths: 1e-5.
    const double tol = precision == Precision::Double ? 1e-9 : 1e-5;
    double worst = 0;
    for (const auto& [name, scene] : comparison_scenes(Method::Truncated)) {
      ASSERT_NO_THROW(r.render(scene)) << name;
      const std::vector<Image> maps = r.shadow_maps();
      ASSERT_EQ(maps.size(), scene.lights.size()) << name;
      for (size_t l = 0; l < maps.size(); ++l) {
        const Image want = penumbra::reference::shadow_map(scene, l);
        EXPECT_EQ(maps[l].width, 32);
        EXPECT_EQ(maps[l].height, 32);
        // The map must show the occluder: some texels nearer than the ground's nearest.
        double lo = 1e300, hi = 0;
        for (double v : want.data) lo = std::min(lo, v), hi = std::max(hi, v);
        EXPECT_LT(lo, hi - 0.3) << name << " light " << l << ": the map shows no occluder";
        worst = std::max(worst, expect_close(maps[l], want, tol, true,
                                             name + " light " + std::to_string(l) + " map"));
      }
    }
    std::cout << "[shadow] maps " << (precision == Precision::Double ? "double" : "float")
              << ": max relative error " << worst << std::endl;
  }
  // With shadows off there are no maps.
  Renderer& r = shared_renderer(*ctx, Precision::Double);
  Scene none = shadow_scene(Lighting::Point);
  none.params.shadows = Shadows::None;
  ASSERT_NO_THROW(r.render(none));
  EXPECT_TRUE(r.shadow_maps().empty());
}

// Light-pass σ_L and γ_L are honoured when given (0 selects light_pass_sigma/gamma defaults).
TEST(ShadowMaps, LightSigmaAndGamma) {
  REQUIRE_CONTEXT(ctx);
  Renderer& r = shared_renderer(*ctx, Precision::Double);
  Scene s = shadow_scene(Lighting::Point);
  s.params.light_sigma = 1e-3;
  s.params.light_gamma = 1e-2;
  ASSERT_NO_THROW(r.render(s));
  const Image want = penumbra::reference::shadow_map(s, 0);
  expect_close(r.shadow_maps().at(0), want, 1e-9, true, "σ_L, γ_L map");
  Scene d = s;
  d.params.light_sigma = d.params.light_gamma = 0;
  EXPECT_GT(max_error(penumbra::reference::shadow_map(d, 0), want, true, nullptr), 1e-4)
      << "σ_L, γ_L change the map";
  expect_matches_reference(r, s, kDoubleTol, "σ_L, γ_L render");
}

// ---------------------------------------------------------------------------------------------
// (b) Kernels against the reference.

class ShadowKernels : public ::testing::TestWithParam<Method> {};

TEST_P(ShadowKernels, DoubleMatchesReference) {
  REQUIRE_CONTEXT(ctx);
  Renderer& r = shared_renderer(*ctx, Precision::Double);
  double worst = 0;
  for (const auto& [name, scene] : comparison_scenes(GetParam()))
    worst =
        std::max(worst, expect_matches_reference(r, scene, kDoubleTol,
                                                 std::string(name_of(GetParam())) + " " + name));
  std::cout << "[shadow] double " << name_of(GetParam()) << ": max colour error " << worst
            << std::endl;
}

TEST_P(ShadowKernels, FloatMatchesReference) {
  REQUIRE_CONTEXT(ctx);
  Renderer& r = shared_renderer(*ctx, Precision::Float);
  double worst = 0;
  for (const auto& [name, scene] : comparison_scenes(GetParam()))
    worst =
        std::max(worst, expect_matches_reference(r, scene, kFloatTol,
                                                 std::string(name_of(GetParam())) + " " + name));
  std::cout << "[shadow] float " << name_of(GetParam()) << ": max colour error " << worst
            << std::endl;
}

INSTANTIATE_TEST_SUITE_P(Shadow, ShadowKernels,
                         ::testing::Values(Method::Truncated, Method::Exact, Method::Gemm),
                         [](const auto& info) { return std::string(name_of(info.param)); });

// The shadows show in these comparisons: hard shadows change the image against none.
TEST(ShadowDouble, ShadowsChangeTheImage) {
  REQUIRE_CONTEXT(ctx);
  for (const auto& [name, scene] : comparison_scenes(Method::Truncated)) {
    Scene none = scene;
    none.params.shadows = Shadows::None;
    const double diff = max_error(penumbra::reference::render(scene, 0).color,
                                  penumbra::reference::render(none, 0).color, false, nullptr);
    EXPECT_GT(diff, 0.2) << name << ": the shadow does not show";
  }
}

// ---------------------------------------------------------------------------------------------
// (c), (d) Sampling methods.

// Exact on penumbra's kernels (exact backend `kernels`, named here so that the tuning's `auto`
// cannot pick CLBlast for both) and gemm (exact backend `clblast`) evaluate the same sum
// v = Σ g·S / Σ g, both as Σ_i (Σ_j gy_j·S_ji)·gx_i / (Σgx·Σgy) through matrix products, in
// paper_hard_exact.cl's and CLBlast's different orders. In double they agree to rounding (~1e-16
// relative in v, times 1/γ_s = 25 in the logit): 1e-11. In float the reordering costs ~1e-7
// relative in v (≈ 5e-7 absolute at depth ≈ 5), ≈ 1e-5 in the logit after 1/γ_s, so ≤ s(1 − s)·1e-5
// ≤ 3e-6 of a light's colour, besides the raster's own float rounding being the same in both: 1e-5.
// The comparison scenes, and the first again with a 40² map: no multiple of paper_hard_exact.cl's
// column blocks (MM_VW, 2·MM_VW), so that the products' ragged edges are compared too.
std::vector<NamedScene> exact_scenes() {
  std::vector<NamedScene> scenes = comparison_scenes(Method::Exact);
  NamedScene ragged = scenes.front();
  ragged.name += ", 40² map";
  ragged.scene.params.shadow_map_size = 40;
  scenes.push_back(ragged);
  return scenes;
}

TEST(ShadowSampling, ExactEqualsGemm) {
  REQUIRE_CONTEXT(ctx);
  for (Precision precision : {Precision::Double, Precision::Float}) {
    Renderer& r = shared_renderer(*ctx, precision);
    const double tol = precision == Precision::Double ? 1e-11 : 1e-5;
    double worst = 0;
    for (const auto& [name, scene] : exact_scenes()) {
      Scene kernels = scene, gemm = scene;
      kernels.params.exact_backend = ExactBackend::Kernels;
      set_method(gemm.params, Method::Gemm);
      std::vector<RenderOutput> a, b;
      ASSERT_NO_THROW(a = r.render(kernels)) << name;
      ASSERT_NO_THROW(b = r.render(gemm)) << name;
      for (size_t v = 0; v < a.size(); ++v) {
        worst = std::max(worst, expect_close(b[v].color, a[v].color, tol, false,
                                             name + " gemm vs exact colour"));
        expect_close(b[v].depth, a[v].depth, tol, true, name + " gemm vs exact depth");
      }
    }
    std::cout << "[shadow] exact vs gemm " << (precision == Precision::Double ? "double" : "float")
              << ": max colour difference " << worst << std::endl;
  }
}

// The bundled scene at 128² with a 256² map keeps ~12k fragments, which the exact path takes in
// two batches forward and three backward (double: 8192 and 4096 fragments each), its weight
// matrices kept zero outside each batch's nonzero weights (paper_lookups.cl, the exact sum): the
// batches agree with CLBlast's GEMM, which multiplies every weight, as one batch does.
TEST(ShadowSampling, ExactInBatchesEqualsGemm) {
  REQUIRE_CONTEXT(ctx);
  Renderer& r = shared_renderer(*ctx, Precision::Double);
  Scene kernels = penumbra::load_scene(std::string(PENUMBRA_DATA_DIR) + "/scenes/turnaround.json");
  kernels.cameras.front().width = kernels.cameras.front().height = 128;
  kernels.params.shadow_model = ShadowModel::Paper;
  kernels.params.shadows = Shadows::Hard;
  kernels.params.shadow_map_size = 256;
  set_method(kernels.params, Method::Exact);
  kernels.params.exact_backend = ExactBackend::Kernels;
  Scene gemm = kernels;
  set_method(gemm.params, Method::Gemm);
  std::vector<RenderOutput> a, b;
  ASSERT_NO_THROW(a = r.render(kernels));
  const auto weights = penumbra::random_loss_weights(kernels, 5);
  SceneGrads ga, gb;
  ASSERT_NO_THROW(ga = r.backward(kernels, weights));
  ASSERT_NO_THROW(b = r.render(gemm));
  ASSERT_NO_THROW(gb = r.backward(gemm, weights));
  expect_close(b[0].color, a[0].color, 1e-11, false, "batches vs gemm colour");
  const double scale = penumbra::max_abs_gradient(ga);
  ASSERT_GT(scale, 0);
  double worst = 0;
  for (size_t m = 0; m < ga.vertices.size(); ++m)
    for (size_t i = 0; i < ga.vertices[m].size(); ++i)
      for (int k = 0; k < 3; ++k)
        worst = std::max(worst, std::abs(ga.vertices[m][i][k] - gb.vertices[m][i][k]) / scale);
  std::cout << "[shadow] exact in batches vs gemm gradients: max difference " << worst
            << " of the largest entry" << std::endl;
  EXPECT_LE(worst, 1e-10);
}

// Their gradients are the same too: in double to rounding, relative to the largest entry.
TEST(ShadowSampling, ExactEqualsGemmGradients) {
  REQUIRE_CONTEXT(ctx);
  Renderer& r = shared_renderer(*ctx, Precision::Double);
  for (const auto& [name, scene] : exact_scenes()) {
    Scene kernels = scene, gemm = scene;
    kernels.params.exact_backend = ExactBackend::Kernels;
    set_method(gemm.params, Method::Gemm);
    const auto weights = penumbra::random_loss_weights(scene, 13);
    SceneGrads a, b;
    ASSERT_NO_THROW(r.render(kernels)) << name;
    ASSERT_NO_THROW(a = r.backward(kernels, weights)) << name;
    ASSERT_NO_THROW(r.render(gemm)) << name;
    ASSERT_NO_THROW(b = r.backward(gemm, weights)) << name;
    const double scale = penumbra::max_abs_gradient(a);
    ASSERT_GT(scale, 0) << name;
    double worst = 0;
    const std::string label = name;  // a lambda may not capture a structured binding (C++17)
    auto compare = [&](const std::vector<glm::dvec3>& x, const std::vector<glm::dvec3>& y) {
      ASSERT_EQ(x.size(), y.size()) << label;
      for (size_t i = 0; i < x.size(); ++i)
        for (int k = 0; k < 3; ++k) worst = std::max(worst, std::abs(x[i][k] - y[i][k]) / scale);
    };
    for (size_t m = 0; m < a.vertices.size(); ++m) compare(a.vertices[m], b.vertices[m]);
    compare(a.light_position, b.light_position);
    compare(a.light_color, b.light_color);
    std::cout << "[shadow] exact vs gemm gradients, " << name << ": max difference " << worst
              << " of the largest entry" << std::endl;
    EXPECT_LE(worst, 1e-10) << name;
  }
}

// Truncation error shrinks with ε_λ: g' = g − ε_λ inside R = sqrt(2σ_s·ln(1/ε_λ)) differs from g
// by ε_λ per texel plus the tail beyond R, both → 0 with ε_λ.
TEST(ShadowSampling, TruncatedApproachesExact) {
  REQUIRE_CONTEXT(ctx);
  Renderer& r = shared_renderer(*ctx, Precision::Double);
  for (const auto& [name, scene] : comparison_scenes(Method::Exact)) {
    std::vector<RenderOutput> exact;
    ASSERT_NO_THROW(exact = r.render(scene)) << name;
    std::vector<double> diffs;
    std::ostringstream line;
    for (double eps : {1e-1, 1e-2, 1e-4, 1e-8}) {
      Scene t = scene;
      set_method(t.params, Method::Truncated);
      t.params.lambda_eps = eps;
      std::vector<RenderOutput> got;
      ASSERT_NO_THROW(got = r.render(t)) << name;
      diffs.push_back(max_colour_difference(got, exact));
      line << " ε_λ=" << eps << ": " << diffs.back();
    }
    std::cout << "[shadow] truncated vs exact, " << name << ":" << line.str() << std::endl;
    EXPECT_GT(diffs[0], 1e-3) << name << ": ε_λ = 0.1 should visibly differ";
    for (size_t i = 1; i < diffs.size(); ++i)
      EXPECT_LT(diffs[i], diffs[i - 1]) << name << " step " << i << line.str();
    EXPECT_LT(diffs.back(), 1e-5) << name << line.str();
  }
}

// The exact sums visit only nonzero_part of the whole map (common/window.clh), on the ground
// that its weights are exactly 0 beyond it, which is what keeps them bit for bit the whole map's
// sums. Checked for the axis weights as the kernels form them (scalar, and on ROW lanes), in
// float and double, for σ from 0.25 to 400 texel² and 1e30 (whose radius no int holds) and μ
// anywhere in a 256² map (200 centres each): every nonzero weight lies inside, and for σ ≤ 8
// the part is narrower than the map.
TEST(ShadowSampling, ExactSumsLeaveOutOnlyZeroWeights) {
  REQUIRE_CONTEXT(ctx);
  const std::string kernel = R"(
__kernel void outside(int Wm, int Hm, real sigma, __global const real* mus, __global int* out) {
  int k = get_global_id(0);
  real2 mu = (real2)(mus[2 * k], mus[2 * k + 1]);
  Window w = nonzero_part(sampling_window(mu, 0, 0, Wm, Hm), mu, sigma);
  int bad = 0;
  for (int i0 = 0; i0 < max(Wm, Hm); i0 += ROW) {
    real t[ROW];
    vstoreR(axis_weight((real)i0 + LANER - mu.x, sigma), 0, t);
    for (int l = 0; l < ROW && i0 + l < Wm; ++l)
      bad += (t[l] != 0 || axis_weight((real)(i0 + l) - mu.x, sigma) != 0) &&
             (i0 + l < w.x0 || i0 + l > w.x1);
    vstoreR(axis_weight((real)i0 + LANER - mu.y, sigma), 0, t);
    for (int l = 0; l < ROW && i0 + l < Hm; ++l)
      bad += (t[l] != 0 || axis_weight((real)(i0 + l) - mu.y, sigma) != 0) &&
             (i0 + l < w.y0 || i0 + l > w.y1);
  }
  out[2 * k] = bad;
  out[2 * k + 1] = max(w.x1 - w.x0, w.y1 - w.y0) + 1;
})";
  const std::string source = Context::kernel_source("common/window.clh") + kernel;
  const int side = 256, n = 200;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> at(-0.5, side - 0.5);
  std::vector<double> mus(2 * n);
  for (double& m : mus) m = at(rng);
  for (Precision p : {Precision::Float, Precision::Double}) {
    const bool dbl = p == Precision::Double;
    cl::Program program(ctx->cl_context(), source);
    program.build(Context::build_options(std::string("-DSAMPLING_EXACT -DROW=16") +
                                         (dbl ? " -DPENUMBRA_DOUBLE" : ""))
                      .c_str());
    cl::Kernel k(program, "outside");
    const size_t size = dbl ? sizeof(double) : sizeof(float);
    std::vector<float> musf(mus.begin(), mus.end());
    cl::Buffer in(ctx->cl_context(), CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, 2 * n * size,
                  dbl ? static_cast<void*>(mus.data()) : static_cast<void*>(musf.data()));
    cl::Buffer out(ctx->cl_context(), CL_MEM_WRITE_ONLY, 2 * n * sizeof(int));
    for (double sigma : {0.25, 2.0, 8.0, 400.0, 1e30}) {
      const std::string label =
          std::string(dbl ? "double" : "float") + ", σ " + std::to_string(sigma);
      k.setArg(0, side);
      k.setArg(1, side);
      if (dbl)
        k.setArg(2, sigma);
      else
        k.setArg(2, float(sigma));
      k.setArg(3, in);
      k.setArg(4, out);
      ctx->queue().enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(n));
      std::vector<int> got(2 * n);
      ctx->queue().enqueueReadBuffer(out, CL_TRUE, 0, got.size() * sizeof(int), got.data());
      int bad = 0, widest = 0;
      for (int i = 0; i < n; ++i) bad += got[2 * i], widest = std::max(widest, got[2 * i + 1]);
      EXPECT_EQ(bad, 0) << label << ": nonzero weights outside the part the sums visit";
      if (sigma <= 8) {
        EXPECT_LT(widest, side) << label << ": the part is the whole map";
      }
    }
  }
}

// ---------------------------------------------------------------------------------------------
// (e) Gradients.

std::vector<GradCase> gradient_cases(Method sampling) {
  return {
      {"point", shadow_scene(Lighting::Point, sampling), 3},
      {"directional (orthographic camera)", shadow_scene(Lighting::Directional, sampling, true), 5},
      {"two lights", shadow_scene(Lighting::Two, sampling), 7}};
}

class ShadowGradCheck : public ::testing::TestWithParam<Method> {};

TEST_P(ShadowGradCheck, Double) {
  REQUIRE_CONTEXT(ctx);
  Renderer& r = shared_renderer(*ctx, Precision::Double);
  int light_positions = 0;
  for (auto& [name, scene, seed] : gradient_cases(GetParam())) {
    penumbra::fit_light_frusta(scene);  // fixed frusta: gradients and differences agree
    for (const Light& l : scene.lights) ASSERT_TRUE(l.frustum.fitted);
    GradCheckOptions options;
    options.samples = 40;
    options.seed = seed;
    GradCheckResult result;
    ASSERT_NO_THROW(result = penumbra::gradcheck(r, scene, options)) << name;
    const std::string tag = std::string(name_of(GetParam())) + " " + name;
    std::cout << "[shadow gradcheck] " << tag << ": checked=" << result.checked
              << " failed=" << result.failed << " failure_fraction=" << result.failure_fraction()
              << " max_rel_err=" << result.max_rel_err << std::endl;
    EXPECT_TRUE(result.passed()) << tag << "\n" << describe(result);
    EXPECT_GE(result.checked, 30) << tag;
    // Occluder (mesh 0) and receiver (mesh 1) vertices are checked; so is the position of every
    // point light scene's light (directional lights have none to check).
    EXPECT_TRUE(has_entry(result, "mesh0.v")) << tag << "\n" << describe(result);
    EXPECT_TRUE(has_entry(result, "mesh1.v")) << tag << "\n" << describe(result);
    bool point = false;
    for (const Light& l : scene.lights) point |= l.type == LightType::Point;
    if (point) {
      EXPECT_TRUE(has_entry(result, "light0.position")) << tag << "\n" << describe(result);
      ++light_positions;
    }
  }
  EXPECT_GE(light_positions, 2);
}

// The same check with a loss that sees only the ground where the shadow falls (colour only;
// pixels where the occluder shows are left out): occluder vertices reach this loss only
// through the shadow map S, so the light pass's backward (and μ, d of the receivers) is what
// is checked here.
TEST_P(ShadowGradCheck, ThroughTheMapOnly) {
  REQUIRE_CONTEXT(ctx);
  Renderer& r = shared_renderer(*ctx, Precision::Double);
  for (auto& [name, scene, seed] : gradient_cases(GetParam())) {
    const std::string tag = std::string(name_of(GetParam())) + " " + name;
    // Ground pixels: the depth equals that of the ground alone. Shadowed: hard ≠ none.
    Scene ground_only = scene, none = scene;
    ground_only.meshes = {scene.meshes[1]};
    ground_only.params.shadows = none.params.shadows = Shadows::None;
    const RenderOutput g = penumbra::reference::render(ground_only, 0);
    const RenderOutput h = penumbra::reference::render(scene, 0);
    const RenderOutput n = penumbra::reference::render(none, 0);
    std::vector<penumbra::OutputGrads> weights(1);
    weights[0].color = Image(h.color.width, h.color.height, 3);
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> normal;
    int pixels = 0;
    for (int y = 0; y < h.color.height; ++y)
      for (int x = 0; x < h.color.width; ++x) {
        const bool ground =
            std::abs(h.depth.at(x, y) - g.depth.at(x, y)) <= 1e-9 * g.depth.at(x, y);
        double shadow = 0;
        for (int c = 0; c < 3; ++c)
          shadow = std::max(shadow, std::abs(h.color.at(x, y, c) - n.color.at(x, y, c)));
        if (!ground || shadow < 0.05) continue;  // lit ground differs by only (1 − s) ≈ 1%
        ++pixels;
        for (int c = 0; c < 3; ++c) weights[0].color.at(x, y, c) = normal(rng);
      }
    ASSERT_GE(pixels, 20) << tag << ": too few shadowed ground pixels";
    ASSERT_NO_THROW(r.render(scene)) << tag;
    SceneGrads analytic;
    ASSERT_NO_THROW(analytic = r.backward(scene, weights)) << tag;
    GradCheckOptions options;
    options.samples = 40;
    options.seed = seed + 100;
    GradCheckResult result;
    ASSERT_NO_THROW(
        result = penumbra::compare_with_finite_differences(r, scene, weights, analytic, options))
        << tag;
    std::cout << "[shadow gradcheck] " << tag << ", shadow region only (" << pixels
              << " px): checked=" << result.checked << " failed=" << result.failed
              << " failure_fraction=" << result.failure_fraction()
              << " max_rel_err=" << result.max_rel_err << std::endl;
    EXPECT_TRUE(result.passed()) << tag << "\n" << describe(result);
    // The occluder's vertices matter to this loss (through S), and some were compared at a
    // size well above the absolute floor.
    double occluder = 0;
    for (const auto& v : analytic.vertices[0])
      occluder = std::max({occluder, std::abs(v.x), std::abs(v.y), std::abs(v.z)});
    EXPECT_GT(occluder, 1e-2 * penumbra::max_abs_gradient(analytic)) << tag;
    int occluder_entries = 0;
    for (const auto& e : result.entries)
      if (e.name.compare(0, 7, "mesh0.v") == 0 && std::abs(e.numeric) > 10 * result.atol)
        ++occluder_entries;
    EXPECT_GE(occluder_entries, 1) << tag << "\n" << describe(result);
  }
}

INSTANTIATE_TEST_SUITE_P(Shadow, ShadowGradCheck,
                         ::testing::Values(Method::Truncated, Method::Exact, Method::Gemm),
                         [](const auto& info) { return std::string(name_of(info.param)); });

// ---------------------------------------------------------------------------------------------
// (f) A visible shadow.

// The light 5 units straight above a ball of radius 0.5 whose bottom is 0.5 above the ground:
// the ground point below the ball's centre lies in its umbra (shadow radius ≈ 0.6), a ground
// point 1.7 units away is lit.
TEST(ShadowVisible, GroundUnderOccluderIsDark) {
  REQUIRE_CONTEXT(ctx);
  Renderer& r = shared_renderer(*ctx, Precision::Double);
  for (Method sampling : {Method::Truncated, Method::Exact, Method::Gemm}) {
    const Scene hard = shadow_scene(Lighting::Overhead, sampling);
    Scene none = hard;
    none.params.shadows = Shadows::None;
    std::vector<RenderOutput> h, n;
    ASSERT_NO_THROW(h = r.render(hard));
    ASSERT_NO_THROW(n = r.render(none));
    const RenderOutput want = penumbra::reference::render(hard, 0);
    const auto dark = pixel_of(hard.cameras[0], {0.1, 0.0, 0.15});
    const auto lit = pixel_of(hard.cameras[0], {1.3, 0.0, 1.1});
    const double dark_h = luminance(h[0].color, dark), lit_h = luminance(h[0].color, lit);
    const double dark_n = luminance(n[0].color, dark), lit_n = luminance(n[0].color, lit);
    std::cout << "[shadow] visible (" << name_of(sampling) << "): shadowed pixel " << dark_h
              << " (unshadowed " << dark_n << "), lit pixel " << lit_h << " (unshadowed " << lit_n
              << ")" << std::endl;
    // In the umbra only the ambient term remains (≈ 0.2·0.7 = 0.14); lit ground ≈ 0.7·(0.2 + cos).
    EXPECT_LT(dark_h, 0.2) << name_of(sampling);
    EXPECT_GT(lit_h, dark_h + 0.4) << name_of(sampling);
    // Without shadows the same pixel is lit, and the lit pixel barely changes with them.
    EXPECT_GT(dark_n, dark_h + 0.5) << name_of(sampling);
    EXPECT_NEAR(lit_h, lit_n, 0.02) << name_of(sampling);
    // The kernels agree with the reference at both pixels.
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(h[0].color.at(dark.first, dark.second, c),
                  want.color.at(dark.first, dark.second, c), 1e-9);
      EXPECT_NEAR(h[0].color.at(lit.first, lit.second, c), want.color.at(lit.first, lit.second, c),
                  1e-9);
    }
  }
}

// ---------------------------------------------------------------------------------------------
// (g) Determinism.

TEST(ShadowDeterminism, BackwardIsBitIdentical) {
  REQUIRE_CONTEXT(ctx);
  for (Precision precision : {Precision::Double, Precision::Float}) {
    Renderer& r = shared_renderer(*ctx, precision);
    for (Method sampling : {Method::Truncated, Method::Gemm, Method::Exact}) {
      const Scene scene = shadow_scene(Lighting::Two, sampling);
      const auto weights = penumbra::random_loss_weights(scene, 11);
      const std::string tag =
          std::string(name_of(sampling)) + (precision == Precision::Double ? " double" : " float");
      ASSERT_NO_THROW(r.render(scene)) << tag;
      SceneGrads a, b, c;
      ASSERT_NO_THROW(a = r.backward(scene, weights)) << tag;
      ASSERT_NO_THROW(b = r.backward(scene, weights)) << tag;
      expect_identical(a, b, tag + " (two backward calls)");
      ASSERT_NO_THROW(r.render(scene)) << tag;
      ASSERT_NO_THROW(c = r.backward(scene, weights)) << tag;
      expect_identical(a, c, tag + " (render again)");
      // The gradient reaches the light and both meshes.
      EXPECT_GT(penumbra::max_abs_gradient(a), 0) << tag;
      double lp = 0;
      for (const auto& v : a.light_position) lp = std::max(lp, glm::length(v));
      EXPECT_GT(lp, 0) << tag;
    }
  }
}

// A renderer keeps the exact lookups' weights from render to render (ExactWeights, ops.hpp):
// through scenes with fewer fragments (the kept rows reused, the rows past the batch left as
// they were), another map size (new weights) and back, it renders and differentiates as a
// fresh one does, bit for bit.
TEST(ShadowDeterminism, KeptExactWeightsGiveAFreshRenderersBits) {
  REQUIRE_CONTEXT(ctx);
  for (Precision precision : {Precision::Double, Precision::Float}) {
    Scene base = shadow_scene(Lighting::Two, Method::Exact);
    Scene shrunk = base;  // fewer fragments
    for (Mesh& m : shrunk.meshes)
      for (dvec3& v : m.vertices) v *= 0.8;
    Scene small_map = base;
    small_map.params.shadow_map_size = 32;
    Renderer kept(*ctx, precision);
    int step = 0;
    for (const Scene* s : {&base, &shrunk, &small_map, &base, &shrunk}) {
      const std::string what = "scene " + std::to_string(step++) +
                               (precision == Precision::Double ? " double" : " float");
      const auto weights = penumbra::random_loss_weights(*s, 7);
      std::vector<RenderOutput> a, b;
      SceneGrads ga, gb;
      ASSERT_NO_THROW(a = kept.render(*s)) << what;
      ASSERT_NO_THROW(ga = kept.backward(*s, weights)) << what;
      Renderer fresh(*ctx, precision);
      ASSERT_NO_THROW(b = fresh.render(*s)) << what;
      ASSERT_NO_THROW(gb = fresh.backward(*s, weights)) << what;
      for (size_t c = 0; c < a.size(); ++c) EXPECT_EQ(a[c].color.data, b[c].color.data) << what;
      expect_identical(ga, gb, what);
    }
  }
}

// ---------------------------------------------------------------------------------------------
// (h) Fragments facing away from the light.

// shadow_sample gives a fragment in the map that faces away from the light (n·l ≤ 0) s = 1
// without a lookup where σ_s and ε_λ assure Σg' > 0 there, and exact_weights gives it a row of
// zeros (s = 1, no gradient): kernels that look every fragment up give the same images and
// gradients bit for bit, truncated at σ_s and ε_λ that skip and at ones that do not
// (σ_s = ε_λ = 0.05: the texel nearest μ may weigh less than ε_λ, Σg' may be 0), exact on
// penumbra's products and on CLBlast's; kernels that store NaN there give NaN colours (s·0),
// so the skip happens in these scenes.
constexpr const char* kFacingStore = "    rec_light[r * nl + light].w = 1;";
constexpr const char* kExactNorm = "  norm[k] = (real4)(sx.x, sy.x, looked_up, 0);";

TEST(ShadowFacing, SkippedLookupsChangeNoBit) {
  REQUIRE_CONTEXT(ctx);
  const std::string always = kernels_looking_up_every_fragment("penumbra_shadow_look_up_all");
  for (Precision p : {Precision::Float, Precision::Double})
    for (Method method : {Method::Truncated, Method::Exact, Method::Gemm})
      for (const NamedScene& named : comparison_scenes(method))
        for (const double sigma_eps : {0.0, 0.05}) {  // 0: the scene's σ_s = 2, ε_λ = 1e-3
          if (sigma_eps > 0 && method != Method::Truncated) continue;
          Scene scene = named.scene;
          if (sigma_eps > 0) scene.params.sigma_s = scene.params.lambda_eps = sigma_eps;
          expect_skip_changes_no_bit(always, scene, p,
                                     named.name + " " + name_of(method) + " " + name_of(p) +
                                         (sigma_eps > 0 ? " σ_s = ε_λ = 0.05" : ""));
        }
}

TEST(ShadowFacing, LookupsSkipped) {
  REQUIRE_CONTEXT(ctx);
  const std::string poisoned =
      patched_kernels("penumbra_shadow_facing_nan", "paper_lookups.cl", kFacingStore,
                      "    rec_light[r * nl + light].w = NAN;");
  expect_skip_taken(poisoned, shadow_scene(Lighting::Point), "point");
  const std::string exact = patched_kernels(  // s = NaN for the rows left out as facing away
      "penumbra_shadow_facing_exact_nan", "paper_lookups.cl", kExactNorm,
      std::string(kExactNorm) + "\n  if (inside_map(x.xy, Wm, Hm) && !looked_up) norm[k].z = NAN;");
  for (Method method : {Method::Exact, Method::Gemm})
    expect_skip_taken(exact, shadow_scene(Lighting::Point, method), name_of(method));
}

// ---------------------------------------------------------------------------------------------
// (i) The gathers' texel buckets.

// shadow_boxes (and for the accurate model's passes pcf_boxes), through texel_box, bucket only
// the fragments with a gradient to pass to the maps (a nonzero gather scale). Under a loss that
// leaves the image's left half out (and so the fragments there, besides those facing away from
// a light), kernels that bucket every fragment in the map give the same images and gradients
// bit for bit, for both models and hard and soft shadows. And the buckets leave fragments out:
// with a soft_gather that turns NaN on meeting a fragment without a gradient, the gradients
// stay finite with the project's buckets and are NaN with every fragment bucketed.
const KernelEdit kBucketEvery{"common/window.clh", "!inside_map(mu, Wm, Hm) || g == 0)",
                              "!inside_map(mu, Wm, Hm))"};

Scene bucket_scene(Lighting lighting, Shadows shadows, ShadowModel model) {
  Scene s = shadow_scene(lighting);
  for (Light& l : s.lights) l.size = l.type == LightType::Point ? 1.0 : 0.6;
  shadow_params(s, shadows, Method::Truncated, model);
  fit_light_frusta(s);
  return s;
}

std::vector<OutputGrads> right_half_loss(const Scene& scene) {
  std::vector<OutputGrads> weights = random_loss_weights(scene, 11);
  for (OutputGrads& w : weights)
    for (Image* im : {&w.color, &w.silhouette, &w.depth}) clear_left_half(*im);
  return weights;
}

TEST(ShadowBuckets, FragmentsWithoutGradientLeftOutChangeNoBit) {
  REQUIRE_CONTEXT(ctx);
  const std::string every = patched_kernels("penumbra_bucket_every", {kBucketEvery});
  for (Precision p : {Precision::Float, Precision::Double})
    for (Lighting lighting : {Lighting::Point, Lighting::Two})
      for (ShadowModel model : {ShadowModel::Paper, ShadowModel::Accurate})
        for (Shadows sh : {Shadows::Hard, Shadows::Soft}) {
          const Scene scene = bucket_scene(lighting, sh, model);
          const std::string what = std::string(lighting == Lighting::Point ? "point" : "two") +
                                   (model == ShadowModel::Paper ? " paper " : " accurate ") +
                                   (sh == Shadows::Hard ? "hard " : "soft ") + name_of(p);
          const auto weights = right_half_loss(scene);
          const Results a = results_with("", scene, p, weights),
                        b = results_with(every, scene, p, weights);
          EXPECT_TRUE(same_images(a.images, b.images)) << what;
          expect_identical(a.grads, b.grads, what + ": buckets of fragments with gradients or all",
                           true);
        }
}

TEST(ShadowBuckets, FragmentsWithoutGradientLeftOut) {
  REQUIRE_CONTEXT(ctx);
  const KernelEdit poison{"paper_lookups.cl", "    if (k == 0) continue;",
                          "    if (k == 0) {\n      accS[0] = NAN;\n      continue;\n    }"};
  const std::string poisoned = patched_kernels("penumbra_bucket_nan", {poison}),
                    every = patched_kernels("penumbra_bucket_every_nan", {poison, kBucketEvery});
  const Scene scene = bucket_scene(Lighting::Point, Shadows::Soft, ShadowModel::Paper);
  const auto weights = right_half_loss(scene);
  EXPECT_TRUE(all_finite(grads_with(poisoned, scene, Precision::Float, weights)));
  EXPECT_FALSE(all_finite(grads_with(every, scene, Precision::Float, weights)))
      << "no fragment without a gradient was in the buckets";
}

}  // namespace
