// Plain double-precision reference of the forward pass without shadows (SPEC §0–§2, s = 1).
//
// Written for clarity, not speed: every pixel of the view visits every face of every mesh, with
// no tiling, no cut-off shortcuts beyond the SoftRas cut-off the SPEC defines, and no shared
// code with the OpenCL kernels. Tests compare the kernels against this file.
//
// Conventions (the kernels follow the same ones):
//   camera basis   f = normalize(target − eye), r = normalize(f × up), u = r × f;
//   view space     c = P − eye, z = c·f, x_c = c·r, y_c = c·u;
//   screen         perspective x = x_c / (z·tan(fov/2)), y = y_c / (z·tan(fov/2));
//                  orthographic x = x_c / h, y = y_c / h (depth z as above);
//   pixel centres  x = (2px + 1 − W)/H, y = (H − 2py − 1)/H, row 0 at the top.
#include "penumbra/reference.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <glm/glm.hpp>
#include <limits>
#include <vector>

namespace penumbra::reference {
namespace {

using glm::dvec2;
using glm::dvec3;

constexpr double kPi = 3.14159265358979323846;
// Faces whose projected doubled area is at most this are skipped (degenerate on screen).
constexpr double kMinScreenArea = 1e-20;

// Logistic function, evaluated without overflow for any |u|.
double sigmoid(double u) {
  if (u >= 0.0) return 1.0 / (1.0 + std::exp(-u));
  const double e = std::exp(u);
  return e / (1.0 + e);
}

// log(1 − sigmoid(u)) = −softplus(u), evaluated without overflow for any |u|.
double log_one_minus_sigmoid(double u) {
  if (u > 0.0) return -u - std::log1p(std::exp(-u));
  return -std::log1p(std::exp(u));
}

double cross2(dvec2 a, dvec2 b) { return a.x * b.y - a.y * b.x; }

// Squared distance from point q to segment [a, b].
double point_segment_dist2(dvec2 q, dvec2 a, dvec2 b) {
  const dvec2 ab = b - a;
  const double len2 = glm::dot(ab, ab);
  double t = len2 > 0.0 ? glm::dot(q - a, ab) / len2 : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  const dvec2 p = a + t * ab - q;
  return glm::dot(p, p);
}

// The view transform of one camera.
struct View {
  dvec3 eye, f, r, u;
  bool perspective;
  double scale;  // tan(fov/2) (perspective) or the half-height (orthographic)
  double near, far;
  int width, height;

  explicit View(const Camera& cam)
      : eye(cam.eye),
        perspective(cam.projection == Projection::Perspective),
        near(cam.near),
        far(cam.far),
        width(cam.width),
        height(cam.height) {
    f = glm::normalize(cam.target - cam.eye);
    r = glm::normalize(glm::cross(f, cam.up));
    u = glm::cross(r, f);
    scale = perspective ? std::tan(0.5 * cam.fov_deg * kPi / 180.0) : cam.half_height;
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
std::vector<Face> setup_faces(const Scene& scene, const View& view) {
  std::vector<Face> faces;
  for (const Mesh& mesh : scene.meshes) {
    for (size_t fi = 0; fi < mesh.faces.size(); ++fi) {
      const glm::ivec3 idx = mesh.faces[fi];
      Face face;
      bool behind = false;
      for (int k = 0; k < 3; ++k) {
        face.V[k] = mesh.vertices[size_t(idx[k])];
        face.z[k] = view.depth(face.V[k]);
        if (face.z[k] < view.near) behind = true;
        face.albedo[k] = mesh.albedo_mode == AlbedoMode::PerVertex ? mesh.albedo[size_t(idx[k])]
                                                                   : mesh.albedo[fi];
      }
      if (behind) continue;  // any vertex in front of the near plane: dropped (no clipping)
      for (int k = 0; k < 3; ++k) face.p[k] = view.screen(face.V[k]);
      face.area2 = cross2(face.p[1] - face.p[0], face.p[2] - face.p[0]);
      if (std::abs(face.area2) <= kMinScreenArea) continue;
      face.normal = glm::normalize(glm::cross(face.V[1] - face.V[0], face.V[2] - face.V[0]));
      if (scene.params.cull_backfaces) {
        const dvec3 to_camera = view.perspective ? view.eye - face.V[0] : -view.f;
        if (glm::dot(face.normal, to_camera) <= 0.0) continue;
      }
      faces.push_back(face);
    }
  }
  return faces;
}

// Colour of face `face` at perspective-correct barycentrics b (SPEC §2, no shadows).
dvec3 shade(const Scene& scene, const View& view, const Face& face, const dvec3& b) {
  const dvec3 X = b[0] * face.V[0] + b[1] * face.V[1] + b[2] * face.V[2];
  const dvec3 a = b[0] * face.albedo[0] + b[1] * face.albedo[1] + b[2] * face.albedo[2];
  dvec3 n = face.normal;
  const dvec3 to_camera = view.perspective ? view.eye - X : -view.f;
  if (glm::dot(n, to_camera) < 0.0) n = -n;
  dvec3 color = a * scene.ambient;
  for (const Light& light : scene.lights) {
    const dvec3 l = light.type == LightType::Point ? glm::normalize(light.position - X)
                                                   : -glm::normalize(light.direction);
    color += a * light.color * std::max(0.0, glm::dot(n, l));
  }
  return color;
}

}  // namespace

RenderOutput render(const Scene& scene, size_t camera_index) {
  const Camera& cam = scene.cameras.at(camera_index);
  const View view(cam);
  const RenderParams& params = scene.params;
  const std::vector<Face> faces = setup_faces(scene, view);

  // Outside faces at or beyond this squared distance have D < ε_D and are skipped.
  const double cutoff2 = params.sigma * std::log(1.0 / params.dist_eps - 1.0);

  RenderOutput out;
  out.color = Image(cam.width, cam.height, 3);
  out.silhouette = Image(cam.width, cam.height, 1);
  out.depth = Image(cam.width, cam.height, 1);

  // Per-pixel list of faces contributing colour and depth.
  struct Fragment {
    double D, ztilde, z;
    dvec3 color;
  };
  std::vector<Fragment> fragments;

  for (int py = 0; py < cam.height; ++py) {
    for (int px = 0; px < cam.width; ++px) {
      const dvec2 q = view.pixel_center(px, py);
      fragments.clear();
      double log_transparency = 0.0;  // log Π(1 − D_f) over all non-skipped faces

      for (const Face& face : faces) {
        // Screen barycentrics (signed-area ratios; positive inside for either winding).
        const double w0 = cross2(face.p[1] - q, face.p[2] - q) / face.area2;
        const double w1 = cross2(face.p[2] - q, face.p[0] - q) / face.area2;
        const double w2 = cross2(face.p[0] - q, face.p[1] - q) / face.area2;
        const bool inside = w0 > 0.0 && w1 > 0.0 && w2 > 0.0;

        const double d2 = std::min({point_segment_dist2(q, face.p[0], face.p[1]),
                                    point_segment_dist2(q, face.p[1], face.p[2]),
                                    point_segment_dist2(q, face.p[2], face.p[0])});
        if (!inside && d2 >= cutoff2) continue;  // SoftRas cut-off: D treated as exactly 0

        const double u = (inside ? 1.0 : -1.0) * d2 / params.sigma;
        const double D = sigmoid(u);
        log_transparency += log_one_minus_sigmoid(u);

        // Clamped, renormalised screen barycentrics, then depth and perspective-correct b.
        dvec3 wc(std::max(w0, 0.0), std::max(w1, 0.0), std::max(w2, 0.0));
        wc /= wc[0] + wc[1] + wc[2];
        double z;
        dvec3 b;
        if (view.perspective) {
          const double inv_z = wc[0] / face.z[0] + wc[1] / face.z[1] + wc[2] / face.z[2];
          z = 1.0 / inv_z;
          for (int k = 0; k < 3; ++k) b[k] = z * wc[k] / face.z[k];
        } else {
          z = wc[0] * face.z[0] + wc[1] * face.z[1] + wc[2] * face.z[2];
          b = wc;
        }
        if (z < cam.near || z > cam.far) continue;  // silhouette only

        const double ztilde = (cam.far - z) / (cam.far - cam.near);
        fragments.push_back({D, ztilde, z, shade(scene, view, face, b)});
      }

      // Soft aggregation (SPEC §1, SoftRas's stable form).
      double m = params.eps;
      for (const Fragment& fr : fragments) m = std::max(m, fr.ztilde);
      const double e_bg = std::exp((params.eps - m) / params.gamma);
      double Z = e_bg;
      dvec3 color = e_bg * scene.background;
      double depth = e_bg * cam.far;
      for (const Fragment& fr : fragments) {
        const double weight = fr.D * std::exp((fr.ztilde - m) / params.gamma);
        Z += weight;
        color += weight * fr.color;
        depth += weight * fr.z;
      }
      color /= Z;
      depth /= Z;

      for (int c = 0; c < 3; ++c) out.color.at(px, py, c) = color[c];
      out.depth.at(px, py) = depth;
      out.silhouette.at(px, py) = 0.0 - std::expm1(log_transparency);  // +0 when empty
    }
  }
  return out;
}

}  // namespace penumbra::reference
