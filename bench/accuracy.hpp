#pragma once
// Accuracy against the ray-traced truth (truth.hpp), shared by the benchmark group
// (bench_accuracy.cpp) and the test of the accurate model's targets (test_accuracy.cpp).
//
// Scenes (camera 0 of data/scenes/turnaround.json, 256² unless named, a point light of diameter
// D_L = 0.5 on the 8 × 8 ground plane, default settings):
//   sphere             the bundled unit sphere resting on the ground, light at (3, 6, 2.5);
//   knot_h0, knot_h0.3, knot_h1
//                      a (2, 3) torus knot tube (torus_knot: 3840 faces, 2.8 wide, 1.0 tall)
//                      lying flat, its lowest point 0 (touching the ground), 0.3 and 1 above it;
//   grazing            a sphere of radius 0.5 resting on the ground under a light 8 away at an
//                      elevation of 18° (seen from the sphere's centre);
//   among              a light 0.9 above the ground among four spheres of radius 0.3 resting
//                      on it, 1.1 away on four sides: its shadows fall 40° to 75° from straight
//                      down, in four directions (ShadowMapShape::Auto maps them on a cube);
//   among_frustum      the same held to one frustum (ShadowMapShape::Frustum, 120°): what
//                      the cube gives, and costs (a benchmark case, outside the targets).
//   sphere_100k, sphere_100k_512
//                      the sphere scene with a sphere of 100,820 faces in its place, at 256²
//                      and at 512²: penumbra at scale beside a ray tracer (benchmark cases,
//                      outside the targets).
//
// Metrics of one render against the truth that matches its shadow mode (point light for hard
// and none, sphere light for soft), over ground pixels (the rays of the pixel and of every
// pixel within the silhouette margin hit the ground: silhouettes, where the soft rasterizer
// blends a nearer surface in, are left out; the margin is how far that blend reaches,
// √(σ ln(1/ε_D − 1)) screen units — 1.2 px at the default σ — rounded up to whole pixels).
// penumbra's visibility is its per-pixel shadow term, recovered from three renders of the same
// scene: s = (C − C_ambient) / (C_unshadowed − C_ambient), channels summed.
//   area_ratio   ground pixels with s < 0.5 over ground pixels with truth visibility < 0.5;
//   lit_error    mean relative colour error Σ_k|C_k − T_k| / Σ_k T_k over ground pixels the
//                truth lights fully (visibility 1);
//   rmse_shadow  colour RMSE over the shadow region: ground pixels within 8 px of a pixel
//                the sphere-light truth shadows (visibility < 0.999, penumbra included), the
//                same pixels for every method of a scene;
//   leak         the contact region (ground pixels within 3 px of a surface point 0.1 or less
//                from a caster vertex on the ground): the fraction of its pixels the truth
//                shadows (v < 0.5) that penumbra lights (s ≥ 0.5); absent where nothing
//                touches the ground.
#include <optional>
#include <string>
#include <vector>

#include "common.hpp"
#include "truth.hpp"

namespace penumbra::bench {

// A (p, q) torus knot tube: the curve ((R + r cos qt) cos pt, (R + r cos qt) sin pt, r sin qt),
// t ∈ [0, 2π), swept by a circle of radius `tube` in the plane normal to it; its z axis turned
// to +y (lying flat) and its lowest vertex at height `lift`. segments × sides × 2 faces,
// outward counter-clockwise.
Mesh torus_knot(int p, int q, double R, double r, double tube, int segments, int sides, double lift,
                glm::dvec3 albedo = {0.85, 0.35, 0.3});

const std::vector<std::string>& accuracy_scene_names();

// What an accuracy case renders: a scene of accuracy_scene_names() and the shadow settings.
struct AccuracyCase {
  std::string scene = "sphere";
  ShadowModel model = ShadowModel::Accurate;
  Shadows shadows = Shadows::Hard;
  Sampling sampling = Sampling::Truncated;
  ExactBackend exact_backend = ExactBackend::Kernels;  // as Case::exact_backend
  std::optional<int> map;         // unset: the shadow model's default (shadow_map_side)
  std::optional<double> sigma_s;  // unset: the shadow model's default
};

// The scene of the case, its light frusta fitted to it.
Scene accuracy_scene(const AccuracyCase& c);

// The truth of a scene (ray-traced once per process and scene; it does not depend on the
// shadow settings) and the one that matches a shadow mode.
const GroundTruth& truth(const std::string& scene, TruthLight light);
TruthLight truth_for(Shadows shadows);

// penumbra's colour and per-pixel shadow term (see above) of camera 0.
struct Rendered {
  Image color;
  std::vector<double> vis;
};
Rendered render_visibility(Renderer& r, const Scene& s);

struct AccuracyMetrics {
  double area_ratio = 0, lit_error = 0, rmse_shadow = 0;
  std::optional<double> leak;
  int ground_pixels = 0, shadow_pixels = 0, true_shadow_pixels = 0, lit_pixels = 0,
      contact_pixels = 0, contact_shadow_pixels = 0;
  int leaking_on_edge = 0;  // leaking contact pixels beside a pixel the truth lights
};
AccuracyMetrics measure(const AccuracyCase& c, const Rendered& rendered);

// The targets for the accurate model.
struct AccuracyTargets {
  static constexpr double area = 0.05;       // |area_ratio − 1| ≤
  static constexpr double lit = 0.02;        // lit_error ≤
  static constexpr double rmse = 0.05;       // rmse_shadow ≤
  static constexpr double leak = 0.0;        // leak ≤
  static constexpr double time_ratio = 1.5;  // accurate / paper forward time ≤
};

// truth | penumbra | difference, side by side, as a PNG: the difference is white where they
// agree, red where penumbra is darker than the truth, blue where it is brighter, at 4× the
// mean difference of the channels.
void save_comparison(const GroundTruth& truth, const Image& color, const std::string& path);

// What a side-by-side comparison with another renderer needs (bench/mitsuba_side_by_side.py),
// written into `dir`: the scene as a scene file, <scene>.json, with its meshes as OBJ beside
// it; the truth's colour for hard and soft shadows, <scene>_truth_<hard|soft>.npy (H × W × 3);
// and the shadow region of rmse_shadow, <scene>_region.npy (H × W, 1 inside, 0 outside).
void save_side_by_side(const std::string& scene, const std::string& dir);

}  // namespace penumbra::bench
