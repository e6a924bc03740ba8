// Host side of kernels/penumbra.cl: the penumbra map of a light's view, and its backward.
#include "ops/ops.hpp"

namespace penumbra::detail {

void penumbra_forward(Kernels& k, const DeviceGeometry& g, ViewState& lv) {
  Context& ctx = k.ctx();
  const int kTile = k.tuning().penumbra.tile;
  const size_t ntex = size_t(lv.W) * lv.H;
  lv.pen_boxes = alloc_ints(ctx, size_t(g.nf) * 4);
  auto& bx = k.get("penumbra.cl", "penumbra_boxes");
  set_args(bx, lv.vscreen, g.faces, lv.fnormal, lv.P, g.nf, lv.W, lv.H, lv.pen_boxes);
  launch_1d(ctx, bx, g.nf);
  lv.pen_bins = bin_boxes(k, lv.pen_boxes, g.nf, lv.W, lv.H, kTile);
  lv.pen_map = alloc_reals(ctx, k.precision(), ntex);
  lv.pen_sums = alloc_reals(ctx, k.precision(), ntex * 2);
  auto& pf = k.get("penumbra.cl", "penumbra_fwd");
  const Bins& b = lv.pen_bins;
  set_args(pf, lv.vscreen, g.faces, lv.fnormal, lv.pen_boxes, lv.P, lv.W, lv.H, lv.depth, kTile,
           b.tiles_x, b.offsets, b.counts, b.items, lv.pen_map, lv.pen_sums);
  const int lanes = penumbra_lanes(k.ctx().info(), k.tuning());
  launch(ctx, pf, cl::NDRange((lv.W + lanes - 1) / lanes, lv.H),
         cl::NDRange(std::max(1, 8 / lanes), 8));
}

cl::Buffer penumbra_backward_texels(Kernels& k, const DeviceGeometry& g, ViewState& lv,
                                    const cl::Buffer& gP, double* gsize) {
  Context& ctx = k.ctx();
  const int kTile = lv.pen_bins.tile;
  const size_t ntex = size_t(lv.W) * lv.H;
  cl::Buffer gS = alloc_reals(ctx, k.precision(), ntex), gDL = alloc_reals(ctx, k.precision(), ntex);
  auto& pb = k.get("penumbra.cl", "penumbra_bwd_texel");
  const Bins& b = lv.pen_bins;
  set_args(pb, lv.vscreen, g.faces, lv.fnormal, lv.pen_boxes, lv.P, lv.W, lv.H, lv.depth, kTile,
           b.tiles_x, b.offsets, b.counts, b.items, lv.pen_map, lv.pen_sums, gP, gS, gDL);
  const int lanes = penumbra_lanes(ctx.info(), k.tuning());
  launch(ctx, pb, cl::NDRange((lv.W + lanes - 1) / lanes, lv.H),
         cl::NDRange(std::max(1, 8 / lanes), 8));
  for (double v : download_reals(ctx, k.precision(), gDL, ntex)) *gsize += v;  // texel order
  return gS;
}

void penumbra_backward_faces(Kernels& k, const DeviceGeometry& g, ViewState& lv,
                             const cl::Buffer& gP, FaceGrads& fg) {
  auto& pb = k.get("penumbra.cl", "penumbra_bwd_face");
  set_args(pb, lv.vscreen, g.faces, lv.fnormal, lv.pen_boxes, lv.P, g.nf, lv.W, lv.H, lv.depth,
           lv.pen_map, lv.pen_sums, gP, fg.screen);
  launch_1d(k.ctx(), pb, g.nf, 16);
}

}  // namespace penumbra::detail
