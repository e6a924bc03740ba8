// The renderer: packs a scene for the device, runs the stages per view, and runs them
// backwards for gradients.
#include "penumbra/renderer.hpp"

#include <cmath>

#include "common/layout.h"
#include "ops/ops.hpp"
#include "penumbra/error.hpp"

namespace penumbra {
namespace detail {

Kernels::Kernels(Context& ctx, Precision precision, RasterTuning tuning)
    : ctx_(ctx), precision_(precision), tuning_(tuning) {}

std::string Kernels::options(const std::string& file) const {
  std::string o = precision_define(precision_);
  if (file == "bin.cl" || file == "raster.cl") o += " -DTILE=" + std::to_string(tuning_.tile);
  if (file == "raster.cl")
    o += " -DPPW=" + std::to_string(tuning_.pixels_per_item) +
         " -DBRUTE_FORCE=" + std::to_string(tuning_.brute_force ? 1 : 0);
  return o;
}

cl::Kernel& Kernels::get(const std::string& file, const std::string& name) {
  auto key = file + ":" + name;
  auto it = kernels_.find(key);
  if (it != kernels_.end()) return it->second;
  cl::Program& program = ctx_.program(file, options(file));
  return kernels_.emplace(key, cl::Kernel(program, name.c_str())).first->second;
}

}  // namespace detail

namespace {

using detail::DeviceGeometry;
using detail::ViewState;

// The scene with all meshes concatenated, in the layouts the kernels read.
struct Packed {
  int nv = 0, nf = 0;
  std::vector<double> vworld, albedo;  // nv × 4, 3·nf × 4
  std::vector<int> faces;              // nf × 4
  std::vector<size_t> vertex_offset, face_offset;
};

Packed pack(const Scene& s) {
  Packed p;
  for (auto& m : s.meshes) {
    p.vertex_offset.push_back(p.nv);
    p.face_offset.push_back(p.nf);
    for (auto& v : m.vertices) p.vworld.insert(p.vworld.end(), {v.x, v.y, v.z, 0.0});
    for (size_t f = 0; f < m.faces.size(); ++f) {
      auto F = m.faces[f];
      p.faces.insert(p.faces.end(), {F.x + p.nv, F.y + p.nv, F.z + p.nv, 0});
      for (int k = 0; k < 3; ++k) {
        auto a = m.albedo_mode == AlbedoMode::PerFace ? m.albedo[f] : m.albedo[F[k]];
        p.albedo.insert(p.albedo.end(), {a.x, a.y, a.z, 0.0});
      }
    }
    p.nv += int(m.vertices.size());
    p.nf += int(m.faces.size());
  }
  return p;
}

std::vector<double> view_params(const Scene& s, const Camera& c) {
  const auto& r = s.params;
  std::vector<double> P(P_SIZE, 0.0);
  P[P_SIGMA] = r.sigma;
  P[P_GAMMA] = r.gamma;
  P[P_EPS] = r.eps;
  P[P_CUTOFF_D2] = r.sigma * std::log(1.0 / r.dist_eps - 1.0);
  P[P_NEAR] = c.near;
  P[P_FAR] = c.far;
  P[P_ORTHO] = c.projection == Projection::Orthographic ? 1 : 0;
  P[P_SCALE] = c.projection == Projection::Orthographic
                   ? c.half_height
                   : std::tan(0.5 * c.fov_deg * 3.14159265358979323846 / 180.0);
  P[P_CULL] = r.cull_backfaces ? 1 : 0;
  P[P_NLIGHTS] = double(s.lights.size());
  auto put = [&](int at, glm::dvec3 v) {
    P[at] = v.x;
    P[at + 1] = v.y;
    P[at + 2] = v.z;
  };
  glm::dvec3 f = glm::normalize(c.target - c.eye);
  glm::dvec3 right = glm::normalize(glm::cross(f, c.up));
  put(P_EYE, c.eye);
  put(P_RIGHT, right);
  put(P_UP, glm::cross(right, f));
  put(P_FWD, f);
  put(P_AMBIENT, s.ambient);
  put(P_BACKGROUND, s.background);
  for (size_t i = 0; i < s.lights.size(); ++i) {
    const Light& L = s.lights[i];
    int at = P_LIGHTS + int(i) * P_LIGHT_STRIDE;
    put(at + L_POS, L.type == LightType::Point ? L.position : L.direction);
    P[at + L_POINT] = L.type == LightType::Point ? 1 : 0;
    put(at + L_COLOR, L.color);
    P[at + L_SIZE] = L.size;
  }
  return P;
}

Image channels(const std::vector<double>& rgba, int W, int H, int first, int count) {
  Image img(W, H, count);
  for (size_t i = 0; i < size_t(W) * H; ++i)
    for (int c = 0; c < count; ++c) img.data[i * count + c] = rgba[i * 4 + first + c];
  return img;
}

void check_grad_image(const Image& g, int W, int H, int C, const char* what, size_t view) {
  if (g.data.empty()) return;
  if (g.width != W || g.height != H || g.channels != C || g.data.size() != size_t(W) * H * C)
    throw Error("gradient of " + std::string(what) + " for camera " + std::to_string(view) +
                " is " + std::to_string(g.width) + "x" + std::to_string(g.height) + "x" +
                std::to_string(g.channels) + ", expected " + std::to_string(W) + "x" +
                std::to_string(H) + "x" + std::to_string(C));
}

}  // namespace

struct Renderer::Impl {
  Context& ctx;
  Precision precision;
  RasterTuning tuning;
  detail::Kernels kernels;
  // State of the most recent render(), kept for backward().
  Packed packed;
  DeviceGeometry geometry;
  std::vector<ViewState> views;
  std::vector<std::vector<double>> view_P;

  Impl(Context& c, Precision p, RasterTuning t) : ctx(c), precision(p), tuning(t), kernels(c, p, t) {}
};

Renderer::Renderer(Context& context, Precision precision, RasterTuning tuning) {
  if (tuning.tile < 1 || tuning.pixels_per_item < 1 || tuning.tile % tuning.pixels_per_item)
    throw Error("raster tuning: tile (" + std::to_string(tuning.tile) +
                ") must be a positive multiple of pixels_per_item (" +
                std::to_string(tuning.pixels_per_item) + ")");
  size_t group = size_t(tuning.tile / tuning.pixels_per_item) * tuning.tile;
  if (group > context.info().max_work_group)
    throw Error("raster tuning: a " + std::to_string(tuning.tile) + "-pixel tile with " +
                std::to_string(tuning.pixels_per_item) + " pixel(s) per work-item needs " +
                std::to_string(group) + " work-items per group; device '" + context.info().name +
                "' allows " + std::to_string(context.info().max_work_group));
  if (precision == Precision::Double && !context.info().fp64)
    throw Error("device '" + context.info().name + "' has no double precision (cl_khr_fp64)");
  impl_ = std::make_unique<Impl>(context, precision, tuning);
}

Renderer::~Renderer() = default;
Precision Renderer::precision() const { return impl_->precision; }
const RasterTuning& Renderer::tuning() const { return impl_->tuning; }

std::vector<RenderOutput> Renderer::render(const Scene& scene) {
  validate(scene);
  if (scene.lights.size() > P_MAX_LIGHTS)
    throw Error("scene has " + std::to_string(scene.lights.size()) + " lights; at most " +
                std::to_string(P_MAX_LIGHTS) + " are supported");
  Impl& m = *impl_;
  Context& ctx = m.ctx;
  m.packed = pack(scene);
  const Packed& p = m.packed;
  DeviceGeometry& g = m.geometry;
  g.nv = p.nv;
  g.nf = p.nf;
  g.vworld = detail::upload_reals(ctx, m.precision, p.vworld);
  g.faces = detail::upload_ints(ctx, p.faces);
  g.albedo = detail::upload_reals(ctx, m.precision, p.albedo);

  m.views.assign(scene.cameras.size(), ViewState{});
  m.view_P.clear();
  std::vector<RenderOutput> out;
  for (size_t c = 0; c < scene.cameras.size(); ++c) {
    const Camera& cam = scene.cameras[c];
    ViewState& v = m.views[c];
    v.W = cam.width;
    v.H = cam.height;
    m.view_P.push_back(view_params(scene, cam));
    v.P = detail::upload_reals(ctx, m.precision, m.view_P.back());
    detail::transform_forward(m.kernels, g, v);
    if (!m.tuning.brute_force) detail::bin_faces(m.kernels, g, v);
    detail::raster_forward(m.kernels, g, v);
    const size_t npix = size_t(v.W) * v.H;
    auto image = detail::download_reals(ctx, m.precision, v.image, npix * 4);
    auto aux = detail::download_reals(ctx, m.precision, v.aux, npix * 4);
    RenderOutput o;
    o.color = channels(image, v.W, v.H, 0, 3);
    o.silhouette = channels(image, v.W, v.H, 3, 1);
    o.depth = channels(aux, v.W, v.H, 0, 1);
    out.push_back(std::move(o));
  }
  return out;
}

SceneGrads Renderer::backward(const Scene& scene, const std::vector<OutputGrads>& grads) {
  Impl& m = *impl_;
  Context& ctx = m.ctx;
  Packed now = pack(scene);
  bool same = now.vworld == m.packed.vworld && now.faces == m.packed.faces &&
              now.albedo == m.packed.albedo && scene.cameras.size() == m.views.size();
  for (size_t c = 0; same && c < scene.cameras.size(); ++c)
    same = view_params(scene, scene.cameras[c]) == m.view_P[c];
  if (!same)
    throw Error("backward: the scene differs from the one last rendered; call render() first");
  if (grads.size() != scene.cameras.size())
    throw Error("backward: got gradients for " + std::to_string(grads.size()) +
                " camera(s), the scene has " + std::to_string(scene.cameras.size()));

  const Packed& p = m.packed;
  const int nl = int(scene.lights.size());
  std::vector<double> gvert(size_t(p.nv) * 4, 0.0), galb(size_t(p.nf) * 12, 0.0),
      glight(size_t(2 * nl + 1) * 4, 0.0);
  // Vertex → (face·3 + corner) adjacency, in face order, for the gather in transform_bwd.
  {
    std::vector<int> count(p.nv + 1, 0), adj(size_t(p.nf) * 3);
    for (int i = 0; i < p.nf * 3; ++i) ++count[p.faces[(i / 3) * 4 + i % 3] + 1];
    for (int v = 0; v < p.nv; ++v) count[v + 1] += count[v];
    std::vector<int> cursor(count.begin(), count.end() - 1);
    for (int i = 0; i < p.nf * 3; ++i) adj[cursor[p.faces[(i / 3) * 4 + i % 3]]++] = i;
    m.geometry.adj_offsets = detail::upload_ints(ctx, count);
    m.geometry.adj = detail::upload_ints(ctx, adj);
  }
  for (size_t c = 0; c < m.views.size(); ++c) {
    const ViewState& v = m.views[c];
    const OutputGrads& g = grads[c];
    check_grad_image(g.color, v.W, v.H, 3, "color", c);
    check_grad_image(g.silhouette, v.W, v.H, 1, "silhouette", c);
    check_grad_image(g.depth, v.W, v.H, 1, "depth", c);
    const size_t npix = size_t(v.W) * v.H;
    std::vector<double> gimage(npix * 4, 0.0), gdepth(npix, 0.0);
    for (size_t i = 0; i < npix; ++i) {
      for (int k = 0; k < 3 && !g.color.data.empty(); ++k) gimage[i * 4 + k] = g.color.data[i * 3 + k];
      if (!g.silhouette.data.empty()) gimage[i * 4 + 3] = g.silhouette.data[i];
      if (!g.depth.data.empty()) gdepth[i] = g.depth.data[i];
    }
    auto gimage_buf = detail::upload_reals(ctx, m.precision, gimage);
    auto gdepth_buf = detail::upload_reals(ctx, m.precision, gdepth);
    auto fg = detail::raster_backward(m.kernels, m.geometry, v, nl, gimage_buf, gdepth_buf);
    auto gv = detail::transform_backward(m.kernels, m.geometry, v, fg);
    auto gv_host = detail::download_reals(ctx, m.precision, gv, size_t(p.nv) * 4);
    auto ga_host = detail::download_reals(ctx, m.precision, fg.albedo, size_t(p.nf) * 12);
    auto gl_host = detail::download_reals(ctx, m.precision, fg.light, size_t(p.nf) * (2 * nl + 1) * 4);
    for (size_t i = 0; i < gvert.size(); ++i) gvert[i] += gv_host[i];
    for (size_t i = 0; i < galb.size(); ++i) galb[i] += ga_host[i];
    for (int f = 0; f < p.nf; ++f)  // fixed order: reproducible
      for (size_t i = 0; i < glight.size(); ++i) glight[i] += gl_host[f * glight.size() + i];
  }

  SceneGrads out;
  for (size_t mi = 0; mi < scene.meshes.size(); ++mi) {
    const Mesh& mesh = scene.meshes[mi];
    std::vector<glm::dvec3> gv(mesh.vertices.size()), ga(mesh.albedo.size(), glm::dvec3(0.0));
    for (size_t i = 0; i < gv.size(); ++i) {
      const double* s = &gvert[(p.vertex_offset[mi] + i) * 4];
      gv[i] = {s[0], s[1], s[2]};
    }
    for (size_t f = 0; f < mesh.faces.size(); ++f)
      for (int k = 0; k < 3; ++k) {
        const double* s = &galb[((p.face_offset[mi] + f) * 3 + k) * 4];
        size_t to = mesh.albedo_mode == AlbedoMode::PerFace ? f : size_t(mesh.faces[f][k]);
        ga[to] += glm::dvec3(s[0], s[1], s[2]);
      }
    out.vertices.push_back(std::move(gv));
    out.albedo.push_back(std::move(ga));
  }
  for (int i = 0; i < nl; ++i) {
    out.light_position.push_back({glight[8 * i], glight[8 * i + 1], glight[8 * i + 2]});
    out.light_color.push_back({glight[8 * i + 4], glight[8 * i + 5], glight[8 * i + 6]});
  }
  out.ambient = {glight[8 * nl], glight[8 * nl + 1], glight[8 * nl + 2]};
  return out;
}

}  // namespace penumbra
