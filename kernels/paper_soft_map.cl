// Stage 4 (paper model, soft shadows) — the penumbra map P of one light (math.md §4.3, §8.5;
// paper eqs. 9–10, outer penumbra only), rendered in the light's own view after its shadow map S
// (stages 1–3) and read by the lookups (stage 5, paper_lookups.cl); forward and backward.
// For texel q with receiver depth S_q and each face t in front of it (z_t < S_q):
//   d_t distance from q to t (screen units, 0 inside), z_t its depth at q,
//   b_t = D_L·(S_q − z_t)/S_q cone width, r_t = d_t·z_t·tan(θ/2) (or d_t·h), τ_t = r_t/b_t < 1,
//   m_t soft membership, v_t = 1 − m_t·(1 − τ_t), weight a_t = (1 − v_t)·e^{−γ_P v_t},
//   P_q = (e^{−γ_P} + Σ a_t v_t) / (e^{−γ_P} + Σ a_t),
// summed with every exponent shifted by the smallest v (1 for the lit term), so that a large
// γ_P cannot underflow the sums to 0/0.
// The membership is sigmoid((S_q − β − z_t)/γ_s) less its value at z_t = S_q, rescaled to
// reach 1: m_t = max(0, σ(x) − σ₀)/(1 − σ₀), σ₀ = σ(−β/γ_s). As printed it would stay at σ₀
// where a face covering the texel (τ_t = 0) meets the receiver depth and is dropped, and P
// would jump there; this way m_t, hence 1 − v_t and the face's weight, reach 0 first.
// Culling: τ_t < 1 needs d_t < D_L·(1/z_t − 1/S_q)/scale (or D_L·(1 − z_t/S_q)/h), so each
// face is binned into the map tiles its box widened by that bound touches, with z_t its
// smallest corner depth and S_q the largest receiver depth in map cells near it, and a texel
// visits only its tile's list.
// Buffers (light view; V vertices, F faces, map W × H): vscreen V × real4, faces F × int4,
// fnormal F × real4 (.w = screen area, 0 for a dropped face), S W·H × real;
// P W·H × real (output), pen_sums W·H × real2 (the shift v₀ and the shifted denominator
// e^{−γ_P(1−v₀)} + Σ (1 − v)·e^{−γ_P(v−v₀)}), gP W·H × real (backward input).
// cell_max (cells_x × cells_y × real) the largest S of each cell × cell texels.
// Launch: soft_map_cells one work-item per cell; soft_map_boxes and soft_map_bwd_face one
// work-item per face; soft_map_fwd and soft_map_bwd_texel PPW consecutive texels of a row per
// work-item (2-D; a run never straddles two tiles).
#ifndef PPW
#define PPW 1  // texels per work-item in soft_map_fwd and soft_map_bwd_texel; divides the tile
#endif
#include "common/lanes.clh"

// World units per screen unit at depth z in the light's view.
inline real world_per_screen(real z, __global const real* P) {
  return P[P_FRAME + FR_ORTHO] > 0 ? P[P_FRAME + FR_SCALE] : z * P[P_FRAME + FR_SCALE];
}

// One occluder's term at texel q. Returns 0 if the face does not count (behind the receiver,
// or q outside its cone).
typedef struct {
  Fragment fr;
  real d, b, r, tau, sig, m, v;
} Occluder;

INLINE int occluder_fwd(real2 q, real S, const ScreenFace* F, __global const real* P,
                        Occluder* o) {
  fragment_shape(q, F->p, F->area, &o->fr);
  fragment_depth(F->z, P, &o->fr);
  real z = o->fr.z, DL = P[P_LIGHT_SIZE];
  if (!(z < S) || !(DL > 0)) return 0;
  o->d = o->fr.inside ? 0 : sqrt(o->fr.d2);
  o->b = DL * (S - z) / S;
  o->r = o->d * world_per_screen(z, P);
  o->tau = o->r / o->b;
  if (!(o->tau < 1)) return 0;
  real s0 = sigmoid(-P[P_BETA] / P[P_GAMMA_S]);
  o->sig = sigmoid((S - P[P_BETA] - z) / P[P_GAMMA_S]);
  o->m = fmax(o->sig - s0, R(0)) / (1 - s0);
  o->v = 1 - o->m * (1 - o->tau);
  return 1;
}

// Backward of one occluder's v_t for dL/dv = gv: adds dL/dS_q and dL/dD_L, and returns
// dL/dz_t and dL/dd²_t through `gz`, `gd2`.
INLINE void occluder_bwd(real S, const Occluder* o, __global const real* P, real gv, real* gS,
                         real* gDL, real* gz, real* gd2) {
  real z = o->fr.z, DL = P[P_LIGHT_SIZE], gs = P[P_GAMMA_S];
  real gm = -gv * (1 - o->tau), gtau = gv * o->m;
  real s0 = sigmoid(-P[P_BETA] / gs);  // m = max(0, σ((S − β − z)/γ_s) − σ₀)/(1 − σ₀)
  real gsig = o->m > 0 ? gm * o->sig * (1 - o->sig) / (gs * (1 - s0)) : R(0);
  *gS += gsig;
  *gz -= gsig;
  real gr = gtau / o->b, gb = -gtau * o->tau / o->b;  // τ = r/b
  *gS += gb * DL * z / (S * S);                          // b = D_L·(1 − z/S)
  *gz -= gb * DL / S;
  *gDL += gb * (S - z) / S;
  real k = world_per_screen(z, P);                       // r = d·k(z)
  if (P[P_FRAME + FR_ORTHO] == 0) *gz += gr * o->d * P[P_FRAME + FR_SCALE];
  if (!o->fr.inside && o->d > 0) *gd2 += gr * k / (2 * o->d);
}

// dP/dv_t for P = N/Dn with a = (1 − v)·e^{−γ_P v}, from the shifted denominator and shift
// (pen_sums): the ratio is the same for any shift.
inline real soft_map_dv(const Occluder* o, real Pq, real2 sums, __global const real* P) {
  real gp = P[P_GAMMA_P], e = exp(-gp * (o->v - sums.x));
  real a = (1 - o->v) * e, da = -e * (1 + gp * (1 - o->v));
  return (a + (o->v - Pq) * da) / sums.y;
}

// The largest receiver depth S of each cell of cell × cell texels (the last ones cut by the
// map's edge), which bounds the cone of every face above it.
FORWARD_KERNEL void soft_map_cells(int W, int H, __global const real* S, int cell, int cells_x,
                                   int cells_y, __global real* cell_max) {
  int c = get_global_id(0);
  if (c >= cells_x * cells_y) return;
  int i0 = (c % cells_x) * cell, j0 = (c / cells_x) * cell;
  real m = -INFINITY;
  for (int j = j0; j < min(j0 + cell, H); ++j)
    for (int i = i0; i < min(i0 + cell, W); ++i) m = fmax(m, S[j * W + i]);
  cell_max[c] = m;
}

// Texels of the face's screen box widened by `radius` (screen units), with a texel of margin;
// x0 > x1 when it misses the map. Texel centres x = (2i + 1 − W)/H, y = (H − 2j − 1)/H.
INLINE int4 widened_box(const ScreenFace* F, real radius, int W, int H) {
  real xlo = fmin(F->p[0].x, fmin(F->p[1].x, F->p[2].x)) - radius;
  real xhi = fmax(F->p[0].x, fmax(F->p[1].x, F->p[2].x)) + radius;
  real ylo = fmin(F->p[0].y, fmin(F->p[1].y, F->p[2].y)) - radius;
  real yhi = fmax(F->p[0].y, fmax(F->p[1].y, F->p[2].y)) + radius;
  real fx0 = clamp((xlo * H + W - 1) / 2 - 1, R(-1), (real)W);
  real fx1 = clamp((xhi * H + W - 1) / 2 + 1, R(-1), (real)W);
  real fy0 = clamp((H - 1 - yhi * H) / 2 - 1, R(-1), (real)H);
  real fy1 = clamp((H - 1 - ylo * H) / 2 + 1, R(-1), (real)H);
  return (int4)(max((int)ceil(fx0), 0), max((int)ceil(fy0), 0), min((int)floor(fx1), W - 1),
                min((int)floor(fy1), H - 1));
}

// The largest of cell_max over the cells that `box` touches.
inline real cells_max(int4 box, __global const real* cell_max, int cell, int cells_x) {
  real m = -INFINITY;
  for (int cy = box.y / cell; cy <= box.w / cell; ++cy)
    for (int cx = box.x / cell; cx <= box.z / cell; ++cx) m = fmax(m, cell_max[cy * cells_x + cx]);
  return m;
}

// Each face's box: where its cone can reach. With S ≤ S_max on a texel, τ < 1 needs
// d < D_L·(1/z − 1/S_max)/scale ≤ D_L/(z_min·scale)·(1 − z_min/S_max) (orthographic: the same
// factor on D_L/h), z_min the smallest corner depth. So from the box of D_L/(z_min·scale),
// each round's box, which holds every texel the face reaches, bounds S by the cells it
// touches and shrinks the radius by that factor; two rounds take most of the gain.
FORWARD_KERNEL void soft_map_boxes(__global const real4* vscreen, __global const int4* faces,
                                   __global const real4* fnormal, __global const real* P, int nf,
                                   int W, int H, __global const real* cell_max, int cell,
                                   int cells_x, __global int4* boxes) {
  int f = get_global_id(0);
  if (f >= nf) return;
  boxes[f] = (int4)(1, 1, 0, 0);
  if (fnormal[f].w == 0 || !(P[P_LIGHT_SIZE] > 0)) return;
  ScreenFace F = load_screen_face(f, vscreen, faces, fnormal);
  real zmin = fmin(F.z[0], fmin(F.z[1], F.z[2]));
  real radius = P[P_LIGHT_SIZE] / world_per_screen(zmin, P);
  int4 box = widened_box(&F, radius, W, H);
  for (int round = 0; round < 2 && box.x <= box.z && box.y <= box.w; ++round) {
    real factor = fmax(1 - zmin / cells_max(box, cell_max, cell, cells_x), R(0));
    int4 smaller = widened_box(&F, radius * factor, W, H);
    if (mask_all(smaller == box)) break;
    box = smaller;
  }
  if (box.x <= box.z && box.y <= box.w) boxes[f] = box;
}

#define TEXEL_FACES                                                              \
  int tile, int tiles_x, __global const int *tile_offsets,                       \
      __global const int *tile_counts, __global const int *tile_faces

// occluder_fwd on every lane of a run of texels: which lanes face F counts at (in_cone), with
// the terms the forward and the texel backward need. Returns 0 when it counts at none.
typedef struct {
  realP z, tau, b, sig, m, v;
  maskP in_cone;
} LanesOccluder;

INLINE int lanes_occluder(realP qx, real qy, realP Sq, maskP valid, const ScreenFace* F,
                          __global const real* P, LanesOccluder* o) {
  const real DL = P[P_LIGHT_SIZE], gs = P[P_GAMMA_S], beta = P[P_BETA];
  realP w[3], d2, bc[3];
  maskP inside;
  lanes_shape(qx, (realP)qy, F->p, F->area, P, w, &d2, &inside, 0);
  o->z = lanes_depth(w, F->z, P, bc);
  maskP front = valid && o->z < Sq;
  if (!ANY(front)) return 0;
  realP d = inside ? (realP)0 : sqrt(d2);
  o->b = DL * (Sq - o->z) / Sq;
  realP r = d * (P[P_FRAME + FR_ORTHO] > 0 ? (realP)P[P_FRAME + FR_SCALE]
                                           : o->z * P[P_FRAME + FR_SCALE]);
  o->tau = r / o->b;
  o->in_cone = front && o->tau < 1;
  if (!ANY(o->in_cone)) return 0;
  const real s0 = sigmoid(-beta / gs);
  realP x = (Sq - beta - o->z) / gs, e = exp(-fabs(x));
  o->sig = x >= 0 ? 1 / (1 + e) : e / (1 + e);
  o->m = fmax(o->sig - s0, R(0)) / (1 - s0);
  o->v = 1 - o->m * (1 - o->tau);
  return 1;
}

// The occluder term of one entry of the run's tile list (a `continue` when the face counts at
// none of the run's lanes), as `o`: the loop body's start in soft_map_fwd and
// soft_map_bwd_texel (i0, j, qx, qy, Sq, valid and the buffers in scope).
#define LANES_OCCLUDER(entry, o)                                                          \
  int f = entry;                                                                          \
  if (!face_box_holds_run(boxes[f], i0, j)) continue;                                     \
  ScreenFace F = load_screen_face(f, vscreen, faces, fnormal);                            \
  LanesOccluder o;                                                                        \
  if (!lanes_occluder(qx, qy, Sq, valid, &F, P, &o)) continue;

inline int face_box_holds_run(int4 bb, int i0, int j) {
  return j >= bb.y && j <= bb.w && i0 + PPW - 1 >= bb.x && i0 <= bb.z;
}

// The lanes' pixel centres and values of a map at texels i0 .. i0 + PPW − 1 of row j (the
// last texel repeated past the row's end).
inline realP lanes_load(__global const real* a, int i0, int j, int W) {
  real t[PPW];
  for (int l = 0; l < PPW; ++l) t[l] = a[j * W + min(i0 + l, W - 1)];
  return VLOADP(0, t);
}

FORWARD_KERNEL void soft_map_fwd(__global const real4* vscreen, __global const int4* faces,
                                 __global const real4* fnormal, __global const int4* boxes,
                                 __global const real* P, int W, int H, __global const real* S,
                                 TEXEL_FACES, __global real* Pmap, __global real2* pen_sums) {
  int i0 = get_global_id(0) * PPW, j = get_global_id(1);
  if (i0 >= W || j >= H) return;
  const realP qx = lanes_x(i0, W, H);
  const real qy = (real)(H - 2 * j - 1) / H;
  const maskP valid = lanes_valid(i0, W);
  const realP Sq = lanes_load(S, i0, j, W);
  const real gp = P[P_GAMMA_P];
  realP num = 0, den = 0, shift = 1;
  int t = (i0 / tile) + (j / tile) * tiles_x;
  for (int k = 0; P[P_LIGHT_SIZE] > 0 && k < tile_counts[t]; ++k) {
    LANES_OCCLUDER(tile_faces[tile_offsets[t] + k], o)
    maskP lower = o.in_cone && o.v < shift;  // a new smallest v: rescale what was summed to it
    realP scale = exp(-gp * (shift - o.v));
    num = lower ? num * scale : num;
    den = lower ? den * scale : den;
    shift = lower ? o.v : shift;
    realP a = (1 - o.v) * exp(-gp * (o.v - shift));
    num += o.in_cone ? a * o.v : (realP)0;
    den += o.in_cone ? a : (realP)0;
  }
  realP lit = exp(-gp * (1 - shift));
  real Pj[PPW], shiftj[PPW], denj[PPW];
  VSTOREP((lit + num) / (lit + den), 0, Pj);
  VSTOREP(shift, 0, shiftj);
  VSTOREP(lit + den, 0, denj);
  for (int l = 0; l < PPW && i0 + l < W; ++l) {
    Pmap[j * W + i0 + l] = Pj[l];
    pen_sums[j * W + i0 + l] = (real2)(shiftj[l], denj[l]);
  }
}

// Backward, per texel: dL/dS_q and dL/dD_L (summed over texels on the host) from dL/dP_q.
BACKWARD_KERNEL void soft_map_bwd_texel(__global const real4* vscreen, __global const int4* faces,
                                        __global const real4* fnormal, __global const int4* boxes,
                                        __global const real* P, int W, int H,
                                        __global const real* S, TEXEL_FACES,
                                        __global const real* Pmap, __global const real2* pen_sums,
                                        __global const real* gP, __global real* gS,
                                        __global real* gDL) {
  int i0 = get_global_id(0) * PPW, j = get_global_id(1);
  if (i0 >= W || j >= H) return;
  const realP gPq = lanes_load(gP, i0, j, W);
  const maskP valid = lanes_valid(i0, W) && gPq != 0;
  realP gs = 0, gd = 0;
  if (ANY(valid)) {
    const realP qx = lanes_x(i0, W, H), Sq = lanes_load(S, i0, j, W);
    const realP Pq = lanes_load(Pmap, i0, j, W);
    const real qy = (real)(H - 2 * j - 1) / H;
    real shifts[PPW], dens[PPW];
    for (int l = 0; l < PPW; ++l) {
      real2 sums = pen_sums[j * W + min(i0 + l, W - 1)];
      shifts[l] = sums.x, dens[l] = sums.y;
    }
    const realP shift = VLOADP(0, shifts), den = VLOADP(0, dens);
    const real gp = P[P_GAMMA_P], DL = P[P_LIGHT_SIZE], gsp = P[P_GAMMA_S];
    const real gsig_scale = 1 / (gsp * (1 - sigmoid(-P[P_BETA] / gsp)));  // occluder_bwd's dm/dσ
    int t = (i0 / tile) + (j / tile) * tiles_x;
  for (int k = 0; P[P_LIGHT_SIZE] > 0 && k < tile_counts[t]; ++k) {
    LANES_OCCLUDER(tile_faces[tile_offsets[t] + k], o)
      // soft_map_dv and occluder_bwd (dL/dS_q and dL/dD_L only) on every lane.
      realP e = exp(-gp * (o.v - shift));
      realP a = (1 - o.v) * e, da = -e * (1 + gp * (1 - o.v));
      realP gv = gPq * (a + (o.v - Pq) * da) / den;
      realP gm = -gv * (1 - o.tau), gtau = gv * o.m;
      realP gsig = o.m > 0 ? gm * o.sig * (1 - o.sig) * gsig_scale : (realP)0;
      realP gb = -gtau * o.tau / o.b;
      gs += o.in_cone ? gsig + gb * DL * o.z / (Sq * Sq) : (realP)0;
      gd += o.in_cone ? gb * (Sq - o.z) / Sq : (realP)0;
    }
  }
  real gsj[PPW], gdj[PPW];
  VSTOREP(gs, 0, gsj);
  VSTOREP(gd, 0, gdj);
  for (int l = 0; l < PPW && i0 + l < W; ++l) {
    gS[j * W + i0 + l] = gsj[l];
    gDL[j * W + i0 + l] = gdj[l];
  }
}

// Which of texels i0 .. i0 + PPW − 1 of row j face F counts at (1, else 0): occluder_fwd's
// test on PPW lanes at once, which round as it does, so that soft_map_bwd_face runs its
// per-texel work only where occluder_fwd passes.
INLINE void lanes_counted(int i0, int j, int W, int H, const ScreenFace* F,
                          __global const real* S, __global const real* P, real* counts) {
  LanesOccluder o;
  if (!lanes_occluder(lanes_x(i0, W, H), (real)(H - 2 * j - 1) / H, lanes_load(S, i0, j, W),
                      lanes_valid(i0, W), F, P, &o))
    o.in_cone = 0;
  VSTOREP(o.in_cone ? (realP)1 : (realP)0, 0, counts);
}

// Backward, per face: dL/d(light-screen position, depth) of its corners, added to
// gface_screen (3F × real4) in a fixed texel order.
BACKWARD_KERNEL void soft_map_bwd_face(__global const real4* vscreen, __global const int4* faces,
                                       __global const real4* fnormal, __global const int4* boxes,
                                       __global const real* P, int nf, int W, int H,
                                       __global const real* S, __global const real* Pmap,
                                       __global const real2* pen_sums, __global const real* gP,
                                       __global real4* gface_screen) {
  int f = get_global_id(0);
  if (f >= nf) return;
  int4 bb = boxes[f];
  if (bb.x > bb.z) return;
  ScreenFace F = load_screen_face(f, vscreen, faces, fnormal);
  real2 gp[3] = {0, 0, 0};
  real gzk[3] = {0, 0, 0};
  real zero[3] = {0, 0, 0};
  for (int j = bb.y; j <= bb.w; ++j) {
    real counts[PPW];
    for (int i = bb.x; i <= bb.z; ++i) {
      int lane = (i - bb.x) % PPW;
      if (lane == 0) lanes_counted(i, j, W, H, &F, S, P, counts);
      if (counts[lane] == 0) continue;
      int tex = j * W + i;
      if (gP[tex] == 0) continue;
      real2 q = pixel_centre(i, j, W, H);
      Occluder o;
      if (!occluder_fwd(q, S[tex], &F, P, &o)) continue;
      real gz = 0, gd2 = 0, unused = 0, unused2 = 0;
      real gv = gP[tex] * soft_map_dv(&o, Pmap[tex], pen_sums[tex], P);
      occluder_bwd(S[tex], &o, P, gv, &unused, &unused2, &gz, &gd2);
      fragment_geometry_bwd(q, F.p, F.z, F.area, P, &o.fr, gd2, gz, zero, gp, gzk);
    }
  }
  for (int k = 0; k < 3; ++k) gface_screen[3 * f + k] += (real4)(gp[k], gzk[k], 0);
}
