// Host side of kernels/raster.cl.
#include "ops/ops.hpp"
#include "penumbra/error.hpp"

namespace penumbra::detail {

void raster_forward(Kernels& k, const DeviceGeometry& g, ViewState& v) {
  Context& ctx = k.ctx();
  const auto& t = k.tuning();
  const size_t npix = size_t(v.W) * v.H;
  v.image = alloc_reals(ctx, k.precision(), npix * 4);
  v.aux = alloc_reals(ctx, k.precision(), npix * 4);
  if (t.brute_force) {  // the kernel ignores the bins; give it valid empty buffers
    v.bins.tiles_x = 1;
    v.bins.offsets = v.bins.counts = v.bins.faces = alloc_ints(ctx, 1);
  }
  auto& rf = k.get("raster.cl", "raster_fwd");
  set_args(rf, v.vscreen, g.vworld, g.faces, v.fbbox, v.fnormal, g.albedo, v.P, v.W, v.H, g.nf,
           v.bins.tiles_x, v.bins.offsets, v.bins.counts, v.bins.faces, v.image, v.aux);
  const size_t tiles_x = (v.W + t.tile - 1) / t.tile, tiles_y = (v.H + t.tile - 1) / t.tile;
  launch(ctx, rf, cl::NDRange(tiles_x * t.tile / t.pixels_per_item, tiles_y * t.tile),
         cl::NDRange(t.tile / t.pixels_per_item, t.tile));
}

FaceGrads raster_backward(Kernels& k, const DeviceGeometry& g, const ViewState& v, int nlights,
                          const cl::Buffer& gimage, const cl::Buffer& gdepth) {
  Context& ctx = k.ctx();
  FaceGrads fg;
  fg.screen = alloc_reals(ctx, k.precision(), size_t(g.nf) * 12);
  fg.world = alloc_reals(ctx, k.precision(), size_t(g.nf) * 12);
  fg.albedo = alloc_reals(ctx, k.precision(), size_t(g.nf) * 12);
  fg.light = alloc_reals(ctx, k.precision(), size_t(g.nf) * (2 * nlights + 1) * 4);
  auto& rb = k.get("raster.cl", "raster_bwd");
  set_args(rb, v.vscreen, g.vworld, g.faces, v.fbbox, v.fnormal, g.albedo, v.P, v.W, v.H, g.nf,
           v.image, v.aux, gimage, gdepth, fg.screen, fg.world, fg.albedo, fg.light);
  launch_1d(ctx, rb, g.nf, 16);
  return fg;
}

}  // namespace penumbra::detail
