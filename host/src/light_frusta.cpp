// Shadow-map frusta fitted to a scene (scene.hpp: fit_light_frusta, refit_light_frusta,
// blocker_search_sigma): to every vertex for the paper's shadow model, tightly to the faces that
// can cast a shadow for the accurate one (math.md §4.1, §7.4).
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "common/layout.h"
#include "penumbra/error.hpp"
#include "penumbra/scene.hpp"

namespace penumbra {

namespace {

// Marks in `casts` the vertices of the faces of `m` that can cast a shadow onto the scene
// (bounds b): a face shadows only points beyond its plane as seen from the light, so a face with
// the whole bounding box on the light's side (a ground under everything) casts none. A face
// whose corners are all marked already is not tested: it could add none.
void mark_casters(const Mesh& m, const Light& light, const Bounds& b, std::vector<char>& casts) {
  casts.assign(m.vertices.size(), 0);
  const double diagonal = glm::length(b.hi - b.lo);
  for (const glm::ivec3& F : m.faces) {
    if (casts[size_t(F.x)] && casts[size_t(F.y)] && casts[size_t(F.z)]) continue;
    const glm::dvec3 V0 = m.vertices[F.x],
                     n = glm::cross(m.vertices[F.y] - V0, m.vertices[F.z] - V0);
    const double side =
        glm::dot(n, light.type == LightType::Point ? light.position - V0 : -light.direction);
    const double tol = 1e-9 * glm::length(n) * diagonal;
    bool beyond = false;
    for (int c = 0; c < 8 && !beyond; ++c) {
      const glm::dvec3 corner(c & 1 ? b.hi.x : b.lo.x, c & 2 ? b.hi.y : b.lo.y,
                              c & 4 ? b.hi.z : b.lo.z);
      const double at = glm::dot(n, corner - V0);
      beyond = side > 0 ? at < -tol : side < 0 ? at > tol : false;
    }
    if (beyond)
      for (int k = 0; k < 3; ++k) casts[size_t(F[k])] = 1;
  }
}

// The vertices of the faces that can cast a shadow onto the scene (mark_casters), each once (a
// frustum fitted to them depends on the set alone). Empty when no face can.
std::vector<glm::dvec3> occluder_vertices(const Scene& scene, const Light& light, const Bounds& b) {
  std::vector<glm::dvec3> out;
  std::vector<char> casts;
  for (const Mesh& m : scene.meshes) {
    mark_casters(m, light, b, casts);
    for (size_t v = 0; v < m.vertices.size(); ++v)
      if (casts[v]) out.push_back(m.vertices[v]);
  }
  return out;
}

// Fits one light's frustum: it looks at the centre of `aim`'s bounds and holds `aim` (plus
// `halo`, a lateral margin in world units per unit of depth for a point light, in world units
// for a directional one) in its field of view, and every vertex of the scene (bounds b) in its
// depth range.
void fit_frustum(const Scene& scene, const Bounds& b, Light& l, const std::vector<glm::dvec3>& aim,
                 double halo) {
  Bounds ab{glm::dvec3(std::numeric_limits<double>::infinity()),
            glm::dvec3(-std::numeric_limits<double>::infinity())};
  for (const glm::dvec3& v : aim) ab.lo = glm::min(ab.lo, v), ab.hi = glm::max(ab.hi, v);
  const glm::dvec3 c = ab.center();
  const double r = std::max(b.radius(), 1e-9);
  const double margin = 1.02;  // a little room around the outermost vertex
  LightFrustum& f = l.frustum;
  const glm::dvec3 eye =
      l.type == LightType::Point ? l.position : c - 2 * r * glm::normalize(l.direction);
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
    const double z = glm::dot(d, fwd), x = std::abs(glm::dot(d, right)),
                 y = std::abs(glm::dot(d, up));
    extent = std::max({extent, x, y});
    if (z > 1e-3 * r)
      slope = std::max(slope, std::max(x, y) / z);
    else
      behind = true;
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
    f.fov_deg = behind ? kWidestFit : std::min(cone, kWidestFit);
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

// The filter window's share of half the map (texels), at most a half: the margin a frustum's
// edge keeps around what it must hold, so that the windows of the points there lie inside.
double window_share(const RenderParams& p) {
  const double window = std::sqrt(2 * shadow_sigma_s(p) * std::log(1 / p.lambda_eps)) + 1;
  return std::min(2.0 * window / shadow_map_side(p), 0.5);
}

// σ_b for the nearest blocker at depth `zmin` (along the light's view) over the farthest
// receiver at the frustum's far plane: σ_s + (widest penumbra in texels)²/16, the penumbra
// capped at half the map.
double search_sigma_from(const RenderParams& p, const Light& light, double zmin) {
  const LightFrustum& f = light.frustum;
  const bool ortho = light.type == LightType::Directional;
  const double tan_half = std::tan(f.fov_deg * 3.14159265358979323846 / 360);
  const double k = shadow_map_side(p) / (2 * (ortho ? f.half_size : tan_half));
  double w = light.size * k * (ortho ? f.far - zmin : 1 / zmin - 1 / f.far);
  w = std::min(std::max(w, 0.0), 0.5 * shadow_map_side(p));
  return shadow_sigma_s(p) + w * w / 16;
}

void fit_occluder_frustum(const Scene& scene, const Bounds& b, Light& l,
                          const std::vector<glm::dvec3>& occ);

// The accurate model's frustum: tight around what can cast a shadow, widened by the penumbra
// a light of diameter D_L casts around it and by the filter window (math.md §4.1, §7.4;
// docs/shadows.md); every vertex when nothing can cast a shadow.
void fit_tight_frustum(const Scene& scene, Light& l, const Bounds& b) {
  std::vector<glm::dvec3> occ = occluder_vertices(scene, l, b);
  if (occ.empty()) return fit_frustum(scene, b, l, scene_vertices(scene), 0.0);
  fit_occluder_frustum(scene, b, l, occ);
  if (scene.params.shadows != Shadows::Soft || !(l.size > 0)) return;
  // The blocker search reaches as far as the penumbra of the nearest occluder can.
  const LightFrustum& f = l.frustum;
  const glm::dvec3 eye =
      l.type == LightType::Point ? l.position : f.target - f.distance * glm::normalize(l.direction);
  const glm::dvec3 fwd = glm::normalize(f.target - eye);
  double zocc = std::numeric_limits<double>::infinity();
  for (const glm::dvec3& v : occ) zocc = std::min(zocc, glm::dot(v - eye, fwd));
  l.frustum.search_sigma = search_sigma_from(scene.params, l, std::max(zocc, f.near));
}

// The tight frustum around the occluders' vertices `occ`.
void fit_occluder_frustum(const Scene& scene, const Bounds& b, Light& l,
                          const std::vector<glm::dvec3>& occ) {
  const RenderParams& p = scene.params;
  const double soft = p.shadows == Shadows::Soft ? l.size : 0.0;
  const double texels = window_share(p);
  if (l.type == LightType::Point) {
    double zocc = std::numeric_limits<double>::infinity();
    for (const glm::dvec3& v : occ) zocc = std::min(zocc, glm::length(v - l.position));
    fit_frustum(scene, b, l, occ, 0.0);
    const double t = std::tan(l.frustum.fov_deg * 3.14159265358979323846 / 360);
    const double halo = 0.5 * soft / std::max(zocc, 1e-12);
    l.frustum.fitted = false;
    if (l.frustum.fov_deg < kWidestFit)
      return fit_frustum(scene, b, l, occ, (t + halo) / (1 - texels) - t);
    return fit_frustum(scene, b, l, scene_vertices(scene), 0.0);
  }
  fit_frustum(scene, b, l, occ, 0.0);
  const double h = l.frustum.half_size, depth = l.frustum.far - l.frustum.near;
  l.frustum.fitted = false;
  fit_frustum(scene, b, l, occ, (h + 0.5 * soft * depth) / (1 - texels) - h);
}

// |v|∞: a point's depth in the cube face that lights it.
double cube_depth(glm::dvec3 v) { return std::max({std::abs(v.x), std::abs(v.y), std::abs(v.z)}); }

// A point light's cube (LightFrustum::cube): each face's 90° widened by the band where it hands
// over to the next (CUBE_BLEND_TAN), by the penumbra a light of diameter D_L casts around the
// nearest of `occ` (the casters) and by the filter window, so that the windows (and penumbrae)
// of the points in that band lie in its map; depths hold every vertex, and the accurate
// model's blocker search reaches the penumbra of the nearest caster.
void fit_cube(const Scene& scene, const Bounds& b, Light& l, const std::vector<glm::dvec3>& occ) {
  const RenderParams& p = scene.params;
  const double r = std::max(b.radius(), 1e-9), margin = 1.02;
  double zmin = std::numeric_limits<double>::infinity(), zmax = 0, zocc = zmin;
  for (const Mesh& m : scene.meshes)
    for (const glm::dvec3& v : m.vertices) {
      zmin = std::min(zmin, cube_depth(v - l.position));
      zmax = std::max(zmax, cube_depth(v - l.position));
    }
  for (const glm::dvec3& v : occ) zocc = std::min(zocc, cube_depth(v - l.position));
  LightFrustum& f = l.frustum;
  f.near = std::max(zmin / (2 * margin), 1e-3 * r);
  f.far = std::max(zmax * margin, 2 * f.near);
  const double soft = p.shadows == Shadows::Soft ? l.size : 0.0;
  const double halo = 0.5 * soft / std::max(std::min(zocc, zmax), f.near);
  f.fov_deg =
      2 * std::atan((CUBE_BLEND_TAN + halo) / (1 - window_share(p))) * 180 / 3.14159265358979323846;
  f.target = l.position + glm::dvec3(0, -1, 0);  // unused; keeps the frustum well formed
  f.up = {0, 0, 1};
  f.cube = f.fitted = f.automatic = true;
  if (shadow_model_traits(p.shadow_model).casters_only && soft > 0 && !occ.empty())
    f.search_sigma = search_sigma_from(p, l, std::max(zocc, f.near));
}

// Whether light `l`, fitted as one frustum, should be mapped on a cube instead.
bool wants_cube(const Light& l) {
  if (l.type != LightType::Point || l.shadow_map == ShadowMapShape::Frustum) return false;
  return l.shadow_map == ShadowMapShape::Cube || l.frustum.fov_deg >= kWidestFit;
}

}  // namespace

std::vector<Light> cube_faces(const std::vector<Light>& lights, std::vector<int>* light_of) {
  std::vector<Light> out;
  if (light_of) light_of->clear();
  for (size_t i = 0; i < lights.size(); ++i) {
    const int faces = lights[i].frustum.cube ? 6 : 1;
    for (int k = 0; k < faces; ++k) {
      out.push_back(lights[i]);
      if (light_of) light_of->push_back(int(i));
      if (faces == 1) continue;
      LightFrustum& f = out.back().frustum;
      glm::dvec3 axis(0.0);
      axis[k / 2] = k % 2 ? -1.0 : 1.0;
      f.target = lights[i].position + axis;
      f.up = k / 2 == 1 ? glm::dvec3(0, 0, 1) : glm::dvec3(0, 1, 0);
      f.cube = false;
      f.cube_face = k;
    }
  }
  return out;
}

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
    l.frustum = LightFrustum{};  // search_sigma set by the accurate model's fit (soft shadows)
    const bool tight = shadow_model_traits(scene.params.shadow_model).casters_only;
    if (tight)
      fit_tight_frustum(scene, l, b);
    else
      fit_frustum(scene, b, l, scene_vertices(scene), 0.0);
    if (wants_cube(l))
      fit_cube(scene, b, l, tight ? occluder_vertices(scene, l, b) : scene_vertices(scene));
  }
}

double blocker_search_sigma(const RenderParams& p, const Light& light) {
  if (p.shadows != Shadows::Soft || !(light.size > 0)) return shadow_sigma_s(p);
  if (light.frustum.search_sigma > 0) return light.frustum.search_sigma;
  return search_sigma_from(p, light, light.frustum.near);
}

int blocker_search_stride(double sigma_b) {
  return std::max(1, int(std::floor(std::sqrt(sigma_b) / 2)));
}

bool frustum_holds_casters(const Scene& scene, const Light& light) {
  const LightFrustum& f = light.frustum;
  const bool point = light.type == LightType::Point;
  const glm::dvec3 eye =
      point ? light.position : f.target - f.distance * glm::normalize(light.direction);
  const glm::dvec3 fwd = glm::normalize(f.target - eye);
  const glm::dvec3 right = glm::normalize(glm::cross(fwd, f.up)), up = glm::cross(right, fwd);
  const double slack = 1 + 1e-6, tan_half = std::tan(f.fov_deg * 3.14159265358979323846 / 360);
  const Bounds b = bounds(scene);
  std::vector<char> casts;
  for (const Mesh& m : scene.meshes) {  // the casters tested where marked, not gathered first
    mark_casters(m, light, b, casts);
    for (size_t v = 0; v < m.vertices.size(); ++v) {
      if (!casts[v]) continue;
      const glm::dvec3 d = m.vertices[v] - eye;
      const double z = glm::dot(d, fwd),
                   side = std::max(std::abs(glm::dot(d, right)), std::abs(glm::dot(d, up)));
      const double half_width = point ? z * tan_half : f.half_size;
      if (!(z * slack >= f.near && z <= f.far * slack && side <= half_width * slack)) return false;
    }
  }
  return true;
}

void refit_light_frusta(Scene& scene) {
  for (Light& l : scene.lights)
    if (l.frustum.automatic) l.frustum.fitted = false;
  fit_light_frusta(scene);
}

}  // namespace penumbra
