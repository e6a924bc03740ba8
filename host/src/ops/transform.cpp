// Host side of kernels/transform.cl.
#include "ops/ops.hpp"

namespace penumbra::detail {

void transform_forward(Kernels& k, const DeviceGeometry& g, ViewState& v) {
  Context& ctx = k.ctx();
  v.vscreen = alloc_reals(ctx, k.precision(), size_t(g.nv) * 4);
  v.fbbox = alloc_ints(ctx, size_t(g.nf) * 4);
  v.fnormal = alloc_reals(ctx, k.precision(), size_t(g.nf) * 4);
  auto& tf = k.get("transform.cl", "transform_fwd");
  set_args(tf, g.vworld, v.P, g.nv, v.vscreen);
  launch_1d(ctx, tf, g.nv);
  auto& fs = k.get("transform.cl", "face_setup");
  set_args(fs, g.vworld, v.vscreen, g.faces, v.P, g.nf, v.W, v.H, v.fbbox, v.fnormal);
  launch_1d(ctx, fs, g.nf);
}

void transform_backward(Kernels& k, const DeviceGeometry& g, const ViewState& v,
                        const FaceGrads& fg, cl::Buffer& gvertices, cl::Buffer& gframe) {
  gvertices = alloc_reals(k.ctx(), k.precision(), size_t(g.nv) * 4);
  gframe = alloc_reals(k.ctx(), k.precision(), size_t(g.nv) * 16);
  auto& tb = k.get("transform.cl", "transform_bwd");
  set_args(tb, g.vworld, v.vscreen, v.P, g.nv, g.adj_offsets, g.adj, fg.screen, fg.world,
           gvertices, gframe);
  launch_1d(k.ctx(), tb, g.nv);
}

}  // namespace penumbra::detail
