// Plain double-precision reference of the forward pass (math.md §1–§3) with hard shadows (math.md
// §4.2, §6.1, eq. 7: filter then compare) and soft shadows (math.md §4.3 penumbra map, §6.3 eq. 11:
// compare then filter, with the receiver-plane depth bias and the front-most test), with truncated
// or exact Gaussian sampling of the maps.
//
// Written for clarity, not speed: every pixel of the view visits every face of every mesh, with
// no tiling, no cut-off shortcuts beyond the coverage cut-off of math.md §2.1, and no shared
// code with the OpenCL kernels. Tests compare the kernels against this file. The light pass
// (shadow map S) is the same raster as the camera's, run from the light's frame.
//
// Conventions (the kernels follow the same ones):
//   camera basis   f = normalize(target − eye), r = normalize(f × up), u = r × f;
//   view space     c = P − eye, z = c·f, x_c = c·r, y_c = c·u;
//   screen         perspective x = x_c / (z·tan(fov/2)), y = y_c / (z·tan(fov/2));
//                  orthographic x = x_c / h, y = y_c / h (depth z as above);
//   pixel centres  x = (2px + 1 − W)/H, y = (H − 2py − 1)/H, row 0 at the top.
//   light frames   point light: eye = position, f = normalize(frustum.target − position),
//                  perspective with the frustum's fov; directional: f = normalize(direction),
//                  eye = frustum.target − distance·f, orthographic with half-height half_size;
//                  r and u from frustum.up as for a camera; near/far from the frustum.
//   shadow map     μx = (x·H_s + W_s − 1)/2, μy = (H_s − 1 − y·H_s)/2 (texel centres at
//                  integers, row 0 at the top), d = the light-view depth z.
//   penumbra map   per texel of the light's view, over every face valid in that view, with the
//                  membership offset of math.md §4.3 (m = max(0, σ(x) − σ₀)/(1 − σ₀)).
//
// The kernels also leave out of colour and depth a fragment whose aggregation weight is below
// weight_eps times the pixel's largest; the reference keeps every fragment (the difference is
// at most ~weight_eps relative).
#include "penumbra/reference.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <glm/glm.hpp>
#include <limits>
#include <string>
#include <vector>

#include "common/layout.h"
#include "penumbra/error.hpp"
#include "reference/raster.hpp"

namespace penumbra::reference {

using namespace detail;  // the rasterizer (raster.hpp)

namespace {

// The scene as the renderer sees it: light frusta not given are fitted (math.md §4.1), a cube's
// faces lights of their own (cube_faces).
Scene fitted(const Scene& scene) {
  Scene s = scene;
  if (!s.lights.empty()) fit_light_frusta(s);
  s.lights = cube_faces(s.lights, nullptr);
  return s;
}

// The share of `light` at X: a cube's face k (math.md §4.1) W_k / Σ_j W_j, W_j the product of
// g(r) = 1 − smoothstep(−1, 1, ln r / ln CUBE_BLEND_TAN) over X's two tangents r off face j's
// axis (0 behind the face); any other light 1.
double share(const Light& light, const dvec3& X) {
  const int face = light.frustum.cube_face;
  if (face < 0) return 1.0;
  const dvec3 u = X - light.position;
  auto g = [](double r) {
    const double t = std::clamp((std::log(r) / std::log(CUBE_BLEND_TAN) + 1) / 2, 0.0, 1.0);
    return 1 - t * t * (3 - 2 * t);
  };
  double W[6];
  for (int j = 0; j < 6; ++j) {
    const int a = j / 2;
    const double d = j % 2 ? -u[a] : u[a];
    W[j] = d > 0 ? g(std::abs(u[(a + 1) % 3]) / d) * g(std::abs(u[(a + 2) % 3]) / d) : 0.0;
  }
  const double sum = W[0] + W[1] + W[2] + W[3] + W[4] + W[5];
  return sum > 0 ? W[face] / sum : 0.0;
}

// The light pass of light `index` of a scene whose frusta are fitted (math.md §4.2): the soft depth
// I_z from the light's frame with σ_L, γ_L (light_sigma, light_gamma when set, else the
// documented defaults of light_pass_sigma, light_pass_gamma); the background lies at the
// frustum's far plane.
struct ShadowMap {
  View view;
  Image S;  // W_s × H_s, row-major, row 0 at the top
  Image P;  // the penumbra map, same layout (soft shadows only; empty otherwise)
  Image A;  // the silhouette of the light pass: its faces' coverage (the accurate model's)
};

// The scene without the faces that cannot cast a shadow from `light`: those facing it with the
// whole bounding box on its side of their plane (within 1e-5 of the box's diagonal).
Scene casters_only(const Scene& scene, const Light& light) {
  const Bounds b = bounds(scene);
  const double tol = 1e-5 * glm::length(b.hi - b.lo);
  Scene out = scene;
  for (size_t m = 0; m < scene.meshes.size(); ++m) {
    const Mesh& in = scene.meshes[m];
    Mesh& kept = out.meshes[m];
    kept.faces.clear();
    if (in.albedo_mode == AlbedoMode::PerFace) kept.albedo.clear();
    for (size_t fi = 0; fi < in.faces.size(); ++fi) {
      const dvec3 V0 = in.vertices[size_t(in.faces[fi].x)];
      const dvec3 n = glm::normalize(glm::cross(in.vertices[size_t(in.faces[fi].y)] - V0,
                                                in.vertices[size_t(in.faces[fi].z)] - V0));
      const dvec3 to_light =
          light.type == LightType::Point ? light.position - V0 : -light.direction;
      bool shadows_nothing = glm::dot(n, to_light) > 0;
      for (int c = 0; c < 8 && shadows_nothing; ++c) {
        const dvec3 corner(c & 1 ? b.hi.x : b.lo.x, c & 2 ? b.hi.y : b.lo.y,
                           c & 4 ? b.hi.z : b.lo.z);
        shadows_nothing = glm::dot(n, corner - V0) >= -tol;
      }
      if (shadows_nothing) continue;
      kept.faces.push_back(in.faces[fi]);
      if (in.albedo_mode == AlbedoMode::PerFace) kept.albedo.push_back(in.albedo[fi]);
    }
  }
  return out;
}

ShadowMap light_pass(const Scene& scene, size_t index) {
  const RenderParams& p = scene.params;
  const View view = View::of_light(scene.lights.at(index), shadow_map_side(p));
  const double sigma = light_pass_sigma(p);
  const double gamma = light_pass_gamma(p);
  const Shader no_colour = [](const Face&, const dvec3&) { return dvec3(0.0); };
  const bool casters = shadow_model_traits(p.shadow_model).casters_only;
  RenderOutput out = raster(casters ? casters_only(scene, scene.lights[index]) : scene, view, sigma,
                            gamma, dvec3(0.0), no_colour);
  return {view, std::move(out.depth), Image(), std::move(out.silhouette)};
}

// The penumbra map P of light `index` (math.md §4.3, paper eqs. 9–10, outer penumbra only) from its
// shadow map S: for texel centre q with receiver depth S_q and every face t valid in the light's
// view, d_t = distance from q to t (screen units, 0 strictly inside), z_t = depth of t at q
// (clamped barycentrics, perspective-correct unless orthographic); t counts if z_t < S_q, D_L > 0
// and τ_t = r_t/b_t < 1 with b_t = D_L·(S_q − z_t)/S_q, r_t = d_t·z_t·tan(θ_L/2) (or d_t·h_L).
// Membership m_t = max(0, σ(x) − σ₀)/(1 − σ₀), x = (S_q − β − z_t)/γ_s, σ₀ = σ(−β/γ_s)
// (math.md §4.3); v_t = 1 − m_t·(1 − τ_t), a_t = (1 − v_t)·e^{−γ_P v_t};
// P_q = (e^{−γ_P} + Σ a_t v_t)/(e^{−γ_P} + Σ a_t). Every texel visits every face (no culling).
Image penumbra(const Scene& scene, const ShadowMap& map, double light_size) {
  const RenderParams& p = scene.params;
  const View& view = map.view;
  const std::vector<Face> faces = setup_faces(scene, view);
  const int W = view.width, H = view.height;
  const double sigma0 = sigmoid(-shadow_beta(p) / shadow_gamma_s(p));
  const double lit = std::exp(-p.gamma_p);
  Image P(W, H, 1);
  for (int j = 0; j < H; ++j)
    for (int i = 0; i < W; ++i) {
      const dvec2 q = view.pixel_center(i, j);
      const double Sq = map.S.at(i, j);
      double num = 0.0, den = 0.0;
      for (const Face& face : faces) {
        dvec3 w;
        for (int k = 0; k < 3; ++k)
          w[k] = cross2(face.p[(k + 1) % 3] - q, face.p[(k + 2) % 3] - q) / face.area2;
        const bool inside = w[0] > 0.0 && w[1] > 0.0 && w[2] > 0.0;
        dvec3 wc(std::max(w[0], 0.0), std::max(w[1], 0.0), std::max(w[2], 0.0));
        wc /= wc[0] + wc[1] + wc[2];
        const double z = view.perspective
                             ? 1.0 / (wc[0] / face.z[0] + wc[1] / face.z[1] + wc[2] / face.z[2])
                             : wc[0] * face.z[0] + wc[1] * face.z[1] + wc[2] * face.z[2];
        if (!(z < Sq) || !(light_size > 0.0)) continue;  // only occluders in front count
        const double d = inside
                             ? 0.0
                             : std::sqrt(std::min({point_segment_dist2(q, face.p[0], face.p[1]),
                                                   point_segment_dist2(q, face.p[1], face.p[2]),
                                                   point_segment_dist2(q, face.p[2], face.p[0])}));
        const double b = light_size * (Sq - z) / Sq;                            // cone width
        const double r = d * (view.perspective ? z * view.scale : view.scale);  // world units
        const double tau = r / b;
        if (!(tau < 1.0)) continue;  // q outside t's cone
        const double x = (Sq - shadow_beta(p) - z) / shadow_gamma_s(p);
        const double m = std::max(0.0, sigmoid(x) - sigma0) / (1.0 - sigma0);
        const double v = 1.0 - m * (1.0 - tau);
        const double a = (1.0 - v) * std::exp(-p.gamma_p * v);
        num += a * v;
        den += a;
      }
      P.at(i, j) = (lit + num) / (lit + den);
    }
  return P;
}

ShadowMap light_pass_with_penumbra(const Scene& scene, size_t index) {
  ShadowMap map = light_pass(scene, index);
  map.P = penumbra(scene, map, scene.lights.at(index).size);
  return map;
}

// Texel coordinates μ of screen point s in the map (the shadow-map convention above).
dvec2 map_texel(const ShadowMap& map, dvec2 s) {
  const double Ws = map.S.width, Hs = map.S.height;
  return {(s.x * Hs + Ws - 1) / 2.0, (Hs - 1 - s.y * Hs) / 2.0};
}
bool inside_map(const ShadowMap& map, dvec2 mu) {
  return mu.x >= -0.5 && mu.x < map.S.width - 0.5 && mu.y >= -0.5 && mu.y < map.S.height - 0.5;
}

// Calls visit(i, j, dx, dy, g') for every texel (i, j) = μ + (dx, dy), of every stride-th row
// and column, where the weight g' = g − ε of the Gaussian g of variance σ around μ is positive,
// in row order: truncated, ε = cut and only the texels within R = sqrt(2σ·ln(1/ε)); exact,
// ε = 0 and every texel.
template <class Visit>
void for_each_weight(const ShadowMap& map, const RenderParams& p, dvec2 mu, double sigma,
                     double cut, int stride, Visit visit) {
  const int Ws = map.S.width, Hs = map.S.height;
  int i0 = 0, i1 = Ws - 1, j0 = 0, j1 = Hs - 1;
  double eps = 0.0;
  if (p.sampling == Sampling::Truncated) {
    eps = cut;
    const double R = std::sqrt(2.0 * sigma * std::log(1.0 / eps));
    i0 = std::max(int(std::ceil(mu.x - R)), 0);
    i1 = std::min(int(std::floor(mu.x + R)), Ws - 1);
    j0 = std::max(int(std::ceil(mu.y - R)), 0);
    j1 = std::min(int(std::floor(mu.y + R)), Hs - 1);
  }
  for (int j = j0; j <= j1; ++j)
    for (int i = i0; i <= i1; ++i) {
      if (i % stride != 0 || j % stride != 0) continue;
      const double dx = i - mu.x, dy = j - mu.y;
      const double g = std::exp(-(dx * dx + dy * dy) / (2.0 * sigma)) - eps;
      if (g > 0.0) visit(i, j, dx, dy, g);
    }
}

// Shadow term s of world point X for one light (math.md §6.1, hard shadows, eq. 7): Gaussian-
// filtered map depth around X's texel position, compared with X's light depth.
double shadow_term(const ShadowMap& map, const RenderParams& p, const dvec3& X) {
  const dvec2 mu = map_texel(map, map.view.screen(X));
  const double d = map.view.depth(X);
  if (!inside_map(map, mu)) return 1.0;
  double sum = 0.0, acc = 0.0;
  for_each_weight(map, p, mu, shadow_sigma_s(p), p.lambda_eps, 1,
                  [&](int i, int j, double, double, double g) {
                    sum += g;
                    acc += g * map.S.at(i, j);
                  });
  if (!(sum > 0.0)) return 1.0;  // no texel has weight: lit
  return sigmoid((acc / sum - d + shadow_beta(p)) / shadow_gamma_s(p));
}

// Receiver-plane depth gradient ∇_μ d (math.md §5.3) of `face` at a point of light depth d: the
// gradient of light-view depth over the face's plane with respect to texel coordinates. With the
// corners projected to (μ_k, z_k), A = cross2(μ1 − μ0, μ2 − μ0) and n_k = ∇_μ(A·w_k), perspective
// 1/d is affine in μ: ∇d = −d²·Σ_k n_k/(A·z_k); orthographic ∇d = Σ_k n_k·z_k/A. Zero for a face
// edge-on to the light (|A| ≤ machine ε relative to its squared edge lengths).
dvec2 receiver_gradient(const ShadowMap& map, const Face& face, double d) {
  std::array<dvec2, 3> mu;
  std::array<double, 3> z;
  for (int k = 0; k < 3; ++k) {
    mu[k] = map_texel(map, map.view.screen(face.V[k]));
    z[k] = map.view.depth(face.V[k]);
  }
  const dvec2 e1 = mu[1] - mu[0], e2 = mu[2] - mu[0];
  const double A = cross2(e1, e2);
  if (std::abs(A) <= std::numeric_limits<double>::epsilon() * (glm::dot(e1, e1) + glm::dot(e2, e2)))
    return dvec2(0.0);
  dvec2 G(0.0);
  for (int k = 0; k < 3; ++k) {
    const dvec2 a = mu[size_t(k + 1) % 3], b = mu[size_t(k + 2) % 3];
    const dvec2 n(a.y - b.y, b.x - a.x);
    G += map.view.perspective ? n / (A * z[size_t(k)]) : n * z[size_t(k)] / A;
  }
  return map.view.perspective ? -d * d * G : G;
}

// Shadow term s of world point X on `face` for one light (math.md §6.3, soft shadows, eq. 11:
// compare then filter): every texel of the window compares its S with the receiver's depth
// extrapolated along the face's plane, d_ij = d + ∇_μ d·((i, j) − μ); front = σ((S − d_ij +
// β)/γ_s), at = σ((d_ij − S + β)/γ_s), term = front·(1 − at·(1 − P)); s = Σ g'·term / Σ g'.
double soft_shadow_term(const ShadowMap& map, const RenderParams& p, const Face& face,
                        const dvec3& X) {
  const dvec2 mu = map_texel(map, map.view.screen(X));
  const double d = map.view.depth(X);
  if (!inside_map(map, mu)) return 1.0;
  const dvec2 grad = receiver_gradient(map, face, d);
  double sum = 0.0, acc = 0.0;
  for_each_weight(map, p, mu, shadow_sigma_s(p), p.lambda_eps, 1,
                  [&](int i, int j, double dx, double dy, double g) {
                    const double dij = d + grad.x * dx + grad.y * dy;
                    const double S = map.S.at(i, j), P = map.P.at(i, j);
                    const double front = sigmoid((S - dij + shadow_beta(p)) / shadow_gamma_s(p));
                    const double at = sigmoid((dij - S + shadow_beta(p)) / shadow_gamma_s(p));
                    sum += g;
                    acc += g * front * (1.0 - at * (1.0 - P));
                  });
  if (!(sum > 0.0)) return 1.0;  // no texel has weight: lit
  return acc / sum;
}

// The accurate model (kernels/accurate_lookups.cl): c = 1 − A·smoothstep(β − 2γ_s, β + 2γ_s, d_ij −
// S_ij).
double lit_step(double delta, double A, const RenderParams& p) {
  const double t = std::clamp(
      (delta - (shadow_beta(p) - 2 * shadow_gamma_s(p))) / (4 * shadow_gamma_s(p)), 0.0, 1.0);
  return 1 - A * t * t * (3 - 2 * t);
}

// Σw, Σw·c, Σw·S, Σw·c·S over the Gaussian window of variance `sigma` around μ, at every
// `stride`-th texel of each axis.
std::array<double, 4> pcf_sums(const ShadowMap& map, const RenderParams& p, dvec2 mu, double d,
                               dvec2 grad, double sigma, double cut, int stride = 1) {
  std::array<double, 4> sums{};
  for_each_weight(map, p, mu, sigma, cut, stride,
                  [&](int i, int j, double dx, double dy, double g) {
                    const double S = map.S.at(i, j);
                    const double c = lit_step(d + grad.x * dx + grad.y * dy - S, map.A.at(i, j), p);
                    sums[0] += g, sums[1] += g * c, sums[2] += g * S, sums[3] += g * c * S;
                  });
  return sums;
}

// Shadow term s of world point X on `face` for `light` in the accurate model: percentage-closer
// filtering with σ_s (hard), or with σ widened by the penumbra width from a blocker search (soft).
double pcf_shadow_term(const ShadowMap& map, const RenderParams& p, const Light& light,
                       const Face& face, const dvec3& X) {
  const dvec2 mu = map_texel(map, map.view.screen(X));
  const double d = map.view.depth(X);
  if (!inside_map(map, mu)) return 1.0;
  const int Hs = map.S.height;
  dvec2 grad = receiver_gradient(map, face, d);
  const bool ortho = light.type == LightType::Directional;
  const double k =
      Hs / (2 * (ortho ? light.frustum.half_size : std::tan(light.frustum.fov_deg * M_PI / 360)));
  // Slope limit: a face within 1° of edge-on extrapolates as if at 1° (texel size over tan 1°).
  const double limit = (ortho ? 1.0 : std::abs(d)) / (k * 0.017455), len = glm::length(grad);
  if (len > limit) grad *= limit / len;
  double sigma = shadow_sigma_s(p);
  if (p.shadows == Shadows::Soft) {
    const double sigma_b = blocker_search_sigma(p, light);
    const auto b = pcf_sums(map, p, mu, d, grad, sigma_b, 0.05,  // the search's cut and stride
                            blocker_search_stride(sigma_b));
    const double kappa = 1e-3 * b[0], V = b[0] - b[1] + kappa;
    const double zb = V > 0 ? (b[2] - b[3] + kappa * d) / V : d;
    const double w = light.size * k * std::max(0.0, ortho ? d - zb : 1 / zb - 1 / d);
    sigma = std::min(shadow_sigma_s(p) + w * w / 16, sigma_b);
  }
  const auto f = pcf_sums(map, p, mu, d, grad, sigma, p.lambda_eps);
  return f[0] > 0.0 ? f[1] / f[0] : 1.0;
}

// The shadow term of `light` at X by the reference of the scene's shadow model (a model added
// to ShadowModel without a case here stops the build: -Wswitch).
double shadow_term_of_model(const ShadowMap& map, const RenderParams& p, const Light& light,
                            const Face& face, const dvec3& X) {
  switch (p.shadow_model) {
    case ShadowModel::Accurate:
      return pcf_shadow_term(map, p, light, face, X);
    case ShadowModel::Paper:
      return p.shadows == Shadows::Soft ? soft_shadow_term(map, p, face, X)
                                        : shadow_term(map, p, X);
    case ShadowModel::Count:
      break;
  }
  throw Error("reference: no shadow model " + std::to_string(int(p.shadow_model)));
}

// Colour of face `face` at perspective-correct barycentrics b (math.md §3), with shadow terms
// from `maps` (one per light; empty when shadows are off, s = 1).
dvec3 shade(const Scene& scene, const View& view, const std::vector<ShadowMap>& maps,
            const Face& face, const dvec3& b) {
  const dvec3 X = b[0] * face.V[0] + b[1] * face.V[1] + b[2] * face.V[2];
  const dvec3 a = b[0] * face.albedo[0] + b[1] * face.albedo[1] + b[2] * face.albedo[2];
  dvec3 n = face.normal;
  const dvec3 to_camera = view.perspective ? view.eye - X : -view.f;
  if (glm::dot(n, to_camera) < 0.0) n = -n;
  dvec3 color = a * scene.ambient;  // never shadowed
  for (size_t li = 0; li < scene.lights.size(); ++li) {
    const Light& light = scene.lights[li];
    const double w = share(light, X);
    if (w == 0) continue;
    const dvec3 l = light.type == LightType::Point ? glm::normalize(light.position - X)
                                                   : -glm::normalize(light.direction);
    const double s =
        maps.empty() ? 1.0 : shadow_term_of_model(maps[li], scene.params, light, face, X);
    color += s * w * a * light.color * std::max(0.0, glm::dot(n, l));
  }
  return color;
}

void require_light(const Scene& scene, size_t light) {
  if (light >= scene.lights.size())
    throw Error("reference: light " + std::to_string(light) + " asked for; the scene has " +
                std::to_string(scene.lights.size()));
}

}  // namespace

RenderOutput render(const Scene& scene, size_t camera_index) {
  validate(scene);
  const Camera& cam = scene.cameras.at(camera_index);
  const Scene work =  // frusta fitted when shadows need them
      scene.params.shadows == Shadows::None ? scene : fitted(scene);
  const View view = View::of_camera(cam);

  std::vector<ShadowMap> maps;
  const bool penumbra_maps =
      work.params.shadows == Shadows::Soft && work.params.shadow_model == ShadowModel::Paper;
  if (work.params.shadows != Shadows::None && !penumbra_maps)
    for (size_t l = 0; l < work.lights.size(); ++l) maps.push_back(light_pass(work, l));
  if (penumbra_maps)
    for (size_t l = 0; l < work.lights.size(); ++l)
      maps.push_back(light_pass_with_penumbra(work, l));

  const Shader shader = [&](const Face& face, const dvec3& b) {
    return shade(work, view, maps, face, b);
  };
  return raster(work, view, work.params.sigma, work.params.gamma, work.background, shader);
}

Image shadow_map(const Scene& scene, size_t light) {
  require_light(scene, light);
  return light_pass(fitted(scene), light).S;
}

Image penumbra_map(const Scene& scene, size_t light) {
  require_light(scene, light);
  return light_pass_with_penumbra(fitted(scene), light).P;
}

}  // namespace penumbra::reference
