// View parameter blocks and frames (view_params.hpp).
#include "view_params.hpp"

#include <cmath>

#include "common/layout.h"
#include "shadow_models.hpp"

namespace penumbra::detail {
namespace {

// A camera's frame: where it is and where it looks (layout.h, FR_*).
struct Frame {
  glm::dvec3 eye, fwd, right, up;
  double scale = 1;
  bool ortho = false;
};

Frame make_frame(glm::dvec3 eye, glm::dvec3 fwd, glm::dvec3 up_hint, double scale, bool ortho) {
  Frame f;
  f.eye = eye;
  f.fwd = glm::normalize(fwd);
  f.right = glm::normalize(glm::cross(f.fwd, up_hint));
  f.up = glm::cross(f.right, f.fwd);
  f.scale = scale;
  f.ortho = ortho;
  return f;
}

double tan_half(double fov_deg) { return std::tan(0.5 * fov_deg * 3.14159265358979323846 / 180); }

Frame camera_frame(const Camera& c) {
  bool ortho = c.projection == Projection::Orthographic;
  return make_frame(c.eye, c.target - c.eye, c.up, ortho ? c.half_height : tan_half(c.fov_deg),
                    ortho);
}

// A point light looks from its position at the frustum's target; a directional light looks
// along its direction from `distance` before the target.
Frame light_frame(const Light& L) {
  const LightFrustum& f = L.frustum;
  if (L.type == LightType::Point)
    return make_frame(L.position, f.target - L.position, f.up, tan_half(f.fov_deg), false);
  glm::dvec3 d = glm::normalize(L.direction);
  return make_frame(f.target - f.distance * d, d, f.up, f.half_size, true);
}

}  // namespace

// dL/d(light position, or direction) through the light's frame, given dL/d(eye, fwd, right, up).
glm::dvec3 light_frame_backward(const Light& L, glm::dvec3 g_eye, glm::dvec3 g_fwd,
                                glm::dvec3 g_right, glm::dvec3 g_up) {
  // A cube's face looks along its axis wherever the light is (cube_faces): its frame moves with
  // the light without turning.
  if (L.frustum.cube_face >= 0) return g_eye;
  const Frame fr = light_frame(L);
  const LightFrustum& f = L.frustum;
  // up = right × fwd
  g_right += glm::cross(fr.fwd, g_up);
  g_fwd += glm::cross(g_up, fr.right);
  // right = normalize(w), w = fwd × up_hint
  glm::dvec3 w = glm::cross(fr.fwd, f.up);
  glm::dvec3 g_w = (g_right - fr.right * glm::dot(fr.right, g_right)) / glm::length(w);
  g_fwd += glm::cross(f.up, g_w);
  if (L.type == LightType::Point) {  // eye = position, fwd = normalize(target − position)
    glm::dvec3 v = f.target - L.position;
    return g_eye - (g_fwd - fr.fwd * glm::dot(fr.fwd, g_fwd)) / glm::length(v);
  }
  g_fwd -= f.distance * g_eye;  // eye = target − distance·fwd, fwd = normalize(direction)
  return (g_fwd - fr.fwd * glm::dot(fr.fwd, g_fwd)) / glm::length(L.direction);
}

namespace {

void put3(std::vector<double>& P, int at, glm::dvec3 v) {
  P[at] = v.x;
  P[at + 1] = v.y;
  P[at + 2] = v.z;
}

void put_frame(std::vector<double>& P, int at, const Frame& f) {
  put3(P, at + FR_EYE, f.eye);
  put3(P, at + FR_FWD, f.fwd);
  put3(P, at + FR_RIGHT, f.right);
  put3(P, at + FR_UP, f.up);
  P[at + FR_SCALE] = f.scale;
  P[at + FR_ORTHO] = f.ortho ? 1 : 0;
}

// Parameters shared by camera and light views.
std::vector<double> base_params(const RenderParams& r, double sigma, double gamma, double near,
                                double far, const Frame& frame) {
  std::vector<double> P(P_SIZE, 0.0);
  P[P_SIGMA] = sigma;
  P[P_GAMMA] = gamma;
  P[P_EPS] = r.eps;
  P[P_CUTOFF_D2] = sigma * std::log(1.0 / r.dist_eps - 1.0);
  P[P_NEAR] = near;
  P[P_FAR] = far;
  P[P_CULL] = r.cull_backfaces ? 1 : 0;
  P[P_WEIGHT_LOG] = std::log(1.0 / r.weight_eps);
  P[P_SHADOWS] = double(int(r.shadows));
  P[P_SIGMA_S] = shadow_sigma_s(r);
  P[P_LAMBDA_EPS] = r.lambda_eps;
  P[P_WINDOW_R2] = 2 * P[P_SIGMA_S] * std::log(1 / r.lambda_eps);  // once here, not per fragment
  P[P_WINDOW_R] = std::sqrt(P[P_WINDOW_R2]);
  // The texel nearest a μ, at most half a texel off along each axis, weighs e^(−1/(4σ_s)) or
  // more: where that is at least 2ε_λ (and the window reaches half a texel), its g' ≥ ε_λ > 0
  // (the factor 2 absorbs the kernels' rounding).
  P[P_NEAREST_TEXEL_COUNTS] =
      P[P_WINDOW_R] >= 0.5 && std::exp(-0.25 / P[P_SIGMA_S]) >= 2 * r.lambda_eps ? 1 : 0;
  P[P_GAMMA_S] = shadow_gamma_s(r);
  P[P_BETA] = shadow_beta(r);
  P[P_GAMMA_P] = r.gamma_p;
  put_frame(P, P_FRAME, frame);
  return P;
}

}  // namespace

std::vector<double> view_params(const Scene& s, const Camera& c) {
  std::vector<double> P =
      base_params(s.params, s.params.sigma, s.params.gamma, c.near, c.far, camera_frame(c));
  P[P_NLIGHTS] = double(s.lights.size());
  const ShadowModelPasses& model = shadow_model_passes(s.params.shadow_model);
  P[P_SHADOW_MODEL] = model.layout_code;
  P[P_RECEIVER_PLANE] = s.params.shadows == Shadows::Soft ||
                        (model.hard_receiver_plane && s.params.shadows == Shadows::Hard);
  put3(P, P_AMBIENT, s.ambient);
  put3(P, P_BACKGROUND, s.background);
  for (size_t i = 0; i < s.lights.size(); ++i) {
    const Light& L = s.lights[i];
    int at = P_LIGHTS + int(i) * P_LIGHT_STRIDE;
    put3(P, at + L_POS, L.type == LightType::Point ? L.position : L.direction);
    P[at + L_POINT] = L.type == LightType::Point ? 1 : 0;
    put3(P, at + L_COLOR, L.color);
    P[at + L_SIZE] = L.size;
    if (s.params.shadows != Shadows::None)  // (no frustum is fitted for a view without)
      put_frame(P, at + L_FRAME, light_frame(L));
    P[at + L_MAP_W] = P[at + L_MAP_H] = shadow_map_side(s.params);
    P[at + L_SEARCH_SIGMA] = blocker_search_sigma(s.params, L);
    P[at + L_SEARCH_STRIDE] = blocker_search_stride(P[at + L_SEARCH_SIGMA]);
    P[at + L_CUBE_FACE] = L.frustum.cube_face;
  }
  return P;
}

// The view of light `i` rendering its shadow map: depth only (no lights, black).
std::vector<double> light_view_params(const Scene& s, size_t i) {
  const RenderParams& r = s.params;
  const LightFrustum& f = s.lights[i].frustum;
  std::vector<double> P = base_params(r, light_pass_sigma(r), light_pass_gamma(r), f.near, f.far,
                                      light_frame(s.lights[i]));
  P[P_SHADOWS] = 0;
  P[P_LIGHT_SIZE] = s.lights[i].size;
  if (shadow_model_traits(r.shadow_model).casters_only) {  // the map holds the casters alone
    const Bounds b = bounds(s);
    P[P_CASTERS_ONLY] = 1;
    put3(P, P_SCENE_LO, b.lo);
    put3(P, P_SCENE_HI, b.hi);
  }
  return P;
}

}  // namespace penumbra::detail
