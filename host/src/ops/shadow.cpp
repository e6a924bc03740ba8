// Host side of kernels/shadow.cl: sampling the light's shadow map for every kept fragment,
// truncated or exact (direct kernels), or exact as matrix products with CLBlast.
#include <clblast.h>

#include <algorithm>

#include "ops/ops.hpp"
#include "penumbra/error.hpp"

namespace penumbra::detail {

namespace {

const std::string kExact = "-DEXACT=1", kTruncated = "-DEXACT=0";
constexpr int kGatherTile = 16;  // light-map tile of the truncated gather

void check(clblast::StatusCode status, const char* what) {
  if (status != clblast::StatusCode::kSuccess)
    throw Error(std::string("CLBlast ") + what + " failed with status " +
                std::to_string(int(status)));
}

// C (m × n, row-major, ldc) = alpha·op(A)·op(B) + beta·C.
void gemm(Kernels& k, bool ta, bool tb, size_t m, size_t n, size_t kk, const cl::Buffer& A,
          size_t lda, const cl::Buffer& B, size_t ldb, double beta, cl::Buffer& C, size_t ldc) {
  cl_command_queue q = k.ctx().queue()();
  auto t = [](bool x) { return x ? clblast::Transpose::kYes : clblast::Transpose::kNo; };
  if (k.precision() == Precision::Double)
    check(clblast::Gemm<double>(clblast::Layout::kRowMajor, t(ta), t(tb), m, n, kk, 1.0, A(), 0,
                                lda, B(), 0, ldb, beta, C(), 0, ldc, &q),
          "GEMM");
  else
    check(clblast::Gemm<float>(clblast::Layout::kRowMajor, t(ta), t(tb), m, n, kk, 1.0f, A(), 0,
                               lda, B(), 0, ldb, float(beta), C(), 0, ldc, &q),
          "GEMM");
}

// Fragments per GEMM batch: the weight and product matrices stay under ~96 MiB.
size_t gemm_chunk(Kernels& k, int Wm, int Hm) {
  size_t per = size_t(std::max(Wm, Hm)) * 4 * real_size(k.precision());
  return std::max<size_t>(1, (size_t(96) << 20) / per);
}

// Zero-filled: CLBlast computes β·C even for β = 0, so C must hold no NaN from old memory.
cl::Buffer zeros(Kernels& k, size_t count) {
  return upload_reals(k.ctx(), k.precision(), std::vector<double>(count, 0.0));
}

}  // namespace

void shadow_forward(Kernels& k, Sampling sampling, ViewState& v, int light, const ViewState& lv) {
  Context& ctx = k.ctx();
  const int Wm = lv.W, Hm = lv.H;
  const int n = int(v.nrec), nl = v.nlights;
  if (n == 0) return;
  if (sampling != Sampling::Gemm) {
    auto& s = k.get("shadow.cl", "shadow_sample", sampling == Sampling::Exact ? kExact : kTruncated);
    set_args(s, v.P, n, light, nl, Wm, Hm, lv.depth, v.rec_light);
    launch_1d(ctx, s, n);
    return;
  }
  const size_t chunk = std::min<size_t>(gemm_chunk(k, Wm, Hm), n);
  cl::Buffer Gx = zeros(k, chunk * Wm), Gy = zeros(k, chunk * Hm), T = zeros(k, chunk * Hm),
             norm = zeros(k, chunk * 4);
  auto& wts = k.get("shadow.cl", "gemm_weights", kExact);
  auto& fin = k.get("shadow.cl", "gemm_finish", kExact);
  for (int r0 = 0; r0 < n; r0 += int(chunk)) {
    const int m = std::min(int(chunk), n - r0);
    set_args(wts, v.P, r0, m, light, nl, Wm, Hm, v.rec_light, Gx, Gx, 0, Gy, norm);
    launch_1d(ctx, wts, m);
    gemm(k, false, true, m, Hm, Wm, Gx, Wm, lv.depth, Wm, 0.0, T, Hm);  // T = Gx·Sᵀ
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
  if (sampling != Sampling::Gemm) {
    const std::string& variant = sampling == Sampling::Exact ? kExact : kTruncated;
    auto& sb = k.get("shadow.cl", "shadow_sample_bwd", variant);
    set_args(sb, v.P, n, light, nl, Wm, Hm, lv.depth, v.rec_light, v.rec_lgrad);
    launch_1d(ctx, sb, n);
    Bins bins;
    if (sampling == Sampling::Truncated) {  // texels gather from the windows that cover them
      cl::Buffer boxes = alloc_ints(ctx, size_t(n) * 4);
      auto& bx = k.get("shadow.cl", "shadow_boxes", variant);
      set_args(bx, v.P, n, light, nl, Wm, Hm, v.rec_light, boxes);
      launch_1d(ctx, bx, n);
      bins = bin_boxes(k, boxes, n, Wm, Hm, kGatherTile);
    } else {
      bins.offsets = bins.counts = bins.items = alloc_ints(ctx, 1);
    }
    auto& ga = k.get("shadow.cl", "shadow_gather", variant);
    set_args(ga, v.P, n, light, nl, Wm, Hm, v.rec_light, v.rec_lgrad, kGatherTile, bins.tiles_x,
             bins.offsets, bins.counts, bins.items, gS);
    launch(ctx, ga, cl::NDRange(Wm, Hm), cl::NDRange(8, 8));
    return gS;
  }
  const size_t chunk = std::min<size_t>(gemm_chunk(k, Wm, Hm) / 2, n);
  cl::Buffer Gx = zeros(k, chunk * Wm), Gxd = zeros(k, chunk * Wm), Gy = zeros(k, chunk * Hm),
             T = zeros(k, chunk * Hm), Td = zeros(k, chunk * Hm), norm = zeros(k, chunk * 4);
  auto& wts = k.get("shadow.cl", "gemm_weights", kExact);
  auto& fin = k.get("shadow.cl", "gemm_finish_bwd", kExact);
  for (int r0 = 0; r0 < n; r0 += int(chunk)) {
    const int m = std::min(int(chunk), n - r0);
    set_args(wts, v.P, r0, m, light, nl, Wm, Hm, v.rec_light, Gx, Gxd, 1, Gy, norm);
    launch_1d(ctx, wts, m);
    gemm(k, false, true, m, Hm, Wm, Gx, Wm, lv.depth, Wm, 0.0, T, Hm);    // T = Gx·Sᵀ
    gemm(k, false, true, m, Hm, Wm, Gxd, Wm, lv.depth, Wm, 0.0, Td, Hm);  // Td = Gxd·Sᵀ
    set_args(fin, v.P, r0, m, light, nl, Wm, Hm, T, Td, Gx, Gy, norm, v.rec_light, v.rec_lgrad);
    launch_1d(ctx, fin, m);
    gemm(k, true, false, Hm, Wm, m, Gy, Hm, Gx, Wm, 1.0, gS, Wm);  // gS += (a ⊙ Gy)ᵀ·Gx
  }
  return gS;
}

}  // namespace penumbra::detail
