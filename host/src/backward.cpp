// The renderer's backward pipeline, the forward's mirror (renderer.cpp): every camera's pass
// back to its fragments' shadow lookups and faces, then every light's pass back from the
// gradients of its shadow map (and penumbra map) summed over the cameras.
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "penumbra/error.hpp"
#include "renderer_impl.hpp"
#include "shadow_models.hpp"
#include "view_params.hpp"

namespace penumbra {

namespace {

// An image gradient's size (an empty one is zero).
void check_grad_image(const Image& g, int W, int H, int C, const char* what, size_t view) {
  if (g.data.empty()) return;
  if (g.width != W || g.height != H || g.channels != C || g.data.size() != size_t(W) * H * C)
    throw Error("gradient of " + std::string(what) + " for camera " + std::to_string(view) +
                " is " + std::to_string(g.width) + "x" + std::to_string(g.height) + "x" +
                std::to_string(g.channels) + ", expected " + std::to_string(W) + "x" +
                std::to_string(H) + "x" + std::to_string(C));
}

// A NaN or infinite value would turn every gradient it reaches into NaN.
template <class Real>
void check_finite(const Real* g, int W, int H, int C, const char* what, size_t view) {
  for (size_t i = 0; g && i < size_t(W) * H * C; ++i) {
    if (std::isfinite(g[i])) continue;
    const size_t pixel = i / size_t(C);
    throw Error("gradient of " + std::string(what) + " for camera " + std::to_string(view) +
                " is " + (std::isnan(g[i]) ? "NaN" : "infinite") + " at pixel (" +
                std::to_string(pixel % size_t(W)) + ", " + std::to_string(pixel / size_t(W)) +
                "); gradients must be finite");
  }
}

// Adds the `rows` rows of `sum.size()` reals of `buf` to `sum`, in row order (reproducible).
void accumulate_rows(Context& ctx, Precision precision, std::vector<double>& sum,
                     const cl::Buffer& buf, size_t rows) {
  const size_t n = sum.size();
  detail::read_reals(ctx, precision, buf, rows * n, [&](const auto* g) {
    for (size_t r = 0; r < rows; ++r)
      for (size_t i = 0; i < n; ++i) sum[i] += g[r * n + i];
  });
}

// Adds the sum of the `rows` rows of `sum.size()` reals of `buf` to `sum`: the device sums runs
// of rows (sum_rows), the host adds the runs in order, so only a few hundred rows are read.
void accumulate_row_sum(detail::Kernels& k, std::vector<double>& sum, const cl::Buffer& buf,
                        size_t rows) {
  const detail::RowParts parts = detail::sum_rows(k, buf, rows, sum.size());
  accumulate_rows(k.ctx(), k.precision(), sum, parts.partial, parts.parts);
}

// Adds the `into.size()` reals of `buf` to `into`.
void accumulate(Context& ctx, Precision precision, std::vector<double>& into,
                const cl::Buffer& buf) {
  accumulate_rows(ctx, precision, into, buf, 1);
}

// An image gradient (R, G, B, silhouette per pixel) with dL/d(silhouette) = `g`: a light view's
// coverage A is its silhouette.
std::vector<double> silhouette_grads(const std::vector<double>& g) {
  std::vector<double> image(g.size() * 4, 0.0);
  for (size_t i = 0; i < g.size(); ++i) image[i * 4 + 3] = g[i];
  return image;
}

glm::dvec3 vec3_at(const std::vector<double>& a, size_t at) {
  return glm::dvec3(a[at], a[at + 1], a[at + 2]);
}

// Rows [first, first + n) of rows of 4 reals, as vectors (written once: no zeros first).
template <class Real>
std::vector<glm::dvec3> vec3_rows(const Real* a, size_t first, size_t n) {
  std::vector<glm::dvec3> rows;
  rows.reserve(n);
  for (size_t i = first; i < first + n; ++i)
    rows.emplace_back(a[i * 4], a[i * 4 + 1], a[i * 4 + 2]);
  return rows;
}

// For targets 0..n-1: offsets (n + 1) into the indices i with target[i] == t, grouped by target
// and ascending within each group (the fixed order of the device's gathers).
std::pair<std::vector<int>, std::vector<int>> grouped(const std::vector<int>& target, int n) {
  std::vector<int> offsets(size_t(n) + 1, 0), items(target.size());
  for (int t : target) ++offsets[size_t(t) + 1];
  for (int t = 0; t < n; ++t) offsets[size_t(t) + 1] += offsets[size_t(t)];
  std::vector<int> cursor(offsets.begin(), offsets.end() - 1);
  for (size_t i = 0; i < target.size(); ++i) items[size_t(cursor[size_t(target[i])]++)] = int(i);
  return {std::move(offsets), std::move(items)};
}

bool same_meshes(const std::vector<Mesh>& a, const std::vector<Mesh>& b) {
  if (!same_faces(a, b) || !same_albedo(a, b)) return false;
  for (size_t i = 0; i < a.size(); ++i)
    if (a[i].vertices != b[i].vertices) return false;
  return true;
}

}  // namespace

template <class Real>
void Renderer::Impl::check_backward(const Scene& given,
                                    const std::vector<GradBuffers<Real>>& grads) {
  // The meshes as given (packing them again cost 3.9 ms per call at 100k faces); the rest as
  // render() fitted and normalised it, copied without the meshes. The binding names every
  // member of Scene: one added to Scene stops the build here until it is copied too.
  [[maybe_unused]] const auto& [meshes, cameras, lights, ambient, background, params] = given;
  Scene fitted{{}, cameras, lights, ambient, background, params};
  for (size_t l = 0; l < fitted.lights.size() && l < frusta.size(); ++l)
    if (!fitted.lights[l].frustum.fitted) fitted.lights[l].frustum = frusta[l];
  fitted.lights = drawn_lights(fitted, nullptr);
  fitted = detail::normalised(fitted, norm);
  bool same = same_meshes(given.meshes, meshes_as_given()) &&
              fitted.cameras.size() == camera_passes.size() &&
              fitted.lights.size() == scene.lights.size() &&
              fitted.params.shadows == scene.params.shadows;
  for (size_t c = 0; same && c < fitted.cameras.size(); ++c)
    same = detail::view_params(fitted, fitted.cameras[c]) == view_P[c];
  if (!same)
    throw Error("backward: the scene differs from the one last rendered; call render() first");
  detail::check_memory(ctx, estimate_device_memory(scene, precision, true, &kernels.tuning()),
                       "the backward pass of the scene (" + std::to_string(packed.nf) + " faces)");
  if (grads.size() != given.cameras.size())
    throw Error("backward: got gradients for " + std::to_string(grads.size()) +
                " camera(s), the scene has " + std::to_string(given.cameras.size()));
  for (size_t c = 0; c < grads.size(); ++c) {
    const int W = camera_passes[c].view.W, H = camera_passes[c].view.H;
    check_finite(grads[c].color, W, H, 3, "color", c);
    check_finite(grads[c].silhouette, W, H, 1, "silhouette", c);
    check_finite(grads[c].depth, W, H, 1, "depth", c);
  }
}

BackwardSums& Renderer::Impl::start_backward() {
  const Packed& p = packed;
  BackwardSums& sums = backward_sums;
  const size_t nl = scene.lights.size(), maps = light_passes.size();
  sums.vertices = detail::zero_reals(ctx, precision, size_t(p.nv) * 4);
  sums.albedo = detail::zero_reals(ctx, precision, size_t(p.na) * 4);
  sums.lights.assign((6 * nl + 1) * 4, 0.0);
  sums.light_size.assign(nl, 0.0);
  sums.frames.resize(nl);
  for (std::vector<double>& f : sums.frames) f.assign(16, 0.0);
  for (auto* per_map : {&sums.maps, &sums.penumbra_maps, &sums.covers}) {
    per_map->resize(maps);
    for (size_t l = 0; l < maps; ++l)
      (*per_map)[l].assign(size_t(light_passes[l].view.W) * light_passes[l].view.H, 0.0);
  }
  if (!geometry.adj()) build_adjacency();  // once per set of faces (upload_geometry)
  return sums;
}

// Each face corner (face·3 + corner) grouped by its vertex, for the gather in transform_bwd, and
// by its albedo entry, for albedo_bwd.
void Renderer::Impl::build_adjacency() {
  const Packed& p = packed;
  std::vector<int> vertex(size_t(p.nf) * 3), entry(size_t(p.nf) * 3);
  for (size_t mi = 0; mi < scene.meshes.size(); ++mi) {
    const Mesh& m = scene.meshes[mi];
    for (size_t f = 0; f < m.faces.size(); ++f)
      for (int k = 0; k < 3; ++k) {
        const size_t i = (p.face_offset[mi] + f) * 3 + size_t(k);
        vertex[i] = p.faces[i / 3 * 4 + size_t(k)];
        entry[i] = int(p.albedo_offset[mi]) +
                   (m.albedo_mode == AlbedoMode::PerFace ? int(f) : m.faces[f][k]);
      }
  }
  const auto [vertex_offsets, by_vertex] = grouped(vertex, p.nv);
  geometry.adj_offsets = detail::upload_ints(ctx, vertex_offsets);
  geometry.adj = detail::upload_ints(ctx, by_vertex);
  const auto [entry_offsets, by_entry] = grouped(entry, p.na);
  geometry.albedo_offsets = detail::upload_ints(ctx, entry_offsets);
  geometry.albedo_corners = detail::upload_ints(ctx, by_entry);
}

template <class Real>
void Renderer::Impl::camera_backward(int camera, const GradBuffers<Real>& g, BackwardSums& sums) {
  ViewPass& cp = camera_passes[camera];  // its fragments keep the exact lookups' weights
  const int W = cp.view.W, H = cp.view.H;
  stage("resolve");
  const size_t npix = size_t(W) * H;
  cl::Buffer gimage_buf = detail::alloc_reals(ctx, precision, npix * 4);
  detail::fill_reals(ctx, precision, gimage_buf, npix * 4, [&](auto* at) {
    for (size_t i = 0; i < npix; ++i) {
      for (int k = 0; k < 3; ++k) at[i * 4 + k] = g.color ? g.color[i * 3 + k] : 0;
      at[i * 4 + 3] = g.silhouette ? g.silhouette[i] : 0;
    }
  });
  cl::Buffer gdepth_buf = detail::alloc_reals(ctx, precision, npix);
  const double unit = 1 / norm.scale;  // dL/d(device depth) = dL/d(depth) / scale
  detail::fill_reals(ctx, precision, gdepth_buf, npix, [&](auto* at) {
    for (size_t i = 0; i < npix; ++i) at[i] = g.depth ? g.depth[i] * unit : 0;
  });
  auto fgr = detail::raster_resolve_backward(kernels, cp.view, cp.fragments, cp.resolved,
                                             gimage_buf, gdepth_buf);
  const detail::ShadowModelPasses& model = detail::shadow_model_passes(scene.params.shadow_model);
  for (size_t l = 0; l < light_passes.size(); ++l) {
    stage("shadow lookups");
    auto gm = model.lookup_backward(kernels, scene.params, scene.lights[l], cp.view, cp.fragments,
                                    fgr, int(l), light_passes[l].maps(), &sums.light_size[l]);
    accumulate(ctx, precision, sums.maps[l], gm.S);
    if (gm.P()) accumulate(ctx, precision, sums.penumbra_maps[l], gm.P);
    if (gm.A()) accumulate(ctx, precision, sums.covers[l], gm.A);
  }
  stage("faces");
  auto fg = detail::raster_backward(kernels, geometry, cp.view, cp.screen, cp.fragments, fgr,
                                    gimage_buf, gdepth_buf);
  sum_face_grads(cp, fg, sums, &sums.lights, nullptr);
}

// The model's light map (the paper model's penumbra map) back to its shadow map, the light's
// size and the occluders; then the shadow map (and, where the lookups read it, the coverage)
// back through the light's own raster pass.
void Renderer::Impl::light_backward(int light, BackwardSums& sums) {
  const LightPass& lp = light_passes[light];
  const cl::Buffer& S = lp.resolved.depth;
  const size_t ntex = size_t(lp.view.W) * lp.view.H;
  const detail::ShadowModelPasses& model = detail::shadow_model_passes(scene.params.shadow_model);
  cl::Buffer gpen;
  if (model.builds_light_map(scene.params)) {
    stage(model.light_map_stage);
    gpen = detail::upload_reals(ctx, precision, sums.penumbra_maps[light]);
    accumulate(ctx, precision, sums.maps[light],
               model.light_map_backward_texels(kernels, geometry, lp.view, lp.screen, S,
                                               lp.penumbra, gpen, &sums.light_size[light]));
  }
  stage("shadow map");
  auto gimage_buf = shadow_model_traits(scene.params.shadow_model).casters_only
                        ? detail::upload_reals(ctx, precision, silhouette_grads(sums.covers[light]))
                        : detail::zero_reals(ctx, precision, ntex * 4);
  auto gdepth_buf = detail::upload_reals(ctx, precision, sums.maps[light]);
  auto fgr = detail::raster_resolve_backward(kernels, lp.view, lp.fragments, lp.resolved,
                                             gimage_buf, gdepth_buf);
  auto fg = detail::raster_backward(kernels, geometry, lp.view, lp.screen, lp.fragments, fgr,
                                    gimage_buf, gdepth_buf);
  if (gpen())
    model.light_map_backward_faces(kernels, geometry, lp.view, lp.screen, S, lp.penumbra, gpen, fg);
  sum_face_grads(lp, fg, sums, nullptr, &sums.frames[light]);
}

// The face corners' gradients of one view through its transform: adds dL/d(vertices) to the
// sums, and a camera's dL/d(albedo) and per-face light gradients (`glights`) or a light view's
// dL/d(its frame) (`gframe`). A light's view has no colour (its image gradient's R, G, B are 0),
// so its albedo gradients are zeros, left unread.
void Renderer::Impl::sum_face_grads(const ViewPass& vp, const detail::FaceGrads& fg,
                                    BackwardSums& sums, std::vector<double>* glights,
                                    std::vector<double>* gframe) {
  const cl::Buffer frame =
      detail::transform_backward(kernels, geometry, vp.view, vp.screen, fg, sums.vertices);
  if (gframe) accumulate_row_sum(kernels, *gframe, frame, size_t(packed.nv));
  if (glights) {
    detail::albedo_backward(kernels, geometry, fg, sums.albedo);
    accumulate_row_sum(kernels, *glights, fg.light, size_t(packed.nf));
  }
}

SceneGrads Renderer::Impl::scene_grads(const BackwardSums& sums) const {
  const Scene& s = scene;
  const Packed& p = packed;
  SceneGrads out;
  detail::read_reals(ctx, precision, sums.vertices, size_t(p.nv) * 4, [&](const auto* g) {
    for (size_t mi = 0; mi < s.meshes.size(); ++mi)
      out.vertices.push_back(vec3_rows(g, p.vertex_offset[mi], s.meshes[mi].vertices.size()));
  });
  detail::read_reals(ctx, precision, sums.albedo, size_t(p.na) * 4, [&](const auto* g) {
    for (size_t mi = 0; mi < s.meshes.size(); ++mi)
      out.albedo.push_back(vec3_rows(g, p.albedo_offset[mi], s.meshes[mi].albedo.size()));
  });
  const std::vector<double>& gl = sums.lights;
  const int nl = int(s.lights.size());
  out.light_position.assign(frusta.size(), glm::dvec3(0.0));  // one per given light
  out.light_color.assign(frusta.size(), glm::dvec3(0.0));
  out.light_size.assign(frusta.size(), 0.0);
  for (int l = 0; l < nl; ++l) {
    // Frame gradients from the camera passes (fragments projected into the map) and from the
    // light's own pass (vertices projected into the map).
    const size_t fo = size_t(2 * nl + 1 + 4 * l) * 4;
    const std::vector<double>& fr = sums.frames[l];
    glm::dvec3 gpos = vec3_at(gl, 8 * size_t(l));
    if (!light_passes.empty())
      gpos += detail::light_frame_backward(
          s.lights[l], vec3_at(gl, fo) + vec3_at(fr, 0), vec3_at(gl, fo + 4) + vec3_at(fr, 4),
          vec3_at(gl, fo + 8) + vec3_at(fr, 8), vec3_at(gl, fo + 12) + vec3_at(fr, 12));
    // A cube's faces are lights of their own here: each adds to the light it comes from, in
    // world units (d/d(world length) = scale · d/d(device length)).
    const double k = norm.scale;
    const size_t to = size_t(light_of[size_t(l)]);
    out.light_position[to] += s.lights[size_t(l)].type == LightType::Point ? gpos * k : gpos;
    out.light_color[to] += vec3_at(gl, 8 * size_t(l) + 4);
    out.light_size[to] += sums.light_size[l] * k;
  }
  out.ambient = vec3_at(gl, 8 * size_t(nl));
  if (const double k = norm.scale; k != 1) {  // d/d(world length) = scale · d/d(device length)
    for (auto& mesh : out.vertices)
      for (glm::dvec3& g : mesh) g *= k;
  }
  return out;
}

SceneGrads Renderer::Impl::backward(const Scene& scene, const std::vector<OutputGrads>& grads) {
  std::vector<GradBuffers<double>> buffers;
  for (size_t c = 0; c < grads.size() && c < camera_passes.size(); ++c) {
    const int W = camera_passes[c].view.W, H = camera_passes[c].view.H;
    const OutputGrads& g = grads[c];
    check_grad_image(g.color, W, H, 3, "color", c);
    check_grad_image(g.silhouette, W, H, 1, "silhouette", c);
    check_grad_image(g.depth, W, H, 1, "depth", c);
    const auto at = [](const Image& i) { return i.data.empty() ? nullptr : i.data.data(); };
    buffers.push_back({at(g.color), at(g.silhouette), at(g.depth)});
  }
  buffers.resize(grads.size());  // (more than the cameras: refused by check_backward)
  return backward(scene, buffers);
}

// Every camera's pass backwards, then every light's.
template <class Real>
SceneGrads Renderer::Impl::backward(const Scene& scene,
                                    const std::vector<GradBuffers<Real>>& grads) {
  Impl& m = *this;
  const Impl::CallProfile profile(m, "backward", "check");
  m.check_backward(scene, grads);
  m.started = true;
  m.mark("sums");
  BackwardSums& sums = m.start_backward();
  const int nc = int(m.camera_passes.size()), lights = int(m.light_passes.size());
  const int passes = nc + lights;
  for (int c = 0; c < nc; ++c) {
    m.begin_pass("backward", "view", c, nc, c, passes);
    m.camera_backward(c, grads[size_t(c)], sums);
  }
  for (int l = 0; l < lights; ++l) {
    m.begin_pass("backward", "light", l, int(m.scene.lights.size()), nc + l, passes);
    m.light_backward(l, sums);
  }
  m.mark("gradients");
  return m.scene_grads(sums);
}

SceneGrads Renderer::backward(const Scene& scene, const std::vector<OutputGrads>& grads) {
  return impl_->exclusive([&] { return impl_->backward(scene, grads); });
}

SceneGrads Renderer::backward(const Scene& scene, const std::vector<GradBuffers<float>>& grads) {
  return impl_->exclusive([&] { return impl_->backward(scene, grads); });
}

SceneGrads Renderer::backward(const Scene& scene, const std::vector<GradBuffers<double>>& grads) {
  return impl_->exclusive([&] { return impl_->backward(scene, grads); });
}

}  // namespace penumbra
