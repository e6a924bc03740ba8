// Host side of kernels/transform.cl.
#include "ops/args.hpp"

namespace penumbra::detail {

namespace {

struct TransformFwdArgs {
  static constexpr const char* file = "transform.cl";
  static constexpr const char* kernel = "transform_fwd";
  const cl::Buffer &vworld, &P;
  cl_int nv;
  const cl::Buffer& vscreen;
  auto fields() const { return std::tie(vworld, P, nv, vscreen); }
};

struct FaceSetupArgs {
  static constexpr const char* file = "transform.cl";
  static constexpr const char* kernel = "face_setup";
  const cl::Buffer &vworld, &vscreen, &faces, &P;
  cl_int nf, W, H;
  const cl::Buffer &fbbox, &fnormal;
  auto fields() const { return std::tie(vworld, vscreen, faces, P, nf, W, H, fbbox, fnormal); }
};

struct TransformBwdArgs {
  static constexpr const char* file = "transform.cl";
  static constexpr const char* kernel = "transform_bwd";
  static constexpr KernelPart part = KernelPart::Backward;
  const cl::Buffer &vworld, &vscreen, &P;
  cl_int nv;
  const cl::Buffer &adj_offsets, &adj, &gface_screen, &gface_world, &gvworld, &gframe;
  auto fields() const {
    return std::tie(vworld, vscreen, P, nv, adj_offsets, adj, gface_screen, gface_world, gvworld,
                    gframe);
  }
};

struct AlbedoBwdArgs {
  static constexpr const char* file = "transform.cl";
  static constexpr const char* kernel = "albedo_bwd";
  static constexpr KernelPart part = KernelPart::Backward;
  cl_int na;
  const cl::Buffer &offsets, &corners, &gface_albedo, &galbedo;
  auto fields() const { return std::tie(na, offsets, corners, gface_albedo, galbedo); }
};

struct SumRowsArgs {
  static constexpr const char* file = "transform.cl";
  static constexpr const char* kernel = "sum_rows";
  static constexpr KernelPart part = KernelPart::Backward;
  const cl::Buffer& in;
  cl_int rows, n, run, parts;
  const cl::Buffer& partial;
  auto fields() const { return std::tie(in, rows, n, run, parts, partial); }
};

// The most parts sum_rows splits rows into: runs short enough that a float sum of one loses
// little (at most about 100ε relative at 100k rows), few enough rows for the host to add.
constexpr size_t kSumParts = 1024;

}  // namespace

RowParts sum_rows(Kernels& k, const cl::Buffer& in, size_t rows, size_t n) {
  const size_t run = (rows + kSumParts - 1) / kSumParts, parts = (rows + run - 1) / run;
  RowParts out{alloc_reals(k.ctx(), k.precision(), parts * n), parts};
  auto& sr = bind_args(
      k, SumRowsArgs{in, cl_int(rows), cl_int(n), cl_int(run), cl_int(parts), out.partial});
  launch_1d(k.ctx(), sr, parts * n);
  return out;
}

ScreenGeometry transform_forward(Kernels& k, const DeviceGeometry& g, const View& v) {
  Context& ctx = k.ctx();
  ScreenGeometry sg;
  sg.vscreen = alloc_reals(ctx, k.precision(), size_t(g.nv) * 4);
  sg.fbbox = alloc_ints(ctx, size_t(g.nf) * 4);
  sg.fnormal = alloc_reals(ctx, k.precision(), size_t(g.nf) * 4);
  auto& tf = bind_args(k, TransformFwdArgs{g.vworld, v.P, g.nv, sg.vscreen});
  launch_1d(ctx, tf, g.nv);
  auto& fs = bind_args(
      k, FaceSetupArgs{g.vworld, sg.vscreen, g.faces, v.P, g.nf, v.W, v.H, sg.fbbox, sg.fnormal});
  launch_1d(ctx, fs, g.nf);
  return sg;
}

cl::Buffer transform_backward(Kernels& k, const DeviceGeometry& g, const View& v,
                              const ScreenGeometry& sg, const FaceGrads& fg,
                              const cl::Buffer& gvertices) {
  cl::Buffer frame = alloc_reals(k.ctx(), k.precision(), size_t(g.nv) * 16);
  auto& tb = bind_args(k, TransformBwdArgs{g.vworld, sg.vscreen, v.P, g.nv, g.adj_offsets, g.adj,
                                           fg.screen, fg.world, gvertices, frame});
  launch_1d(k.ctx(), tb, g.nv);
  return frame;
}

void albedo_backward(Kernels& k, const DeviceGeometry& g, const FaceGrads& fg,
                     const cl::Buffer& galbedo) {
  auto& ab =
      bind_args(k, AlbedoBwdArgs{g.na, g.albedo_offsets, g.albedo_corners, fg.albedo, galbedo});
  launch_1d(k.ctx(), ab, g.na);
}

}  // namespace penumbra::detail
