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
  return "(" + std::to_string(v.x) + ", " + std::to_string(v.y) + ", " + std::to_string(v.z) + ")";
}

bool finite(const glm::dvec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

bool any_negative(const glm::dvec3& v) { return v.x < 0 || v.y < 0 || v.z < 0; }

[[noreturn]] void fail(const std::string& message) { throw Error(message); }

// The largest coordinate a position may have: the fits and the normalisation square distances
// in double precision, which stay finite below 1e150.
constexpr double kMaxCoordinate = 1e100;

// Fails unless the position `v` is finite and within ±kMaxCoordinate.
void check_position(const glm::dvec3& v, const std::string& what) {
  if (!finite(v)) fail(what + " " + vec(v) + " is not finite");
  const glm::dvec3 a = glm::abs(v);
  if (std::max({a.x, a.y, a.z}) > kMaxCoordinate)
    fail(what + " " + vec(v) + " has a coordinate beyond ±" + num(kMaxCoordinate) +
         ", too large for its squared distances to stay finite");
}

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

// relative_area(a, b, c) > 1e-12, decided without its divisions and roots where the answer
// is clear (every face of a sound mesh; at 100k faces this was 2.6 ms of each render): with
// the edges' squares between 1e-100 and 1e100, |ab × ac|² above 1.1e-24 times the longest
// edge's fourth power puts the relative area 4.8 % above the bound, far beyond the rounding
// of either computation (the cross product's, near the bound, a few 1e-4 relative).
bool clearly_not_degenerate(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c) {
  const glm::dvec3 ab = b - a, ac = c - a, bc = c - b, n = glm::cross(ab, ac);
  const double l2 = std::max({glm::dot(ab, ab), glm::dot(ac, ac), glm::dot(bc, bc)});
  return l2 > 1e-100 && l2 < 1e100 && glm::dot(n, n) > 1.1e-24 * l2 * l2;
}

// Finite and within ±kMaxCoordinate (a NaN fails the comparison too).
bool within_coordinates(const glm::dvec3& v) {
  return std::abs(v.x) <= kMaxCoordinate && std::abs(v.y) <= kMaxCoordinate &&
         std::abs(v.z) <= kMaxCoordinate;
}

// The vertices of a mesh, checked on every render, their bounds added to `b` in the same pass: a
// message is built only for a vertex that fails, not a label for each.
void validate_vertices(const Mesh& mesh, const std::string& label, Bounds& b) {
  if (mesh.vertices.empty()) fail(label + " has no vertices");
  bool within = true;
  for (const glm::dvec3& v : mesh.vertices) {
    within &= within_coordinates(v);
    b.lo = glm::min(b.lo, v);
    b.hi = glm::max(b.hi, v);
  }
  for (size_t i = 0; !within && i < mesh.vertices.size(); ++i) {
    const glm::dvec3& v = mesh.vertices[i];
    if (within_coordinates(v)) continue;
    if (!finite(v))
      fail(label + ": vertex " + std::to_string(i) + " has a non-finite coordinate " + vec(v));
    check_position(v, label + ": vertex " + std::to_string(i));
  }
}

// The faces of a mesh whose vertices validate_vertices accepted.
void validate_faces(const Mesh& mesh, const std::string& label, DegenerateFaces degenerate) {
  const auto n = static_cast<long long>(mesh.vertices.size());
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    const glm::ivec3& t = mesh.faces[f];
    for (int k = 0; k < 3; ++k) {
      if (t[k] < 0 || t[k] >= n)
        fail(label + ": face " + std::to_string(f) + " " + ivec(t) + " has vertex index " +
             std::to_string(t[k]) + " out of range [0, " + std::to_string(n) + ")");
    }
    if (t.x == t.y || t.y == t.z || t.z == t.x)
      fail(label + ": face " + std::to_string(f) + " " + ivec(t) + " repeats a vertex index");
    const glm::dvec3 &a = mesh.vertices[t.x], &b = mesh.vertices[t.y], &c = mesh.vertices[t.z];
    if (degenerate == DegenerateFaces::Refuse && degenerate_triangle(a, b, c))
      fail(label + ": face " + std::to_string(f) + " " + ivec(t) +
           " is degenerate (its corners are on one line: twice its area is " +
           num(relative_area(a, b, c)) + " times its longest edge squared)");
  }
}

void validate_albedo(const Mesh& mesh, const std::string& label) {
  const bool per_vertex = mesh.albedo_mode == AlbedoMode::PerVertex;
  const size_t want = per_vertex ? mesh.vertices.size() : mesh.faces.size();
  if (mesh.albedo.size() != want)
    fail(label + ": albedo count " + std::to_string(mesh.albedo.size()) + " does not match the " +
         (per_vertex ? "vertex count " : "face count ") + std::to_string(want) + " (" +
         (per_vertex ? "per-vertex" : "per-face") + " albedo)");
  for (size_t i = 0; i < mesh.albedo.size(); ++i) {
    const glm::dvec3& a = mesh.albedo[i];
    if (!finite(a)) fail(label + ": albedo " + std::to_string(i) + " is non-finite " + vec(a));
    if (any_negative(a)) fail(label + ": albedo " + std::to_string(i) + " is negative " + vec(a));
  }
}

}  // namespace

bool degenerate_triangle(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c) {
  return !clearly_not_degenerate(a, b, c) && !(relative_area(a, b, c) > 1e-12);
}

namespace {

std::string mesh_label(const Mesh& mesh) {
  return mesh.name.empty() ? std::string("mesh (unnamed)") : "mesh '" + mesh.name + "'";
}

void validate_camera(const Camera& c, const std::string& label) {
  if (c.width < 1 || c.width > kMaxImageSize || c.height < 1 || c.height > kMaxImageSize)
    fail(label + ": image size " + std::to_string(c.width) + "x" + std::to_string(c.height) +
         " must be between 1 and " + std::to_string(kMaxImageSize) + " on each side");
  check_position(c.eye, label + ": eye");
  check_position(c.target, label + ": target");
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
    fail(label + ": far " + num(c.far) + " must be finite and greater than near " + num(c.near));
  const glm::dvec3 dir = c.target - c.eye;
  const double dir_len = glm::length(dir);
  if (!(dir_len > 0)) fail(label + ": eye and target are the same point " + vec(c.eye));
  const double up_len = glm::length(c.up);
  if (!(up_len > 0)) fail(label + ": up vector is zero");
  const double sin_angle = glm::length(glm::cross(dir / dir_len, c.up / up_len));
  if (!(sin_angle > 1e-9))
    fail(label + ": up " + vec(c.up) + " is parallel to the view direction " + vec(dir / dir_len));
}

void validate_light(const Light& l, const std::string& label) {
  if (l.type == LightType::Point) {
    check_position(l.position, label + ": position");
  } else {
    if (!finite(l.direction)) fail(label + ": direction " + vec(l.direction) + " is not finite");
    if (!(glm::length(l.direction) > 0)) fail(label + ": directional light has zero direction");
  }
  if (!finite(l.color)) fail(label + ": color " + vec(l.color) + " is not finite");
  if (any_negative(l.color)) fail(label + ": color " + vec(l.color) + " is negative");
  if (!std::isfinite(l.size)) fail(label + ": size " + num(l.size) + " is not finite");
  if (l.size < 0) fail(label + ": size " + num(l.size) + " is negative");
  const LightFrustum& f = l.frustum;
  if (l.shadow_map == ShadowMapShape::Cube && l.type == LightType::Directional)
    fail(label + ": shadow_map 'cube' is for point lights; a directional light has one frustum");
  if (!f.fitted) return;
  if (l.shadow_map == ShadowMapShape::Cube && !f.automatic && !f.cube)
    fail(label + ": shadow_map 'cube' fits its own frusta; give no frustum with it");
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
    fail(std::string("render parameter ") + name + " = " + num(v) + " must be positive and finite");
}

// The one place that rejects combinations of the independent shadow settings.
void check_combination(const RenderParams& p) {
  if (p.exact_backend == ExactBackend::CLBlast) {
    if (p.sampling != Sampling::Exact)
      fail("exact backend 'clblast' computes the exact sum; it needs sampling 'exact', not '" +
           word(p.sampling) + "'");
    if (p.shadows == Shadows::Soft)
      fail(
          "soft shadows sum with penumbra's kernels; their sum does not factor into matrix "
          "products (exact backend 'clblast', sampling 'gemm'): use exact backend 'kernels' "
          "or 'auto'");
    if (const ShadowModelTraits& m = shadow_model_traits(p.shadow_model);
        p.shadows != Shadows::None && !m.exact_products)
      fail(std::string("the ") + m.word + " shadow model " + m.no_products +
           "; its sum does not factor into matrix products (exact backend 'clblast', sampling "
           "'gemm'): use exact backend 'kernels' or 'auto', or shadow model 'paper'");
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
  if (!(shadow_map_side(p) >= 1 && shadow_map_side(p) <= kMaxShadowMapSize))
    fail("render parameter shadow_map_size = " + std::to_string(shadow_map_side(p)) +
         " must be in [1, " + std::to_string(kMaxShadowMapSize) + "]");
  if (p.light_sigma != 0) check_open_unit("light_sigma", p.light_sigma);
  if (p.light_gamma != 0) check_open_unit("light_gamma", p.light_gamma);
  check_open_unit("weight_eps", p.weight_eps);
  check_combination(p);
}

}  // namespace

namespace {
// All of a mesh but what is known (passed before, unchanged since); its bounds added to `b`.
struct Known {
  bool faces = false, albedo = false;
};
void validate_mesh(const Mesh& mesh, const std::string& label, DegenerateFaces degenerate,
                   Known known, Bounds& b) {
  if (mesh.faces.empty()) fail(label + " has no faces");
  validate_vertices(mesh, label, b);
  if (!known.faces) validate_faces(mesh, label, degenerate);
  if (!known.albedo) validate_albedo(mesh, label);
}

Bounds empty_bounds() {  // none yet: every vertex widens them
  const double inf = std::numeric_limits<double>::infinity();
  return {glm::dvec3(inf), glm::dvec3(-inf)};
}

Bounds validate_scene(const Scene& scene, DegenerateFaces degenerate, Known known) {
  if (scene.meshes.empty()) fail("scene has no meshes");
  Bounds b = empty_bounds();
  for (size_t i = 0; i < scene.meshes.size(); ++i) {
    const Mesh& m = scene.meshes[i];
    validate_mesh(m, "mesh " + std::to_string(i) + (m.name.empty() ? "" : " '" + m.name + "'"),
                  degenerate, known, b);
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
  return b;
}
}  // namespace

void validate(const Mesh& mesh, DegenerateFaces degenerate) {
  Bounds b = empty_bounds();
  validate_mesh(mesh, mesh_label(mesh), degenerate, {}, b);
}

void validate(const Scene& scene, DegenerateFaces degenerate) {
  validate_scene(scene, degenerate, {});
}

Bounds validated_bounds(const Scene& scene, bool faces_known, bool albedo_known) {
  return validate_scene(scene, DegenerateFaces::Allow, {faces_known, albedo_known});
}

Bounds bounds(const Scene& scene) {
  Bounds b = empty_bounds();
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
  return p.light_sigma > 0 ? p.light_sigma : p.sigma / 10;
}
double light_pass_gamma(const RenderParams& p) {
  return p.light_gamma > 0 ? p.light_gamma : p.gamma;
}

double shadow_sigma_s(const RenderParams& p) {
  return p.sigma_s ? *p.sigma_s : shadow_model_traits(p.shadow_model).sigma_s;
}
double shadow_gamma_s(const RenderParams& p) {
  return p.gamma_s ? *p.gamma_s : p.depth_unit * shadow_model_traits(p.shadow_model).gamma_s;
}
double shadow_beta(const RenderParams& p) {
  return p.beta ? *p.beta : p.depth_unit * shadow_model_traits(p.shadow_model).beta;
}
int shadow_map_side(const RenderParams& p) {
  return p.shadow_map_size ? *p.shadow_map_size : shadow_model_traits(p.shadow_model).map_side;
}

Camera orbit(const Camera& camera, double angle) {
  const double c = std::cos(angle), s = std::sin(angle);
  auto turn = [&](const glm::dvec3& v) {
    return glm::dvec3(c * v.x + s * v.z, v.y, -s * v.x + c * v.z);
  };
  Camera out = camera;
  out.eye = camera.target + turn(camera.eye - camera.target);
  out.up = turn(camera.up);
  return out;
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
  // The depth-unit defaults (math.md §10) are for a unit sphere: scale them with the mesh.
  scene.params.depth_unit = r;
  fit_light_frusta(scene);
  validate(scene);
  return scene;
}

}  // namespace penumbra
