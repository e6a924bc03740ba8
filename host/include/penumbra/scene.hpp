#pragma once
// Scene model: meshes, cameras, lights and render parameters (math.md §1, §3, §10).
// Host-side values are double so that gradient checks can run entirely in double precision.
#include <glm/glm.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "penumbra/shared_array.hpp"

namespace penumbra {

enum class AlbedoMode { PerVertex, PerFace };

struct Mesh {
  std::string name;
  std::vector<glm::dvec3> vertices;
  // Shared by the mesh's copies until written (shared_array.hpp): a renderer knows the last
  // call's faces and albedo in O(1).
  SharedArray<glm::ivec3> faces;   // indices into vertices, counter-clockwise
  SharedArray<glm::dvec3> albedo;  // one per vertex or one per face (see albedo_mode)
  AlbedoMode albedo_mode = AlbedoMode::PerVertex;
};

enum class Projection { Perspective, Orthographic };

// The largest image side and shadow-map side validate() accepts.
constexpr int kMaxImageSize = 16384;
constexpr int kMaxShadowMapSize = 8192;

struct Camera {
  glm::dvec3 eye{0, 0, 5}, target{0, 0, 0}, up{0, 1, 0};
  Projection projection = Projection::Perspective;
  double fov_deg = 40.0;     // vertical field of view (perspective)
  double half_height = 1.0;  // half the visible height in world units (orthographic)
  double near = 0.1, far = 100.0;
  int width = 256, height = 256;
};

enum class LightType { Point, Directional };

// The camera a light renders its shadow map with (math.md §4.1). It is fitted once — to the scene's
// bounds, by fit_light_frusta — and then held fixed: a constant of the render, not a function
// of the vertices, so that gradients and finite differences see the same function.
// Point light: eye at the light's position, looking at `target`, perspective with `fov_deg`.
// Directional light: orthographic with half-size `half_size`, looking along the light's
// direction at `target` from `distance` away.
// The widest frustum fit_light_frusta gives a point light (degrees): where its casters need a
// wider one (a light among the objects), it maps them on a cube (ShadowMapShape::Auto), or, held
// to one frustum, gives it this width, and casters beyond it cast no shadow.
constexpr double kWidestFit = 120.0;

// How a point light's shadows are mapped (docs/shadows.md, "Cube shadow maps"): `Frustum` (one
// shadow map, the frustum above), `Cube` (six, one per face of a cube around the light, each
// shading the points in its 90°: shadows in every direction, for six maps' cost), or `Auto`
// (one frustum when the casters fit in one at most kWidestFit wide, the cube when not).
// Directional lights have one frustum.
enum class ShadowMapShape { Auto, Frustum, Cube };

struct LightFrustum {
  bool fitted = false;
  bool automatic = false;  // fitted by fit_light_frusta, not given

  glm::dvec3 target{0, 0, 0};
  glm::dvec3 up{0, 1, 0};
  double fov_deg = 60.0;
  double half_size = 1.0;
  double distance = 10.0;
  double near = 0.1, far = 100.0;
  // Accurate soft shadows: the blocker search's variance σ_b (texel²), fixed with the fit like
  // the rest of the frustum; 0 (a given frustum): blocker_search_sigma computes it.
  double search_sigma = 0.0;
  // A point light's cube (fitted for ShadowMapShape::Cube or Auto): six frusta of `fov_deg`
  // sharing `near` and `far`, each looking along one axis from the light (`target` and `up`
  // unused). The renderer draws one shadow map per face (cube_faces).
  bool cube = false;
  // One face of a cube: 0 … 5 for +x, −x, +y, −y, +z, −z; −1 for a frustum of its own. A face
  // sheds its light only on the points whose direction from the light lies nearest its axis
  // (ties to the lower axis), so that exactly one face lights each point; its `fov_deg`, wider
  // than 90°, holds the filter windows of the points near its edges.
  int cube_face = -1;
};

struct Light {
  LightType type = LightType::Point;
  glm::dvec3 position{0, 5, 5};    // point light
  glm::dvec3 direction{0, -1, 0};  // directional light: direction the light travels
  glm::dvec3 color{1, 1, 1};       // RGB intensity I_L
  double size = 0.0;               // light diameter D_L (soft shadows)
  ShadowMapShape shadow_map = ShadowMapShape::Auto;  // point lights
  LightFrustum frustum;                              // fitted by fit_light_frusta when not given
};

// The lights as the renderer draws their shadow maps: each light whose frustum is a cube as its
// six faces (LightFrustum::cube_face 0 … 5, each a frustum of its own), every other light as
// it is; `light_of` gets, for each, the index of the light it came from.
std::vector<Light> cube_faces(const std::vector<Light>& lights, std::vector<int>* light_of);

enum class Shadows { None, Hard, Soft };
// How the Gaussian shadow filter is summed (docs/shadows.md): `Truncated` (the texels within
// the window where the weight exceeds ε_λ) or `Exact` (every texel of the map).
enum class Sampling { Truncated, Exact };
// One row per sampling method, in scene_words.cpp's table: its word (scene files, --sampling,
// Python), what it sums (--sampling's help), and whether that sum is a window around each
// fragment (`windowed`: the gathers then find the fragments through texel buckets, and the
// paper model's hard shadows take their per-fragment kernel) or the whole map (whose sum of
// the paper model's hard shadows factors into matrix products).
struct SamplingMethod {
  Sampling value;
  const char* word;
  const char* sums;
  bool windowed;
};
const std::vector<SamplingMethod>& sampling_methods();
const SamplingMethod& sampling_method(Sampling s);
// Who computes the exact sum of the paper model's hard shadows, which factors into two matrix
// products: `Kernels` (penumbra's kernels/paper_hard_exact.cl), `CLBlast` (CLBlast's GEMM), or
// `Auto` (the tuning's choice for the device: ExactSumTuning::clblast, data/tuning/*.json). Every
// other exact sum (soft shadows, the accurate model) runs penumbra's own kernels.
enum class ExactBackend { Auto, Kernels, CLBlast };
// How shadows are computed (docs/shadows.md): `Accurate` (percentage-closer filtering of a
// smooth-step depth compare with a receiver-plane bias; soft shadows widen the filter by the
// penumbra width found by a blocker search; light frusta fitted tightly to the occluders) or
// `Paper` (the paper's model: filter then compare for hard shadows, the penumbra map for soft).
// `Count` is no model but how many there are: every value below it has its row in
// shadow_models() and in the renderer's table (tests/test_shadow_models.cpp checks both).
enum class ShadowModel { Accurate, Paper, Count };
// One row per shadow model, in scene_words.cpp's table: its word (scene files, --shadow-model,
// Python, messages) and what it does (--shadow-model's help); its defaults of σ_s (texel²), γ_s and
// β (per depth unit) and of the map side W_s (shadow_sigma_s, ...); whether its light pass holds
// only the faces that can cast a shadow (`casters_only`: their coverage A is a lookup input and the
// frustum is fitted tightly to them; otherwise every vertex, so that every receiver lies in the
// map); and whether the exact sum of its hard shadows factors into two matrix products
// (`exact_products`: paper_hard_exact.cl or CLBlast, exact backend `clblast`), with why not where
// it does not
// (`no_products`).
struct ShadowModelTraits {
  ShadowModel value;
  const char* word;
  const char* does;
  double sigma_s, gamma_s, beta;
  int map_side;
  bool casters_only, exact_products;
  const char* no_products;
};
const std::vector<ShadowModelTraits>& shadow_models();
const ShadowModelTraits& shadow_model_traits(ShadowModel m);

// The words scene files, the command line and messages use for each value of an enum above,
// in one place: word(e), the value of a word (nullptr-like failure as false), and the list
// of choices for a message ("none, hard or soft").
template <class E>
const std::vector<std::pair<E, std::string>>& enum_words();
template <class E>
std::string word(E value) {
  for (const auto& [v, w] : enum_words<E>())
    if (v == value) return w;
  return "?";
}
template <class E>
bool from_word(const std::string& w, E* value) {
  for (const auto& [v, name] : enum_words<E>())
    if (name == w) return *value = v, true;
  return false;
}
template <class E>
std::string word_choices() {
  const auto& words = enum_words<E>();
  std::string out;
  for (size_t i = 0; i < words.size(); ++i)
    out += (i == 0 ? "" : i + 1 == words.size() ? " or " : ", ") + words[i].second;
  return out;
}

// The word "gemm", which scene files and --sampling keep accepting for sampling `exact` with
// exact backend `clblast` (the one word that sets both).
inline const char* gemm_shorthand() { return "gemm"; }
// The sampling (and, for the shorthand, the exact backend) of a word of `sampling`: a word of
// Sampling, or gemm_shorthand(). False for any other word.
bool sampling_from_word(const std::string& w, Sampling* sampling,
                        std::optional<ExactBackend>* backend);
// "truncated, exact or gemm": the words sampling_from_word accepts.
std::string sampling_word_choices();

// math.md §10, names as in its table.
struct RenderParams {
  double sigma = 1e-5;     // coverage sharpness σ (screen units²)
  double gamma = 1e-4;     // aggregation sharpness γ
  double eps = 1e-3;       // background depth ε of the aggregation
  double dist_eps = 1e-4;  // coverage cut-off ε_D
  // σ_s, γ_s and β: unset, each takes its shadow model's default (shadow_sigma_s, ...).
  std::optional<double> sigma_s;  // shadow-map Gaussian variance (texel²)
  double lambda_eps = 1e-3;       // truncation threshold ε_λ
  std::optional<double> gamma_s;  // depth-compare softness γ_s (depth units)
  std::optional<double> beta;     // depth bias β (depth units)
  double gamma_p = 10.0;          // penumbra soft-minimum sharpness γ_P
  bool cull_backfaces = false;
  Shadows shadows = Shadows::None;
  Sampling sampling = Sampling::Truncated;
  ExactBackend exact_backend = ExactBackend::Auto;  // exact sum of the paper's hard shadows
  ShadowModel shadow_model = ShadowModel::Accurate;
  // W_s = H_s, texels; unset, the shadow model's default (shadow_map_side).
  std::optional<int> shadow_map_size;
  double light_sigma = 0.0;  // σ_L of the light pass; 0 → σ/10 (light_pass_sigma)
  double light_gamma = 0.0;  // γ_L of the light pass; 0 → γ (light_pass_gamma)
  // A fragment whose aggregation weight is below ε_w times the largest (the background's
  // included) is left out of the colour and depth (but not the silhouette), so
  // that shadow terms are sampled only where they can show.
  double weight_eps = 1e-10;
  // World size that the depth-unit defaults of γ_s and β are for (1: a unit-radius object);
  // framed_scene sets the mesh's bounding radius.
  double depth_unit = 1.0;
};

// σ_s, γ_s and β in force: the value given, else the shadow model's default — paper: 2 texel²,
// 0.02, 0.05 (math.md §10); accurate: 0.35 texel², 0.004, 0.01 (its compare needs no slack for a
// tilted receiver, so a small β keeps contact shadows closed; docs/shadows.md). γ_s and β
// defaults are multiplied by depth_unit.
double shadow_sigma_s(const RenderParams& p);
double shadow_gamma_s(const RenderParams& p);
double shadow_beta(const RenderParams& p);
// The shadow map's side W_s = H_s in force: shadow_map_size, else the shadow model's default —
// paper: 256 texels; accurate: 384 (a hard shadow's edge falls within a fraction of a texel of
// the true edge, so the map sets how far it can stray; against the ray tracer a 256² map left
// one contact pixel lit on a knot touching the ground, bench/accuracy.hpp).
int shadow_map_side(const RenderParams& p);

struct Scene {
  std::vector<Mesh> meshes;
  std::vector<Camera> cameras;
  std::vector<Light> lights;
  glm::dvec3 ambient{0.2, 0.2, 0.2};
  glm::dvec3 background{1, 1, 1};
  RenderParams params;
};

// What validate() makes of a face whose corners are on one line (zero area): `Refuse` it (a
// file's mesh: a fault of the file) or `Allow` it (what render() does: such a face contributes
// nothing and gets a zero gradient, so an optimisation step that collapses a face goes on).
enum class DegenerateFaces { Refuse, Allow };
// Throws penumbra::Error naming the first problem: NaN/inf values, out-of-range indices,
// zero-area faces (unless allowed), albedo count mismatch, zero-size images, non-positive σ/γ,
// near ≥ far, ...
void validate(const Scene& scene, DegenerateFaces degenerate = DegenerateFaces::Refuse);
void validate(const Mesh& mesh, DegenerateFaces degenerate = DegenerateFaces::Refuse);
// Whether validate() calls the triangle (a, b, c) degenerate: its corners on one line, twice
// its area at most 1e-12 times its longest edge squared (at any scale).
bool degenerate_triangle(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c);

// Axis-aligned bounds and bounding sphere of all meshes.
struct Bounds {
  glm::dvec3 lo, hi;
  glm::dvec3 center() const { return 0.5 * (lo + hi); }
  double radius() const { return 0.5 * glm::length(hi - lo); }
};
Bounds bounds(const Scene& scene);

// σ_L and γ_L of the light pass (math.md §4.2): light_sigma / light_gamma when set, else σ_L = σ/10
// and γ_L = γ.
// A face's soft depth just outside its edge is taken at its nearest boundary point (clamped
// barycentrics, math.md §2.2), which biases S near the edges of coplanar neighbours by about
// (√σ_L in texels) × (depth slope per texel); at σ_L = σ a ground plane seen at a grazing angle
// showed faint lines along every edge. A tenth of σ keeps the bias well under β. The accurate
// model weights each compare by the casters' coverage, which keeps its shadow's edge on the
// outline; against the ray tracer (bench/accuracy.hpp) a sharper σ/32 (with σ_s = 0.5) left
// the knots' hard shadow-region RMSE at 0.0495, σ/10 with σ_s = 0.35 gives 0.047.
double light_pass_sigma(const RenderParams& p);
double light_pass_gamma(const RenderParams& p);

// Fits the frustum of every light whose frustum is not fitted yet (docs/scene-format.md): the
// light looks at the centre of the bounds of what it must hold and its cone (orthographic box)
// holds it, its depth range every vertex. The paper model holds every vertex, so that every
// receiver lies inside the map; the accurate model holds the faces that can cast a shadow,
// widened by their penumbra and the filter window (receivers outside the map are lit).
void fit_light_frusta(Scene& scene);

// Variance σ_b (texel²) of the accurate model's blocker search for `light` (soft shadows; σ_s
// otherwise): wide enough for the widest penumbra its fitted frustum can hold, the nearest
// depth over the farthest, capped at a window of half the map.
double blocker_search_sigma(const RenderParams& p, const Light& light);
// The blocker search's stride for variance σ_b: it sums over every stride-th texel of each axis,
// the largest stride that its Gaussian's standard deviation spans twice (1 for σ_b < 16).
int blocker_search_stride(double sigma_b);

// Fits again the frusta fit_light_frusta fitted (after render parameters changed).
void refit_light_frusta(Scene& scene);

// Whether `light`'s frustum (fitted or given) holds every vertex of the faces that can cast a
// shadow in `scene`: where it does not, those shadows are cut off at the map's edge.
bool frustum_holds_casters(const Scene& scene, const Light& light);

// Every vertex of every mesh, in order.
std::vector<glm::dvec3> scene_vertices(const Scene& scene);

// A scene around one mesh, with a camera and a light that frame it (for `render --mesh`).
Scene framed_scene(Mesh mesh, int width = 256, int height = 256);

// `camera` turned by `angle` radians about the vertical (+y) axis through its target (the
// turnaround's frames).
Camera orbit(const Camera& camera, double angle);

}  // namespace penumbra
