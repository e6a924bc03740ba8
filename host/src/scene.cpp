// Scene validation, bounds and the default framing of a single mesh (scene.hpp).
#include "penumbra/scene.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <string>

#include "penumbra/error.hpp"

namespace penumbra {
namespace {

constexpr int kMaxImageSize = 16384;

// Values in messages: shortest form that identifies the number (%.9g-like).
std::string num(double v) {
  std::ostringstream s;
  s.precision(9);
  s << v;
  return s.str();
}

std::string vec(const glm::dvec3& v) {
  return "(" + num(v.x) + ", " + num(v.y) + ", " + num(v.z) + ")";
}

std::string ivec(const glm::ivec3& v) {
  return "(" + std::to_string(v.x) + ", " + std::to_string(v.y) + ", " + std::to_string(v.z) +
         ")";
}

bool finite(const glm::dvec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

bool any_negative(const glm::dvec3& v) { return v.x < 0 || v.y < 0 || v.z < 0; }

[[noreturn]] void fail(const std::string& message) { throw Error(message); }

// Twice the area of the triangle (a, b, c) over its longest edge squared: 0 for corners on one
// line, at most √3/2, the same at any scale and whatever else the mesh holds. The edges are
// first divided by their largest coordinate, so that no square overflows or underflows.
double relative_area(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c) {
  glm::dvec3 ab = b - a, ac = c - a, bc = c - b;
  const glm::dvec3 m = glm::max(glm::abs(ab), glm::max(glm::abs(ac), glm::abs(bc)));
  const double largest = std::max({m.x, m.y, m.z});
  if (!(largest > 0) || !std::isfinite(largest)) return 0;
  ab /= largest, ac /= largest, bc /= largest;
  const double longest = std::max({glm::length(ab), glm::length(ac), glm::length(bc)});
  return glm::length(glm::cross(ab, ac)) / (longest * longest);
}

void validate_mesh(const Mesh& mesh, const std::string& label) {
  if (mesh.faces.empty()) fail(label + " has no faces");
  if (mesh.vertices.empty()) fail(label + " has no vertices");

  const auto n = static_cast<long long>(mesh.vertices.size());
  for (size_t i = 0; i < mesh.vertices.size(); ++i) {
    const glm::dvec3& v = mesh.vertices[i];
    if (!finite(v))
      fail(label + ": vertex " + std::to_string(i) + " has a non-finite coordinate " + vec(v));
  }

  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    const glm::ivec3& t = mesh.faces[f];
    for (int k = 0; k < 3; ++k) {
      if (t[k] < 0 || t[k] >= n)
        fail(label + ": face " + std::to_string(f) + " " + ivec(t) + " has vertex index " +
             std::to_string(t[k]) + " out of range [0, " + std::to_string(n) + ")");
    }
    if (t.x == t.y || t.y == t.z || t.z == t.x)
      fail(label + ": face " + std::to_string(f) + " " + ivec(t) + " repeats a vertex index");
    const double area = relative_area(mesh.vertices[t.x], mesh.vertices[t.y], mesh.vertices[t.z]);
    if (!(area > 1e-12))
      fail(label + ": face " + std::to_string(f) + " " + ivec(t) +
           " is degenerate (its corners are on one line: twice its area is " + num(area) +
           " times its longest edge squared)");
  }

  const bool per_vertex = mesh.albedo_mode == AlbedoMode::PerVertex;
  const size_t want = per_vertex ? mesh.vertices.size() : mesh.faces.size();
  if (mesh.albedo.size() != want)
    fail(label + ": albedo count " + std::to_string(mesh.albedo.size()) + " does not match the " +
         (per_vertex ? "vertex count " : "face count ") + std::to_string(want) + " (" +
         (per_vertex ? "per-vertex" : "per-face") + " albedo)");
  for (size_t i = 0; i < mesh.albedo.size(); ++i) {
    const glm::dvec3& a = mesh.albedo[i];
    if (!finite(a))
      fail(label + ": albedo " + std::to_string(i) + " is non-finite " + vec(a));
    if (any_negative(a)) fail(label + ": albedo " + std::to_string(i) + " is negative " + vec(a));
  }
}

std::string mesh_label(const Mesh& mesh) {
  return mesh.name.empty() ? std::string("mesh (unnamed)") : "mesh '" + mesh.name + "'";
}

void validate_camera(const Camera& c, const std::string& label) {
  if (c.width < 1 || c.width > kMaxImageSize || c.height < 1 || c.height > kMaxImageSize)
    fail(label + ": image size " + std::to_string(c.width) + "x" + std::to_string(c.height) +
         " must be between 1 and " + std::to_string(kMaxImageSize) + " on each side");
  if (!finite(c.eye)) fail(label + ": eye " + vec(c.eye) + " is not finite");
  if (!finite(c.target)) fail(label + ": target " + vec(c.target) + " is not finite");
  if (!finite(c.up)) fail(label + ": up " + vec(c.up) + " is not finite");
  if (c.projection == Projection::Perspective) {
    if (!(c.fov_deg > 0 && c.fov_deg < 180))
      fail(label + ": fov " + num(c.fov_deg) + " degrees must be in (0, 180)");
  } else {
    if (!(c.half_height > 0) || !std::isfinite(c.half_height))
      fail(label + ": half_height " + num(c.half_height) + " must be positive and finite");
  }
  if (!(c.near > 0) || !std::isfinite(c.near))
    fail(label + ": near " + num(c.near) + " must be positive and finite");
  if (!(c.far > c.near) || !std::isfinite(c.far))
    fail(label + ": far " + num(c.far) + " must be finite and greater than near " +
         num(c.near));
  const glm::dvec3 dir = c.target - c.eye;
  const double dir_len = glm::length(dir);
  if (!(dir_len > 0)) fail(label + ": eye and target are the same point " + vec(c.eye));
  const double up_len = glm::length(c.up);
  if (!(up_len > 0)) fail(label + ": up vector is zero");
  const double sin_angle = glm::length(glm::cross(dir / dir_len, c.up / up_len));
  if (!(sin_angle > 1e-9))
    fail(label + ": up " + vec(c.up) + " is parallel to the view direction " +
         vec(dir / dir_len));
}

void validate_light(const Light& l, const std::string& label) {
  if (l.type == LightType::Point) {
    if (!finite(l.position)) fail(label + ": position " + vec(l.position) + " is not finite");
  } else {
    if (!finite(l.direction)) fail(label + ": direction " + vec(l.direction) + " is not finite");
    if (!(glm::length(l.direction) > 0)) fail(label + ": directional light has zero direction");
  }
  if (!finite(l.color)) fail(label + ": color " + vec(l.color) + " is not finite");
  if (any_negative(l.color)) fail(label + ": color " + vec(l.color) + " is negative");
  if (!std::isfinite(l.size)) fail(label + ": size " + num(l.size) + " is not finite");
  if (l.size < 0) fail(label + ": size " + num(l.size) + " is negative");
  const LightFrustum& f = l.frustum;
  if (!f.fitted) return;
  if (!finite(f.target) || !finite(f.up))
    fail(label + ": frustum target/up " + vec(f.target) + " " + vec(f.up) + " is not finite");
  if (l.type == LightType::Point && !(f.fov_deg > 0 && f.fov_deg < 180))
    fail(label + ": frustum fov " + num(f.fov_deg) + " must be in (0, 180) degrees");
  if (l.type == LightType::Directional && !(f.half_size > 0 && f.distance > 0))
    fail(label + ": frustum half_size " + num(f.half_size) + " and distance " + num(f.distance) +
         " must be positive");
  if (!(f.near > 0 && f.far > f.near && std::isfinite(f.far)))
    fail(label + ": frustum near " + num(f.near) + " and far " + num(f.far) +
         " must satisfy 0 < near < far");
  glm::dvec3 dir = l.type == LightType::Point ? f.target - l.position : l.direction;
  if (!(glm::length(dir) > 0) ||
      !(glm::length(glm::cross(glm::normalize(dir), f.up)) > 1e-9 * glm::length(f.up)))
    fail(label + ": frustum up " + vec(f.up) + " is parallel to the light's view direction");
}

void check_open_unit(const char* name, double v) {
  if (!(v > 0 && v < 1))
    fail(std::string("render parameter ") + name + " = " + num(v) + " must be in (0, 1)");
}

void check_positive(const char* name, double v) {
  if (!(v > 0) || !std::isfinite(v))
    fail(std::string("render parameter ") + name + " = " + num(v) +
         " must be positive and finite");
}

// The one place that rejects combinations of the independent shadow settings.
void check_combination(const RenderParams& p) {
  if (p.exact_backend == ExactBackend::CLBlast) {
    if (p.sampling != Sampling::Exact)
      fail("exact backend 'clblast' computes the exact sum; it needs sampling 'exact', not '" +
           word(p.sampling) + "'");
    if (p.shadows == Shadows::Soft)
      fail("soft shadows sum with penumbra's kernels; their sum does not factor into matrix "
           "products (exact backend 'clblast', sampling 'gemm'): use exact backend 'kernels' "
           "or 'auto'");
    if (p.shadows != Shadows::None && p.shadow_model == ShadowModel::Accurate)
      fail("the accurate shadow model compares, then filters; its sum does not factor into "
           "matrix products (exact backend 'clblast', sampling 'gemm'): use exact backend "
           "'kernels' or 'auto', or shadow model 'paper'");
  }
}

void validate_params(const RenderParams& p) {
  check_open_unit("sigma", p.sigma);
  check_open_unit("gamma", p.gamma);
  check_open_unit("eps", p.eps);
  check_open_unit("dist_eps", p.dist_eps);
  check_positive("sigma_s", shadow_sigma_s(p));
  check_open_unit("lambda_eps", p.lambda_eps);
  check_positive("gamma_s", shadow_gamma_s(p));
  check_positive("depth_unit", p.depth_unit);
  if (!std::isfinite(shadow_beta(p)))
    fail("render parameter beta = " + num(shadow_beta(p)) + " is not finite");
  check_positive("gamma_p", p.gamma_p);
  if (!(p.shadow_map_size >= 1 && p.shadow_map_size <= 8192))
    fail("render parameter shadow_map_size = " + std::to_string(p.shadow_map_size) +
         " must be in [1, 8192]");
  if (p.light_sigma != 0) check_open_unit("light_sigma", p.light_sigma);
  if (p.light_gamma != 0) check_open_unit("light_gamma", p.light_gamma);
  check_open_unit("weight_eps", p.weight_eps);
  check_combination(p);
}

}  // namespace

template <>
const std::vector<std::pair<Shadows, std::string>>& enum_words<Shadows>() {
  static const std::vector<std::pair<Shadows, std::string>> words{
      {Shadows::None, "none"}, {Shadows::Hard, "hard"}, {Shadows::Soft, "soft"}};
  return words;
}
template <>
const std::vector<std::pair<Sampling, std::string>>& enum_words<Sampling>() {
  static const std::vector<std::pair<Sampling, std::string>> words{
      {Sampling::Truncated, "truncated"}, {Sampling::Exact, "exact"}};
  return words;
}
template <>
const std::vector<std::pair<ExactBackend, std::string>>& enum_words<ExactBackend>() {
  static const std::vector<std::pair<ExactBackend, std::string>> words{
      {ExactBackend::Auto, "auto"}, {ExactBackend::Kernels, "kernels"},
      {ExactBackend::CLBlast, "clblast"}};
  return words;
}

bool sampling_from_word(const std::string& w, Sampling* sampling,
                        std::optional<ExactBackend>* backend) {
  if (w == gemm_shorthand()) {
    *sampling = Sampling::Exact;
    *backend = ExactBackend::CLBlast;
    return true;
  }
  backend->reset();
  return from_word(w, sampling);
}

std::string sampling_word_choices() {
  std::string out;
  for (const auto& [value, w] : enum_words<Sampling>()) out += w + ", ";
  return out.substr(0, out.size() - 2) + " or " + gemm_shorthand();
}
template <>
const std::vector<std::pair<ShadowModel, std::string>>& enum_words<ShadowModel>() {
  static const std::vector<std::pair<ShadowModel, std::string>> words{
      {ShadowModel::Accurate, "accurate"}, {ShadowModel::Paper, "paper"}};
  return words;
}

void validate(const Mesh& mesh) { validate_mesh(mesh, mesh_label(mesh)); }

void validate(const Scene& scene) {
  if (scene.meshes.empty()) fail("scene has no meshes");
  for (size_t i = 0; i < scene.meshes.size(); ++i) {
    const Mesh& m = scene.meshes[i];
    validate_mesh(m, "mesh " + std::to_string(i) + (m.name.empty() ? "" : " '" + m.name + "'"));
  }
  if (scene.cameras.empty()) fail("scene has no cameras");
  for (size_t i = 0; i < scene.cameras.size(); ++i)
    validate_camera(scene.cameras[i], "camera " + std::to_string(i));
  for (size_t i = 0; i < scene.lights.size(); ++i)
    validate_light(scene.lights[i], "light " + std::to_string(i));
  if (!finite(scene.ambient)) fail("ambient " + vec(scene.ambient) + " is not finite");
  if (any_negative(scene.ambient)) fail("ambient " + vec(scene.ambient) + " is negative");
  if (!finite(scene.background)) fail("background " + vec(scene.background) + " is not finite");
  validate_params(scene.params);
}

Bounds bounds(const Scene& scene) {
  Bounds b;
  b.lo = glm::dvec3(std::numeric_limits<double>::infinity());
  b.hi = glm::dvec3(-std::numeric_limits<double>::infinity());
  bool any = false;
  for (const Mesh& m : scene.meshes)
    for (const glm::dvec3& v : m.vertices) {
      b.lo = glm::min(b.lo, v);
      b.hi = glm::max(b.hi, v);
      any = true;
    }
  if (!any) fail("cannot compute the bounds of a scene with no vertices");
  return b;
}

double light_pass_sigma(const RenderParams& p) {
  if (p.light_sigma > 0) return p.light_sigma;
  return p.shadow_model == ShadowModel::Accurate ? p.sigma / 32 : p.sigma / 10;
}
double light_pass_gamma(const RenderParams& p) {
  return p.light_gamma > 0 ? p.light_gamma : p.gamma;
}

namespace {

// The vertices of the faces that can cast a shadow onto the scene: a face shadows only points
// beyond its plane as seen from the light, so a face with the whole bounding box on the light's
// side (a ground under everything) casts none. Empty when no face can.
std::vector<glm::dvec3> occluder_vertices(const Scene& scene, const Light& light, const Bounds& b) {
  std::vector<glm::dvec3> out;
  for (const Mesh& m : scene.meshes)
    for (const glm::ivec3& F : m.faces) {
      const glm::dvec3 V0 = m.vertices[F.x], n = glm::cross(m.vertices[F.y] - V0, m.vertices[F.z] - V0);
      const double side = glm::dot(n, light.type == LightType::Point ? light.position - V0 : -light.direction);
      const double tol = 1e-9 * glm::length(n) * glm::length(b.hi - b.lo);
      bool beyond = false;
      for (int c = 0; c < 8 && !beyond; ++c) {
        const glm::dvec3 corner(c & 1 ? b.hi.x : b.lo.x, c & 2 ? b.hi.y : b.lo.y, c & 4 ? b.hi.z : b.lo.z);
        const double at = glm::dot(n, corner - V0);
        beyond = side > 0 ? at < -tol : side < 0 ? at > tol : false;
      }
      if (beyond)
        for (int k = 0; k < 3; ++k) out.push_back(m.vertices[F[k]]);
    }
  return out;
}

// Fits one light's frustum: it looks at the centre of `aim`'s bounds and holds `aim` (plus
// `halo`, a lateral margin in world units per unit of depth for a point light, in world units
// for a directional one) in its field of view, and every vertex of the scene in its depth range.
void fit_frustum(const Scene& scene, Light& l, const std::vector<glm::dvec3>& aim, double halo) {
  Bounds ab{glm::dvec3(std::numeric_limits<double>::infinity()), glm::dvec3(-std::numeric_limits<double>::infinity())};
  for (const glm::dvec3& v : aim) ab.lo = glm::min(ab.lo, v), ab.hi = glm::max(ab.hi, v);
  const glm::dvec3 c = ab.center();
  const double r = std::max(bounds(scene).radius(), 1e-9);
  const double margin = 1.02;  // a little room around the outermost vertex
  LightFrustum& f = l.frustum;
  const glm::dvec3 eye = l.type == LightType::Point ? l.position : c - 2 * r * glm::normalize(l.direction);
  glm::dvec3 fwd = l.type == LightType::Point ? c - eye : l.direction;
  if (!(glm::length(fwd) > 1e-12 * r)) fwd = {0, -1, 0};
  fwd = glm::normalize(fwd);
  f.target = eye + fwd * std::max(glm::length(c - eye), r);
  f.up = std::abs(fwd.y) < 0.99 ? glm::dvec3(0, 1, 0) : glm::dvec3(0, 0, 1);
  const glm::dvec3 right = glm::normalize(glm::cross(fwd, f.up)), up = glm::cross(right, fwd);
  double zmin = std::numeric_limits<double>::infinity(), zmax = 0, extent = 0, slope = 0;
  bool behind = false;
  for (const glm::dvec3& v : aim) {
    const glm::dvec3 d = v - eye;
    const double z = glm::dot(d, fwd), x = std::abs(glm::dot(d, right)), y = std::abs(glm::dot(d, up));
    extent = std::max({extent, x, y});
    if (z > 1e-3 * r) slope = std::max(slope, std::max(x, y) / z);
    else behind = true;
  }
  for (const Mesh& m : scene.meshes)
    for (const glm::dvec3& v : m.vertices) {
      const double z = glm::dot(v - eye, fwd);
      zmin = std::min(zmin, z);
      zmax = std::max(zmax, z);
      behind |= z <= 1e-3 * r;
    }
  if (l.type == LightType::Point) {
    // A light among the geometry sees part of it behind itself: a wide cone, and receivers
    // outside it are lit.
    const double cone = 2 * std::atan(margin * slope + halo) * 180 / 3.14159265358979323846;
    f.fov_deg = behind ? 120.0 : std::min(cone, 120.0);
    f.near = std::max(zmin / margin, 1e-3 * r);
    f.far = std::max(zmax * margin, f.near * 2);
  } else {
    f.half_size = margin * extent + halo;
    f.distance = glm::length(f.target - eye);
    f.near = std::max(zmin - 0.05 * r, 1e-3 * r);
    f.far = zmax + 0.05 * r;
  }
  f.fitted = true;
  f.automatic = true;
}

// σ_b for the nearest blocker at depth `zmin` (along the light's view) over the farthest
// receiver at the frustum's far plane: σ_s + (widest penumbra in texels)²/16, the penumbra
// capped at half the map.
double search_sigma_from(const RenderParams& p, const Light& light, double zmin) {
  const LightFrustum& f = light.frustum;
  const bool ortho = light.type == LightType::Directional;
  const double tan_half = std::tan(f.fov_deg * 3.14159265358979323846 / 360);
  const double k = p.shadow_map_size / (2 * (ortho ? f.half_size : tan_half));
  double w = light.size * k * (ortho ? f.far - zmin : 1 / zmin - 1 / f.far);
  w = std::min(std::max(w, 0.0), 0.5 * p.shadow_map_size);
  return shadow_sigma_s(p) + w * w / 16;
}

void fit_occluder_frustum(const Scene& scene, Light& l, const std::vector<glm::dvec3>& occ);

// The accurate model's frustum: tight around what can cast a shadow, widened by the penumbra
// a light of diameter D_L casts around it and by the filter window (SPEC-level details in
// docs/shadows.md); every vertex when nothing can cast a shadow.
void fit_tight_frustum(const Scene& scene, Light& l, const Bounds& b) {
  std::vector<glm::dvec3> occ = occluder_vertices(scene, l, b);
  if (occ.empty()) return fit_frustum(scene, l, scene_vertices(scene), 0.0);
  fit_occluder_frustum(scene, l, occ);
  if (scene.params.shadows != Shadows::Soft || !(l.size > 0)) return;
  // The blocker search reaches as far as the penumbra of the nearest occluder can.
  const LightFrustum& f = l.frustum;
  const glm::dvec3 eye = l.type == LightType::Point ? l.position
                                                    : f.target - f.distance * glm::normalize(l.direction);
  const glm::dvec3 fwd = glm::normalize(f.target - eye);
  double zocc = std::numeric_limits<double>::infinity();
  for (const glm::dvec3& v : occ) zocc = std::min(zocc, glm::dot(v - eye, fwd));
  l.frustum.search_sigma = search_sigma_from(scene.params, l, std::max(zocc, f.near));
}

// The tight frustum around the occluders' vertices `occ`.
void fit_occluder_frustum(const Scene& scene, Light& l, const std::vector<glm::dvec3>& occ) {
  const RenderParams& p = scene.params;
  const double soft = p.shadows == Shadows::Soft ? l.size : 0.0;
  const double window = std::sqrt(2 * shadow_sigma_s(p) * std::log(1 / p.lambda_eps)) + 1;  // texels
  const double texels = std::min(2.0 * window / p.shadow_map_size, 0.5);  // share of the map
  if (l.type == LightType::Point) {
    double zocc = std::numeric_limits<double>::infinity();
    for (const glm::dvec3& v : occ) zocc = std::min(zocc, glm::length(v - l.position));
    fit_frustum(scene, l, occ, 0.0);
    const double t = std::tan(l.frustum.fov_deg * 3.14159265358979323846 / 360);
    const double halo = 0.5 * soft / std::max(zocc, 1e-12);
    l.frustum.fitted = false;
    if (l.frustum.fov_deg < 120.0)
      return fit_frustum(scene, l, occ, (t + halo) / (1 - texels) - t);
    return fit_frustum(scene, l, scene_vertices(scene), 0.0);
  }
  fit_frustum(scene, l, occ, 0.0);
  const double h = l.frustum.half_size, depth = l.frustum.far - l.frustum.near;
  l.frustum.fitted = false;
  fit_frustum(scene, l, occ, (h + 0.5 * soft * depth) / (1 - texels) - h);
}

}  // namespace

std::vector<glm::dvec3> scene_vertices(const Scene& scene) {
  std::vector<glm::dvec3> all;
  for (const Mesh& m : scene.meshes) all.insert(all.end(), m.vertices.begin(), m.vertices.end());
  return all;
}

void fit_light_frusta(Scene& scene) {
  bool any = false;
  for (const Light& l : scene.lights) any |= !l.frustum.fitted;
  if (!any) return;
  const Bounds b = bounds(scene);
  for (Light& l : scene.lights) {
    if (l.frustum.fitted) continue;
    l.frustum.search_sigma = 0.0;  // set by the accurate model's fit (soft shadows)
    if (scene.params.shadow_model == ShadowModel::Accurate)
      fit_tight_frustum(scene, l, b);
    else
      fit_frustum(scene, l, scene_vertices(scene), 0.0);

  }
}

double shadow_sigma_s(const RenderParams& p) {
  return p.sigma_s ? *p.sigma_s : p.shadow_model == ShadowModel::Paper ? 2.0 : 0.5;
}
double shadow_gamma_s(const RenderParams& p) {
  return p.gamma_s ? *p.gamma_s : p.depth_unit * (p.shadow_model == ShadowModel::Paper ? 0.02 : 0.004);
}
double shadow_beta(const RenderParams& p) {
  return p.beta ? *p.beta : p.depth_unit * (p.shadow_model == ShadowModel::Paper ? 0.05 : 0.01);
}

double blocker_search_sigma(const RenderParams& p, const Light& light) {
  if (p.shadows != Shadows::Soft || !(light.size > 0)) return shadow_sigma_s(p);
  if (light.frustum.search_sigma > 0) return light.frustum.search_sigma;
  return search_sigma_from(p, light, light.frustum.near);
}

void refit_light_frusta(Scene& scene) {
  for (Light& l : scene.lights)
    if (l.frustum.automatic) l.frustum.fitted = false;
  fit_light_frusta(scene);
}

Scene framed_scene(Mesh mesh, int width, int height) {
  validate(mesh);
  Scene scene;
  scene.meshes.push_back(std::move(mesh));
  const Mesh& m = scene.meshes.front();

  // Bounding sphere: centre of the box, radius to the farthest vertex (tighter than the
  // half-diagonal for round shapes).
  const glm::dvec3 center = bounds(scene).center();
  double r = 0;
  for (const glm::dvec3& v : m.vertices) r = std::max(r, glm::length(v - center));
  if (!(r > 0)) r = 1;

  // Camera: fov 40°, elevation 25°, looking at the centre from the front (+z). The distance
  // makes the sphere's silhouette span ~70% of the narrower image side.
  Camera cam;
  cam.projection = Projection::Perspective;
  cam.fov_deg = 40.0;
  cam.width = width;
  cam.height = height;
  const double half_fov = glm::radians(cam.fov_deg) / 2;
  const double aspect = (width > 0 && height > 0) ? double(width) / height : 1.0;
  const double tan_fit = 0.7 * std::tan(half_fov) * std::min(1.0, aspect);
  const double dist = r * std::sqrt(1 + tan_fit * tan_fit) / tan_fit;  // r / sin(atan(t))
  const double elev = glm::radians(25.0);
  cam.target = center;
  cam.eye = center + dist * glm::dvec3(0, std::sin(elev), std::cos(elev));
  cam.up = {0, 1, 0};
  cam.near = std::max(0.01 * r, dist - 2 * r);
  cam.far = dist + 2 * r;
  scene.cameras.push_back(cam);

  // One point light above, in front and to the left, three radii from the centre.
  Light light;
  light.type = LightType::Point;
  light.position = center + 3 * r * glm::normalize(glm::dvec3(-1, 1.5, 1));
  light.color = {1, 1, 1};
  light.size = 0.2 * r;
  scene.lights.push_back(light);

  scene.ambient = {0.2, 0.2, 0.2};
  scene.background = {1, 1, 1};
  // The depth-unit defaults (SPEC §7) are for a unit sphere: scale them with the mesh.
  scene.params.depth_unit = r;
  fit_light_frusta(scene);
  validate(scene);
  return scene;
}

}  // namespace penumbra
