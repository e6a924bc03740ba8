// Host side of kernels/shadow.cl: sampling a light's maps for every kept fragment.
// Hard shadows: truncated (a window per fragment) or exact (the whole map, as matrix products
// computed by matmul.cl or by CLBlast). Soft shadows: truncated or exact, direct sums.
#include <algorithm>

#include "ops/ops.hpp"
#include "penumbra/error.hpp"

namespace penumbra::detail {

namespace {

// Fragments per batch of the exact path: its weight and product matrices stay under ~96 MiB.
size_t exact_batch(Kernels& k, int Wm, int Hm) {
  size_t per = size_t(std::max(Wm, Hm)) * 6 * real_size(k.precision());
  return std::max<size_t>(1, (size_t(96) << 20) / per);
}



}  // namespace

// The fragments bucketed by the texel nearest their μ (bin.cl with one-texel tiles).
Bins texel_buckets(Kernels& k, ViewState& v, int light, int Wm, int Hm) {
  const int n = int(v.nrec);
  cl::Buffer boxes = alloc_ints(k.ctx(), size_t(n) * 4);
  auto& bx = k.get("shadow.cl", "shadow_boxes");
  set_args(bx, v.P, n, light, v.nlights, Wm, Hm, v.rec_light, boxes);
  launch_1d(k.ctx(), bx, n);
  return bin_boxes(k, boxes, n, Wm, Hm, 1);
}

void shadow_forward(Kernels& k, Shadows mode, Sampling sampling, ViewState& v, int light,
                    const ViewState& lv) {
  Context& ctx = k.ctx();
  const int Wm = lv.W, Hm = lv.H;
  const int n = int(v.nrec), nl = v.nlights;
  if (n == 0) return;
  if (mode == Shadows::Soft) {
    if (sampling == Sampling::Gemm)
      throw Error("soft shadows sample with 'truncated' or 'exact'; their sum does not factor "
                  "into matrix products ('gemm')");
    auto& s = k.get("shadow.cl", "soft_sample", exact_define(sampling));
    set_args(s, v.P, n, light, nl, Wm, Hm, lv.depth, lv.pen_map, v.rec_light, v.rec_light2);
    launch_1d(ctx, s, n);
    return;
  }
  if (sampling == Sampling::Truncated) {
    auto& s = k.get("shadow.cl", "shadow_sample");
    set_args(s, v.P, n, light, nl, Wm, Hm, lv.depth, v.rec_light);
    launch_1d(ctx, s, n);
    return;
  }
  const bool clblast = sampling == Sampling::Gemm || k.tuning().exact.clblast;
  const size_t batch = std::min<size_t>(exact_batch(k, Wm, Hm), n);
  const Precision p = k.precision();
  cl::Buffer Gx = zero_reals(ctx, p, batch * Wm), Gy = zero_reals(ctx, p, batch * Hm),
             T = zero_reals(ctx, p, batch * Hm), norm = zero_reals(ctx, p, batch * 4);
  auto& wts = k.get("shadow.cl", "exact_weights");
  auto& fin = k.get("shadow.cl", "exact_finish");
  for (int r0 = 0; r0 < n; r0 += int(batch)) {
    const int m = std::min(int(batch), n - r0);
    set_args(wts, v.P, r0, m, light, nl, Wm, Hm, v.rec_light, Gx, Gx, 0, Gy, norm);
    launch_1d(ctx, wts, m);
    matmul_nt(k, clblast, m, Hm, Wm, Gx, Wm, lv.depth, Wm, 0.0, T, Hm);  // T = Gx·Sᵀ
    set_args(fin, v.P, r0, m, light, nl, Hm, T, Gy, norm, v.rec_light);
    launch_1d(ctx, fin, m);
  }
}

MapGrads shadow_backward(Kernels& k, Shadows mode, Sampling sampling, ViewState& v, int light,
                         const ViewState& lv) {
  Context& ctx = k.ctx();
  const Precision p = k.precision();
  const int Wm = lv.W, Hm = lv.H;
  const int n = int(v.nrec), nl = v.nlights;
  MapGrads g;
  g.S = zero_reals(ctx, p, size_t(Wm) * Hm);
  if (n == 0) return g;
  if (mode == Shadows::Soft) {
    const char* variant = exact_define(sampling);
    auto& sb = k.get("shadow.cl", "soft_sample_bwd", variant);
    set_args(sb, v.P, n, light, nl, Wm, Hm, lv.depth, lv.pen_map, v.rec_light, v.rec_light2,
             v.rec_lgrad, v.rec_lgrad2);
    launch_1d(ctx, sb, n);
    Bins bins;  // the exact gather visits every fragment and needs no buckets
    if (sampling == Sampling::Truncated)
      bins = texel_buckets(k, v, light, Wm, Hm);
    else
      bins.offsets = bins.counts = bins.items = alloc_ints(ctx, 1);
    g.P = zero_reals(ctx, p, size_t(Wm) * Hm);
    auto& ga = k.get("shadow.cl", "soft_gather", variant);
    set_args(ga, v.P, n, light, nl, Wm, Hm, lv.depth, lv.pen_map, v.rec_light, v.rec_light2,
             v.rec_lgrad, bins.offsets, bins.counts, bins.items, g.S, g.P);
    const int row = shadow_row_width(k.ctx().info());  // texels per item
    launch(ctx, ga, cl::NDRange((Wm + row - 1) / row, Hm), cl::NDRange(8, 8));
    return g;
  }
  if (sampling == Sampling::Truncated) {
    auto& sb = k.get("shadow.cl", "shadow_sample_bwd");
    set_args(sb, v.P, n, light, nl, Wm, Hm, lv.depth, v.rec_light, v.rec_lgrad);
    launch_1d(ctx, sb, n);
    Bins bins = texel_buckets(k, v, light, Wm, Hm);  // texels gather from nearby fragments
    auto& ga = k.get("shadow.cl", "shadow_gather");
    set_args(ga, v.P, n, light, nl, Wm, Hm, v.rec_light, v.rec_lgrad, bins.offsets, bins.counts,
             bins.items, g.S);
    const int row = shadow_row_width(k.ctx().info());  // texels per item
    launch(ctx, ga, cl::NDRange((Wm + row - 1) / row, Hm), cl::NDRange(8, 8));
    return g;
  }
  const bool clblast = sampling == Sampling::Gemm || k.tuning().exact.clblast;
  const size_t batch = std::min<size_t>(exact_batch(k, Wm, Hm) / 2, n);
  cl::Buffer Gx = zero_reals(ctx, p, batch * Wm), Gxd = zero_reals(ctx, p, batch * Wm),
             Gy = zero_reals(ctx, p, batch * Hm), T = zero_reals(ctx, p, batch * Hm),
             Td = zero_reals(ctx, p, batch * Hm), norm = zero_reals(ctx, p, batch * 4);
  auto& wts = k.get("shadow.cl", "exact_weights");
  auto& fin = k.get("shadow.cl", "exact_finish_bwd");
  for (int r0 = 0; r0 < n; r0 += int(batch)) {
    const int m = std::min(int(batch), n - r0);
    set_args(wts, v.P, r0, m, light, nl, Wm, Hm, v.rec_light, Gx, Gxd, 1, Gy, norm);
    launch_1d(ctx, wts, m);
    matmul_nt(k, clblast, m, Hm, Wm, Gx, Wm, lv.depth, Wm, 0.0, T, Hm);    // Gx·Sᵀ
    matmul_nt(k, clblast, m, Hm, Wm, Gxd, Wm, lv.depth, Wm, 0.0, Td, Hm);  // Gxd·Sᵀ
    set_args(fin, v.P, r0, m, light, nl, Wm, Hm, T, Td, Gx, Gy, norm, v.rec_light, v.rec_lgrad);
    launch_1d(ctx, fin, m);
    matmul_tn(k, clblast, Hm, Wm, m, Gy, Hm, Gx, Wm, 1.0, g.S, Wm);  // += (a⊙Gy)ᵀ·Gx
  }
  return g;
}

}  // namespace penumbra::detail
