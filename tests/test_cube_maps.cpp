// Cube shadow maps (scene.hpp: ShadowMapShape, LightFrustum::cube; docs/shadows.md, "Cube shadow
// maps"): a point light among the objects casts shadows in every direction.
//
//   CubeMaps.FitChoosesTheCubeWhereOneFrustumCannotHoldTheCasters   the automatic choice, the
//                                                  scene file's word, and what is refused
//   CubeMaps.KernelsMatchReference                 colours against the reference renderer
//                                                  (double), both models, hard and soft
//   CubeMaps.LightInsideAClosedSphereShadowsTheGround   every ground pixel in shadow, where one
//                                                  frustum leaves most of them lit
//   CubeMaps.GradCheckAcrossFaceSeams              double-precision gradients against finite
//                                                  differences, with penumbrae crossing seams
//   CubeMaps.LightGradientsSumOverFaces            one gradient per given light, whatever its maps
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>

#include "penumbra/gradcheck.hpp"
#include "penumbra/io.hpp"
#include "scenes.hpp"

namespace {

using glm::dvec3;
using namespace penumbra;
using namespace penumbra_tests;

constexpr dvec3 kLight{0.05, 0.8, 0.03};

// A light 0.8 above a 4×4 ground among four spheres of radius 0.3 resting on it, 0.9 from the
// light's foot on four sides: their shadows start inside the square |x − x_L|, |z − z_L| ≤ 0.8
// that the cube's lower face lights and run out across its edges into the side faces'.
Scene among_scene(Shadows shadows, ShadowModel model) {
  Scene s;
  s.meshes = {icosphere({0.9, 0.3, 0.0}, 0.3, 1, "east"),
              icosphere({-0.9, 0.3, 0.0}, 0.3, 1, "west"),
              icosphere({0.0, 0.3, 0.9}, 0.3, 1, "south"),
              icosphere({0.0, 0.3, -0.9}, 0.3, 1, "north"), ground(2.0, 8)};
  s.cameras = {front_camera(false)};
  s.lights = {point_light(kLight, {0.9, 0.85, 0.8}, 0.3)};
  shadow_params(s, shadows, Sampling::Truncated, model);
  return s;
}

TEST(CubeMaps, FitChoosesTheCubeWhereOneFrustumCannotHoldTheCasters) {
  for (ShadowModel model : {ShadowModel::Accurate, ShadowModel::Paper}) {
    Scene s = among_scene(Shadows::Hard, model);
    fit_light_frusta(s);
    EXPECT_TRUE(s.lights[0].frustum.cube) << word(model) << ": a light among the objects";
    EXPECT_EQ(cube_faces(s.lights, nullptr).size(), 6U);
    s.lights[0].position = {0.0, 5.0, 0.0};
    refit_light_frusta(s);
    EXPECT_FALSE(s.lights[0].frustum.cube) << word(model) << ": a light above the objects";
    s.lights[0].shadow_map = ShadowMapShape::Cube;
    refit_light_frusta(s);
    EXPECT_TRUE(s.lights[0].frustum.cube) << word(model) << ": a cube asked for";
    s.lights[0].position = kLight;
    s.lights[0].shadow_map = ShadowMapShape::Frustum;
    refit_light_frusta(s);
    EXPECT_FALSE(s.lights[0].frustum.cube) << word(model) << ": one frustum asked for";
    EXPECT_EQ(s.lights[0].frustum.fov_deg, kWidestFit);
  }
  std::vector<int> light_of;
  Scene two = among_scene(Shadows::Hard, ShadowModel::Accurate);
  two.lights.push_back(directional_light({0.2, -1.0, 0.1}, {0.3, 0.3, 0.3}));
  fit_light_frusta(two);
  const std::vector<Light> maps = cube_faces(two.lights, &light_of);
  ASSERT_EQ(maps.size(), 7U);
  EXPECT_EQ(light_of, (std::vector<int>{0, 0, 0, 0, 0, 0, 1}));
  for (int k = 0; k < 6; ++k) EXPECT_EQ(maps[size_t(k)].frustum.cube_face, k);
  EXPECT_EQ(maps[6].frustum.cube_face, -1);

  two.lights[1].shadow_map = ShadowMapShape::Cube;
  EXPECT_NE(error_of([&] { validate(two); }).find("light 1: shadow_map 'cube' is for point lights"),
            std::string::npos);
}

// The bundled scene with `extra` after its light's size, written to `path`.
std::string bundled_scene_with(const std::string& extra, const std::string& path) {
  std::ifstream in(std::string(PENUMBRA_DATA_DIR) + "/scenes/turnaround.json");
  std::ostringstream text;
  text << in.rdbuf();
  std::string s = text.str();
  for (size_t at = s.find("../meshes/"); at != std::string::npos; at = s.find("../meshes/"))
    s.replace(at, 2, PENUMBRA_DATA_DIR);
  const std::string size = "\"size\": 0.5";
  EXPECT_NE(s.find(size), std::string::npos);
  s.replace(s.find(size), size.size(), size + extra);
  write_file(path, s, "scene");
  return path;
}

TEST(CubeMaps, SceneFileSaysHowALightIsMapped) {
  const std::string dir = fresh_temp_dir("cube_scene");
  for (const std::string word : {"auto", "frustum", "cube"}) {
    const std::string path =
        bundled_scene_with(", \"shadow_map\": \"" + word + "\"", dir + "/" + word + ".json");
    EXPECT_EQ(load_scene(path).lights[0].frustum.cube, word == "cube")
        << word << " (the bundled light is above its sphere)";
  }
  const std::string bad = bundled_scene_with(", \"shadow_map\": \"sphere\"", dir + "/bad.json");
  EXPECT_NE(error_of([&] { load_scene(bad); }).find("shadow_map"), std::string::npos);
}

TEST(CubeMaps, KernelsMatchReference) {
  REQUIRE_CONTEXT(ctx);
  Renderer& r = shared_renderer(*ctx, Precision::Double);
  for (ShadowModel model : {ShadowModel::Accurate, ShadowModel::Paper})
    for (Shadows shadows : {Shadows::Hard, Shadows::Soft}) {
      const std::string tag = std::string("cube ") + word(model) + " " + word(shadows);
      const double worst =
          expect_matches_reference(r, among_scene(shadows, model), {1e-9, 1e-9, 1e-6}, tag);
      std::cout << "[cube reference] " << tag << ": max colour error " << worst << std::endl;
    }
}

// The share of the ground's pixels brighter than 0.02 with the light inside a closed sphere of
// radius 0.5 above it, no ambient light, default render parameters. The pixels the sphere
// covers in part are left out: its inside, which the light does reach, blends into its outline.
double lit_share(Renderer& r, ShadowMapShape shape, Shadows shadows, ShadowModel model) {
  Scene s = among_scene(shadows, model);
  s.meshes = {icosphere({0.0, 0.8, 0.0}, 0.5, 2, "shell"), ground(2.0, 8)};
  s.lights[0].shadow_map = shape;
  s.ambient = dvec3(0.0);
  s.params = RenderParams{};  // the model's own map and filter
  s.params.shadows = shadows;
  s.params.shadow_model = model;
  Scene shell = s;
  shell.meshes.pop_back();
  const RenderOutput out = r.render(s).front();
  const Image& c = out.color;
  const Image covered = r.render(shell).front().silhouette;
  size_t lit = 0, ground = 0;
  for (size_t i = 0; i < covered.data.size(); ++i) {
    if (covered.data[i] > 0 || out.silhouette.data[i] < 0.5) continue;  // the sphere, the sky
    ground += 1;
    lit += std::max({c.data[3 * i], c.data[3 * i + 1], c.data[3 * i + 2]}) > 0.02;
  }
  return double(lit) / double(ground);
}

TEST(CubeMaps, LightInsideAClosedSphereShadowsTheGround) {
  REQUIRE_CONTEXT(ctx);
  Renderer& r = shared_renderer(*ctx, Precision::Float);
  for (ShadowModel model : {ShadowModel::Accurate, ShadowModel::Paper})
    for (Shadows shadows : {Shadows::Hard, Shadows::Soft}) {
      const std::string tag = std::string(word(model)) + " " + word(shadows);
      const double cube = lit_share(r, ShadowMapShape::Auto, shadows, model),
                   frustum = lit_share(r, ShadowMapShape::Frustum, shadows, model);
      std::cout << "[closed sphere] " << tag << ": lit pixels " << cube << " (cube), " << frustum
                << " (one frustum)" << std::endl;
      // The accurate model's hard shadow leaks faint light along the shell's edges, where one
      // layer of faces covers a texel in part (docs/shadows.md): 2.6 % of the pixels.
      EXPECT_LT(cube, 0.05) << tag;
      EXPECT_GT(frustum, 0.5) << tag;
    }
}

// Ground points on the edges of the lower face's square (where the cube's seams meet the
// ground) whose pixel lies in a penumbra: visibility (C − C_ambient) / (C_unshadowed −
// C_ambient) strictly between 0.05 and 0.95.
int seam_penumbra_pixels(Renderer& r, const Scene& s) {
  Scene unshadowed = s, ambient = s;
  unshadowed.params.shadows = ambient.params.shadows = Shadows::None;
  ambient.lights[0].color = dvec3(0.0);
  const Image C = r.render(s).front().color, U = r.render(unshadowed).front().color,
              A = r.render(ambient).front().color;
  const Camera& cam = s.cameras.front();
  int count = 0;
  for (double t = -0.8; t <= 0.8; t += 0.01)
    for (const dvec3& X :
         {dvec3(kLight.x + 0.8, 0, kLight.z + t), dvec3(kLight.x - 0.8, 0, kLight.z + t),
          dvec3(kLight.x + t, 0, kLight.z + 0.8), dvec3(kLight.x + t, 0, kLight.z - 0.8)}) {
      const auto [px, py] = pixel_of(cam, X);
      if (px < 0 || py < 0 || px >= cam.width || py >= cam.height) continue;
      const size_t i = (size_t(py) * size_t(cam.width) + size_t(px)) * 3;
      const double v = (C.data[i] - A.data[i]) / std::max(U.data[i] - A.data[i], 1e-12);
      count += v > 0.05 && v < 0.95;
    }
  return count;
}

TEST(CubeMaps, GradCheckAcrossFaceSeams) {
  REQUIRE_CONTEXT(ctx);
  for (ShadowModel model : {ShadowModel::Accurate, ShadowModel::Paper})
    for (Shadows shadows : {Shadows::Hard, Shadows::Soft}) {
      const std::string tag = std::string(word(model)) + " " + word(shadows);
      Scene s = among_scene(shadows, model);
      fit_light_frusta(s);
      ASSERT_TRUE(s.lights[0].frustum.cube) << tag;
      EXPECT_GT(seam_penumbra_pixels(shared_renderer(*ctx, Precision::Double), s), 4)
          << tag << ": no penumbra where the seams meet the ground";
      GradCheckOptions options;
      options.samples = 16;
      options.seed = 3;
      const GradCheckResult g = gradcheck(*ctx, s, options);
      std::cout << "[cube gradcheck] " << tag << ": checked=" << g.checked << " failed=" << g.failed
                << " max_rel_err=" << g.max_rel_err << std::endl;
      EXPECT_TRUE(g.passed()) << tag << "\n" << describe(g);
      EXPECT_TRUE(has_entry(g, "light0.position.")) << tag << "\n" << describe(g);
    }
}

TEST(CubeMaps, LightGradientsSumOverFaces) {
  REQUIRE_CONTEXT(ctx);
  Renderer& r = shared_renderer(*ctx, Precision::Double);
  Scene s = among_scene(Shadows::Soft, ShadowModel::Accurate);
  s.lights.push_back(directional_light({0.2, -1.0, 0.1}, {0.3, 0.3, 0.3}, 0.05));
  r.render(s);
  EXPECT_EQ(r.shadow_maps().size(), 7U) << "six faces and one frustum";
  const SceneGrads grads = r.backward(s, random_loss_weights(s, 1));
  ASSERT_EQ(grads.light_position.size(), 2U);
  ASSERT_EQ(grads.light_color.size(), 2U);
  ASSERT_EQ(grads.light_size.size(), 2U);
  EXPECT_GT(glm::length(grads.light_color[0]), 0.0);
  EXPECT_GT(glm::length(grads.light_position[0]), 0.0);
}

}  // namespace
