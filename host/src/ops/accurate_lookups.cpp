// Host side of kernels/accurate_lookups.cl: the accurate model's shadow lookup (percentage-closer
// filtering, with a blocker search for soft shadows) for every kept fragment, truncated or exact.
#include <algorithm>
#include <cmath>

#include "ops/args.hpp"

namespace penumbra::detail {

namespace {

constexpr double kSearchEps = 0.05;  // PCF_SEARCH_EPS of accurate_lookups.cl

// The blocker search's texels of a light's map: every stride-th of each axis (accurate_lookups.cl's
// search map); the map itself at stride 1 or where there is no search (hard shadows).
struct SearchMap {
  cl::Buffer S, A;
  cl_int W, H;
  auto fields() const { return std::tie(S, A, W, H); }
};

struct PcfSearchMapArgs {
  static constexpr const char* file = "accurate_lookups.cl";
  static constexpr const char* kernel = "pcf_search_map";
  cl_int Wm;
  const cl::Buffer &S, &A;
  cl_int stride;
  const SearchMap& out;
  auto fields() const { return std::tie(Wm, S, A, stride, out); }
};

struct PcfWindowLogsArgs {
  static constexpr const char* file = "accurate_lookups.cl";
  static constexpr const char* kernel = "pcf_window_logs";
  const cl::Buffer &P, &logs;
  auto fields() const { return std::tie(P, logs); }
};

struct PcfSampleArgs {
  static constexpr const char* file = "accurate_lookups.cl";
  static constexpr const char* kernel = "pcf_sample";
  MapLookup at;
  const cl::Buffer &logs, &S, &A;
  const SearchMap& search;
  const cl::Buffer &rec_shade, &rec_light, &rec_light2;
  auto fields() const { return std::tie(at, logs, S, A, search, rec_shade, rec_light, rec_light2); }
};

struct PcfSampleBwdArgs {
  static constexpr const char* file = "accurate_lookups.cl";
  static constexpr const char* kernel = "pcf_sample_bwd";
  static constexpr KernelPart part = KernelPart::Backward;
  MapLookup at;
  const cl::Buffer &logs, &S, &A;
  const SearchMap& search;
  const cl::Buffer &rec_light, &rec_light2, &rec_lgrad, &rec_lgrad2;
  auto fields() const {
    return std::tie(at, logs, S, A, search, rec_light, rec_light2, rec_lgrad, rec_lgrad2);
  }
};

struct PcfGatherArgs {
  static constexpr const char* file = "accurate_lookups.cl";
  static constexpr const char* kernel = "pcf_gather";
  static constexpr KernelPart part = KernelPart::Gather;
  MapLookup at;
  const cl::Buffer& logs;
  cl_int reach;
  const cl::Buffer &S, &A, &grec, &gslope;
  BinLists buckets;
  const cl::Buffer &bucket_radius, &chunks, &gS, &gA;
  cl_int search, Wg;
  auto fields() const {
    return std::tie(at, logs, reach, S, A, grec, gslope, buckets, bucket_radius, chunks, gS, gA,
                    search, Wg);
  }
};

// The gather entries' copies of their fragments (accurate_lookups.cl's grec, gslope).
struct GatherRecords {
  cl::Buffer grec, gslope;
  auto fields() const { return std::tie(grec, gslope); }
};

struct PcfGatherRecordsArgs {
  static constexpr const char* file = "accurate_lookups.cl";
  static constexpr const char* kernel = "pcf_gather_records";
  static constexpr KernelPart part = KernelPart::Backward;
  MapLookup at;
  cl_int search;
  const cl::Buffer &entry_of, &rec_light, &rec_light2, &rec_lgrad, &rec_lgrad2;
  const GatherRecords& out;
  auto fields() const {
    return std::tie(at, search, entry_of, rec_light, rec_light2, rec_lgrad, rec_lgrad2, out);
  }
};

struct PcfBoxesArgs {
  static constexpr const char* file = "accurate_lookups.cl";
  static constexpr const char* kernel = "pcf_boxes";
  static constexpr KernelPart part = KernelPart::Backward;
  MapLookup at;
  cl_int search, Wb, Hb;
  const cl::Buffer &rec_light, &rec_lgrad, &rec_lgrad2, &boxes;
  auto fields() const {
    return std::tie(at, search, Wb, Hb, rec_light, rec_lgrad, rec_lgrad2, boxes);
  }
};

struct PcfGatherEntryOfArgs {
  static constexpr const char* file = "accurate_lookups.cl";
  static constexpr const char* kernel = "pcf_gather_entry_of";
  static constexpr KernelPart part = KernelPart::Backward;
  cl_int entries;
  const cl::Buffer &bucket_recs, &entry_of;
  auto fields() const { return std::tie(entries, bucket_recs, entry_of); }
};

struct PcfGatherChunksArgs {
  static constexpr const char* file = "accurate_lookups.cl";
  static constexpr const char* kernel = "pcf_gather_chunks";
  static constexpr KernelPart part = KernelPart::Backward;
  MapLookup at;
  cl_int search;
  const cl::Buffer &rec_light, &rec_light2, &rec_lgrad, &rec_lgrad2, &chunks;
  auto fields() const {
    return std::tie(at, search, rec_light, rec_light2, rec_lgrad, rec_lgrad2, chunks);
  }
};

struct PcfBucketRadiusArgs {
  static constexpr const char* file = "accurate_lookups.cl";
  static constexpr const char* kernel = "pcf_bucket_radius";
  static constexpr KernelPart part = KernelPart::Backward;
  cl_int W, H;
  const cl::Buffer &logs, &grec, &offsets, &counts, &radius;
  auto fields() const { return std::tie(W, H, logs, grec, offsets, counts, radius); }
};

// A pass of the gather: the filters' terms over the map (W × H texels), or (soft shadows) the
// searches' over the search map.
struct GatherPass {
  bool search;
  cl_int W, H;
};

// Texels within which a pass of the gather finds every fragment whose window can hold a texel,
// plus one for the bucket's rounding: the filters' (variance σ_f cut at ε_λ), at most σ_b wide
// for soft shadows (filter_sigma), as the device holds it, a bound known without reading the
// fragments back; or the searches' in the search map (σ_b / st² cut at PCF_SEARCH_EPS).
int gather_reach(Precision precision, const RenderParams& p, double search_sigma, bool search) {
  const double sigma_b = precision == Precision::Float ? double(float(search_sigma)) : search_sigma;
  double r2;
  if (search) {
    const int st = blocker_search_stride(search_sigma);
    r2 = 2 * sigma_b / (st * st) * std::log(1 / kSearchEps);
  } else {
    double sigma = shadow_sigma_s(p);  // hard shadows: every filter has σ_s
    if (p.shadows == Shadows::Soft) sigma = std::max(sigma, sigma_b);
    r2 = 2 * sigma * std::log(1 / p.lambda_eps);
  }
  return int(std::ceil(std::sqrt(r2))) + 1;
}

// pcf_gather's texel buckets and each bucket's radius (pcf_bucket_radius), placeholders for
// the exact gather; the exact gather's chunk boxes (pcf_gather_chunks), a placeholder for the
// truncated one; the entries' copies of their fragments, in the order the gather visits them.
struct GatherBuckets {
  Bins bins;
  cl::Buffer radius, chunks;
  GatherRecords records;
};

// The copies of the fragments for pcf_gather (pcf_gather_records), one per entry: per bucket
// entry (`bins`, truncated), per fragment (exact).
GatherRecords gather_records(Kernels& k, Sampling sampling, const Fragments& f,
                             const FragmentGrads& fgr, const MapLookup& at, bool search,
                             const Bins& bins) {
  Context& ctx = k.ctx();
  const std::string variant = sampling_define(sampling);
  const bool bucketed = sampling_method(sampling).windowed;
  const size_t nrec = size_t(at.nrec), entries = bucketed ? bins.total : nrec;
  cl::Buffer entry_of = alloc_ints(ctx, bucketed ? nrec : 1);
  if (bucketed && entries > 0) {
    ctx.queue().enqueueFillBuffer(entry_of, cl_int(-1), 0, nrec * sizeof(cl_int));
    launch_1d(ctx,
              bind_args(k, PcfGatherEntryOfArgs{cl_int(entries), bins.items, entry_of}, variant),
              entries);
  }
  const size_t n = std::max<size_t>(entries, 1);
  GatherRecords g{alloc_reals(ctx, k.precision(), n * 8), alloc_reals(ctx, k.precision(), n * 2)};
  if (entries > 0)
    launch_1d(ctx,
              bind_args(k,
                        PcfGatherRecordsArgs{at, cl_int(search), entry_of, f.rec_light,
                                             f.rec_light2, fgr.rec_lgrad, fgr.rec_lgrad2, g},
                        variant),
              nrec);
  return g;
}

// The fragments with a gradient for a pass bucketed by the texel of its map nearest their μ
// (μ/st on the search map).
Bins pass_buckets(Kernels& k, Sampling sampling, const Fragments& f, const FragmentGrads& fgr,
                  const MapLookup& at, const GatherPass& pass) {
  const int n = at.nrec;
  cl::Buffer boxes = alloc_ints(k.ctx(), size_t(n) * 4);
  launch_1d(k.ctx(),
            bind_args(k,
                      PcfBoxesArgs{at, cl_int(pass.search), pass.W, pass.H, f.rec_light,
                                   fgr.rec_lgrad, fgr.rec_lgrad2, boxes},
                      sampling_define(sampling)),
            n);
  return bin_boxes(k, boxes, n, pass.W, pass.H, 1);
}

GatherBuckets gather_buckets(Kernels& k, Sampling sampling, const Fragments& f,
                             const FragmentGrads& fgr, const MapLookup& at, const cl::Buffer& logs,
                             const GatherPass& pass) {
  Context& ctx = k.ctx();
  GatherBuckets b;
  if (!sampling_method(sampling).windowed) {
    b.bins.offsets = b.bins.counts = b.bins.items = alloc_ints(ctx, 1);
    b.radius = alloc_reals(ctx, k.precision(), 1);
    b.chunks = gather_chunks(k, at.nrec, [&](const cl::Buffer& out) -> cl::Kernel& {
      return bind_args(k,
                       PcfGatherChunksArgs{at, cl_int(pass.search), f.rec_light, f.rec_light2,
                                           fgr.rec_lgrad, fgr.rec_lgrad2, out},
                       sampling_define(sampling));
    });
    b.records = gather_records(k, sampling, f, fgr, at, pass.search, b.bins);
    return b;
  }
  b.chunks = alloc_ints(ctx, 4);
  const size_t texels = size_t(pass.W) * pass.H;
  b.bins = pass_buckets(k, sampling, f, fgr, at, pass);
  b.records = gather_records(k, sampling, f, fgr, at, pass.search, b.bins);
  b.radius = alloc_reals(ctx, k.precision(), texels);
  auto& radius = bind_args(k,
                           PcfBucketRadiusArgs{pass.W, pass.H, logs, b.records.grec, b.bins.offsets,
                                               b.bins.counts, b.radius},
                           sampling_define(sampling));
  launch_1d(ctx, radius, texels);
  return b;
}

// One pass of the gather: dL/dS and dL/dA of the W × H texels S, A into gS, gA (Wm wide),
// written by the map's pass, added to the map's texels (st·I, st·J) by the search map's.
void gather_pass(Kernels& k, const RenderParams& p, double search_sigma, const Fragments& f,
                 const FragmentGrads& fgr, const MapLookup& at, const cl::Buffer& logs,
                 const GatherPass& pass, const cl::Buffer& S, const cl::Buffer& A,
                 const cl::Buffer& gS, const cl::Buffer& gA) {
  const GatherBuckets buckets = gather_buckets(k, p.sampling, f, fgr, at, logs, pass);
  const int reach = gather_reach(k.precision(), p, search_sigma, pass.search);
  const MapLookup on{at.P, at.nrec, at.light, at.nl, pass.W, pass.H};
  auto& ga = bind_args(k,
                       PcfGatherArgs{on, logs, reach, S, A, buckets.records.grec,
                                     buckets.records.gslope, buckets.bins, buckets.radius,
                                     buckets.chunks, gS, gA, cl_int(pass.search), at.Wm},
                       sampling_define(p.sampling));
  launch_gather(k, ga, pass.W, pass.H);
}

SearchMap search_map(Kernels& k, const RenderParams& p, double search_sigma, const LightMaps& lm) {
  const int st = blocker_search_stride(search_sigma);
  if (p.shadows != Shadows::Soft || st == 1) return {lm.S, lm.A, lm.W, lm.H};
  const int W = (lm.W - 1) / st + 1, H = (lm.H - 1) / st + 1;
  const size_t texels = size_t(W) * H;
  SearchMap m{alloc_reals(k.ctx(), k.precision(), texels),
              alloc_reals(k.ctx(), k.precision(), texels), W, H};
  auto& copy = bind_args(k, PcfSearchMapArgs{lm.W, lm.S, lm.A, st, m},  // pcf_sample's program
                         sampling_define(p.sampling));
  launch_1d(k.ctx(), copy, size_t(m.W) * m.H);
  return m;
}

// log(1/ε) of the filter's and the search's cuts for view parameters P (accurate_lookups.cl's
// WindowLogs).
cl::Buffer window_logs(Kernels& k, const cl::Buffer& P, Sampling sampling) {
  cl::Buffer logs = alloc_reals(k.ctx(), k.precision(), 2);
  launch_1d(k.ctx(), bind_args(k, PcfWindowLogsArgs{P, logs}, sampling_define(sampling)), 1, 1);
  return logs;
}

}  // namespace

void pcf_forward(Kernels& k, const RenderParams& p, double search_sigma, const View& v,
                 Fragments& f, int light, const LightMaps& lm) {
  const int n = int(f.nrec);
  if (n == 0) return;
  const MapLookup at{v.P, n, light, v.nlights, lm.W, lm.H};
  const SearchMap search = search_map(k, p, search_sigma, lm);
  const cl::Buffer logs = window_logs(k, v.P, p.sampling);
  auto& s = bind_args(
      k, PcfSampleArgs{at, logs, lm.S, lm.A, search, f.rec_shade, f.rec_light, f.rec_light2},
      sampling_define(p.sampling));
  launch_1d(k.ctx(), s, n);
}

MapGrads pcf_backward(Kernels& k, const RenderParams& p, double search_sigma, const View& v,
                      const Fragments& f, FragmentGrads& fgr, int light, const LightMaps& lm,
                      double* gsize) {
  Context& ctx = k.ctx();
  const int Wm = lm.W, Hm = lm.H, n = int(f.nrec), nl = v.nlights;
  MapGrads g;
  g.S = zero_reals(ctx, k.precision(), size_t(Wm) * Hm);
  g.A = zero_reals(ctx, k.precision(), size_t(Wm) * Hm);
  if (n == 0) return g;
  const std::string variant = sampling_define(p.sampling);
  const MapLookup at{v.P, n, light, nl, Wm, Hm};
  const SearchMap search = search_map(k, p, search_sigma, lm);
  const cl::Buffer logs = window_logs(k, v.P, p.sampling);
  auto& sb = bind_args(k,
                       PcfSampleBwdArgs{at, logs, lm.S, lm.A, search, f.rec_light, f.rec_light2,
                                        fgr.rec_lgrad, fgr.rec_lgrad2},
                       variant);
  launch_1d(ctx, sb, n);
  gather_pass(k, p, search_sigma, f, fgr, at, logs, {false, Wm, Hm}, lm.S, lm.A, g.S, g.A);
  if (p.shadows == Shadows::Soft) {
    gather_pass(k, p, search_sigma, f, fgr, at, logs, {true, search.W, search.H}, search.S,
                search.A, g.S, g.A);
    // dL/dD_L: Σ over the fragments, on the device in parts
    const RowParts sums = sum_rows(k, fgr.rec_lgrad2, size_t(n), size_t(nl) * 4);
    read_reals(ctx, k.precision(), sums.partial, sums.parts * nl * 4, [&](const auto* g2) {
      for (size_t part = 0; part < sums.parts; ++part) *gsize += g2[(part * nl + light) * 4 + 3];
    });
  }
  return g;
}

}  // namespace penumbra::detail
