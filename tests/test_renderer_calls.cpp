// The Renderer's call contract (renderer.hpp): threads that share a renderer take turns, and
// renderers of several threads share a context; an abandoned call leaves it usable, gradients
// must be finite, a collapsed face renders as if it were absent, a given frustum that leaves out
// casters warns once, each call checks what changed since the last (an edit after a render
// included), render_into writes what render() returns into the caller's memory, and backward
// takes its gradients from there as from images.
#include <gtest/gtest.h>

#include <functional>
#include <limits>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "penumbra/error.hpp"
#include "penumbra/renderer.hpp"
#include "penumbra/scene.hpp"
#include "scenes.hpp"

using namespace penumbra;
using namespace penumbra_tests;

namespace {

// A sphere over the ground, one point light, hard shadows (the accurate model).
Scene sphere_over_ground(double x = 0.0) {
  Scene s;
  s.meshes = {icosphere({x, 0.8, 0}, 0.5), ground(2.0, 4)};
  s.cameras = {front_camera(false)};
  s.lights = {point_light({0.5, 4, 0.5}, {1, 1, 1})};
  shadow_params(s, Shadows::Hard, Sampling::Truncated, ShadowModel::Accurate);
  return s;
}

}  // namespace

TEST(RendererCalls, ThreadsSharingARendererTakeTurns) {
  REQUIRE_CONTEXT(ctx);
  const std::vector<Scene> scenes{sphere_over_ground(-0.3), sphere_over_ground(0.4)};
  std::vector<Image> expected(scenes.size());
  for (size_t k = 0; k < scenes.size(); ++k)
    expected[k] = Renderer(*ctx).render(scenes[k])[0].color;
  Renderer shared(*ctx);
  std::vector<int> mismatches(scenes.size(), 0);
  std::vector<std::thread> threads;
  for (size_t k = 0; k < scenes.size(); ++k)
    threads.emplace_back([&, k] {
      for (int i = 0; i < 5; ++i)
        mismatches[k] += shared.render(scenes[k])[0].color.data != expected[k].data;
    });
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(mismatches, std::vector<int>(scenes.size(), 0));
}

// Renderers of several threads on one new context build its programs at once.
TEST(RendererCalls, RenderersOfSeveralThreadsShareANewContext) {
  REQUIRE_CONTEXT(ctx);
  const Scene scene = sphere_over_ground();
  const Image expected = Renderer(*ctx).render(scene)[0].color;
  Context fresh(std::to_string(ctx->info().index));
  std::vector<std::string> outcomes(4);
  std::vector<std::thread> threads;
  threads.reserve(outcomes.size());
  for (std::string& outcome : outcomes)
    threads.emplace_back([&] {
      try {
        outcome = Renderer(fresh).render(scene)[0].color.data == expected.data ? "" : "differs";
      } catch (const std::exception& e) {
        outcome = e.what();
      }
    });
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(outcomes, std::vector<std::string>(4));
}

TEST(RendererCalls, AnAbandonedCallLeavesTheRendererUsable) {
  REQUIRE_CONTEXT(ctx);
  const Scene scene = sphere_over_ground();
  Renderer renderer(*ctx);
  int stages = 0;
  renderer.set_interrupt_check([&] {
    if (++stages == 3) throw std::runtime_error("stop");
  });
  EXPECT_THROW(renderer.render(scene), std::runtime_error);
  renderer.set_interrupt_check(nullptr);
  std::vector<OutputGrads> none(1);
  try {
    renderer.backward(scene, none);
    ADD_FAILURE() << "backward after an abandoned render did not throw";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("call render() first"), std::string::npos) << e.what();
  }
  EXPECT_EQ(renderer.render(scene)[0].color.data, Renderer(*ctx).render(scene)[0].color.data);
}

TEST(RendererCalls, NonFiniteGradientsAreRefused) {
  REQUIRE_CONTEXT(ctx);
  const Scene scene = sphere_over_ground();
  Renderer renderer(*ctx);
  const std::vector<RenderOutput> views = renderer.render(scene);
  std::vector<OutputGrads> dL(1);
  dL[0].depth = Image(views[0].depth.width, views[0].depth.height, 1, 0.0);
  dL[0].depth.at(5, 2) = std::numeric_limits<double>::infinity();
  try {
    renderer.backward(scene, dL);
    ADD_FAILURE() << "an infinite gradient was taken";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(),
                 "gradient of depth for camera 0 is infinite at pixel (5, 2); gradients must be "
                 "finite");
  }
}

TEST(RendererCalls, ACollapsedFaceRendersAsIfAbsent) {
  REQUIRE_CONTEXT(ctx);
  const Scene scene = sphere_over_ground();
  Scene collapsed = scene;
  Mesh& sphere = collapsed.meshes[0];
  const int n = int(sphere.vertices.size());
  // Inside the sphere, so that the scene's bounds (and the light's frustum) stay as they were.
  for (glm::dvec3 p :
       {glm::dvec3(0.1, 0.9, 0.1), glm::dvec3(0.1, 0.9, 0.1), glm::dvec3(0.2, 1.0, 0.15)})
    sphere.vertices.push_back(p), sphere.albedo.push_back({0.5, 0.5, 0.5});
  sphere.faces.push_back({n, n + 1, n + 2});  // two corners at one point: zero area
  EXPECT_THROW(validate(collapsed), Error);   // a file's mesh is refused
  Renderer renderer(*ctx, Precision::Double);
  const RenderOutput with = renderer.render(collapsed)[0];
  std::vector<OutputGrads> dL(1);
  dL[0].color = Image(with.color.width, with.color.height, 3, 1.0);
  const SceneGrads g = renderer.backward(collapsed, dL);
  for (int k = 0; k < 3; ++k) EXPECT_EQ(g.vertices[0][size_t(n + k)], glm::dvec3(0.0)) << k;
  const RenderOutput without = Renderer(*ctx, Precision::Double).render(scene)[0];
  std::string where;
  EXPECT_EQ(max_error(with.color, without.color, false, &where), 0.0) << where;
  EXPECT_EQ(with.depth.data, without.depth.data);
}

TEST(RendererCalls, AGivenFrustumThatLeavesOutCastersWarnsOnce) {
  REQUIRE_CONTEXT(ctx);
  Scene fitted = sphere_over_ground();
  fit_light_frusta(fitted);
  EXPECT_TRUE(frustum_holds_casters(fitted, fitted.lights[0]));
  Scene moved = sphere_over_ground(1.2);
  moved.lights = fitted.lights;  // the frustum fitted to the sphere where it was
  EXPECT_FALSE(frustum_holds_casters(moved, moved.lights[0]));
  Renderer renderer(*ctx);
  testing::internal::CaptureStderr();
  renderer.render(moved);
  renderer.render(moved);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_EQ(err.find("penumbra: warning: the shadow-map frustum given for light 0 leaves out"), 0u)
      << err;
  EXPECT_EQ(err.find("penumbra: warning:", 1), std::string::npos) << err;
}

// A call whose faces and albedo are the last call's checks its vertices alone; any other
// change to the meshes is checked whole.
TEST(RendererCalls, EachCallChecksWhatChanged) {
  REQUIRE_CONTEXT(ctx);
  const Scene scene = sphere_over_ground();
  Renderer renderer(*ctx);
  renderer.render(scene);
  auto refused = [&](const Scene& s, const std::string& words) {
    try {
      renderer.render(s);
    } catch (const Error& e) {
      return std::string(e.what()).find(words) != std::string::npos ? std::string()
                                                                    : std::string(e.what());
    }
    return std::string("not refused");
  };
  Scene moved = scene;
  moved.meshes[0].vertices[3].y = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(refused(moved, "mesh 0 'occluder': vertex 3 has a non-finite coordinate"), "");
  moved.meshes[0].vertices[3].y = 1e101;
  EXPECT_EQ(refused(moved,
                    "mesh 0 'occluder': vertex 3 (0.262865556, 1e+101, 0) has a coordinate beyond"),
            "");
  Scene reindexed = scene;
  const int beyond = int(reindexed.meshes[1].vertices.size());
  reindexed.meshes[1].faces.edit([&](std::vector<glm::ivec3>& f) { f[2].z = beyond; });
  EXPECT_EQ(
      refused(reindexed, "mesh 1 'ground': face 2 (1, 6, 25) has vertex index 25 out of range"),
      "");
  Scene recoloured = scene;
  recoloured.meshes[1].albedo.edit([](std::vector<glm::dvec3>& a) { a[0].x = -1; });
  EXPECT_EQ(refused(recoloured, "mesh 1 'ground': albedo 0 is negative"), "");
  EXPECT_NO_THROW(renderer.render(scene));
}

// The renderer's record of a render shares the scene's faces and albedo (SharedArray): an edit of
// the rendered scene's own faces or albedo gives that scene new values and leaves the record as
// it was, so backward() refuses the edited scene and the next render draws the edit, as a fresh
// renderer does.
TEST(RendererCalls, AnEditAfterARenderReachesTheNextCall) {
  REQUIRE_CONTEXT(ctx);
  const std::vector<std::function<void(Mesh&)>> edits = {
      [](Mesh& m) { m.albedo.edit([](std::vector<glm::dvec3>& a) {
                      a[0] = {0.9, 0.1, 0.1};
                    }); },
      [](Mesh& m) { m.faces.edit([](std::vector<glm::ivec3>& f) { f.resize(f.size() / 2); }); },
  };
  for (const auto& edit : edits) {
    Scene scene = sphere_over_ground();
    Renderer renderer(*ctx);
    const std::vector<RenderOutput> before = renderer.render(scene);
    edit(scene.meshes[1]);
    EXPECT_THROW(renderer.backward(scene, std::vector<OutputGrads>(1)), Error);
    const std::vector<RenderOutput> after = renderer.render(scene);
    Renderer fresh(*ctx);
    EXPECT_EQ(after[0].color.data, fresh.render(scene)[0].color.data);
    EXPECT_NE(after[0].color.data, before[0].color.data);
  }
}

// render_into gives render()'s values in the caller's precision (float: render()'s doubles
// rounded to float), refuses buffers that do not fit the cameras before it renders, and leaves
// the render for backward() as render() does.
TEST(RendererCalls, RenderIntoWritesWhatRenderReturns) {
  REQUIRE_CONTEXT(ctx);
  Scene scene = sphere_over_ground();
  Camera side = front_camera(false);
  side.eye = {2.5, 1.5, 1.0};
  side.width = 24;
  scene.cameras.push_back(side);
  for (Precision precision : {Precision::Float, Precision::Double}) {
    Renderer renderer(*ctx, precision);
    const std::vector<RenderOutput> views = renderer.render(scene);
    std::vector<OutputGrads> dL(views.size());
    dL[1].silhouette = Image(side.width, side.height, 1, 1.0);
    const SceneGrads after_render = renderer.backward(scene, dL);
    std::vector<std::vector<float>> f(3 * scene.cameras.size());
    std::vector<std::vector<double>> d(3 * scene.cameras.size());
    std::vector<OutputBuffers<float>> into_f;
    std::vector<OutputBuffers<double>> into_d;
    for (size_t c = 0; c < views.size(); ++c) {
      const Image* images[3] = {&views[c].color, &views[c].silhouette, &views[c].depth};
      for (int k = 0; k < 3; ++k)
        f[3 * c + k].assign(images[k]->size(), NAN), d[3 * c + k].assign(images[k]->size(), NAN);
      into_f.push_back({f[3 * c].data(), f[3 * c + 1].data(), f[3 * c + 2].data()});
      into_d.push_back({d[3 * c].data(), d[3 * c + 1].data(), d[3 * c + 2].data()});
    }
    renderer.render_into(scene, into_f);
    EXPECT_EQ(renderer.backward(scene, dL).vertices, after_render.vertices);
    renderer.render_into(scene, into_d);
    for (size_t c = 0; c < views.size(); ++c) {
      const Image* images[3] = {&views[c].color, &views[c].silhouette, &views[c].depth};
      for (int k = 0; k < 3; ++k) {
        EXPECT_EQ(d[3 * c + k], images[k]->data) << c << " " << k;
        const std::vector<float> rounded(images[k]->data.begin(), images[k]->data.end());
        EXPECT_EQ(f[3 * c + k], rounded) << c << " " << k;
      }
    }
    into_f.pop_back();
    EXPECT_THROW(renderer.render_into(scene, into_f), Error);
    into_d[1].depth = nullptr;
    try {
      renderer.render_into(scene, into_d);
      ADD_FAILURE() << "a null buffer was taken";
    } catch (const Error& e) {
      EXPECT_STREQ(e.what(), "render_into: an output buffer of camera 1 is null");
    }
  }
}

// Without shadows no frustum is fitted (none is used): a light straight above the origin, where
// an unfitted frustum looks along its up vector, renders and differentiates as with one given.
TEST(RendererCalls, WithoutShadowsNoFrustumIsNeeded) {
  REQUIRE_CONTEXT(ctx);
  Scene scene = sphere_over_ground();
  scene.params.shadows = Shadows::None;
  scene.lights[0].position = {0, 4, 0};
  Scene given = scene;
  Scene fitted = scene;
  fitted.params.shadows = Shadows::Hard;
  fit_light_frusta(fitted);
  given.lights = fitted.lights;
  Renderer renderer(*ctx, Precision::Double);
  const RenderOutput without = renderer.render(scene)[0];
  std::vector<OutputGrads> dL(1);
  dL[0].color = Image(without.color.width, without.color.height, 3, 1.0);
  const SceneGrads g = renderer.backward(scene, dL);
  EXPECT_EQ(without.color.data, renderer.render(given)[0].color.data);
  EXPECT_EQ(g.vertices, renderer.backward(given, dL).vertices);
  EXPECT_EQ(g.light_position, renderer.backward(given, dL).light_position);
}

// backward() from the caller's float or double buffers gives what it gives from images of the
// same values (here exact in float), and refuses a non-finite value there too.
TEST(RendererCalls, BackwardFromBuffersEqualsBackwardFromImages) {
  REQUIRE_CONTEXT(ctx);
  const Scene scene = sphere_over_ground();
  Renderer renderer(*ctx);
  const RenderOutput view = renderer.render(scene)[0];
  std::vector<OutputGrads> dL(1);
  dL[0].color = Image(view.color.width, view.color.height, 3);
  dL[0].depth = Image(view.depth.width, view.depth.height, 1);
  for (size_t i = 0; i < dL[0].color.size(); ++i) dL[0].color.data[i] = double(i % 7) / 8 - 0.25;
  for (size_t i = 0; i < dL[0].depth.size(); ++i) dL[0].depth.data[i] = double(i % 5) / 16;
  const SceneGrads from_images = renderer.backward(scene, dL);
  const std::vector<float> color(dL[0].color.data.begin(), dL[0].color.data.end()),
      depth(dL[0].depth.data.begin(), dL[0].depth.data.end());
  const SceneGrads from_floats = renderer.backward(
      scene, std::vector<GradBuffers<float>>{{color.data(), nullptr, depth.data()}});
  const SceneGrads from_doubles =
      renderer.backward(scene, std::vector<GradBuffers<double>>{
                                   {dL[0].color.data.data(), nullptr, dL[0].depth.data.data()}});
  EXPECT_GT(glm::length(from_images.vertices[0][0]) + glm::length(from_images.vertices[0][5]), 0.0);
  EXPECT_EQ(from_floats.vertices, from_images.vertices);
  EXPECT_EQ(from_doubles.vertices, from_images.vertices);
  EXPECT_EQ(from_floats.light_position, from_images.light_position);
  std::vector<float> bad = depth;
  bad[3 * size_t(view.depth.width) + 2] = std::numeric_limits<float>::quiet_NaN();
  try {
    renderer.backward(scene, std::vector<GradBuffers<float>>{{nullptr, nullptr, bad.data()}});
    ADD_FAILURE() << "a NaN gradient was taken";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(),
                 "gradient of depth for camera 0 is NaN at pixel (2, 3); gradients must be finite");
  }
}
