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
  const cl::Buffer &aux, &pix_count, &run_hits;
  auto fields() const {
    return std::tie(vscreen, faces, fbbox, fnormal, P, W, H, nf, tiles_x, tiles, aux, pix_count,
                    run_hits);
  }
};

struct RasterFragmentsArgs {
  static constexpr const char* file = "raster.cl";
  static constexpr const char* kernel = "raster_fragments";
  const cl::Buffer &vscreen, &vworld, &faces, &fbbox, &fnormal, &albedo, &P;
  cl_int W, H, nf, tiles_x;
  BinLists tiles;
  const cl::Buffer &aux, &pix_count, &run_hits, &pix_offset, &pix_n;
  const cl::Buffer &rec_face, &rec_frag, &rec_shade, &rec_light, &rec_light2;
  auto fields() const {
    return std::tie(vscreen, vworld, faces, fbbox, fnormal, albedo, P, W, H, nf, tiles_x, tiles,
                    aux, pix_count, run_hits, pix_offset, pix_n, rec_face, rec_frag, rec_shade,
                    rec_light, rec_light2);
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
  const cl::Buffer& P;
  cl_int W, H;
  const cl::Buffer &pix_offset, &pix_n, &rec_frag, &rec_shade, &rec_light, &image, &aux;
  const cl::Buffer &gimage, &gdepth, &rec_wg, &rec_lgrad;
  auto fields() const {
    return std::tie(P, W, H, pix_offset, pix_n, rec_frag, rec_shade, rec_light, image, aux, gimage,
                    gdepth, rec_wg, rec_lgrad);
  }
};

struct RasterBwdArgs {
  static constexpr const char* file = "raster.cl";
  static constexpr const char* kernel = "raster_bwd";
  const cl::Buffer &vscreen, &vworld, &faces, &fbbox, &fnormal, &albedo, &P;
  cl_int W, H, nf;
  const cl::Buffer &aux, &gimage, &gdepth, &pix_offset, &pix_n;
  const cl::Buffer &rec_face, &rec_light, &rec_wg, &rec_lgrad, &rec_lgrad2;
  const cl::Buffer &gface_screen, &gface_world, &gface_albedo, &gface_light;
  auto fields() const {
    return std::tie(vscreen, vworld, faces, fbbox, fnormal, albedo, P, W, H, nf, aux, gimage,
                    gdepth, pix_offset, pix_n, rec_face, rec_light, rec_wg, rec_lgrad, rec_lgrad2,
                    gface_screen, gface_world, gface_albedo, gface_light);
  }
};

// Global and local sizes of the tiled passes (count, fragments).
void launch_tiled(Kernels& k, cl::Kernel& kernel, const ViewState& v) {
  const auto& t = k.tuning().raster;
  const size_t tiles_x = (v.W + t.tile - 1) / t.tile, tiles_y = (v.H + t.tile - 1) / t.tile;
  launch(k.ctx(), kernel, cl::NDRange(tiles_x * t.tile / t.pixels_per_item, tiles_y * t.tile),
         cl::NDRange(t.tile / t.pixels_per_item, t.tile));
}
}  // namespace

void raster_fragments(Kernels& k, const DeviceGeometry& g, ViewState& v) {
  Context& ctx = k.ctx();
  const Precision p = k.precision();
  const size_t npix = size_t(v.W) * v.H;
  if (k.tuning()
          .raster.brute_force) {  // the kernels ignore the bins; give them valid empty buffers
    v.bins = Bins{};
    v.bins.tiles_x = 1;
    v.bins.offsets = v.bins.counts = v.bins.items = alloc_ints(ctx, 1);
  } else {
    v.bins = bin_boxes(k, v.fbbox, g.nf, v.W, v.H, k.tuning().raster.tile);
  }
  v.aux = alloc_reals(ctx, p, npix * 4);
  v.pix_count = alloc_ints(ctx, npix);
  const int ppw = k.tuning().raster.pixels_per_item;
  const cl::Buffer run_hits = alloc_ints(ctx, size_t(v.H) * ((v.W + ppw - 1) / ppw) * 2);  // ulong
  auto& count =
      bind_args(k, RasterCountArgs{v.vscreen, g.faces, v.fbbox, v.fnormal, v.P, v.W, v.H, g.nf,
                                   v.bins.tiles_x, v.bins, v.aux, v.pix_count, run_hits});
  launch_tiled(k, count, v);

  // Fragment storage of exactly the counted size.
  auto counts = download_ints(ctx, v.pix_count, npix);
  std::vector<int> offsets(npix);
  size_t total = 0;
  for (size_t i = 0; i < npix; ++i) {
    offsets[i] = int(total);
    total += size_t(counts[i]);
  }
  if (total > size_t(INT32_MAX))
    throw Error("the view keeps " + std::to_string(total) + " fragments, more than 2^31");
  // Fragment storage, forward and backward: face, weight, shading terms, light terms.
  const size_t per_fragment =
      sizeof(int) + real_size(p) * 4 * (1 + (1 + v.nlights) + 4 * v.nlights + 1);
  check_memory(ctx, total * per_fragment + npix * 13 * real_size(p),
               "a " + std::to_string(v.W) + "x" + std::to_string(v.H) + " view keeping " +
                   std::to_string(total) + " fragments");
  v.nrec = total;
  v.pix_offset = upload_ints(ctx, offsets);
  v.pix_n = alloc_ints(ctx, npix);
  v.rec_face = alloc_ints(ctx, total);
  v.rec_frag = alloc_reals(ctx, p, total * 4);
  v.rec_shade = alloc_reals(ctx, p, total * 4 * (1 + v.nlights));
  v.rec_light = alloc_reals(ctx, p, total * 4 * v.nlights);
  v.rec_light2 = alloc_reals(ctx, p, total * 4 * v.nlights);
  auto& frag = bind_args(
      k, RasterFragmentsArgs{v.vscreen,      g.vworld,    g.faces,    v.fbbox,     v.fnormal,
                             g.albedo,       v.P,         v.W,        v.H,         g.nf,
                             v.bins.tiles_x, v.bins,      v.aux,      v.pix_count, run_hits,
                             v.pix_offset,   v.pix_n,     v.rec_face, v.rec_frag,  v.rec_shade,
                             v.rec_light,    v.rec_light2});
  launch_tiled(k, frag, v);
}

void raster_resolve(Kernels& k, ViewState& v) {
  const size_t npix = size_t(v.W) * v.H;
  v.image = alloc_reals(k.ctx(), k.precision(), npix * 4);
  v.depth = alloc_reals(k.ctx(), k.precision(), npix);
  v.cover = alloc_reals(k.ctx(), k.precision(), npix);
  auto& res =
      bind_args(k, RasterResolveArgs{v.P, v.W, v.H, v.pix_offset, v.pix_n, v.rec_frag, v.rec_shade,
                                     v.rec_light, v.image, v.aux, v.depth, v.cover});
  launch_1d(k.ctx(), res, npix);
}

void raster_resolve_backward(Kernels& k, ViewState& v, const cl::Buffer& gimage,
                             const cl::Buffer& gdepth) {
  v.rec_wg = alloc_reals(k.ctx(), k.precision(), v.nrec * 4);
  v.rec_lgrad = alloc_reals(k.ctx(), k.precision(), v.nrec * 4 * v.nlights);
  v.rec_lgrad2 = zero_reals(k.ctx(), k.precision(), v.nrec * 4 * v.nlights);
  auto& rb = bind_args(
      k, RasterResolveBwdArgs{v.P, v.W, v.H, v.pix_offset, v.pix_n, v.rec_frag, v.rec_shade,
                              v.rec_light, v.image, v.aux, gimage, gdepth, v.rec_wg, v.rec_lgrad});
  launch_1d(k.ctx(), rb, size_t(v.W) * v.H);
}

FaceGrads raster_backward(Kernels& k, const DeviceGeometry& g, const ViewState& v,
                          const cl::Buffer& gimage, const cl::Buffer& gdepth) {
  Context& ctx = k.ctx();
  FaceGrads fg;
  fg.screen = alloc_reals(ctx, k.precision(), size_t(g.nf) * 12);
  fg.world = alloc_reals(ctx, k.precision(), size_t(g.nf) * 12);
  fg.albedo = alloc_reals(ctx, k.precision(), size_t(g.nf) * 12);
  fg.light = alloc_reals(ctx, k.precision(), size_t(g.nf) * (6 * v.nlights + 1) * 4);
  auto& rb = bind_args(
      k, RasterBwdArgs{v.vscreen,   g.vworld,     g.faces,   v.fbbox,    v.fnormal,   g.albedo,
                       v.P,         v.W,          v.H,       g.nf,       v.aux,       gimage,
                       gdepth,      v.pix_offset, v.pix_n,   v.rec_face, v.rec_light, v.rec_wg,
                       v.rec_lgrad, v.rec_lgrad2, fg.screen, fg.world,   fg.albedo,   fg.light});
  launch_1d(ctx, rb, g.nf, 16);
  return fg;
}

}  // namespace penumbra::detail
