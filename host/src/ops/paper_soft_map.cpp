// Host side of kernels/paper_soft_map.cl: the penumbra map of a light's view, and its backward.
#include "ops/args.hpp"

namespace penumbra::detail {

namespace {

// The edge in texels of the cells whose largest receiver depth bounds the boxes.
constexpr int cell = 16;

struct PenumbraCellsArgs {
  static constexpr const char* file = "paper_soft_map.cl";
  static constexpr const char* kernel = "soft_map_cells";
  cl_int W, H;
  const cl::Buffer& S;
  cl_int cell, cells_x, cells_y;
  const cl::Buffer& cell_max;
  auto fields() const { return std::tie(W, H, S, cell, cells_x, cells_y, cell_max); }
};

struct PenumbraBoxesArgs {
  static constexpr const char* file = "paper_soft_map.cl";
  static constexpr const char* kernel = "soft_map_boxes";
  const cl::Buffer &vscreen, &faces, &fnormal, &P;
  cl_int nf, W, H;
  const cl::Buffer& cell_max;
  cl_int cell, cells_x;
  const cl::Buffer& boxes;
  auto fields() const {
    return std::tie(vscreen, faces, fnormal, P, nf, W, H, cell_max, cell, cells_x, boxes);
  }
};

// The texels' inputs: a light view, its shadow map and the faces binned by their boxes.
struct TexelFaces {
  const cl::Buffer &vscreen, &faces, &fnormal, &boxes, &P;
  cl_int W, H;
  const cl::Buffer& S;
  cl_int tile, tiles_x;
  BinLists tiles;  // with tile and tiles_x: TEXEL_FACES
  auto fields() const {
    return std::tie(vscreen, faces, fnormal, boxes, P, W, H, S, tile, tiles_x, tiles);
  }
};

TexelFaces texel_faces(const DeviceGeometry& g, const View& lv, const ScreenGeometry& sg,
                       const cl::Buffer& S, const SoftMap& pm) {
  const Bins& b = pm.bins;
  return {sg.vscreen, g.faces, sg.fnormal, pm.boxes, lv.P, lv.W, lv.H, S, b.tile, b.tiles_x, b};
}

// soft_map_fwd and soft_map_bwd_texel: rows of `lanes` texels per work-item.
void launch_texels(Kernels& k, cl::Kernel& kernel, const View& lv) {
  const int lanes = soft_map_lanes(k.ctx().info(), k.tuning());
  launch(k.ctx(), kernel, cl::NDRange((lv.W + lanes - 1) / lanes, lv.H),
         cl::NDRange(std::max(1, 8 / lanes), 8));
}

struct PenumbraFwdArgs {
  static constexpr const char* file = "paper_soft_map.cl";
  static constexpr const char* kernel = "soft_map_fwd";
  TexelFaces in;
  const cl::Buffer &Pmap, &pen_sums;
  auto fields() const { return std::tie(in, Pmap, pen_sums); }
};

struct PenumbraBwdTexelArgs {
  static constexpr const char* file = "paper_soft_map.cl";
  static constexpr const char* kernel = "soft_map_bwd_texel";
  static constexpr KernelPart part = KernelPart::Backward;
  TexelFaces in;
  const cl::Buffer &Pmap, &pen_sums, &gP, &gS, &gDL;
  auto fields() const { return std::tie(in, Pmap, pen_sums, gP, gS, gDL); }
};

struct PenumbraBwdFaceArgs {
  static constexpr const char* file = "paper_soft_map.cl";
  static constexpr const char* kernel = "soft_map_bwd_face";
  static constexpr KernelPart part = KernelPart::Backward;
  const cl::Buffer &vscreen, &faces, &fnormal, &boxes, &P;
  cl_int nf, W, H;
  const cl::Buffer &S, &Pmap, &pen_sums, &gP, &gface_screen;
  auto fields() const {
    return std::tie(vscreen, faces, fnormal, boxes, P, nf, W, H, S, Pmap, pen_sums, gP,
                    gface_screen);
  }
};

}  // namespace

SoftMap soft_map_forward(Kernels& k, const DeviceGeometry& g, const View& lv,
                         const ScreenGeometry& sg, const cl::Buffer& S) {
  Context& ctx = k.ctx();
  const size_t ntex = size_t(lv.W) * lv.H;
  SoftMap pm;
  const int cells_x = (lv.W + cell - 1) / cell, cells_y = (lv.H + cell - 1) / cell;
  const cl::Buffer cell_max = alloc_reals(ctx, k.precision(), size_t(cells_x) * cells_y);
  auto& cells = bind_args(k, PenumbraCellsArgs{lv.W, lv.H, S, cell, cells_x, cells_y, cell_max});
  launch_1d(ctx, cells, size_t(cells_x) * cells_y);
  pm.boxes = alloc_ints(ctx, size_t(g.nf) * 4);
  auto& bx = bind_args(k, PenumbraBoxesArgs{sg.vscreen, g.faces, sg.fnormal, lv.P, g.nf, lv.W, lv.H,
                                            cell_max, cell, cells_x, pm.boxes});
  launch_1d(ctx, bx, g.nf);
  pm.bins = bin_boxes(k, pm.boxes, g.nf, lv.W, lv.H, k.tuning().soft_map.tile);
  pm.map = alloc_reals(ctx, k.precision(), ntex);
  pm.sums = alloc_reals(ctx, k.precision(), ntex * 2);
  auto& pf = bind_args(k, PenumbraFwdArgs{texel_faces(g, lv, sg, S, pm), pm.map, pm.sums});
  launch_texels(k, pf, lv);
  return pm;
}

cl::Buffer soft_map_backward_texels(Kernels& k, const DeviceGeometry& g, const View& lv,
                                    const ScreenGeometry& sg, const cl::Buffer& S,
                                    const SoftMap& pm, const cl::Buffer& gP, double* gsize) {
  Context& ctx = k.ctx();
  const size_t ntex = size_t(lv.W) * lv.H;
  cl::Buffer gS = alloc_reals(ctx, k.precision(), ntex),
             gDL = alloc_reals(ctx, k.precision(), ntex);
  auto& pb = bind_args(
      k, PenumbraBwdTexelArgs{texel_faces(g, lv, sg, S, pm), pm.map, pm.sums, gP, gS, gDL});
  launch_texels(k, pb, lv);
  read_reals(ctx, k.precision(), gDL, ntex, [&](const auto* gdl) {
    for (size_t i = 0; i < ntex; ++i) *gsize += gdl[i];  // texel order
  });
  return gS;
}

void soft_map_backward_faces(Kernels& k, const DeviceGeometry& g, const View& lv,
                             const ScreenGeometry& sg, const cl::Buffer& S, const SoftMap& pm,
                             const cl::Buffer& gP, FaceGrads& fg) {
  auto& pb = bind_args(k, PenumbraBwdFaceArgs{sg.vscreen, g.faces, sg.fnormal, pm.boxes, lv.P, g.nf,
                                              lv.W, lv.H, S, pm.map, pm.sums, gP, fg.screen});
  launch_1d(k.ctx(), pb, g.nf, 16);
}

}  // namespace penumbra::detail
