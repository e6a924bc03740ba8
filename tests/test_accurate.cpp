// The accurate shadow model (kernels/accurate_lookups.cl, docs/shadows.md): percentage-closer
// filtering of a smooth-step depth compare with the receiver-plane bias, a blocker search for soft
// shadows (PCSS), and light frusta fitted tightly to what can cast a shadow; on small scenes built
// here (an icosphere above a ground grid, lit by point and directional lights).
//
//   PcfKernels.*      colours against the reference (double ~1e-9, float with a stated bound),
//                     hard and soft, truncated and exact sampling
//   PcfGradCheck.*    backward vs finite differences in double (light sizes included for soft
//                     shadows), and in float within the documented tolerance
//   PcfLit.*          a lit receiver gets s = 1 exactly: lit ground matches the unshadowed render
//   PcfPenumbra.*     the soft penumbra straddles the hard edge (the shadow's darkness summed over
//                     the ground stays that of the hard shadow) and widens with D_L
//   PcfFrustum.*      the fitted frustum is tight around the occluder; a ground under everything
//                     casts no shadow
//   PcfSearch.*       the blocker search's stride, and the scenes above search with strides > 1
//   PcfGemm.*         gemm sampling is refused for the accurate model
//   PcfDeterminism.*  two backward calls give bit-identical gradients
//   PcfFlat.*         the lookups' answer without sums where a window is flat (window_flat:
//                     forward filter and search, backward) changes no bit, and happens
//   PcfFacing.*       pcf_sample's skip of fragments facing away from the light changes no bit
//                     of an image or gradient, and happens
// A missing OpenCL device fails these tests; it never skips them.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <iostream>
#include <string>
#include <tuple>
#include <vector>

#include "penumbra/context.hpp"
#include "penumbra/error.hpp"
#include "penumbra/gradcheck.hpp"
#include "penumbra/reference.hpp"
#include "penumbra/renderer.hpp"
#include "penumbra/scene.hpp"
#include "scenes.hpp"

namespace {

using glm::dvec3;
using namespace penumbra;
using namespace penumbra_tests;

enum class Layout { Point, Directional, Two, Wide };
constexpr Layout kLayouts[] = {Layout::Point, Layout::Directional, Layout::Two, Layout::Wide};

// An icosphere of radius 0.5 centred 1.0 above a 4×4 ground grid over [−2, 2]², with lights of
// size comparable to the occluder's diameter, or (Wide) five times it over a 63² map (odd: the
// search map ends on a partial stride), whose blocker search takes every second texel; accurate
// model, 32² maps (shadow_params).
Scene pcf_scene(Layout layout, Shadows shadows, Sampling sampling) {
  Scene s;
  s.meshes = {icosphere({0.0, 1.0, 0.0}, 0.5), ground(2.0, 4)};
  s.cameras = {front_camera(layout == Layout::Directional)};
  switch (layout) {
    case Layout::Point:
      s.lights = {point_light({0.9, 5.0, 0.7}, {0.9, 0.85, 0.8}, 1.0)};
      break;
    case Layout::Wide:
      s.lights = {point_light({0.9, 5.0, 0.7}, {0.9, 0.85, 0.8}, 2.5)};
      break;
    case Layout::Directional:
      s.lights = {directional_light({-0.35, -1.0, -0.25}, {0.85, 0.9, 0.8}, 0.15)};
      break;
    case Layout::Two:
      s.lights = {point_light({-1.2, 4.5, 0.8}, {0.6, 0.55, 0.5}, 1.0),
                  directional_light({0.3, -1.0, -0.4}, {0.35, 0.4, 0.45}, 0.1)};
      break;
  }
  shadow_params(s, shadows, sampling, ShadowModel::Accurate);
  if (layout == Layout::Wide) s.params.shadow_map_size = 63;
  fit_light_frusta(s);
  return s;
}

const char* name_of(Shadows s) { return s == Shadows::Hard ? "hard" : "soft"; }
const char* name_of(Layout l) {
  switch (l) {
    case Layout::Point:
      return "point";
    case Layout::Directional:
      return "directional";
    case Layout::Two:
      return "two lights";
    case Layout::Wide:
      return "wide point";
  }
  return "?";
}

using Case = std::tuple<Shadows, Sampling>;
class PcfCase : public ::testing::TestWithParam<Case> {};

std::string case_name(const Case& c) {
  return std::string(name_of(std::get<0>(c))) + " " + penumbra_tests::name_of(std::get<1>(c));
}

// Double: the same formulas in the same precision, summed in another order: 1e-9 (colour,
// silhouette; depth relative 1e-6). Float: the raster's bounds of test_raster (silhouette 1e-4,
// depth 1e-5 relative); the compare divides depth rounding (~5e-7 at depths 3–9) by 4γ_s = 0.16
// and the blocker depth moves σ, so a colour moves by at most ~1e-4.
constexpr Tolerance kDoubleTol{1e-9, 1e-9, 1e-6};
constexpr Tolerance kFloatTol{1e-4, 1e-4, 1e-5};

TEST_P(PcfCase, KernelsMatchReference) {
  REQUIRE_CONTEXT(ctx);
  const auto [shadows, sampling] = GetParam();
  for (Precision precision : {Precision::Double, Precision::Float}) {
    Renderer& r = shared_renderer(*ctx, precision);
    for (Layout layout : kLayouts) {
      const Scene scene = pcf_scene(layout, shadows, sampling);
      const Tolerance tol = precision == Precision::Double ? kDoubleTol : kFloatTol;
      const std::string tag =
          case_name(GetParam()) + " " + name_of(layout) + " " + penumbra_tests::name_of(precision);
      const double worst = expect_matches_reference(r, scene, tol, tag);
      std::cout << "[pcf reference] " << tag << ": max colour error " << worst << std::endl;
    }
  }
}

TEST_P(PcfCase, GradCheckDouble) {
  REQUIRE_CONTEXT(ctx);
  const auto [shadows, sampling] = GetParam();
  Renderer& r = shared_renderer(*ctx, Precision::Double);
  for (Layout layout : kLayouts) {
    const Scene scene = pcf_scene(layout, shadows, sampling);
    GradCheckOptions options;
    options.samples = sampling == Sampling::Exact ? 20 : 30;
    options.seed = 11 + int(layout);
    GradCheckResult result;
    ASSERT_NO_THROW(result = gradcheck(r, scene, options));
    const std::string tag = case_name(GetParam()) + " " + name_of(layout);
    std::cout << "[pcf gradcheck] " << tag << ": checked=" << result.checked
              << " failed=" << result.failed << " failure_fraction=" << result.failure_fraction()
              << " max_rel_err=" << result.max_rel_err << std::endl;
    EXPECT_TRUE(result.passed()) << tag << "\n" << describe(result);
    for (size_t l = 0; l < scene.lights.size(); ++l) {
      const std::string light = "light" + std::to_string(l);
      EXPECT_TRUE(has_entry(
          result, light + (scene.lights[l].type == LightType::Point ? ".position" : ".direction")))
          << tag;
      if (shadows == Shadows::Soft) {
        EXPECT_TRUE(has_entry(result, light + ".size")) << tag;
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Pcf, PcfCase,
                         ::testing::Combine(::testing::Values(Shadows::Hard, Shadows::Soft),
                                            ::testing::Values(Sampling::Truncated,
                                                              Sampling::Exact)));

// Float gradients against double differences, within the documented float tolerance.
TEST(PcfGradCheck, FloatWithinTolerance) {
  REQUIRE_CONTEXT(ctx);
  for (Shadows shadows : {Shadows::Hard, Shadows::Soft}) {
    const Scene scene = pcf_scene(Layout::Point, shadows, Sampling::Truncated);
    GradCheckOptions options;
    options.samples = 30;
    options.seed = 5;
    options.precision = Precision::Float;
    GradCheckResult result;
    ASSERT_NO_THROW(result = gradcheck(*ctx, scene, options));
    std::cout << "[pcf gradcheck float] " << name_of(shadows) << ": failed=" << result.failed << "/"
              << result.checked << " max_rel_err=" << result.max_rel_err << std::endl;
    EXPECT_TRUE(result.passed()) << name_of(shadows) << "\n" << describe(result);
  }
}

// Ground pixels whose colour has no shadow in it: the unshadowed render equals the hard and
// the soft render to float rounding wherever the soft shadow leaves the ground fully lit (s = 1
// exactly), and every shadowed pixel is darker, never lighter.
TEST(PcfLit, LitReceiversAreFullyLit) {
  REQUIRE_CONTEXT(ctx);
  Renderer& r = shared_renderer(*ctx, Precision::Double);
  Scene none = pcf_scene(Layout::Point, Shadows::Soft, Sampling::Truncated);
  none.params.shadows = Shadows::None;
  const RenderOutput plain = r.render(none)[0];
  for (Shadows shadows : {Shadows::Hard, Shadows::Soft}) {
    const RenderOutput got = r.render(pcf_scene(Layout::Point, shadows, Sampling::Truncated))[0];
    int lit = 0, darker = 0;
    for (int y = 0; y < plain.color.height; ++y)
      for (int x = 0; x < plain.color.width; ++x) {
        const double a = plain.color.at(x, y, 1), b = got.color.at(x, y, 1);
        EXPECT_LE(b, a + 1e-12) << name_of(shadows) << " pixel " << x << "," << y;
        if (std::abs(a - b) <= 1e-12)
          ++lit;
        else
          ++darker;
      }
    const int pixels = plain.color.width * plain.color.height;
    EXPECT_GT(lit, pixels / 2) << name_of(shadows) << ": most of the ground is lit exactly";
    EXPECT_GT(darker, 20) << name_of(shadows) << ": the occluder casts a shadow";
  }
}

// Σ over the image of (unshadowed − shadowed) green: the darkness a shadow takes away.
double darkness(Renderer& r, const Scene& scene) {
  Scene none = scene;
  none.params.shadows = Shadows::None;
  const Image a = r.render(none)[0].color, b = r.render(scene)[0].color;
  double sum = 0;
  for (int y = 0; y < a.height; ++y)
    for (int x = 0; x < a.width; ++x) sum += a.at(x, y, 1) - b.at(x, y, 1);
  return sum;
}

// A physical penumbra straddles the hard edge: as much light enters the umbra's rim as leaves
// the outer penumbra, so the total darkness stays within 15 % of the hard shadow's while the
// shadow's edge widens with D_L (more pixels partly shadowed). The paper model's outer-only
// penumbra adds darkness instead.
TEST(PcfPenumbra, StraddlesTheHardEdgeAndWidensWithLightSize) {
  REQUIRE_CONTEXT(ctx);
  Renderer& r = shared_renderer(*ctx, Precision::Double);
  Scene hard = pcf_scene(Layout::Point, Shadows::Hard, Sampling::Truncated);
  hard.params.shadow_map_size = 96;
  hard.cameras[0].width = hard.cameras[0].height = 96;
  hard.lights[0].frustum.fitted = false;
  fit_light_frusta(hard);
  const double dark_hard = darkness(r, hard);
  int previous_partial = 0;
  for (double size : {0.4, 1.2}) {
    Scene soft = hard;
    soft.params.shadows = Shadows::Soft;
    soft.lights[0].size = size;
    soft.lights[0].frustum.fitted = false;
    fit_light_frusta(soft);
    const double dark = darkness(r, soft);
    EXPECT_NEAR(dark / dark_hard, 1.0, 0.15) << "D_L = " << size;
    Scene none = soft;
    none.params.shadows = Shadows::None;
    const Image a = r.render(none)[0].color, b = r.render(soft)[0].color;
    int partial = 0;
    for (int y = 0; y < a.height; ++y)
      for (int x = 0; x < a.width; ++x) {
        const double t = b.at(x, y, 1) / a.at(x, y, 1);
        partial += t > 0.55 && t < 0.95;
      }
    EXPECT_GT(partial, previous_partial) << "D_L = " << size;
    previous_partial = partial;
  }
}

// The accurate model's frustum holds the occluder, not the whole ground: its cone is much
// narrower than the paper model's, which holds every vertex.
TEST(PcfFrustum, TightAroundWhatCastsShadows) {
  Scene accurate = pcf_scene(Layout::Point, Shadows::Hard, Sampling::Truncated);
  Scene paper = accurate;
  paper.params.shadow_model = ShadowModel::Paper;
  refit_light_frusta(paper);
  EXPECT_LT(accurate.lights[0].frustum.fov_deg, 0.6 * paper.lights[0].frustum.fov_deg)
      << "accurate " << accurate.lights[0].frustum.fov_deg << "°, paper "
      << paper.lights[0].frustum.fov_deg << "°";
  // Without the occluder nothing casts a shadow: the frustum falls back to every vertex.
  Scene flat = accurate;
  flat.meshes.erase(flat.meshes.begin());
  refit_light_frusta(flat);
  Scene flat_paper = paper;
  flat_paper.meshes.erase(flat_paper.meshes.begin());
  refit_light_frusta(flat_paper);
  EXPECT_NEAR(flat.lights[0].frustum.fov_deg, flat_paper.lights[0].frustum.fov_deg, 1e-9);
}

// The search's Gaussian spans two strides per standard deviation. The soft cases above compare
// with the reference and finite differences at strides above 1 (pcf_search_map, the gather's
// pass over the search map), and at 1.
TEST(PcfSearch, StrideSpansTheGaussian) {
  EXPECT_EQ(blocker_search_stride(0.5), 1);
  EXPECT_EQ(blocker_search_stride(15.9), 1);
  EXPECT_EQ(blocker_search_stride(16), 2);
  EXPECT_EQ(blocker_search_stride(49.75), 3);
  std::vector<int> strides;
  for (Layout layout : kLayouts) {
    const Scene scene = pcf_scene(layout, Shadows::Soft, Sampling::Truncated);
    for (const Light& l : scene.lights)
      strides.push_back(blocker_search_stride(blocker_search_sigma(scene.params, l)));
  }
  EXPECT_GT(*std::max_element(strides.begin(), strides.end()), 1);
  EXPECT_EQ(*std::min_element(strides.begin(), strides.end()), 1);
}

TEST(PcfGemm, Refused) {
  REQUIRE_CONTEXT(ctx);
  Renderer& r = shared_renderer(*ctx, Precision::Double);
  Scene scene = pcf_scene(Layout::Point, Shadows::Hard, Sampling::Exact);
  set_method(scene.params, Method::Gemm);
  try {
    r.render(scene);
    FAIL() << "gemm sampling of the accurate model was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("does not factor"), std::string::npos) << e.what();
  }
}

// The gathers take GATHER_ROWS rows (4 on CPUs) of ROW texels per work-item: a 31² map leaves a
// partial block at the map's bottom and right edges, whose texels must get their gradients like
// every other. Both models (the paper model keeps the ground, under every edge, in its map).
TEST(PcfGather, MapSizeNotAMultipleOfTheBlockPassesGradCheck) {
  REQUIRE_CONTEXT(ctx);
  Renderer& r = shared_renderer(*ctx, Precision::Double);
  for (ShadowModel model : {ShadowModel::Accurate, ShadowModel::Paper})
    for (Shadows shadows : {Shadows::Hard, Shadows::Soft}) {
      Scene scene = pcf_scene(Layout::Point, shadows, Sampling::Truncated);
      shadow_params(scene, shadows, Sampling::Truncated, model);
      scene.params.shadow_map_size = 31;
      for (Light& l : scene.lights) l.frustum = LightFrustum{};
      fit_light_frusta(scene);
      GradCheckOptions options;
      options.samples = 40;
      options.seed = 5;
      GradCheckResult result;
      ASSERT_NO_THROW(result = gradcheck(r, scene, options));
      const std::string tag = std::string(word(model)) + " " + name_of(shadows);
      std::cout << "[pcf gather 31²] " << tag << ": checked=" << result.checked
                << " failed=" << result.failed << " max_rel_err=" << result.max_rel_err
                << std::endl;
      // Every entry, not gradcheck's 5 % allowance: a gather that drops the partial block's last
      // row fails 2 of the 40 entries of the paper model's soft shadows.
      EXPECT_EQ(result.failed, 0) << tag << "\n" << describe(result);
    }
}

TEST(PcfDeterminism, BackwardIsBitIdentical) {
  REQUIRE_CONTEXT(ctx);
  Renderer& r = shared_renderer(*ctx, Precision::Float);
  const Scene scene = pcf_scene(Layout::Two, Shadows::Soft, Sampling::Truncated);
  const auto weights = random_loss_weights(scene, 3);
  r.render(scene);
  const SceneGrads a = r.backward(scene, weights);
  r.render(scene);
  const SceneGrads b = r.backward(scene, weights);
  expect_identical(a, b, "soft truncated");
}

// f(precision, scene, its name) for float and double, each of `layouts`, hard and soft shadows,
// truncated and exact sampling.
template <class F>
void for_each_variant(std::initializer_list<Layout> layouts, F&& f) {
  for (Precision p : {Precision::Float, Precision::Double})
    for (Layout layout : layouts)
      for (Shadows sh : {Shadows::Hard, Shadows::Soft})
        for (Sampling sa : {Sampling::Truncated, Sampling::Exact})
          f(p, pcf_scene(layout, sh, sa),
            std::string(name_of(layout)) + " " + name_of(sh) + " " + penumbra_tests::name_of(sa));
}

// Where a window is flat (window_flat) the lookups answer without its sums: the filter's s = 1,
// the search's z_b = d, and where pcf_sample marked the filter flat (over the wider window the
// backward weighs) the backward's gradients 0 (which pcf_gather then skips). Kernels
// whose window_flat finds none give the same images and gradients bit for bit; kernels that
// answer NaN at one of the three places give NaN colours or gradients, so each happens in
// these scenes.
constexpr const char* kFlatTest = "return !mask_any(slope);";

TEST(PcfFlat, AnswersWithoutSumsChangeNoBit) {
  REQUIRE_CONTEXT(ctx);
  const std::string never = patched_kernels("penumbra_pcf_never_flat", "common/accurate_filter.clh",
                                            kFlatTest, "return 0;");
  for_each_variant({Layout::Point, Layout::Directional},
                   [&](Precision p, const Scene& scene, const std::string& what) {
                     expect_skip_changes_no_bit(never, scene, p, what + ": flat windows");
                   });
}

TEST(PcfFlat, AnswersWithoutSumsHappen) {
  REQUIRE_CONTEXT(ctx);
  const struct {
    Shadows shadows;
    const char *what, *from, *to;
  } places[] = {
      {Shadows::Hard, "filter", "? (real4)(1, 1, 0, 0)", "? (real4)(1, NAN, 0, 0)"},
      {Shadows::Soft, "search", "    if (!window_flat(xb, ",
       "    if (window_flat(xb, nonzero_part(wb, xb.mu, sb), P, Sb, Wb)) {\n"
       "      rec_light[at].w = NAN;\n      return;\n    }\n    if (!window_flat(xb, "},
      {Shadows::Hard, "backward", "G = 0;\n    else", "{ rec_lgrad[at] = NAN; return; }\n    else"},
  };
  for (const auto& place : places) {
    const std::string poisoned = patched_kernels(std::string("penumbra_pcf_flat_nan_") + place.what,
                                                 "accurate_lookups.cl", place.from, place.to);
    const Scene scene = pcf_scene(Layout::Point, place.shadows, Sampling::Truncated);
    const auto weights = random_loss_weights(scene, 11);
    const Results clean = results_with("", scene, Precision::Float, weights),
                  out = results_with(poisoned, scene, Precision::Float, weights);
    ASSERT_TRUE(finite_image(clean.images[0].color) && all_finite(clean.grads)) << place.what;
    EXPECT_FALSE(finite_image(out.images[0].color) && all_finite(out.grads))
        << place.what << ": no flat window was answered without its sums";
  }
}

// pcf_sample gives a fragment in the map that faces away from the light (n·l ≤ 0) s = 1 without
// a lookup: kernels that look every fragment up give the same images and gradients bit for bit;
// kernels that store NaN there give NaN colours (s·0), so the skip happens in these scenes.
constexpr const char* kFacingStore = "    rec_light[at].w = 1;";

TEST(PcfFacing, SkippedLookupsChangeNoBit) {
  REQUIRE_CONTEXT(ctx);
  const std::string always = kernels_looking_up_every_fragment("penumbra_pcf_look_up_all");
  for_each_variant({Layout::Point, Layout::Two},
                   [&](Precision p, const Scene& scene, const std::string& what) {
                     expect_skip_changes_no_bit(always, scene, p, what);
                   });
}

TEST(PcfFacing, LookupsSkipped) {
  REQUIRE_CONTEXT(ctx);
  const std::string poisoned = patched_kernels("penumbra_pcf_facing_nan", "accurate_lookups.cl",
                                               kFacingStore, "    rec_light[at].w = NAN;");
  for (Shadows sh : {Shadows::Hard, Shadows::Soft})
    expect_skip_taken(poisoned, pcf_scene(Layout::Point, sh, Sampling::Truncated), name_of(sh));
}

}  // namespace
