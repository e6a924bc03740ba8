// The renderer: packs a scene for the device, runs the stages per view, and runs them
// backwards for gradients.
#include "penumbra/renderer.hpp"

#include <algorithm>
#include <cmath>

#include "common/layout.h"
#include "ops/ops.hpp"
#include "penumbra/error.hpp"
#include "tuning/stages.hpp"
#include "view_params.hpp"

namespace penumbra {

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
  bool automatic;  // choose the tuning per render from the database
  TuningDatabase database;
  detail::Kernels kernels;
  // State of the most recent render(), kept for backward().
  Scene scene;      // as rendered, light frusta fitted, lengths multiplied by `norm`
  double norm = 1;  // the normalisation (normalisation()): device lengths = world lengths · norm
  std::vector<LightFrustum> frusta;  // the lights' frusta as fitted, in world units
  Packed packed;
  DeviceGeometry geometry;
  std::vector<ViewState> views;        // one per camera
  std::vector<ViewState> light_views;  // one per light, when shadows are on
  std::vector<std::vector<double>> view_P;

  // Progress (set_progress): the observer, where the call is, and which pass of how many.
  ProgressObserver observer;
  RenderProgress progress;
  int pass_done = 0, pass_total = 1;

  Impl(Context& c, Precision p, bool automatic_, const Tuning& t)
      : ctx(c), precision(p), automatic(automatic_), kernels(c, p, t) {
    if (automatic) database = TuningDatabase::load_default();
  }

  void begin_pass(const char* call, const char* pass, int index, int count, int done, int total) {
    progress.call = call;
    progress.pass = pass;
    progress.index = index + 1;
    progress.count = count;
    pass_done = done;
    pass_total = std::max(total, 1);
  }
  void report(double within) {
    ctx.queue().finish();  // what is reported is what runs next
    progress.fraction = std::min(1.0, (pass_done + within) / pass_total);
    observer(progress);
  }
  void stage(const char* name) {
    if (!observer) return;
    progress.stage = name;
    progress.part = progress.parts = 0;
    report(0);
  }

  void render_view(ViewState& v, int W, int H, int nlights, const std::vector<double>& P) {
    v.W = W;
    v.H = H;
    v.nlights = nlights;
    v.P = detail::upload_reals(ctx, precision, P);
    detail::transform_forward(kernels, geometry, v);
    detail::raster_fragments(kernels, geometry, v);
  }

  // Backward of one view for dL/d(image) and dL/d(depth) already on the device, after the
  // shadow backward (if any) has run between `resolve` and `faces`: adds dL/d(vertices) and
  // dL/d(the view's frame) to the host accumulators and returns the per-face light gradients.
  std::vector<double> backward_faces(ViewState& v, const cl::Buffer& gimage,
                                     const cl::Buffer& gdepth, std::vector<double>& gvert,
                                     std::vector<double>& galb, std::vector<double>* gframe,
                                     const cl::Buffer* gpenumbra = nullptr) {
    auto fg = detail::raster_backward(kernels, geometry, v, gimage, gdepth);
    if (gpenumbra) detail::penumbra_backward_faces(kernels, geometry, v, *gpenumbra, fg);
    cl::Buffer gv, gf;
    detail::transform_backward(kernels, geometry, v, fg, gv, gf);
    const Packed& p = packed;
    auto gv_host = detail::download_reals(ctx, precision, gv, size_t(p.nv) * 4);
    auto ga_host = detail::download_reals(ctx, precision, fg.albedo, size_t(p.nf) * 12);
    for (size_t i = 0; i < gvert.size(); ++i) gvert[i] += gv_host[i];
    for (size_t i = 0; i < galb.size(); ++i) galb[i] += ga_host[i];
    if (gframe) {  // Σ over vertices, in order
      auto gf_host = detail::download_reals(ctx, precision, gf, size_t(p.nv) * 16);
      for (int vtx = 0; vtx < p.nv; ++vtx)
        for (int i = 0; i < 16; ++i) (*gframe)[i] += gf_host[size_t(vtx) * 16 + i];
    }
    return detail::download_reals(ctx, precision, fg.light, size_t(p.nf) * (6 * v.nlights + 1) * 4);
  }
};

namespace {
void check_precision(const Context& context, Precision precision) {
  if (precision == Precision::Double && !context.info().fp64)
    throw Error("device '" + context.info().name + "' has no double precision (cl_khr_fp64)");
}
}  // namespace

Renderer::Renderer(Context& context, Precision precision) {
  check_precision(context, precision);
  impl_ = std::make_unique<Impl>(context, precision, true, Tuning{});
}

Renderer::Renderer(Context& context, Precision precision, const Tuning& tuning) {
  check_precision(context, precision);
  Tuning t = detail::for_device(tuning, context.info());
  validate(t, context.info());
  impl_ = std::make_unique<Impl>(context, precision, false, t);
}

Renderer::~Renderer() = default;

void Renderer::set_progress(ProgressObserver observer) {
  Impl& m = *impl_;
  m.observer = std::move(observer);
  if (!m.observer) {
    m.kernels.on_part = nullptr;
    return;
  }
  m.kernels.on_part = [&m](int i, int n) {
    m.progress.part = i + 1;
    m.progress.parts = n;
    m.report(double(i) / n);
  };
}
Precision Renderer::precision() const { return impl_->precision; }
const Tuning& Renderer::tuning() const { return impl_->kernels.tuning(); }

std::vector<RenderOutput> Renderer::render(const Scene& scene) {
  validate(scene);
  if (scene.lights.size() > P_MAX_LIGHTS)
    throw Error("scene has " + std::to_string(scene.lights.size()) + " lights; at most " +
                std::to_string(P_MAX_LIGHTS) + " are supported");
  Impl& m = *impl_;
  Context& ctx = m.ctx;
  m.scene = scene;
  fit_light_frusta(m.scene);  // frusta not given are fitted to this scene and then fixed
  m.frusta.clear();
  for (const Light& l : m.scene.lights) m.frusta.push_back(l.frustum);
  m.norm = detail::normalisation(m.scene);
  if (m.norm != 1) m.scene = scale_scene(m.scene, m.norm);
  if (m.automatic) m.kernels.set_tuning(m.database.lookup(ctx.info(), workload_stats(scene)));
  const Scene& s = m.scene;
  const bool shadows = s.params.shadows != Shadows::None;
  const bool accurate = s.params.shadow_model == ShadowModel::Accurate;
  const int nl = int(s.lights.size());
  m.packed = pack(s);
  const Packed& p = m.packed;
  detail::check_memory(ctx, estimate_device_memory(s, m.precision),
                       "rendering the scene (" + std::to_string(p.nf) + " faces)");
  DeviceGeometry& g = m.geometry;
  g.nv = p.nv;
  g.nf = p.nf;
  g.vworld = detail::upload_reals(ctx, m.precision, p.vworld);
  g.faces = detail::upload_ints(ctx, p.faces);
  g.albedo = detail::upload_reals(ctx, m.precision, p.albedo);

  m.light_views.assign(shadows ? nl : 0, ViewState{});
  const int passes = int(m.light_views.size() + s.cameras.size());
  for (size_t l = 0; l < m.light_views.size(); ++l) {  // shadow maps S
    ViewState& lv = m.light_views[l];
    const int size = s.params.shadow_map_size;
    m.begin_pass("render", "light", int(l), nl, int(l), passes);
    m.stage("shadow map");
    m.render_view(lv, size, size, 0, detail::light_view_params(s, l));
    detail::raster_resolve(m.kernels, lv);
    if (s.params.shadows == Shadows::Soft && !accurate) {
      m.stage("penumbra map");
      detail::penumbra_forward(m.kernels, g, lv);
    }
  }
  m.views.assign(s.cameras.size(), ViewState{});
  m.view_P.clear();
  std::vector<RenderOutput> out;
  for (size_t c = 0; c < s.cameras.size(); ++c) {
    const Camera& cam = s.cameras[c];
    ViewState& v = m.views[c];
    m.begin_pass("render", "view", int(c), int(s.cameras.size()), int(m.light_views.size() + c),
                 passes);
    m.stage("raster");
    m.view_P.push_back(detail::view_params(s, cam));
    m.render_view(v, cam.width, cam.height, nl, m.view_P.back());
    for (size_t l = 0; l < m.light_views.size(); ++l) {
      m.stage("shadow lookups");
      if (accurate)
        detail::pcf_forward(m.kernels, s.params.sampling, v, int(l), m.light_views[l]);
      else
        detail::shadow_forward(m.kernels, s.params, v, int(l), m.light_views[l]);
    }
    m.stage("resolve");
    detail::raster_resolve(m.kernels, v);
    const size_t npix = size_t(v.W) * v.H;
    auto image = detail::download_reals(ctx, m.precision, v.image, npix * 4);
    RenderOutput o;
    o.color = channels(image, v.W, v.H, 0, 3);
    o.silhouette = channels(image, v.W, v.H, 3, 1);
    o.depth = Image(v.W, v.H, 1);
    o.depth.data = detail::download_reals(ctx, m.precision, v.depth, npix);
    if (m.norm != 1)
      for (double& z : o.depth.data) z /= m.norm;
    out.push_back(std::move(o));
  }
  return out;
}

namespace {
std::vector<Image> light_maps(Context& ctx, Precision p, const std::vector<ViewState>& views,
                              cl::Buffer ViewState::*map, double unit = 1) {
  std::vector<Image> maps;
  for (auto& lv : views) {
    if (!(lv.*map)()) continue;
    Image img(lv.W, lv.H, 1);
    img.data = detail::download_reals(ctx, p, lv.*map, size_t(lv.W) * lv.H);
    if (unit != 1)
      for (double& x : img.data) x *= unit;
    maps.push_back(std::move(img));
  }
  return maps;
}
}  // namespace

std::vector<Image> Renderer::shadow_maps() const {
  return light_maps(impl_->ctx, impl_->precision, impl_->light_views, &ViewState::depth,
                    1 / impl_->norm);
}

std::vector<Image> Renderer::penumbra_maps() const {
  return light_maps(impl_->ctx, impl_->precision, impl_->light_views, &ViewState::pen_map);
}

SceneGrads Renderer::backward(const Scene& scene, const std::vector<OutputGrads>& grads) {
  Impl& m = *impl_;
  Context& ctx = m.ctx;
  Scene fitted = scene;
  for (size_t l = 0; l < fitted.lights.size() && l < m.scene.lights.size(); ++l)
    if (!fitted.lights[l].frustum.fitted) fitted.lights[l].frustum = m.frusta[l];
  if (m.norm != 1) fitted = scale_scene(fitted, m.norm);
  Packed now = pack(fitted);
  bool same = now.vworld == m.packed.vworld && now.faces == m.packed.faces &&
              now.albedo == m.packed.albedo && fitted.cameras.size() == m.views.size() &&
              fitted.lights.size() == m.scene.lights.size() &&
              fitted.params.shadows == m.scene.params.shadows;
  for (size_t c = 0; same && c < fitted.cameras.size(); ++c)
    same = detail::view_params(fitted, fitted.cameras[c]) == m.view_P[c];
  if (!same)
    throw Error("backward: the scene differs from the one last rendered; call render() first");
  detail::check_memory(
      ctx, estimate_device_memory(m.scene, m.precision, true),
      "the backward pass of the scene (" + std::to_string(m.packed.nf) + " faces)");
  if (grads.size() != scene.cameras.size())
    throw Error("backward: got gradients for " + std::to_string(grads.size()) +
                " camera(s), the scene has " + std::to_string(scene.cameras.size()));

  const Scene& s = m.scene;
  const Packed& p = m.packed;
  const int nl = int(s.lights.size());
  const bool shadows = !m.light_views.empty();
  const bool accurate = s.params.shadow_model == ShadowModel::Accurate;
  std::vector<double> gsize(nl, 0.0);  // dL/dD_L
  std::vector<double> gvert(size_t(p.nv) * 4, 0.0), galb(size_t(p.nf) * 12, 0.0),
      glight(size_t(6 * nl + 1) * 4, 0.0);
  // dL/d(shadow map S) and dL/d(penumbra map P) of each light, summed over the cameras.
  std::vector<std::vector<double>> gmaps(m.light_views.size()), gpens(m.light_views.size());
  for (size_t l = 0; l < gmaps.size(); ++l) {
    gmaps[l].assign(size_t(m.light_views[l].W) * m.light_views[l].H, 0.0);
    gpens[l].assign(gmaps[l].size(), 0.0);
  }
  auto accumulate = [&](std::vector<double>& into, const cl::Buffer& buf) {
    auto host = detail::download_reals(ctx, m.precision, buf, into.size());
    for (size_t i = 0; i < host.size(); ++i) into[i] += host[i];
  };
  {  // vertex → (face·3 + corner) adjacency, in face order, for the gather in transform_bwd
    std::vector<int> count(p.nv + 1, 0), adj(size_t(p.nf) * 3);
    for (int i = 0; i < p.nf * 3; ++i) ++count[p.faces[(i / 3) * 4 + i % 3] + 1];
    for (int v = 0; v < p.nv; ++v) count[v + 1] += count[v];
    std::vector<int> cursor(count.begin(), count.end() - 1);
    for (int i = 0; i < p.nf * 3; ++i) adj[cursor[p.faces[(i / 3) * 4 + i % 3]]++] = i;
    m.geometry.adj_offsets = detail::upload_ints(ctx, count);
    m.geometry.adj = detail::upload_ints(ctx, adj);
  }
  const int passes = int(m.views.size() + m.light_views.size());
  for (size_t c = 0; c < m.views.size(); ++c) {
    ViewState& v = m.views[c];
    const OutputGrads& g = grads[c];
    m.begin_pass("backward", "view", int(c), int(m.views.size()), int(c), passes);
    m.stage("resolve");
    check_grad_image(g.color, v.W, v.H, 3, "color", c);
    check_grad_image(g.silhouette, v.W, v.H, 1, "silhouette", c);
    check_grad_image(g.depth, v.W, v.H, 1, "depth", c);
    const size_t npix = size_t(v.W) * v.H;
    std::vector<double> gimage(npix * 4, 0.0);
    for (size_t i = 0; i < npix; ++i) {
      for (int k = 0; k < 3 && !g.color.data.empty(); ++k)
        gimage[i * 4 + k] = g.color.data[i * 3 + k];
      if (!g.silhouette.data.empty()) gimage[i * 4 + 3] = g.silhouette.data[i];
    }
    auto gimage_buf = detail::upload_reals(ctx, m.precision, gimage);
    std::vector<double> gdepth =
        g.depth.data.empty() ? std::vector<double>(npix, 0.0) : g.depth.data;
    if (m.norm != 1)  // dL/d(device depth) = dL/d(depth) / norm
      for (double& x : gdepth) x /= m.norm;
    auto gdepth_buf = detail::upload_reals(ctx, m.precision, gdepth);
    detail::raster_resolve_backward(m.kernels, v, gimage_buf, gdepth_buf);
    for (size_t l = 0; l < m.light_views.size(); ++l) {
      m.stage("shadow lookups");
      auto gm = accurate
                    ? detail::pcf_backward(m.kernels, s.params,
                                           blocker_search_sigma(s.params, s.lights[l]), v, int(l),
                                           m.light_views[l], &gsize[l])
                    : detail::shadow_backward(m.kernels, s.params, v, int(l), m.light_views[l]);
      accumulate(gmaps[l], gm.S);
      if (gm.P()) accumulate(gpens[l], gm.P);
    }
    m.stage("faces");
    auto gl = m.backward_faces(v, gimage_buf, gdepth_buf, gvert, galb, nullptr);
    for (int f = 0; f < p.nf; ++f)  // fixed order: reproducible
      for (size_t i = 0; i < glight.size(); ++i) glight[i] += gl[f * glight.size() + i];
  }
  // Penumbra maps back to their shadow maps, the light sizes and the occluders; then the
  // shadow maps back through each light's own raster pass.
  std::vector<std::vector<double>> gframe(nl, std::vector<double>(16, 0.0));
  for (size_t l = 0; l < m.light_views.size(); ++l) {
    ViewState& lv = m.light_views[l];
    const size_t ntex = size_t(lv.W) * lv.H;
    m.begin_pass("backward", "light", int(l), nl, int(m.views.size() + l), passes);
    cl::Buffer gpen;
    if (s.params.shadows == Shadows::Soft && !accurate) {
      m.stage("penumbra map");
      gpen = detail::upload_reals(ctx, m.precision, gpens[l]);
      accumulate(gmaps[l],
                 detail::penumbra_backward_texels(m.kernels, m.geometry, lv, gpen, &gsize[l]));
    }
    m.stage("shadow map");
    auto gimage_buf = detail::zero_reals(ctx, m.precision, ntex * 4);
    auto gdepth_buf = detail::upload_reals(ctx, m.precision, gmaps[l]);
    detail::raster_resolve_backward(m.kernels, lv, gimage_buf, gdepth_buf);
    m.backward_faces(lv, gimage_buf, gdepth_buf, gvert, galb, &gframe[l], gpen() ? &gpen : nullptr);
  }

  SceneGrads out;
  for (size_t mi = 0; mi < s.meshes.size(); ++mi) {
    const Mesh& mesh = s.meshes[mi];
    std::vector<glm::dvec3> gv(mesh.vertices.size()), ga(mesh.albedo.size(), glm::dvec3(0.0));
    for (size_t i = 0; i < gv.size(); ++i) {
      const double* v = &gvert[(p.vertex_offset[mi] + i) * 4];
      gv[i] = {v[0], v[1], v[2]};
    }
    for (size_t f = 0; f < mesh.faces.size(); ++f)
      for (int k = 0; k < 3; ++k) {
        const double* a = &galb[((p.face_offset[mi] + f) * 3 + k) * 4];
        size_t to = mesh.albedo_mode == AlbedoMode::PerFace ? f : size_t(mesh.faces[f][k]);
        ga[to] += glm::dvec3(a[0], a[1], a[2]);
      }
    out.vertices.push_back(std::move(gv));
    out.albedo.push_back(std::move(ga));
  }
  auto vec = [&](const std::vector<double>& a, size_t at) {
    return glm::dvec3(a[at], a[at + 1], a[at + 2]);
  };
  for (int l = 0; l < nl; ++l) {
    // Frame gradients from the camera passes (fragments projected into the map) and from the
    // light's own pass (vertices projected into the map).
    const size_t fo = size_t(2 * nl + 1 + 4 * l) * 4;
    glm::dvec3 ge = vec(glight, fo) + vec(gframe[l], 0),
               gf = vec(glight, fo + 4) + vec(gframe[l], 4),
               gr = vec(glight, fo + 8) + vec(gframe[l], 8),
               gu = vec(glight, fo + 12) + vec(gframe[l], 12);
    glm::dvec3 gpos = vec(glight, 8 * size_t(l));
    if (shadows) gpos += detail::light_frame_backward(s.lights[l], ge, gf, gr, gu);
    out.light_position.push_back(gpos);
    out.light_color.push_back(vec(glight, 8 * size_t(l) + 4));
    out.light_size.push_back(gsize[l]);
  }
  out.ambient = vec(glight, 8 * size_t(nl));
  if (m.norm != 1) {  // d/d(world length) = norm · d/d(device length)
    for (auto& mesh : out.vertices)
      for (glm::dvec3& g : mesh) g *= m.norm;
    for (int l = 0; l < nl; ++l) {
      if (s.lights[l].type == LightType::Point) out.light_position[l] *= m.norm;
      out.light_size[l] *= m.norm;
    }
  }
  return out;
}

}  // namespace penumbra
