#pragma once
// Scene model: meshes, cameras, lights and render parameters (SPEC §0, §2, §7).
// Host-side values are double so that gradient checks can run entirely in double precision.
#include <glm/glm.hpp>
#include <string>
#include <vector>

namespace penumbra {

enum class AlbedoMode { PerVertex, PerFace };

struct Mesh {
  std::string name;
  std::vector<glm::dvec3> vertices;
  std::vector<glm::ivec3> faces;      // indices into vertices, counter-clockwise
  std::vector<glm::dvec3> albedo;     // one per vertex or one per face (see albedo_mode)
  AlbedoMode albedo_mode = AlbedoMode::PerVertex;
};

enum class Projection { Perspective, Orthographic };

struct Camera {
  glm::dvec3 eye{0, 0, 5}, target{0, 0, 0}, up{0, 1, 0};
  Projection projection = Projection::Perspective;
  double fov_deg = 40.0;      // vertical field of view (perspective)
  double half_height = 1.0;   // half the visible height in world units (orthographic)
  double near = 0.1, far = 100.0;
  int width = 256, height = 256;
};

enum class LightType { Point, Directional };

// The camera a light renders its shadow map with (SPEC §3). It is fitted once — to the scene's
// bounds, by fit_light_frusta — and then held fixed: a constant of the render, not a function
// of the vertices, so that gradients and finite differences see the same function.
// Point light: eye at the light's position, looking at `target`, perspective with `fov_deg`.
// Directional light: orthographic with half-size `half_size`, looking along the light's
// direction at `target` from `distance` away.
struct LightFrustum {
  bool fitted = false;
  glm::dvec3 target{0, 0, 0};
  glm::dvec3 up{0, 1, 0};
  double fov_deg = 60.0;
  double half_size = 1.0;
  double distance = 10.0;
  double near = 0.1, far = 100.0;
};

struct Light {
  LightType type = LightType::Point;
  glm::dvec3 position{0, 5, 5};    // point light
  glm::dvec3 direction{0, -1, 0};  // directional light: direction the light travels
  glm::dvec3 color{1, 1, 1};       // RGB intensity I_L
  double size = 0.0;               // light diameter D_L (soft shadows)
  LightFrustum frustum;            // fitted by fit_light_frusta when not given
};

enum class Shadows { None, Hard, Soft };
enum class Sampling { Truncated, Exact, Gemm };

// SPEC §7, names as in its table.
struct RenderParams {
  double sigma = 1e-5;       // coverage sharpness σ (screen units²)
  double gamma = 1e-4;       // aggregation sharpness γ
  double eps = 1e-3;         // background depth ε of the aggregation
  double dist_eps = 1e-4;    // coverage cut-off ε_D
  double sigma_s = 2.0;      // shadow-map Gaussian variance (texel²)
  double lambda_eps = 1e-3;  // truncation threshold ε_λ
  double gamma_s = 0.02;     // depth-compare softness γ_s
  double beta = 0.05;        // depth bias β (depth units)
  double gamma_p = 10.0;     // penumbra soft-minimum sharpness γ_P
  bool cull_backfaces = false;
  Shadows shadows = Shadows::None;
  Sampling sampling = Sampling::Truncated;
  int shadow_map_size = 256;  // W_s = H_s, texels
  double light_sigma = 0.0;   // σ_L of the light pass; 0 → σ/10 (light_pass_sigma)
  double light_gamma = 0.0;   // γ_L of the light pass; 0 → γ (light_pass_gamma)
  // A fragment whose aggregation weight is below ε_w times the largest (the background's
  // included) is left out of the colour and depth (but not the silhouette), so
  // that shadow terms are sampled only where they can show.
  double weight_eps = 1e-10;
};

struct Scene {
  std::vector<Mesh> meshes;
  std::vector<Camera> cameras;
  std::vector<Light> lights;
  glm::dvec3 ambient{0.2, 0.2, 0.2};
  glm::dvec3 background{1, 1, 1};
  RenderParams params;
};

// Throws penumbra::Error naming the first problem: NaN/inf values, out-of-range indices,
// zero-area faces, albedo count mismatch, zero-size images, non-positive σ/γ, near ≥ far, ...
void validate(const Scene& scene);
void validate(const Mesh& mesh);

// Axis-aligned bounds and bounding sphere of all meshes.
struct Bounds {
  glm::dvec3 lo, hi;
  glm::dvec3 center() const { return 0.5 * (lo + hi); }
  double radius() const { return 0.5 * glm::length(hi - lo); }
};
Bounds bounds(const Scene& scene);

// σ_L and γ_L of the light pass (SPEC §3): light_sigma / light_gamma when set, else σ/10 and γ.
// A face's soft depth just outside its edge is taken at its nearest boundary point (clamped
// barycentrics, SPEC §1), which biases S near the edges of coplanar neighbours by about
// (√σ_L in texels) × (depth slope per texel); at σ_L = σ a ground plane seen at a grazing angle
// showed faint lines along every edge. A tenth of σ keeps the bias well under β.
double light_pass_sigma(const RenderParams& p);
double light_pass_gamma(const RenderParams& p);

// Fits the frustum of every light whose frustum is not fitted yet to the scene's bounding
// sphere, so that every receiver lies inside its shadow map (SPEC §3).
void fit_light_frusta(Scene& scene);

// A scene around one mesh, with a camera and a light that frame it (for `render --mesh`).
Scene framed_scene(Mesh mesh, int width = 256, int height = 256);

}  // namespace penumbra
