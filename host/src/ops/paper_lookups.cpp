// Host side of kernels/paper_lookups.cl: sampling a light's maps for every kept fragment.
// Hard shadows: truncated (a window per fragment) or exact (the whole map, as matrix products
// computed by paper_hard_exact.cl or by CLBlast). Soft shadows: truncated or exact, direct sums.
#include <algorithm>

#include "ops/args.hpp"
#include "penumbra/error.hpp"

namespace penumbra::detail {

namespace {

struct ShadowBoxesArgs {
  static constexpr const char* file = "paper_lookups.cl";
  static constexpr const char* kernel = "shadow_boxes";
  static constexpr KernelPart part = KernelPart::Backward;
  MapLookup at;
  const cl::Buffer &rec_light, &rec_lgrad, &boxes;
  auto fields() const { return std::tie(at, rec_light, rec_lgrad, boxes); }
};

struct ShadowSampleArgs {
  static constexpr const char* file = "paper_lookups.cl";
  static constexpr const char* kernel = "shadow_sample";
  MapLookup at;
  const cl::Buffer &S, &rec_shade, &rec_light, &rec_light2;
  auto fields() const { return std::tie(at, S, rec_shade, rec_light, rec_light2); }
};

struct ShadowSampleBwdArgs {
  static constexpr const char* file = "paper_lookups.cl";
  static constexpr const char* kernel = "shadow_sample_bwd";
  static constexpr KernelPart part = KernelPart::Backward;
  MapLookup at;
  const cl::Buffer &S, &rec_light, &rec_light2, &rec_lgrad;
  auto fields() const { return std::tie(at, S, rec_light, rec_light2, rec_lgrad); }
};

struct ShadowGatherArgs {
  static constexpr const char* file = "paper_lookups.cl";
  static constexpr const char* kernel = "shadow_gather";
  static constexpr KernelPart part = KernelPart::Gather;
  MapLookup at;
  const cl::Buffer &rec_light, &rec_lgrad;
  BinLists buckets;
  const cl::Buffer& gS;
  auto fields() const { return std::tie(at, rec_light, rec_lgrad, buckets, gS); }
};

struct SoftSampleArgs {
  static constexpr const char* file = "paper_lookups.cl";
  static constexpr const char* kernel = "soft_sample";
  MapLookup at;
  const cl::Buffer &S, &Pmap, &rec_shade, &rec_light, &rec_light2;
  auto fields() const { return std::tie(at, S, Pmap, rec_shade, rec_light, rec_light2); }
};

struct SoftSampleBwdArgs {
  static constexpr const char* file = "paper_lookups.cl";
  static constexpr const char* kernel = "soft_sample_bwd";
  static constexpr KernelPart part = KernelPart::Backward;
  MapLookup at;
  const cl::Buffer &S, &Pmap, &rec_light, &rec_light2, &rec_lgrad, &rec_lgrad2;
  auto fields() const {
    return std::tie(at, S, Pmap, rec_light, rec_light2, rec_lgrad, rec_lgrad2);
  }
};

struct SoftGatherArgs {
  static constexpr const char* file = "paper_lookups.cl";
  static constexpr const char* kernel = "soft_gather";
  static constexpr KernelPart part = KernelPart::Gather;
  MapLookup at;
  const cl::Buffer &S, &Pmap, &rec_light, &rec_light2, &rec_lgrad;
  BinLists buckets;
  const cl::Buffer &chunks, &gS, &gPmap;
  auto fields() const {
    return std::tie(at, S, Pmap, rec_light, rec_light2, rec_lgrad, buckets, chunks, gS, gPmap);
  }
};

struct SoftGatherChunksArgs {
  static constexpr const char* file = "paper_lookups.cl";
  static constexpr const char* kernel = "soft_gather_chunks";
  static constexpr KernelPart part = KernelPart::Backward;
  MapLookup at;
  const cl::Buffer &rec_light, &rec_lgrad, &chunks;
  auto fields() const { return std::tie(at, rec_light, rec_lgrad, chunks); }
};

// The exact path's kernels take a batch of m fragments from r0 instead of a MapLookup.
struct ExactWeightsArgs {
  static constexpr const char* file = "paper_lookups.cl";
  static constexpr const char* kernel = "exact_weights";
  const cl::Buffer& P;
  cl_int r0, m, light, nl, Wm, Hm;
  const cl::Buffer &rec_shade, &rec_light, &Gx, &Gxd;
  cl_int with_derivative;
  const cl::Buffer &Gy, &Gyd, &norm, &dsum, &support;
  auto fields() const {
    return std::tie(P, r0, m, light, nl, Wm, Hm, rec_shade, rec_light, Gx, Gxd, with_derivative, Gy,
                    Gyd, norm, dsum, support);
  }
};

struct ExactFinishArgs {
  static constexpr const char* file = "paper_lookups.cl";
  static constexpr const char* kernel = "exact_finish";
  const cl::Buffer& P;
  cl_int r0, m, light, nl;
  const cl::Buffer &dot, &norm, &rec_light;
  auto fields() const { return std::tie(P, r0, m, light, nl, dot, norm, rec_light); }
};

struct ExactFinishBwdArgs {
  static constexpr const char* file = "paper_lookups.cl";
  static constexpr const char* kernel = "exact_finish_bwd";
  static constexpr KernelPart part = KernelPart::Backward;
  const cl::Buffer& P;
  cl_int r0, m, light, nl, Hm;
  const cl::Buffer &dots, &Gy, &norm, &dsum, &support, &rec_light, &rec_lgrad;
  auto fields() const {
    return std::tie(P, r0, m, light, nl, Hm, dots, Gy, norm, dsum, support, rec_light, rec_lgrad);
  }
};

// Fragments per batch of the exact path: its weight and product matrices stay under ~96 MiB.
size_t exact_batch(Kernels& k, int Wm, int Hm) {
  size_t per = size_t(std::max(Wm, Hm)) * 6 * real_size(k.precision());
  return std::max<size_t>(1, (size_t(96) << 20) / per);
}

// Light `light`'s exact weights in `kept` where they fit batches of `batch` fragments of a
// W × H map (rows for at least that many, at most twice as many, as reuse_or_alloc keeps
// buffers: the rows past a batch stay as they are, zero outside their supports), else new
// zero-filled ones (the old released first).
ExactWeights& kept_exact_weights(Context& ctx, Precision p, std::vector<ExactWeights>& kept,
                                 int light, size_t batch, int W, int H, bool derivatives) {
  if (kept.size() <= size_t(light)) kept.resize(size_t(light) + 1);
  ExactWeights& w = kept[size_t(light)];
  if (w.W == W && w.H == H && w.derivatives == derivatives && spare_fits(w.batch, batch)) return w;
  w = ExactWeights{};  // the old matrices released before the new are made
  w.batch = batch;
  w.W = W;
  w.H = H;
  w.derivatives = derivatives;
  w.Gx = zero_reals(ctx, p, batch * W);
  w.Gy = zero_reals(ctx, p, batch * H);
  if (derivatives) {
    w.Gxd = zero_reals(ctx, p, batch * W);
    w.Gyd = zero_reals(ctx, p, batch * H);
  }
  w.support = upload_ints(ctx, std::vector<int>(batch * 4, 0));
  return w;
}

void exact_forward(Kernels& k, bool clblast, Fragments& f, const MapLookup& at,
                   const LightMaps& lm) {
  Context& ctx = k.ctx();
  const int n = at.nrec, Wm = at.Wm, Hm = at.Hm, light = at.light, nl = at.nl;
  const size_t batch = std::min<size_t>(exact_batch(k, Wm, Hm), n);
  const Precision p = k.precision();
  // The weights hold zeros outside the supports (ExactWeights); every other entry of a batch is
  // written before it is read.
  ExactWeights& w = kept_exact_weights(ctx, p, f.exact_forward, light, batch, Wm, Hm, false);
  const cl::Buffer &Gx = w.Gx, &Gy = w.Gy, &support = w.support;
  cl::Buffer dot = alloc_reals(ctx, p, batch * 4), norm = alloc_reals(ctx, p, batch * 4);
  ProductScratch scratch;
  for (int r0 = 0; r0 < n; r0 += int(batch)) {
    k.part(r0 / int(batch), (n + int(batch) - 1) / int(batch));
    const int m = std::min(int(batch), n - r0);
    // No derivatives: Gxd, Gyd and dsum are not written.
    auto& wts = bind_args(k, ExactWeightsArgs{at.P, r0, m, light, nl, Wm, Hm, f.rec_shade,
                                              f.rec_light, Gx, Gx, 0, Gy, Gy, norm, norm, support});
    launch_1d(ctx, wts, m);
    // dot_r = Σ_i U_ri·Gx_ri, U = Gy·S
    matmul_nn_rowdots(k, clblast, m, Wm, Hm, Gy, nullptr, Hm, lm.S, Wm, Gx, nullptr, Wm, support,
                      scratch, dot);
    auto& fin = bind_args(k, ExactFinishArgs{at.P, r0, m, light, nl, dot, norm, f.rec_light});
    launch_1d(ctx, fin, m);
  }
}

// The fragments `f` of `v` with a gradient to pass to `light`'s maps (fgr, as the lookups'
// backward completed it) bucketed by the texel nearest their μ in the map (bin.cl with
// one-texel tiles), for the gathers that find the fragments whose window holds a texel.
Bins texel_buckets(Kernels& k, const View& v, const Fragments& f, const FragmentGrads& fgr,
                   int light, int Wm, int Hm) {
  const int n = int(f.nrec);
  cl::Buffer boxes = alloc_ints(k.ctx(), size_t(n) * 4);
  auto& bx = bind_args(
      k, ShadowBoxesArgs{{v.P, n, light, v.nlights, Wm, Hm}, f.rec_light, fgr.rec_lgrad, boxes});
  launch_1d(k.ctx(), bx, n);
  return bin_boxes(k, boxes, n, Wm, Hm, 1);
}

MapGrads soft_backward(Kernels& k, Sampling sampling, const View& v, const Fragments& f,
                       FragmentGrads& fgr, const MapLookup& at, const LightMaps& lm, MapGrads g) {
  const std::string variant = sampling_define(sampling);
  auto& sb = bind_args(k,
                       SoftSampleBwdArgs{at, lm.S, lm.penumbra, f.rec_light, f.rec_light2,
                                         fgr.rec_lgrad, fgr.rec_lgrad2},
                       variant);
  launch_1d(k.ctx(), sb, at.nrec);
  Bins bins;  // the truncated gather's buckets, or the exact gather's chunks
  cl::Buffer chunks;
  if (sampling_method(sampling).windowed) {
    bins = texel_buckets(k, v, f, fgr, at.light, at.Wm, at.Hm);
    chunks = alloc_ints(k.ctx(), 4);
  } else {
    bins.offsets = bins.counts = bins.items = alloc_ints(k.ctx(), 1);
    chunks = gather_chunks(k, at.nrec, [&](const cl::Buffer& out) -> cl::Kernel& {
      return bind_args(k, SoftGatherChunksArgs{at, f.rec_light, fgr.rec_lgrad, out}, variant);
    });
  }
  g.P = zero_reals(k.ctx(), k.precision(), size_t(at.Wm) * at.Hm);
  auto& ga = bind_args(k,
                       SoftGatherArgs{at, lm.S, lm.penumbra, f.rec_light, f.rec_light2,
                                      fgr.rec_lgrad, bins, chunks, g.S, g.P},
                       variant);
  launch_gather(k, ga, at.Wm, at.Hm);
  return g;
}

MapGrads truncated_backward(Kernels& k, const View& v, const Fragments& f, const FragmentGrads& fgr,
                            const MapLookup& at, const LightMaps& lm, MapGrads g) {
  auto& sb = bind_args(k, ShadowSampleBwdArgs{at, lm.S, f.rec_light, f.rec_light2, fgr.rec_lgrad});
  launch_1d(k.ctx(), sb, at.nrec);
  // texels gather from nearby fragments
  Bins bins = texel_buckets(k, v, f, fgr, at.light, at.Wm, at.Hm);
  auto& ga = bind_args(k, ShadowGatherArgs{at, f.rec_light, fgr.rec_lgrad, bins, g.S});
  launch_gather(k, ga, at.Wm, at.Hm);
  return g;
}

MapGrads exact_backward(Kernels& k, bool clblast, Fragments& f, const FragmentGrads& fgr,
                        const MapLookup& at, const LightMaps& lm, MapGrads g) {
  Context& ctx = k.ctx();
  const Precision p = k.precision();
  const int n = at.nrec, Wm = at.Wm, Hm = at.Hm, light = at.light, nl = at.nl;
  const size_t batch = std::min<size_t>(exact_batch(k, Wm, Hm) / 2, n);
  // As exact_forward's.
  ExactWeights& w = kept_exact_weights(ctx, p, f.exact_backward, light, batch, Wm, Hm, true);
  const cl::Buffer &Gx = w.Gx, &Gxd = w.Gxd, &Gy = w.Gy, &Gyd = w.Gyd, &support = w.support;
  cl::Buffer dots = alloc_reals(ctx, p, batch * 4), norm = alloc_reals(ctx, p, batch * 4),
             dsum = alloc_reals(ctx, p, batch * 2);
  ProductScratch scratch;
  for (int r0 = 0; r0 < n; r0 += int(batch)) {
    k.part(r0 / int(batch), (n + int(batch) - 1) / int(batch));
    const int m = std::min(int(batch), n - r0);
    auto& wts =
        bind_args(k, ExactWeightsArgs{at.P, r0, m, light, nl, Wm, Hm, f.rec_shade, f.rec_light, Gx,
                                      Gxd, 1, Gy, Gyd, norm, dsum, support});
    launch_1d(ctx, wts, m);
    // dots_r = Σ_i (U_ri·Gx_ri, U_ri·Gxd_ri, Ud_ri·Gx_ri), U = Gy·S, Ud = Gyd·S
    matmul_nn_rowdots(k, clblast, m, Wm, Hm, Gy, &Gyd, Hm, lm.S, Wm, Gx, &Gxd, Wm, support, scratch,
                      dots);
    auto& fin = bind_args(k, ExactFinishBwdArgs{at.P, r0, m, light, nl, Hm, dots, Gy, norm, dsum,
                                                support, f.rec_light, fgr.rec_lgrad});
    launch_1d(ctx, fin, m);
    // g.S += (a⊙Gy)ᵀ·Gx
    matmul_tn(k, clblast, Hm, Wm, m, Gy, Hm, Gx, Wm, support, scratch, 1.0, g.S, Wm);
  }
  return g;
}

}  // namespace

void launch_gather(Kernels& k, cl::Kernel& gather, int Wm, int Hm) {
  const GatherTuning& t = k.tuning().gather;
  const int row = t.width, rows = t.height, group = t.group;
  const size_t local = group > 1 ? size_t(group) : 8;  // staging gathers: the kernels' group
  launch(k.ctx(), gather, cl::NDRange((Wm + row - 1) / row, (Hm + rows - 1) / rows),
         cl::NDRange(local, local));
}

cl::Buffer gather_chunks(Kernels& k, int nrec,
                         const std::function<cl::Kernel&(const cl::Buffer&)>& bind) {
  const size_t chunks = (size_t(nrec) + kGatherChunk - 1) / kGatherChunk;
  cl::Buffer out = alloc_ints(k.ctx(), std::max<size_t>(chunks, 1) * 4);
  launch_1d(k.ctx(), bind(out), chunks);
  return out;
}

void shadow_forward(Kernels& k, const RenderParams& p, const View& v, Fragments& f, int light,
                    const LightMaps& lm) {
  const int n = int(f.nrec);
  if (n == 0) return;
  const MapLookup at{v.P, n, light, v.nlights, lm.W, lm.H};
  if (p.shadows == Shadows::Soft) {
    auto& s =
        bind_args(k, SoftSampleArgs{at, lm.S, lm.penumbra, f.rec_shade, f.rec_light, f.rec_light2},
                  sampling_define(p.sampling));
    launch_1d(k.ctx(), s, n);
  } else if (sampling_method(p.sampling).windowed) {
    auto& s = bind_args(k, ShadowSampleArgs{at, lm.S, f.rec_shade, f.rec_light, f.rec_light2});
    launch_1d(k.ctx(), s, n);
  } else {
    exact_forward(k, exact_on_clblast(p, k.tuning()), f, at, lm);
  }
}

MapGrads shadow_backward(Kernels& k, const RenderParams& p, const View& v, Fragments& f,
                         FragmentGrads& fgr, int light, const LightMaps& lm) {
  MapGrads g;
  g.S = zero_reals(k.ctx(), k.precision(), size_t(lm.W) * lm.H);
  const int n = int(f.nrec);
  if (n == 0) return g;
  const MapLookup at{v.P, n, light, v.nlights, lm.W, lm.H};
  if (p.shadows == Shadows::Soft) return soft_backward(k, p.sampling, v, f, fgr, at, lm, g);
  if (sampling_method(p.sampling).windowed) return truncated_backward(k, v, f, fgr, at, lm, g);
  return exact_backward(k, exact_on_clblast(p, k.tuning()), f, fgr, at, lm, g);
}

}  // namespace penumbra::detail
