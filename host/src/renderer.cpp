// The renderer's forward pipeline: prepares a scene for the device (packing.cpp packs its
// meshes) and runs the stages of each light's and each camera's pass (renderer_impl.hpp; the
// backward pipeline is backward.cpp).
#include "penumbra/renderer.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>

#include "common/layout.h"
#include "penumbra/error.hpp"
#include "renderer_impl.hpp"
#include "shadow_models.hpp"
#include "view_params.hpp"

namespace penumbra {

Renderer::Impl::TunedFor Renderer::Impl::TunedFor::of(const Scene& s) {
  return {s.cameras.empty() ? Camera{} : s.cameras.front(), s.params.sigma, s.params.dist_eps};
}
bool Renderer::Impl::TunedFor::operator==(const TunedFor& o) const {
  const Camera &a = camera, &b = o.camera;
  return a.eye == b.eye && a.target == b.target && a.up == b.up && a.projection == b.projection &&
         a.fov_deg == b.fov_deg && a.half_height == b.half_height && a.near == b.near &&
         a.far == b.far && a.width == b.width && a.height == b.height && sigma == o.sigma &&
         dist_eps == o.dist_eps;
}

Renderer::Impl::Impl(Context& c, Precision p, bool automatic_, const Tuning& t)
    : ctx(c), precision(p), automatic(automatic_), kernels(c, p, t) {
  if (automatic) database = TuningDatabase::load_default();
}

void Renderer::Impl::begin_pass(const char* call, const char* pass, int index, int count, int done,
                                int total) {
  progress.call = call;
  progress.pass = pass;
  progress.index = index + 1;
  progress.count = count;
  pass_done = done;
  pass_total = std::max(total, 1);
}

void Renderer::Impl::report(double within) {
  ctx.queue().finish();  // what is reported is what runs next
  progress.fraction = std::min(1.0, (pass_done + within) / pass_total);
  observer(progress);
}

void Renderer::Impl::mark(const char* name) { detail::profile_stage(ctx, call, name); }

void Renderer::Impl::stage(const char* name) {
  mark(name);
  if (interrupt_check) interrupt_check();
  if (!observer) return;
  progress.stage = name;
  progress.part = progress.parts = 0;
  report(0);
}

size_t Renderer::Impl::prepare(const Scene& given) {
  // An optimisation moves the vertices of fixed faces, and may change their albedo: the last
  // render's faces (and albedo), checked, packed and on the device, stay (at 100k faces,
  // packing and uploading them took 3-4 ms a render).
  kept = !geometry_current || !same_faces(given.meshes, meshes_as_given()) ? Kept::Nothing
         : same_albedo(given.meshes, meshes_as_given())                    ? Kept::FacesAndAlbedo
                                                                           : Kept::Faces;
  const Bounds extent =
      validated_bounds(given, kept != Kept::Nothing, kept == Kept::FacesAndAlbedo);
  if (given.lights.size() > P_MAX_LIGHTS)
    throw Error("scene has " + std::to_string(given.lights.size()) + " lights; at most " +
                std::to_string(P_MAX_LIGHTS) + " are supported");
  started = true;
  geometry_current = false;  // until upload_geometry() has put this scene's meshes there
  scene = given;             // the faces and albedo shared, not copied
  meshes_normalised = false;
  // Frusta not given are fitted to this scene and then fixed; without shadows none is used.
  if (scene.params.shadows != Shadows::None) fit_light_frusta(scene);
  check_frusta(given, scene);
  frusta.clear();
  for (const Light& l : scene.lights) frusta.push_back(l.frustum);
  scene.lights = drawn_lights(scene, &light_of);
  if (scene.lights.size() > P_MAX_LIGHTS)
    throw Error("the scene's lights need " + std::to_string(scene.lights.size()) +
                " shadow maps (a light mapped on a cube needs 6); at most " +
                std::to_string(P_MAX_LIGHTS) + " are supported");
  norm = detail::normalisation(extent);
  if (norm.identity()) {
    given_meshes.clear();
  } else {
    given_meshes = given.meshes;
    scene = detail::normalised(scene, norm);
    meshes_normalised = true;
  }
  if (automatic && !(kept != Kept::Nothing && tuned_for == TunedFor::of(given))) {
    kernels.set_tuning(database.lookup(ctx.info(), [&] { return workload_stats(given); }));
    tuned_for = TunedFor::of(given);
  }
  pack(scene, packed, kept);
  const size_t estimate = estimate_device_memory(scene, precision, false, &kernels.tuning());
  detail::check_memory(ctx, estimate,
                       "rendering the scene (" + std::to_string(packed.nf) + " faces)");
  return estimate;
}

std::vector<Light> Renderer::Impl::drawn_lights(const Scene& s, std::vector<int>* light_of) {
  if (s.params.shadows != Shadows::None) return cube_faces(s.lights, light_of);
  std::vector<Light> lights = s.lights;
  for (Light& l : lights) l.frustum.cube = false;
  return cube_faces(lights, light_of);
}

void Renderer::Impl::upload_geometry() {
  geometry.nv = packed.nv;
  geometry.nf = packed.nf;
  geometry.na = packed.na;
  if (kept == Kept::Nothing) {  // else into the last render's buffers, of the same sizes
    geometry.vworld = detail::alloc_reals(ctx, precision, size_t(packed.nv) * 4);
    geometry.faces = detail::upload_ints(ctx, packed.faces);
    // backward() builds these for these faces
    geometry.adj_offsets = geometry.adj = geometry.albedo_offsets = geometry.albedo_corners =
        cl::Buffer();
  }
  if (kept != Kept::FacesAndAlbedo)
    geometry.albedo = detail::upload_reals(ctx, precision, packed.albedo);
  write_vertices(ctx, precision, geometry.vworld, scene.meshes, size_t(packed.nv));
  geometry_current = true;
}

namespace {
// The fragments of each pass, moved out; the passes cleared (their other buffers released).
template <class Pass>
std::vector<detail::Fragments> take_fragments(std::vector<Pass>& passes) {
  std::vector<detail::Fragments> fragments;
  fragments.reserve(passes.size());
  for (Pass& p : passes) {
    fragments.push_back(std::move(p.fragments));
    fragments.back().pix_offset = cl::Buffer();  // an upload, made anew each time
  }
  passes.clear();
  return fragments;
}
size_t buffer_bytes(const cl::Buffer& b) { return b() ? b.getInfo<CL_MEM_SIZE>() : 0; }
size_t fragment_bytes(const std::vector<detail::Fragments>& fragments) {
  size_t bytes = 0;
  for (const detail::Fragments& f : fragments) {
    for (const cl::Buffer* b : {&f.aux, &f.pix_n, &f.rec_face, &f.rec_frag, &f.rec_shade,
                                &f.rec_light, &f.rec_light2, &f.face_kept})
      bytes += buffer_bytes(*b);
    for (const auto* kept : {&f.exact_forward, &f.exact_backward})
      for (const detail::ExactWeights& w : *kept)
        for (const cl::Buffer* b : {&w.Gx, &w.Gy, &w.Gxd, &w.Gyd, &w.support})
          bytes += buffer_bytes(*b);
  }
  return bytes;
}
// View i's spare fragments, moved out (none when the last render had no view i).
detail::Fragments take_spare(std::vector<detail::Fragments>& spares, int i) {
  return size_t(i) < spares.size() ? std::move(spares[size_t(i)]) : detail::Fragments{};
}
}  // namespace

// transform → raster → resolve: the shadow map S (and coverage A), then the model's light map
// (the paper model's penumbra map).
void Renderer::Impl::shadow_map_pass(int light, detail::Fragments spare) {
  LightPass& lp = light_passes[light];
  const int size = shadow_map_side(scene.params);
  stage("shadow map");
  rasterise(lp, size, size, 0, detail::light_view_params(scene, light), std::move(spare));
  lp.resolved = detail::raster_resolve(kernels, lp.view, lp.fragments);
  const detail::ShadowModelPasses& model = detail::shadow_model_passes(scene.params.shadow_model);
  if (model.builds_light_map(scene.params)) {
    stage(model.light_map_stage);
    lp.penumbra = model.light_map(kernels, geometry, lp.view, lp.screen, lp.resolved.depth);
  }
}

// transform → raster → the shadow lookups of every light → resolve.
void Renderer::Impl::camera_pass(int camera, detail::Fragments spare) {
  const Camera& cam = scene.cameras[camera];
  ViewPass& cp = camera_passes[camera];
  stage("raster");
  view_P.push_back(detail::view_params(scene, cam));
  rasterise(cp, cam.width, cam.height, int(scene.lights.size()), view_P.back(), std::move(spare));
  const detail::ShadowModelPasses& model = detail::shadow_model_passes(scene.params.shadow_model);
  for (size_t l = 0; l < light_passes.size(); ++l) {
    stage("shadow lookups");
    model.lookup(kernels, scene.params, scene.lights[l], cp.view, cp.fragments, int(l),
                 light_passes[l].maps());
  }
  stage("resolve");
  cp.resolved = detail::raster_resolve(kernels, cp.view, cp.fragments);
}

// The view with parameters P, then transform → raster passes 1–2: its kept fragments.
void Renderer::Impl::rasterise(ViewPass& vp, int W, int H, int nlights,
                               const std::vector<double>& P, detail::Fragments spare) {
  vp.view = {W, H, nlights, P[P_SHADOWS] > 0, detail::upload_reals(ctx, precision, P)};
  vp.screen = detail::transform_forward(kernels, geometry, vp.view);
  vp.fragments = detail::raster_fragments(kernels, geometry, vp.view, vp.screen, std::move(spare));
}

// The outputs read in place from the mapped buffers into the caller's memory: a copy of the
// RGBA buffer and a second depth image, most of their cost page faults of fresh memory, had made
// this function 9.9 % of a 256² no-shadow benchmark's samples (perf), 3.8 % since.
template <class Real>
void Renderer::Impl::write_outputs(const ViewPass& cp, const OutputBuffers<Real>& out) {
  const size_t npix = size_t(cp.view.W) * cp.view.H;
  detail::read_reals(ctx, precision, cp.resolved.image, npix * 4, [&](const auto* rgba) {
    for (size_t i = 0; i < npix; ++i) {
      for (int c = 0; c < 3; ++c) out.color[3 * i + c] = Real(rgba[4 * i + c]);
      out.silhouette[i] = Real(rgba[4 * i + 3]);
    }
  });
  const double scale = norm.scale;  // (z / 1 is z)
  detail::read_reals(ctx, precision, cp.resolved.depth, npix, [&](const auto* z) {
    for (size_t i = 0; i < npix; ++i) out.depth[i] = Real(z[i] / scale);
  });
}

RenderOutput Renderer::Impl::download(const ViewPass& cp) {
  const int W = cp.view.W, H = cp.view.H;
  RenderOutput o{Image(W, H, 3), Image(W, H, 1), Image(W, H, 1)};
  write_outputs(cp, OutputBuffers<double>{o.color.data.data(), o.silhouette.data.data(),
                                          o.depth.data.data()});
  return o;
}

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
  const std::lock_guard<std::mutex> lock(m.busy);
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

void Renderer::Impl::check_frusta(const Scene& given, const Scene& s) {
  if (warned_frustum || s.params.shadows == Shadows::None) return;
  for (size_t l = 0; l < s.lights.size(); ++l) {
    const LightFrustum& f = s.lights[l].frustum;
    if (f.cube) continue;  // holds every direction
    const bool widest = f.automatic && f.fov_deg >= kWidestFit;
    // A fit to this scene narrower than its widest holds every caster by construction.
    if ((!given.lights[l].frustum.fitted && !widest) || frustum_holds_casters(s, s.lights[l]))
      continue;
    if (widest)
      std::fprintf(stderr,
                   "penumbra: warning: light %zu is among the objects: faces that cast its "
                   "shadows lie outside its shadow map (one frustum, %g degrees wide), so those "
                   "shadows are missing\n",
                   l, kWidestFit);
    else
      std::fprintf(stderr,
                   "penumbra: warning: the shadow-map frustum given for light %zu leaves out "
                   "faces that cast its shadows, which are cut off at its edge; leave it "
                   "unfitted (or refit it) to follow the geometry\n",
                   l);
    warned_frustum = true;
    return;
  }
}

void Renderer::Impl::abandon() {
  ctx.queue().finish();  // nothing of the call still runs on buffers released below
  geometry_current = false;
  camera_passes.clear();
  light_passes.clear();
  view_P.clear();
}

std::vector<RenderOutput> Renderer::render(const Scene& scene) {
  return impl_->exclusive([&] {
    std::vector<RenderOutput> out;
    impl_->render(scene, [&](int, const ViewPass& cp) { out.push_back(impl_->download(cp)); });
    return out;
  });
}

template <class Real>
void Renderer::Impl::render_into(const Scene& scene, const std::vector<OutputBuffers<Real>>& out) {
  if (out.size() != scene.cameras.size())
    throw Error("render_into: " + std::to_string(out.size()) + " output buffers for " +
                std::to_string(scene.cameras.size()) + " cameras");
  for (size_t c = 0; c < out.size(); ++c)
    if (!out[c].color || !out[c].silhouette || !out[c].depth)
      throw Error("render_into: an output buffer of camera " + std::to_string(c) + " is null");
  exclusive([&] { render(scene, [&](int c, const ViewPass& cp) { write_outputs(cp, out[c]); }); });
}

void Renderer::render_into(const Scene& scene, const std::vector<OutputBuffers<float>>& out) {
  impl_->render_into(scene, out);
}

void Renderer::render_into(const Scene& scene, const std::vector<OutputBuffers<double>>& out) {
  impl_->render_into(scene, out);
}

void Renderer::set_interrupt_check(std::function<void()> check) {
  const std::lock_guard<std::mutex> lock(impl_->busy);
  impl_->interrupt_check = std::move(check);
}

// Every light's shadow map first (when shadows are on), then every camera's image.
void Renderer::Impl::render(const Scene& scene, const Deliver& deliver) {
  Impl& m = *this;
  const Impl::CallProfile profile(m, "render", "prepare");
  const size_t estimate = m.prepare(scene);
  m.mark("upload");
  m.upload_geometry();
  const int nl = int(m.scene.lights.size()), nc = int(m.scene.cameras.size());
  std::vector<detail::Fragments> spare_lights = take_fragments(m.light_passes),
                                 spare_cameras = take_fragments(m.camera_passes);
  if (!detail::exact_lookups(m.scene.params))  // the weights the last render's lookups kept: unused
    for (detail::Fragments& f : spare_cameras) f.exact_forward.clear(), f.exact_backward.clear();
  // Held beside this render's buffers only where both fit in the memory it was checked against.
  if (fragment_bytes(spare_lights) + fragment_bytes(spare_cameras) + estimate >
      m.ctx.memory_limit()) {
    spare_lights.clear();
    spare_cameras.clear();
  }
  m.light_passes.assign(m.scene.params.shadows != Shadows::None ? nl : 0, LightPass{});
  const int lights = int(m.light_passes.size()), passes = lights + nc;
  for (int l = 0; l < lights; ++l) {
    m.begin_pass("render", "light", l, nl, l, passes);
    m.shadow_map_pass(l, take_spare(spare_lights, l));
  }
  spare_lights.clear();  // those no light pass took, before the cameras need memory
  m.camera_passes.assign(nc, ViewPass{});
  m.view_P.clear();
  for (int c = 0; c < nc; ++c) {
    m.begin_pass("render", "view", c, nc, lights + c, passes);
    m.camera_pass(c, take_spare(spare_cameras, c));
    m.mark("outputs");
    deliver(c, m.camera_passes[size_t(c)]);
  }
}

namespace {
std::vector<Image> light_maps(Context& ctx, Precision p, const std::vector<LightPass>& passes,
                              cl::Buffer detail::LightMaps::*map, double unit = 1) {
  std::vector<Image> maps;
  for (auto& lp : passes) {
    const detail::LightMaps m = lp.maps();
    if (!(m.*map)()) continue;
    Image img(m.W, m.H, 1);
    img.data = detail::download_reals(ctx, p, m.*map, size_t(m.W) * m.H);
    if (unit != 1)
      for (double& x : img.data) x *= unit;
    maps.push_back(std::move(img));
  }
  return maps;
}
}  // namespace

std::vector<Image> Renderer::shadow_maps() const {
  const std::lock_guard<std::mutex> lock(impl_->busy);
  return light_maps(impl_->ctx, impl_->precision, impl_->light_passes, &detail::LightMaps::S,
                    1 / impl_->norm.scale);
}

std::vector<Image> Renderer::penumbra_maps() const {
  const std::lock_guard<std::mutex> lock(impl_->busy);
  return light_maps(impl_->ctx, impl_->precision, impl_->light_passes,
                    &detail::LightMaps::penumbra);
}

std::vector<size_t> Renderer::fragment_counts() const {
  const std::lock_guard<std::mutex> lock(impl_->busy);
  std::vector<size_t> counts;
  for (const ViewPass& cp : impl_->camera_passes) {
    const std::vector<int> n = detail::download_ints(impl_->ctx, cp.fragments.pix_n,
                                                     size_t(cp.view.W) * size_t(cp.view.H));
    counts.push_back(std::accumulate(n.begin(), n.end(), size_t(0)));
  }
  return counts;
}

}  // namespace penumbra
