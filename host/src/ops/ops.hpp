#pragma once
// The pipeline stages on the host side, one file each, mirroring kernels/, in the order they
// run: transform.cpp ↔ transform.cl, bin.cpp ↔ bin.cl, raster.cpp ↔ raster.cl, then per
// shadow model (<model>_<what>): the light map paper_soft_map.cpp ↔ paper_soft_map.cl, and the
// lookups accurate_lookups.cpp ↔ accurate_lookups.cl, paper_lookups.cpp ↔ paper_lookups.cl with
// paper_hard_exact.cpp ↔ paper_hard_exact.cl (the exact hard shadows' products).
#include <CL/opencl.hpp>
#include <algorithm>
#include <cctype>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "cl/device.hpp"
#include "penumbra/renderer.hpp"

namespace penumbra::detail {

// Which kernels of a stage's file a program holds (FORWARD_KERNEL, BACKWARD_KERNEL,
// GATHER_KERNEL in kernels/common/real.clh): a render builds no backward kernel, and the texel
// gathers run blocks of texels of their own (GatherTuning::width, height). A kernel both
// passes launch is a forward one (backward always follows a render of the same Kernels).
enum class KernelPart { Forward, Backward, Gather };

// The options kernels/<file> is built with for this precision, tuning and device, then
// `variant` (a stage's own: -DSAMPLING_<WORD>, bin.cl's -DTILE) and the part's
// (-DBACKWARD_KERNELS, -DGATHER_KERNELS): the one place that decides the -D options of every
// program.
std::string program_options(const std::string& file, Precision precision, const Tuning& tuning,
                            const DeviceInfo& device, const std::string& variant = "",
                            KernelPart part = KernelPart::Forward);
// Every `variant` the stages build kernels/<file> with under `tuning`.
std::vector<std::string> program_variants(const std::string& file, const Tuning& tuning);

// A fixed tuning as the renderer uses it: pixels_per_item 0 becomes the device's default
// (ops/kernels.cpp).
Tuning for_device(Tuning t, const DeviceInfo& device);
// What the renderer does to a scene before packing it (scale.cpp): device points are
// (world point − origin)·scale; the identity for a scene near unit size around the origin.
struct Normalisation {
  glm::dvec3 origin{0.0};
  double scale = 1;
  bool identity() const { return scale == 1 && origin == glm::dvec3(0.0); }
};
Normalisation normalisation(const Bounds& b);  // of the scene's vertices
Scene normalised(const Scene& s, const Normalisation& n);

// Kernel objects of one precision, built on first use for the current tuning, with the options
// of program_options. They are bound and fetched by bind_args() (ops/args.hpp).
class Kernels {
 public:
  // A kernel object, and whether bind_args() has checked its arguments (once per object).
  struct Entry {
    cl::Kernel kernel;
    bool checked = false;
  };
  Kernels(Context& ctx, Precision precision, const Tuning& tuning);
  Entry& get(const std::string& file, const std::string& name, const std::string& variant = "",
             KernelPart part = KernelPart::Forward);
  Context& ctx() { return ctx_; }
  Precision precision() const { return precision_; }
  const Tuning& tuning() const { return tuning_; }
  void set_tuning(const Tuning& tuning) { tuning_ = tuning; }
  // Called before each part of a stage launched in parts (the exact shadow lookups' batches of
  // fragments): (part, parts), part counted from 0. Empty: nothing is called.
  std::function<void(int, int)> on_part;
  void part(int i, int n) {
    if (on_part) on_part(i, n);
  }

 private:
  Context& ctx_;
  Precision precision_;
  Tuning tuning_;
  std::map<std::string, Entry> kernels_;
};

// Mesh data of a whole scene on the device (all meshes concatenated).
struct DeviceGeometry {
  int nv = 0, nf = 0, na = 0;  // na: albedo entries, the meshes' in turn
  cl::Buffer vworld;           // nv × real4
  cl::Buffer faces;            // nf × int4
  cl::Buffer albedo;           // 3·nf × real4, per face corner
  cl::Buffer adj_offsets;      // nv + 1 ints: vertex → (face·3 + corner) list
  cl::Buffer adj;
  cl::Buffer albedo_offsets;  // na + 1 ints: albedo entry → (face·3 + corner) list
  cl::Buffer albedo_corners;
};

// Items (faces, or shadow-map windows) sorted into screen tiles by bin.cl.
struct Bins {
  int tile = 16, tiles_x = 0, tiles_y = 0;
  size_t total = 0;  // entries over all tiles
  cl::Buffer offsets, counts, items;
};

// The lanes of raster_bwd's blocks (raster.cl's PPW in its backward program): the tuning's
// pixels per work-item, at most 8. A face's box is walked in blocks of that many pixels fitted
// to its width; 16 made raster_bwd no faster in the 100k-face accurate hard step (same bits
// whatever the lanes).
inline int raster_backward_lanes(int pixels_per_item) { return std::min(pixels_per_item, 8); }

// Width of the pixel block a raster work-item takes (raster.cl's BLOCK_W): 4×4 pixels from
// 16 per item, 4×2 from 8, 2×2 from 4, 2×1 from 2; its height is pixels_per_item / width.
inline int raster_block_width(int pixels_per_item) {
  return pixels_per_item >= 8 ? 4 : std::min(pixels_per_item, 2);
}

// Texels per work-item of soft_map_fwd: the device's pixels_per_item, at most the penumbra
// tile so that a run stays within one tile's list. Not tied to the raster's tuning, so that
// raster candidates leave the shadows' bits alone.
inline int soft_map_lanes(const DeviceInfo& d, const Tuning& t) {
  return std::min(device_defaults(d).pixels_per_item, t.soft_map.tile);
}

// bin.cl's tile edge in pixels (1: the texel buckets of the shadow gathers).
inline std::string bin_define(int tile) { return "-DTILE=" + std::to_string(tile); }

// The build variant of the shadow lookups for a sampling method: -DSAMPLING_<WORD> (the
// word of sampling_methods() in capitals), which common/window.clh turns into its sum.
inline std::string sampling_define(Sampling s) {
  std::string word = sampling_method(s).word;
  for (char& c : word) c = char(std::toupper(static_cast<unsigned char>(c)));
  return "-DSAMPLING_" + word;
}

// Whether the matrix products of the paper model's exact hard shadows run on CLBlast (the
// exact backend in force, exact_backend_in_force) rather than on paper_hard_exact.cl.
inline bool exact_on_clblast(const RenderParams& p, const Tuning& t) {
  return exact_backend_in_force(p, t) == ExactBackend::CLBlast;
}

// Launches a gather (shadow_gather, soft_gather, pcf_gather) over a W_s × H_s map.
void launch_gather(Kernels& k, cl::Kernel& gather, int Wm, int Hm);
// Fragments per chunk of the exact gathers (window.clh's GATHER_CHUNK, set from here).
constexpr int kGatherChunk = 16;
// The exact gathers' chunk boxes (int4 per kGatherChunk of `nrec` fragments), written by the
// kernel that `bind` binds to the buffer it is given (soft_gather_chunks, pcf_gather_chunks).
cl::Buffer gather_chunks(Kernels& k, int nrec,
                         const std::function<cl::Kernel&(const cl::Buffer&)>& bind);

// The stages' inputs and outputs. A view (a camera, or a light rendering its shadow map) runs
// transform → raster fragments → [shadow lookups] → resolve; each stage returns its own
// struct and takes the structs it reads.

// real4s of rec_shade per fragment: the ambient term and each light's direct term, to be
// weighted by its shadow term; without shadows, where every s is 1, their sum alone.
inline int shade_terms(bool shadows, int nlights) { return shadows ? 1 + nlights : 1; }

// A view: its size, the lights it shades (0 for a light's own view), whether shadow lookups
// fill its fragments' shadow terms (a camera's, with shadows on: P_SHADOWS) and its parameter
// block P (kernels/common/layout.h).
struct View {
  int W = 0, H = 0, nlights = 0;
  bool shadows = false;
  cl::Buffer P;
  // Lights with per-fragment shadow records (rec_light, rec_light2 and their gradients): none
  // without shadows, where every s is 1.
  int shadow_lights() const { return shadows ? nlights : 0; }
  int shade_terms() const { return detail::shade_terms(shadows, nlights); }
};

// transform: the vertices on the view's screen, each face's pixel box and normal.
struct ScreenGeometry {
  cl::Buffer vscreen;         // nv × real4
  cl::Buffer fbbox, fnormal;  // nf × int4, nf × real4
};

// The paper model's exact lookups' Gaussian weight matrices of one light (paper_lookups.cpp), Gx,
// Gy and with derivatives Gxd, Gyd: rows for `batch` fragments of a W × H map. Every row holds
// zeros outside its support (exact_weights clears what the row's last batch left before writing its
// own), so a render keeps them for the next one's lookups of the same shape, which then need no
// new, zero-filled matrices (whose pages fault in as they are filled).
struct ExactWeights {
  size_t batch = 0;
  int W = 0, H = 0;
  bool derivatives = false;
  cl::Buffer Gx, Gy, Gxd, Gyd, support;
};

// Raster passes 1–2: the kept fragments of every pixel (kernels/raster.cl). rec_light and
// rec_light2 hold each fragment's shadow terms per light of View::shadow_lights(): s = 1 from
// the raster, written by the shadow lookups. aux holds per-pixel sums of pass 1, completed by
// resolve.
struct Fragments {
  size_t nrec = 0;  // fragment records: Σ over the pixels of raster_count's bound on the kept
  cl::Buffer aux, pix_offset, pix_n;
  cl::Buffer rec_face, rec_frag, rec_shade, rec_light, rec_light2;
  cl::Buffer face_kept;  // F ints: not 0 where the face kept a fragment at any pixel
  // The exact lookups' weights of each light, forward and backward, handed on from render to
  // render with the rest (paper_lookups.cpp).
  std::vector<ExactWeights> exact_forward, exact_backward;
};

// Raster pass 3: colour and silhouette (image), depth and coverage. Of a light's view, depth
// is its shadow map S and cover the coverage A of its faces.
struct Resolved {
  cl::Buffer image, depth, cover;
};

// A light's view with the paper model's soft shadows: its penumbra map (paper_soft_map.cl), with
// the faces' boxes and bins and the per-texel sums its backward reads.
struct SoftMap {
  cl::Buffer boxes, map, sums;
  Bins bins;
};

// What the shadow lookups read of a light's pass: its W × H shadow map S, the coverage A
// (accurate model) and the penumbra map (paper model, soft shadows; empty otherwise).
struct LightMaps {
  int W = 0, H = 0;
  cl::Buffer S, A, penumbra;
};

// Backward of resolve: per-fragment dL/d(weights) (rec_wg) and dL/ds (rec_lgrad, rec_lgrad2),
// which the shadow backward completes.
struct FragmentGrads {
  cl::Buffer rec_wg, rec_lgrad, rec_lgrad2;
  cl::Buffer gcover;  // per pixel: dL/dA·(1 − A)
};

// Per-face-corner gradients written by raster_backward.
struct FaceGrads {
  cl::Buffer screen, world, albedo;  // 3·nf × real4
  cl::Buffer light;                  // nf × (6·nlights + 1) × real4
};

ScreenGeometry transform_forward(Kernels& k, const DeviceGeometry& g, const View& v);
// Adds one view's dL/d world vertex positions to `gvertices` (nv × real4: the views' in turn, on
// the device) and returns each vertex's share of dL/d(the view's frame) (4·nv × real4: eye, fwd,
// right, up).
cl::Buffer transform_backward(Kernels& k, const DeviceGeometry& g, const View& v,
                              const ScreenGeometry& sg, const FaceGrads& fg,
                              const cl::Buffer& gvertices);
// Adds dL/d(albedo) per albedo entry, from the face corners' (fg.albedo), to `galbedo`
// (na × real4).
void albedo_backward(Kernels& k, const DeviceGeometry& g, const FaceGrads& fg,
                     const cl::Buffer& galbedo);

// The sum of `rows` (≥ 1) rows of n reals of `in`, on the device (transform.cl's sum_rows):
// `parts` partial rows whose sum in order is the whole, the same on every device.
struct RowParts {
  cl::Buffer partial;  // parts × n reals
  size_t parts;
};
RowParts sum_rows(Kernels& k, const cl::Buffer& in, size_t rows, size_t n);

// Sorts `n` items with pixel boxes `boxes` (int4 (x0, y0, x1, y1), empty when x0 > x1) into
// tiles of `tile` pixels over a W × H grid; each tile's list is in item order.
Bins bin_boxes(Kernels& k, const cl::Buffer& boxes, int n, int W, int H, int tile);
// Sorts each of b's lists (b.items from b.offsets, b.counts long) into ascending order, whatever
// order it is in (bin_sort; the program of `b.tile`).
void sort_lists(Kernels& k, const Bins& b);

// Passes 1–2 of the raster: the kept fragments of the view, with shadow terms s = 1, in the
// buffers of `spare` (the same view's fragments from an earlier render) where they fit.
Fragments raster_fragments(Kernels& k, const DeviceGeometry& g, const View& v,
                           const ScreenGeometry& sg, Fragments spare = {});
// Pass 3: colour, silhouette, depth and coverage from the fragments and their shadow terms
// (and I_z, Z into f.aux).
Resolved raster_resolve(Kernels& k, const View& v, Fragments& f);
// Backward of raster_resolve: per-fragment weights and dL/ds.
FragmentGrads raster_resolve_backward(Kernels& k, const View& v, const Fragments& f,
                                      const Resolved& r, const cl::Buffer& gimage,
                                      const cl::Buffer& gdepth);
// Backward of the fragments (after the shadow backward has completed fgr.rec_lgrad).
FaceGrads raster_backward(Kernels& k, const DeviceGeometry& g, const View& v,
                          const ScreenGeometry& sg, const Fragments& f, const FragmentGrads& fgr,
                          const cl::Buffer& gimage, const cl::Buffer& gdepth);

// Buffers the products keep from one batch of rows to the next: made at the first call (the
// largest batch comes first) and reused, so that no batch allocates while an earlier batch's
// commands, and therefore its released buffers, may still be alive on the device.
struct ProductScratch {
  cl::Buffer products, products_d;  // CLBlast's A·B and Ad·B (matmul_nn_rowdots)
  cl::Buffer chunks;                // matmul_tn's chunk boxes
};
// Row-major products by paper_hard_exact.cl or (clblast) by CLBlast. `support` (int4 per row of A
// and B, or of A and D: paper_hard_exact.cl) bounds the nonzero columns of each row, which the
// direct kernels skip and CLBlast's GEMM multiplies. C (m × n) = Aᵀ (A is k × m)·B + beta·C.
void matmul_tn(Kernels& k, bool clblast, size_t m, size_t n, size_t kk, const cl::Buffer& A,
               size_t lda, const cl::Buffer& B, size_t ldb, const cl::Buffer& support,
               ProductScratch& scratch, double beta, cl::Buffer& C, size_t ldc);
// out_r = (Σ_c (A·B)_rc·D_rc, Σ_c (A·B)_rc·Dd_rc, Σ_c (Ad·B)_rc·D_rc, 0) as a real4 (B is
// k × n, D is m × n, Ad and Dd shaped as A and D); without Ad and Dd only the first (.y, .z
// unspecified). The direct kernels never store A·B; CLBlast's GEMM writes it (and Ad·B) to
// the scratch's products, which row_dot(s) reads.
void matmul_nn_rowdots(Kernels& k, bool clblast, size_t m, size_t n, size_t kk, const cl::Buffer& A,
                       const cl::Buffer* Ad, size_t lda, const cl::Buffer& B, size_t ldb,
                       const cl::Buffer& D, const cl::Buffer* Dd, size_t ldd,
                       const cl::Buffer& support, ProductScratch& scratch, cl::Buffer& out);

// CLBlast's own tuner of its Xgemm kernel (clblast::TuneXgemm, float): a random search over
// `fraction` of its parameter space on an m × n × k product. Its fastest set; nothing, with the
// reason in *why, where the tuner failed (too small a fraction finds no legal set).
std::optional<XgemmParameters> clblast_tuned_xgemm(Context& ctx, size_t m, size_t n, size_t k,
                                                   double fraction, std::string* why);

// Whether `p` samples shadows by exact lookups of hard shadows that factor into matrix products
// (the paper model's, exact or gemm sampling), whose weights the fragments keep (ExactWeights).
inline bool exact_lookups(const RenderParams& p) {
  return p.shadows == Shadows::Hard && shadow_model_traits(p.shadow_model).exact_products &&
         !sampling_method(p.sampling).windowed;
}

// The paper model: shadow terms of every fragment `f` of camera view `v` for light `light`,
// sampled from the light's shadow map (and penumbra map for soft shadows)
// (p.shadows, p.sampling and, for the exact sum of hard shadows, exact_on_clblast).
void shadow_forward(Kernels& k, const RenderParams& p, const View& v, Fragments& f, int light,
                    const LightMaps& m);
// Completes fgr.rec_lgrad (and rec_lgrad2) for `light` and returns dL/d(the light's shadow
// map) and, for soft shadows, dL/d(its penumbra map).
struct MapGrads {
  cl::Buffer S, P, A;  // dL/d(shadow map, penumbra map (paper), coverage (accurate))
};
MapGrads shadow_backward(Kernels& k, const RenderParams& p, const View& v, Fragments& f,
                         FragmentGrads& fgr, int light, const LightMaps& m);

// The accurate model (accurate_lookups.cl): shadow terms of every fragment of `v` for `light` by
// percentage-closer filtering of the light's shadow map (a blocker search first for soft
// shadows).
void pcf_forward(Kernels& k, const RenderParams& p, double search_sigma, const View& v,
                 Fragments& f, int light, const LightMaps& m);
// Completes fgr.rec_lgrad (and rec_lgrad2) for `light`, returns dL/dS and dL/dA and adds
// dL/dD_L to *gsize (soft shadows). search_sigma: blocker_search_sigma of the light.
MapGrads pcf_backward(Kernels& k, const RenderParams& p, double search_sigma, const View& v,
                      const Fragments& f, FragmentGrads& fgr, int light, const LightMaps& m,
                      double* gsize);

// The penumbra map of a light's view `lv` from its screen geometry and shadow map S.
SoftMap soft_map_forward(Kernels& k, const DeviceGeometry& g, const View& lv,
                         const ScreenGeometry& sg, const cl::Buffer& S);
// Backward for dL/dP = gP: returns dL/dS through P (W·H reals) and adds dL/dD_L to *gsize.
cl::Buffer soft_map_backward_texels(Kernels& k, const DeviceGeometry& g, const View& lv,
                                    const ScreenGeometry& sg, const cl::Buffer& S,
                                    const SoftMap& pm, const cl::Buffer& gP, double* gsize);
// Adds P's gradient by the light-screen positions and depths of the face corners to fg.screen.
void soft_map_backward_faces(Kernels& k, const DeviceGeometry& g, const View& lv,
                             const ScreenGeometry& sg, const cl::Buffer& S, const SoftMap& pm,
                             const cl::Buffer& gP, FaceGrads& fg);

}  // namespace penumbra::detail
