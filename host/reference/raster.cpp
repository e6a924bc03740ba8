// The soft rasterizer of the CPU reference (raster.hpp): face set-up and the soft rasterization
// of one view, every pixel against every face (math.md §2–§3).
#include "reference/raster.hpp"

#include <algorithm>
#include <limits>

namespace penumbra::reference::detail {

namespace {

// Faces whose projected doubled area is at most this times the sum of their squared edges
// (from corner 0) are skipped: degenerate on screen, edge-on to the view (the kernels' rule).
constexpr double kMinScreenArea = std::numeric_limits<double>::epsilon();

}  // namespace

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
      const dvec2 e1 = face.p[1] - face.p[0], e2 = face.p[2] - face.p[0];
      face.area2 = cross2(e1, e2);
      if (std::abs(face.area2) <= kMinScreenArea * (glm::dot(e1, e1) + glm::dot(e2, e2))) continue;
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
// Soft rasterization of one view (math.md §2) with coverage sharpness σ and aggregation
// sharpness γ; the background has colour `background` and depth view.far.
RenderOutput raster(const Scene& scene, const View& view, double sigma, double gamma,
                    const dvec3& background, const Shader& shader) {
  const RenderParams& params = scene.params;
  const std::vector<Face> faces = setup_faces(scene, view);
  const int W = view.width, H = view.height;

  // Outside faces at or beyond this squared distance have D < ε_D and are skipped.
  const double cutoff2 = sigma * std::log(1.0 / params.dist_eps - 1.0);

  RenderOutput out;
  out.color = Image(W, H, 3);
  out.silhouette = Image(W, H, 1);
  out.depth = Image(W, H, 1);

  // Per-pixel list of faces contributing colour and depth.
  struct Fragment {
    double D, ztilde, z;
    dvec3 color;
  };
  std::vector<Fragment> fragments;

  for (int py = 0; py < H; ++py) {
    for (int px = 0; px < W; ++px) {
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

        const double u = (inside ? 1.0 : -1.0) * d2 / sigma;
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
        if (z < view.near || z > view.far) continue;  // silhouette only

        const double ztilde = (view.far - z) / (view.far - view.near);
        fragments.push_back({D, ztilde, z, shader(face, b)});
      }

      // Soft aggregation (math.md §2.3, SoftRas's stable form).
      double m = params.eps;
      for (const Fragment& fr : fragments) m = std::max(m, fr.ztilde);
      const double e_bg = std::exp((params.eps - m) / gamma);
      double Z = e_bg;
      dvec3 color = e_bg * background;
      double depth = e_bg * view.far;
      for (const Fragment& fr : fragments) {
        const double weight = fr.D * std::exp((fr.ztilde - m) / gamma);
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

}  // namespace penumbra::reference::detail
