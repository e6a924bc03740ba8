// Host side of kernels/shadow.cl: sampling the light's shadow map for every kept fragment,
// truncated (a window per fragment) or exact (the whole map, as matrix products computed by
// matmul.cl or by CLBlast).
#include <algorithm>

#include "ops/ops.hpp"

namespace penumbra::detail {

namespace {

constexpr int kGatherTile = 16;  // light-map tile of the truncated gather

// Fragments per batch of the exact path: its weight and product matrices stay under ~96 MiB.
size_t exact_batch(Kernels& k, int Wm, int Hm) {
  size_t per = size_t(std::max(Wm, Hm)) * 6 * real_size(k.precision());
  return std::max<size_t>(1, (size_t(96) << 20) / per);
}

// Zero-filled, so that no product ever reads NaN from old memory.
cl::Buffer zeros(Kernels& k, size_t count) {
  cl::Buffer b = alloc_reals(k.ctx(), k.precision(), count);
  k.ctx().queue().enqueueFillBuffer(b, cl_uchar(0), 0, std::max<size_t>(count, 1) * real_size(k.precision()));
  return b;
}

}  // namespace

void shadow_forward(Kernels& k, Sampling sampling, ViewState& v, int light, const ViewState& lv) {
  Context& ctx = k.ctx();
  const int Wm = lv.W, Hm = lv.H;
  const int n = int(v.nrec), nl = v.nlights;
  if (n == 0) return;
  if (sampling == Sampling::Truncated) {
    auto& s = k.get("shadow.cl", "shadow_sample");
    set_args(s, v.P, n, light, nl, Wm, Hm, lv.depth, v.rec_light);
    launch_1d(ctx, s, n);
    return;
  }
  const bool clblast = sampling == Sampling::Gemm;
  const size_t batch = std::min<size_t>(exact_batch(k, Wm, Hm), n);
  cl::Buffer Gx = zeros(k, batch * Wm), Gy = zeros(k, batch * Hm), T = zeros(k, batch * Hm),
             norm = zeros(k, batch * 4);
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

cl::Buffer shadow_backward(Kernels& k, Sampling sampling, ViewState& v, int light,
                           const ViewState& lv) {
  Context& ctx = k.ctx();
  const int Wm = lv.W, Hm = lv.H;
  const int n = int(v.nrec), nl = v.nlights;
  cl::Buffer gS = zeros(k, size_t(Wm) * Hm);
  if (n == 0) return gS;
  if (sampling == Sampling::Truncated) {
    auto& sb = k.get("shadow.cl", "shadow_sample_bwd");
    set_args(sb, v.P, n, light, nl, Wm, Hm, lv.depth, v.rec_light, v.rec_lgrad);
    launch_1d(ctx, sb, n);
    // Texels gather from the windows that cover them.
    cl::Buffer boxes = alloc_ints(ctx, size_t(n) * 4);
    auto& bx = k.get("shadow.cl", "shadow_boxes");
    set_args(bx, v.P, n, light, nl, Wm, Hm, v.rec_light, boxes);
    launch_1d(ctx, bx, n);
    Bins bins = bin_boxes(k, boxes, n, Wm, Hm, kGatherTile);
    auto& ga = k.get("shadow.cl", "shadow_gather");
    set_args(ga, v.P, n, light, nl, Wm, Hm, v.rec_light, v.rec_lgrad, kGatherTile, bins.tiles_x,
             bins.offsets, bins.counts, bins.items, gS);
    launch(ctx, ga, cl::NDRange(Wm, Hm), cl::NDRange(8, 8));
    return gS;
  }
  const bool clblast = sampling == Sampling::Gemm;
  const size_t batch = std::min<size_t>(exact_batch(k, Wm, Hm) / 2, n);
  cl::Buffer Gx = zeros(k, batch * Wm), Gxd = zeros(k, batch * Wm), Gy = zeros(k, batch * Hm),
             T = zeros(k, batch * Hm), Td = zeros(k, batch * Hm), norm = zeros(k, batch * 4);
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
    matmul_tn(k, clblast, Hm, Wm, m, Gy, Hm, Gx, Wm, 1.0, gS, Wm);  // += (a⊙Gy)ᵀ·Gx
  }
  return gS;
}

}  // namespace penumbra::detail
