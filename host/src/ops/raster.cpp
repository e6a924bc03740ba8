// Host side of kernels/raster.cl.
#include "ops/args.hpp"
#include "penumbra/error.hpp"

namespace penumbra::detail {

namespace {

struct RasterCountArgs {
  static constexpr const char* file = "raster.cl";
  static constexpr const char* kernel = "raster_count";
  const cl::Buffer &vscreen, &faces, &fbbox, &fnormal, &P;
  cl_int W, H, nf, tiles_x;
  BinLists tiles;  // with tiles_x: TILE_ARGS
  const cl::Buffer &aux, &pix_count, &block_hits;
  auto fields() const {
    return std::tie(vscreen, faces, fbbox, fnormal, P, W, H, nf, tiles_x, tiles, aux, pix_count,
                    block_hits);
  }
};

struct RasterFragmentsArgs {
  static constexpr const char* file = "raster.cl";
  static constexpr const char* kernel = "raster_fragments";
  const cl::Buffer &vscreen, &vworld, &faces, &fbbox, &fnormal, &albedo, &P;
  cl_int W, H, nf, tiles_x;
  BinLists tiles;
  const cl::Buffer &aux, &pix_count, &block_hits, &pix_offset, &pix_n;
  const cl::Buffer &rec_face, &rec_frag, &rec_shade, &rec_light, &rec_light2, &face_kept;
  auto fields() const {
    return std::tie(vscreen, vworld, faces, fbbox, fnormal, albedo, P, W, H, nf, tiles_x, tiles,
                    aux, pix_count, block_hits, pix_offset, pix_n, rec_face, rec_frag, rec_shade,
                    rec_light, rec_light2, face_kept);
  }
};

struct RasterResolveArgs {
  static constexpr const char* file = "raster.cl";
  static constexpr const char* kernel = "raster_resolve";
  const cl::Buffer& P;
  cl_int W, H;
  const cl::Buffer &pix_offset, &pix_n, &rec_frag, &rec_shade, &rec_light, &image, &aux, &depth,
      &cover;
  auto fields() const {
    return std::tie(P, W, H, pix_offset, pix_n, rec_frag, rec_shade, rec_light, image, aux, depth,
                    cover);
  }
};

struct RasterResolveBwdArgs {
  static constexpr const char* file = "raster.cl";
  static constexpr const char* kernel = "raster_resolve_bwd";
  static constexpr KernelPart part = KernelPart::Backward;
  const cl::Buffer& P;
  cl_int W, H;
  const cl::Buffer &pix_offset, &pix_n, &rec_frag, &rec_shade, &rec_light, &image, &aux;
  const cl::Buffer &gimage, &gdepth, &rec_wg, &rec_lgrad, &gcover;
  auto fields() const {
    return std::tie(P, W, H, pix_offset, pix_n, rec_frag, rec_shade, rec_light, image, aux, gimage,
                    gdepth, rec_wg, rec_lgrad, gcover);
  }
};

struct RasterBwdArgs {
  static constexpr const char* file = "raster.cl";
  static constexpr const char* kernel = "raster_bwd";
  static constexpr KernelPart part = KernelPart::Backward;
  const cl::Buffer &vscreen, &vworld, &faces, &fbbox, &fnormal, &albedo, &P;
  cl_int W, H, nf;
  const cl::Buffer &gcover, &gimage, &gdepth, &pix_offset, &pix_n, &face_kept;
  const cl::Buffer &rec_face, &rec_light, &rec_wg, &rec_lgrad, &rec_lgrad2;
  const cl::Buffer &gface_screen, &gface_world, &gface_albedo, &gface_light;
  auto fields() const {
    return std::tie(vscreen, vworld, faces, fbbox, fnormal, albedo, P, W, H, nf, gcover, gimage,
                    gdepth, pix_offset, pix_n, face_kept, rec_face, rec_light, rec_wg, rec_lgrad,
                    rec_lgrad2, gface_screen, gface_world, gface_albedo, gface_light);
  }
};

// Global and local sizes of the tiled passes (count, fragments): a work-item per block of
// pixels_per_item pixels (raster_block_width wide).
void launch_tiled(Kernels& k, cl::Kernel& kernel, const View& v) {
  const auto& t = k.tuning().raster;
  const size_t tiles_x = (v.W + t.tile - 1) / t.tile, tiles_y = (v.H + t.tile - 1) / t.tile;
  const int bw = raster_block_width(t.pixels_per_item);
  const int bh = t.pixels_per_item / bw;
  launch(k.ctx(), kernel, cl::NDRange(tiles_x * t.tile / bw, tiles_y * t.tile / bh),
         cl::NDRange(t.tile / bw, t.tile / bh));
}

// The faces binned into the raster's tiles; with brute_force the kernels ignore the bins and
// get valid empty buffers.
Bins raster_bins(Kernels& k, const DeviceGeometry& g, const View& v, const ScreenGeometry& sg) {
  if (!k.tuning().raster.brute_force)
    return bin_boxes(k, sg.fbbox, g.nf, v.W, v.H, k.tuning().raster.tile);
  Bins b;
  b.tiles_x = 1;
  b.offsets = b.counts = b.items = alloc_ints(k.ctx(), 1);
  return b;
}

// Words of raster_count's bits (raster.cl, TILE_BLOCKS): a word per block and per 64 list entries
// of its tile, one word more per tile for lists that do not start on a word; checked against the
// device's memory.
size_t block_hit_words(Kernels& k, const View& v, const Bins& bins) {
  const auto& t = k.tuning().raster;
  if (t.brute_force) return 1;
  const size_t tiles = size_t(bins.tiles_x) * bins.tiles_y;
  const size_t words = (bins.total / 64 + tiles) * size_t(t.tile * t.tile / t.pixels_per_item);
  check_memory(k.ctx(), words * sizeof(cl_ulong),
               "the list bits of a " + std::to_string(v.W) + "x" + std::to_string(v.H) + " view (" +
                   std::to_string(bins.total) + " list entries)");
  return words;
}

// Each pixel's first fragment from its count (pix_count): offsets into the fragment arrays,
// and their total, checked against the device's memory.
std::vector<int> fragment_offsets(Kernels& k, const View& v, const cl::Buffer& pix_count,
                                  size_t& total) {
  const size_t npix = size_t(v.W) * v.H;
  auto counts = download_ints(k.ctx(), pix_count, npix);
  std::vector<int> offsets(npix);
  total = 0;
  for (size_t i = 0; i < npix; ++i) {
    offsets[i] = int(total);
    total += size_t(counts[i]);
  }
  if (total > size_t(INT32_MAX))
    throw Error("the view keeps " + std::to_string(total) + " fragments, more than 2^31");
  // Fragment storage, forward and backward: face, weight and depth (2 reals), shading terms
  // (4 per term), light terms (4 × 4 per shadowed light), weight gradients (2).
  const size_t per_fragment =
      sizeof(int) + real_size(k.precision()) *
                        (2 + 4 * size_t(v.shade_terms()) + 16 * size_t(v.shadow_lights()) + 2);
  check_memory(k.ctx(), total * per_fragment + npix * 13 * real_size(k.precision()),
               "a " + std::to_string(v.W) + "x" + std::to_string(v.H) + " view keeping " +
                   std::to_string(total) + " fragments");
  return offsets;
}

}  // namespace

Fragments raster_fragments(Kernels& k, const DeviceGeometry& g, const View& v,
                           const ScreenGeometry& sg, Fragments spare) {
  Context& ctx = k.ctx();
  const size_t npix = size_t(v.W) * v.H, rs = real_size(k.precision());
  const Bins bins = raster_bins(k, g, v, sg);
  Fragments f;
  f.aux = reuse_or_alloc(ctx, std::move(spare.aux), npix * 4, rs);
  const cl::Buffer pix_count = alloc_ints(ctx, npix);
  const cl::Buffer block_hits = alloc_ints(ctx, block_hit_words(k, v, bins) * 2);  // ulong
  auto& count =
      bind_args(k, RasterCountArgs{sg.vscreen, g.faces, sg.fbbox, sg.fnormal, v.P, v.W, v.H, g.nf,
                                   bins.tiles_x, bins, f.aux, pix_count, block_hits});
  launch_tiled(k, count, v);

  // Fragment storage of the counted size (the spare's where it fits: see reuse_or_alloc).
  f.pix_offset = upload_ints(ctx, fragment_offsets(k, v, pix_count, f.nrec));
  const size_t i = sizeof(cl_int);
  f.pix_n = reuse_or_alloc(ctx, std::move(spare.pix_n), npix, i);
  f.rec_face = reuse_or_alloc(ctx, std::move(spare.rec_face), f.nrec, i);
  f.rec_frag = reuse_or_alloc(ctx, std::move(spare.rec_frag), f.nrec * 2, rs);
  f.rec_shade =
      reuse_or_alloc(ctx, std::move(spare.rec_shade), f.nrec * 4 * size_t(v.shade_terms()), rs);
  const size_t light_reals = f.nrec * 4 * size_t(v.shadow_lights());
  f.rec_light = reuse_or_alloc(ctx, std::move(spare.rec_light), light_reals, rs);
  f.rec_light2 = reuse_or_alloc(ctx, std::move(spare.rec_light2), light_reals, rs);
  f.face_kept = reuse_or_alloc(ctx, std::move(spare.face_kept), size_t(g.nf), i);
  ctx.queue().enqueueFillBuffer(f.face_kept, cl_int(0), 0, std::max(size_t(g.nf), size_t(1)) * i);
  f.exact_forward = std::move(spare.exact_forward);
  f.exact_backward = std::move(spare.exact_backward);
  auto& frag =
      bind_args(k, RasterFragmentsArgs{
                       sg.vscreen, g.vworld,    g.faces,     sg.fbbox,     sg.fnormal,   g.albedo,
                       v.P,        v.W,         v.H,         g.nf,         bins.tiles_x, bins,
                       f.aux,      pix_count,   block_hits,  f.pix_offset, f.pix_n,      f.rec_face,
                       f.rec_frag, f.rec_shade, f.rec_light, f.rec_light2, f.face_kept});
  launch_tiled(k, frag, v);
  return f;
}

Resolved raster_resolve(Kernels& k, const View& v, Fragments& f) {
  const size_t npix = size_t(v.W) * v.H;
  Resolved r;
  r.image = alloc_reals(k.ctx(), k.precision(), npix * 4);
  r.depth = alloc_reals(k.ctx(), k.precision(), npix);
  r.cover = alloc_reals(k.ctx(), k.precision(), npix);
  auto& res =
      bind_args(k, RasterResolveArgs{v.P, v.W, v.H, f.pix_offset, f.pix_n, f.rec_frag, f.rec_shade,
                                     f.rec_light, r.image, f.aux, r.depth, r.cover});
  launch_1d(k.ctx(), res, npix);
  return r;
}

FragmentGrads raster_resolve_backward(Kernels& k, const View& v, const Fragments& f,
                                      const Resolved& r, const cl::Buffer& gimage,
                                      const cl::Buffer& gdepth) {
  FragmentGrads fgr;
  fgr.rec_wg = alloc_reals(k.ctx(), k.precision(), f.nrec * 2);
  const size_t light_reals = f.nrec * 4 * size_t(v.shadow_lights());
  fgr.rec_lgrad = alloc_reals(k.ctx(), k.precision(), light_reals);
  fgr.rec_lgrad2 = zero_reals(k.ctx(), k.precision(), light_reals);
  fgr.gcover = alloc_reals(k.ctx(), k.precision(), size_t(v.W) * v.H);
  auto& rb = bind_args(k, RasterResolveBwdArgs{v.P, v.W, v.H, f.pix_offset, f.pix_n, f.rec_frag,
                                               f.rec_shade, f.rec_light, r.image, f.aux, gimage,
                                               gdepth, fgr.rec_wg, fgr.rec_lgrad, fgr.gcover});
  launch_1d(k.ctx(), rb, size_t(v.W) * v.H);
  return fgr;
}

FaceGrads raster_backward(Kernels& k, const DeviceGeometry& g, const View& v,
                          const ScreenGeometry& sg, const Fragments& f, const FragmentGrads& fgr,
                          const cl::Buffer& gimage, const cl::Buffer& gdepth) {
  Context& ctx = k.ctx();
  FaceGrads fg;
  fg.screen = alloc_reals(ctx, k.precision(), size_t(g.nf) * 12);
  fg.world = alloc_reals(ctx, k.precision(), size_t(g.nf) * 12);
  fg.albedo = alloc_reals(ctx, k.precision(), size_t(g.nf) * 12);
  fg.light = alloc_reals(ctx, k.precision(), size_t(g.nf) * (6 * v.nlights + 1) * 4);
  auto& rb = bind_args(
      k, RasterBwdArgs{sg.vscreen,     g.vworld,   g.faces,     sg.fbbox,     sg.fnormal,
                       g.albedo,       v.P,        v.W,         v.H,          g.nf,
                       fgr.gcover,     gimage,     gdepth,      f.pix_offset, f.pix_n,
                       f.face_kept,    f.rec_face, f.rec_light, fgr.rec_wg,   fgr.rec_lgrad,
                       fgr.rec_lgrad2, fg.screen,  fg.world,    fg.albedo,    fg.light});
  const int lanes = k.tuning().raster.face_lanes;  // a work-group per face when more than 1
  launch_1d(ctx, rb, size_t(g.nf) * lanes, lanes > 1 ? lanes : 16);
  return fg;
}

}  // namespace penumbra::detail
