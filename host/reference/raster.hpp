// The soft rasterizer of the CPU reference (reference.cpp; math.md §2–§3): the view transform of a
// camera or a light, the faces set up for a view and the soft rasterization of one view, which
// both the camera pass and the light pass (the shadow map S) run. Private to host/reference/;
// the conventions are those at the top of reference.cpp.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <glm/glm.hpp>
#include <vector>

#include "penumbra/reference.hpp"

namespace penumbra::reference::detail {

using glm::dvec2;
using glm::dvec3;

constexpr double kPi = 3.14159265358979323846;

// Logistic function, evaluated without overflow for any |u|.
inline double sigmoid(double u) {
  if (u >= 0.0) return 1.0 / (1.0 + std::exp(-u));
  const double e = std::exp(u);
  return e / (1.0 + e);
}

// log(1 − sigmoid(u)) = −softplus(u), evaluated without overflow for any |u|.
inline double log_one_minus_sigmoid(double u) {
  if (u > 0.0) return -u - std::log1p(std::exp(-u));
  return -std::log1p(std::exp(u));
}

inline double cross2(dvec2 a, dvec2 b) { return a.x * b.y - a.y * b.x; }

// Squared distance from point q to segment [a, b].
inline double point_segment_dist2(dvec2 q, dvec2 a, dvec2 b) {
  const dvec2 ab = b - a;
  const double len2 = glm::dot(ab, ab);
  double t = len2 > 0.0 ? glm::dot(q - a, ab) / len2 : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  const dvec2 p = a + t * ab - q;
  return glm::dot(p, p);
}

// The view transform of one camera or light.
struct View {
  dvec3 eye, f, r, u;
  bool perspective;
  double scale;  // tan(fov/2) (perspective) or the half-height (orthographic)
  double near, far;
  int width, height;

  // eye, viewing direction `fwd` (any length), up hint; scale as above.
  View(const dvec3& eye_, const dvec3& fwd, const dvec3& up_hint, bool perspective_, double scale_,
       double near_, double far_, int width_, int height_)
      : eye(eye_),
        perspective(perspective_),
        scale(scale_),
        near(near_),
        far(far_),
        width(width_),
        height(height_) {
    f = glm::normalize(fwd);
    r = glm::normalize(glm::cross(f, up_hint));
    u = glm::cross(r, f);
  }

  static double tan_half(double fov_deg) { return std::tan(0.5 * fov_deg * kPi / 180.0); }

  static View of_camera(const Camera& cam) {
    const bool persp = cam.projection == Projection::Perspective;
    return View(cam.eye, cam.target - cam.eye, cam.up, persp,
                persp ? tan_half(cam.fov_deg) : cam.half_height, cam.near, cam.far, cam.width,
                cam.height);
  }

  // The frame a light renders its shadow map with (math.md §4.1), map_size² texels.
  static View of_light(const Light& light, int map_size) {
    const LightFrustum& fr = light.frustum;
    if (light.type == LightType::Point)
      return View(light.position, fr.target - light.position, fr.up, true, tan_half(fr.fov_deg),
                  fr.near, fr.far, map_size, map_size);
    const dvec3 d = glm::normalize(light.direction);
    return View(fr.target - fr.distance * d, d, fr.up, false, fr.half_size, fr.near, fr.far,
                map_size, map_size);
  }

  double depth(const dvec3& p) const { return glm::dot(p - eye, f); }

  dvec2 screen(const dvec3& p) const {
    const dvec3 c = p - eye;
    const double denom = perspective ? glm::dot(c, f) * scale : scale;
    return {glm::dot(c, r) / denom, glm::dot(c, u) / denom};
  }

  dvec2 pixel_center(int px, int py) const {
    return {(2.0 * px + 1.0 - width) / height, (height - 2.0 * py - 1.0) / height};
  }
};

// One face, set up for the view: world and screen positions, depths, albedo, normal.
struct Face {
  std::array<dvec3, 3> V;       // world positions
  std::array<dvec2, 3> p;       // screen positions
  std::array<double, 3> z;      // view depths
  std::array<dvec3, 3> albedo;  // per vertex (all three equal for per-face albedo)
  dvec3 normal;                 // unflipped geometric normal, normalize((V1−V0)×(V2−V0))
  double area2;                 // signed doubled screen area
};

// Faces that survive the per-view tests (near plane, degenerate projection, culling).
std::vector<Face> setup_faces(const Scene& scene, const View& view);

// Colour of a fragment of `face` at perspective-correct barycentrics b.
using Shader = std::function<dvec3(const Face& face, const dvec3& b)>;
// Soft rasterization of one view (math.md §2) with coverage sharpness σ and aggregation
// sharpness γ; the background has colour `background` and depth view.far.
RenderOutput raster(const Scene& scene, const View& view, double sigma, double gamma,
                    const dvec3& background, const Shader& shader);

}  // namespace penumbra::reference::detail
