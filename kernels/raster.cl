// Stage 3 — raster: soft coverage, perspective-correct depth, shading and softmax aggregation
// (math.md §2–§3) for a camera or, with no lights, for a light's depth map; backward: the exact
// derivative of all of it (math.md §8).
//
// Three passes, so that shadow terms can be sampled between the second and the third:
//   raster_count      per pixel: softmax maxima, Σ log(1 − D), and a bound on the number of
//                     fragments to keep (those near the running maximum)
//   raster_fragments  per pixel: the kept fragments — (pixel, face) pairs whose aggregation
//                     weight D·e^{z̃/γ} is at least ε_w times the largest (the background's
//                     included) — with their weight, depth, shading terms and light-map
//                     coordinates, in face order
//   raster_resolve    per pixel: colour, silhouette and soft depth from the fragments and the
//                     shadow terms s (1 unless paper_lookups.cl has sampled them)
// Buffers (V vertices, F faces, N = W·H pixels, row 0 at the top, K fragments, nl lights):
//   vscreen, vworld  V × real4;  faces F × int4;  fbbox, fnormal F × int4/real4 (face_setup)
//   albedo           3F × real4 albedo per face corner
//   P                per-view parameters (common/layout.h)
//   tile_offsets, tile_counts, tile_faces   from bin.cl (ignored when BRUTE_FORCE)
//   pix_count, pix_offset, pix_n   N × int: fragment bound, first fragment, fragments kept
//   block_hits       ulong bits, per block of PPW pixels and tile-list entry (see TILE_BLOCKS)
//   face_kept        F × int, zeroed by the host: raster_fragments sets it where the face keeps a
//                    fragment at any pixel (an atomic OR: many blocks may), raster_bwd reads it
//   rec_face K × int; rec_frag K × real2 (D·e^{(z̃−m)/γ}, z)
//   rec_shade K·(1+nl) × real4 (ambient term, 0), then per light (direct term, 1 where the
//                    fragment faces the light, n·l > 0; else 0, its direct term 0 too, and
//                    pcf_sample looks nothing up for it); without shadows (every s is 1) K ×
//                    real4: the fragment's colour, their sum, alone (less to write and read)
//   rec_light K·nl × real4 (μx, μy, d, s): light-map coordinates, light depth, shadow term
//   rec_light2 K·nl × real4 (∇_μ d, 0, 0): receiver-plane depth gradient (soft shadows)
//                    Both only for a view with shadows (P_SHADOWS): without, s is 1 and
//                    neither is written nor read.
//   image N × real4 (R, G, B, silhouette A); aux N × real4 (I_z, m, Z, Σ log(1 − D));
//   depth N × real (I_z again, densely, as the shadow map S when rendering from a light)
//   cover N × real (A again, densely, as the map's caster coverage when rendering from a light)
// Launch of count/fragments: global (ceil(W/TILE)·TILE/BLOCK_W, ceil(H/TILE)·TILE/BLOCK_H),
// local (TILE/BLOCK_W, TILE/BLOCK_H): one work-group per tile, a block of PPW pixels per
// work-item (below).
// resolve and resolve_bwd: one work-item per pixel. raster_bwd: FACE_LANES work-items per face
// (a work-group; 1 on CPUs), which visit the pixels of its bounding box and sum its gradient in
// a fixed order (a gather: no atomics, bit-reproducible; see raster_bwd for its bands).
#include "common/geometry.clh"
#include "common/shade.clh"

#ifndef TILE
#define TILE 16        // screen tile edge in pixels (must match bin.cl)
#endif
#ifndef FACE_LANES
#define FACE_LANES 1   // work-items per face in raster_bwd (a power of two)
#endif
#define MIN_BAND_ROWS 8  // a work-item of raster_bwd walks at least this many rows of a box
#ifndef PPW
#define PPW 1          // pixels per work-item, a power of two up to 16; TILE holds whole blocks
#endif
#ifndef BLOCK_W
#define BLOCK_W 1      // width of a work-item's block of PPW pixels (below); divides PPW
#endif
#ifndef BRUTE_FORCE
#define BRUTE_FORCE 0  // 1: every pixel visits every face (reference path for tests)
#endif

#include "common/lanes.clh"
#include "common/raster_face.clh"
#include "common/raster_tiles.clh"
#include "common/face_sums.clh"

KERNEL_BODY void raster_count_body(int px0, int py0, int lx, int ly, __global const real4* vscreen,
                                   __global const int4* faces, __global const int4* fbbox,
                                   __global const real4* fnormal, __global const real* P, int W,
                                   int H, int nf, TILE_ARGS, __global real4* aux,
                                   __global int* pix_count, __global ulong* block_hits) {
  if (py0 >= H || px0 >= W) return;
  const real weight_log = P[P_WEIGHT_LOG];
  VIEW_RECIPROCALS(P)
  realP qy;
  maskP valid;
  const realP qx = block_lanes(px0, py0, W, H, &qy, &valid);
  // m: running max of z̃ (stabilises the exponentials); M: running max of the log-weights
  // log D + (z̃ − m)/γ, the background's (ε − m)/γ included, relative to the running m.
  realP m = P[P_EPS], M = 0, slog = 0, count = 0;
  FACE_LIST_BEGIN(px0, py0)
  __global ulong* hits_out = BLOCK_HITS_BEGIN(block_hits, lx, ly);
  for (int i0 = 0; i0 < list_count; i0 += 64) {
    ulong hits = 0;
    for (int i = i0; i < min(i0 + 64, list_count); ++i) {
      int f = FACE_AT(i);
      FACE_IN_BLOCK(f)
      LANES_SHAPE
      slog += covered ? -(fmax(u, R(0)) + log1p_e) : (realP)0;
      // Behind the running maxima everywhere (M ≤ 0): neither counted nor raising m or M.
      if (!lanes_may_weigh(&sf, m, M - weight_log - 1, P, inv_gamma, inv_depth_range)) continue;
      LANES_DEPTH
      if (!ANY(in_range)) continue;
      maskP higher = in_range && zt > m;
      M = higher ? M - (zt - m) * inv_gamma : M;
      m = higher ? zt : m;
      realP lw = log_D + (zt - m) * inv_gamma;
      M = in_range ? fmax(M, lw) : M;
      // The running maxima never exceed the final ones, so this counts a superset of the
      // fragments raster_fragments keeps (one e-fold of margin absorbs rounding).
      maskP counted = in_range && lw >= M - weight_log - 1;
      count += counted ? (realP)1 : (realP)0;
      if (ANY(counted)) hits |= (ulong)1 << (i - i0);
    }
    if (!BRUTE_FORCE) HIT_WORD(hits_out, i0) = hits;
  }
  real ms[PPW], Ms[PPW], slogs[PPW], counts[PPW];
  VSTOREP(m, 0, ms);
  VSTOREP(M, 0, Ms);
  VSTOREP(slog, 0, slogs);
  VSTOREP(count, 0, counts);
  for (int j = 0; j < PPW; ++j) {
    if (!block_lane_inside(px0, py0, j, W, H)) continue;
    aux[block_pixel(px0, py0, j, W, H)] = (real4)(Ms[j], ms[j], 0, slogs[j]);
    pix_count[block_pixel(px0, py0, j, W, H)] = (int)counts[j];
  }
}

FORWARD_KERNEL TILE_GROUP
void raster_count(__global const real4* vscreen, __global const int4* faces,
                  __global const int4* fbbox, __global const real4* fnormal,
                  __global const real* P, int W, int H, int nf, TILE_ARGS,
                  __global real4* aux, __global int* pix_count, __global ulong* block_hits) {
  raster_count_body(get_global_id(0) * BLOCK_W, get_global_id(1) * BLOCK_H, get_local_id(0),
                    get_local_id(1), vscreen, faces, fbbox, fnormal, P, W, H, nf, TILE_ARG_NAMES,
                    aux, pix_count, block_hits);
}

KERNEL_BODY void raster_fragments_body(int px0, int py0, int lx, int ly,
                                       __global const real4* vscreen, __global const real4* vworld,
                                       __global const int4* faces, __global const int4* fbbox,
                                       __global const real4* fnormal, __global const real4* albedo,
                                       __global const real* P, int W, int H, int nf, TILE_ARGS,
                                       __global const real4* aux, __global const int* pix_count,
                                       __global const ulong* block_hits,
                                       __global const int* pix_offset, __global int* pix_n,
                                       __global int* rec_face, __global real2* rec_frag,
                                       __global real4* rec_shade, __global real4* rec_light,
                                       __global real4* rec_light2, __global int* face_kept) {
  if (py0 >= H || px0 >= W) return;
  VIEW_RECIPROCALS(P)
  const int nl = (int)P[P_NLIGHTS], shadowed = P[P_SHADOWS] > 0;
  realP qy;
  maskP valid;
  const realP qx = block_lanes(px0, py0, W, H, &qy, &valid);
  real ms[PPW], keeps[PPW];
  int n[PPW], first[PPW], bound[PPW];
  for (int j = 0; j < PPW; ++j) {
    int pix = block_pixel(px0, py0, j, W, H);
    real4 ax = aux[pix];
    ms[j] = ax.y;
    keeps[j] = ax.x - P[P_WEIGHT_LOG];
    n[j] = 0;
    first[j] = pix_offset[pix];
    bound[j] = pix_count[pix];
  }
  const realP m = VLOADP(0, ms), keep = VLOADP(0, keeps);
  FACE_LIST_BEGIN(px0, py0)
  __global const ulong* hits = BLOCK_HITS_BEGIN(block_hits, lx, ly);
  for (int i = next_hit(hits, -1, list_count); i < list_count;
       i = next_hit(hits, i, list_count)) {
    int f = FACE_AT(i);
    FACE_IN_BLOCK(f)
    if (!lanes_may_weigh(&sf, m, keep, P, inv_gamma, inv_depth_range)) continue;
    LANES_SHAPE
    LANES_DEPTH
    realP lw = log_D + (zt - m) * inv_gamma;
    const uint kept = mask_bits(in_range && lw >= keep);  // lane j's bit: a kept fragment
    if (kept == 0) continue;
    atomic_or(&face_kept[f], 1);
    real lws[PPW], zs[PPW], weights[PPW];
    VSTOREP(lw, 0, lws);
    // The scalar exp of every lane, unrolled: the compiler evaluates the lanes' copies as one
    // vector (the same bits per lane), where one kept lane at a time had been a serial chain.
#pragma unroll
    for (int j = 0; j < PPW; ++j) weights[j] = exp(lws[j]);
    VSTOREP(zq, 0, zs);
    Face F = load_face(f, vscreen, vworld, faces, fnormal, albedo);
    FragmentTerms t;
    fragment_terms(b, &F, shadowed, P, &t);
    for (uint lanes = kept; lanes != 0; lanes &= lanes - 1) {  // the kept lanes: their records
      const int j = lowest_bit(lanes);
      if (n[j] >= bound[j]) continue;  // (the bound holds by construction)
      write_record(first[j] + n[j]++, j, f, weights[j], zs[j], &t, nl, shadowed, rec_face,
                   rec_frag, rec_shade, rec_light, rec_light2);
    }
  }
  for (int j = 0; j < PPW; ++j) {
    if (!block_lane_inside(px0, py0, j, W, H)) continue;
    pix_n[block_pixel(px0, py0, j, W, H)] = n[j];
    if (shadowed)
      close_record_list(first[j] + n[j], first[j] + bound[j], nl, rec_face, rec_frag, rec_light,
                        rec_light2);
  }
}

FORWARD_KERNEL TILE_GROUP
void raster_fragments(__global const real4* vscreen, __global const real4* vworld,
                      __global const int4* faces, __global const int4* fbbox,
                      __global const real4* fnormal, __global const real4* albedo,
                      __global const real* P, int W, int H, int nf, TILE_ARGS,
                      __global const real4* aux, __global const int* pix_count,
                      __global const ulong* block_hits, __global const int* pix_offset,
                      __global int* pix_n,
                      __global int* rec_face, __global real2* rec_frag,
                      __global real4* rec_shade, __global real4* rec_light,
                      __global real4* rec_light2, __global int* face_kept) {
  raster_fragments_body(get_global_id(0) * BLOCK_W, get_global_id(1) * BLOCK_H, get_local_id(0),
                        get_local_id(1), vscreen, vworld, faces, fbbox, fnormal, albedo, P, W, H,
                        nf, TILE_ARG_NAMES, aux, pix_count, block_hits, pix_offset, pix_n,
                        rec_face, rec_frag, rec_shade, rec_light, rec_light2, face_kept);
}

// The shadow term s of fragment r for light l: 1 in a view without shadows.
inline real shadow_term(int r, int l, int nl, __global const real* P,
                        __global const real4* rec_light) {
  return P[P_SHADOWS] > 0 ? rec_light[r * nl + l].w : 1;
}

inline real3 fragment_colour(int r, int nl, __global const real* P,
                             __global const real4* rec_shade, __global const real4* rec_light) {
  if (P[P_SHADOWS] <= 0) return rec_shade[r].xyz;  // the sum itself (write_record)
  real3 c = rec_shade[r * (1 + nl)].xyz;
  for (int l = 0; l < nl; ++l)
    c += shadow_term(r, l, nl, P, rec_light) * rec_shade[r * (1 + nl) + 1 + l].xyz;
  return c;
}

// e^x, answering without the call what most of raster_resolve's pixels ask: e^0 = 1, and 0
// below −800, where e^x underflows to 0 in double and float alike (exp gives both exactly so).
inline real exp_or_ends(real x) { return x == 0 ? 1 : x < -800 ? 0 : exp(x); }

FORWARD_KERNEL void raster_resolve(__global const real* P, int W, int H,
                                   __global const int* pix_offset, __global const int* pix_n,
                                   __global const real2* rec_frag, __global const real4* rec_shade,
                                   __global const real4* rec_light, __global real4* image,
                                   __global real4* aux, __global real* depth,
                                   __global real* cover) {
  int pix = get_global_id(0);
  if (pix >= W * H) return;
  const int nl = (int)P[P_NLIGHTS];
  real4 ax = aux[pix];
  real Z = exp_or_ends((P[P_EPS] - ax.y) / P[P_GAMMA]);  // the background's weight
  real3 acc = Z * p_vec3(P, P_BACKGROUND);
  real accz = Z * P[P_FAR];
  for (int r = pix_offset[pix]; r < pix_offset[pix] + pix_n[pix]; ++r) {
    real2 fr = rec_frag[r];
    Z += fr.x;
    acc += fr.x * fragment_colour(r, nl, P, rec_shade, rec_light);
    accz += fr.x * fr.y;
  }
  real A = 1 - exp_or_ends(ax.w);
  image[pix] = (real4)(acc / Z, A);
  aux[pix] = (real4)(accz / Z, ax.y, Z, ax.w);
  depth[pix] = accz / Z;
  cover[pix] = A;
}

// Backward of raster_resolve. gimage N × real4 (dL/dR, dL/dG, dL/dB, dL/dA), gdepth N × real
// (dL/dI_z). Writes rec_wg K × real2 (w, G): the fragment's normalised weight w and
// G = gI·(C − I) + gI_z·(z − I_z), so that dL/d(log weight) = w·G; with shadows, rec_lgrad
// K·nl × real4 (dL/ds, 0, 0, 0), which the shadow backward completes; and gcover N × real,
// dL/dA·(1 − A) with 1 − A = exp(Σ log(1 − D)), which raster_bwd would otherwise recompute for
// every face of the pixel.
BACKWARD_KERNEL void raster_resolve_bwd(__global const real* P, int W, int H,
                                        __global const int* pix_offset, __global const int* pix_n,
                                        __global const real2* rec_frag,
                                        __global const real4* rec_shade,
                                        __global const real4* rec_light,
                                        __global const real4* image, __global const real4* aux,
                                        __global const real4* gimage, __global const real* gdepth,
                                        __global real2* rec_wg, __global real4* rec_lgrad,
                                        __global real* gcover) {
  int pix = get_global_id(0);
  if (pix >= W * H) return;
  const int nl = (int)P[P_NLIGHTS];
  real3 I = image[pix].xyz, gI = gimage[pix].xyz;
  real Iz = aux[pix].x, Z = aux[pix].z, gz = gdepth[pix];
  gcover[pix] = gimage[pix].w * exp(aux[pix].w);
  for (int r = pix_offset[pix]; r < pix_offset[pix] + pix_n[pix]; ++r) {
    real2 fr = rec_frag[r];
    real w = fr.x / Z;
    real3 C = fragment_colour(r, nl, P, rec_shade, rec_light);
    rec_wg[r] = (real2)(w, dot(gI, C - I) + gz * (fr.y - Iz));
    for (int l = 0; P[P_SHADOWS] > 0 && l < nl; ++l)
      rec_lgrad[r * nl + l] = (real4)(w * dot(gI, rec_shade[r * (1 + nl) + 1 + l].xyz), 0, 0, 0);
  }
}

// The fragment of face f at pixel pix, if it was kept: binary search of the pixel's list,
// which is in face order. −1 if absent.
inline int find_fragment(int pix, int f, __global const int* pix_offset,
                         __global const int* pix_n, __global const int* rec_face) {
  int lo = pix_offset[pix], hi = lo + pix_n[pix];
  while (lo < hi) {
    int mid = (lo + hi) / 2;
    if (rec_face[mid] < f) lo = mid + 1;
    else hi = mid;
  }
  return lo < pix_offset[pix] + pix_n[pix] && rec_face[lo] == f ? lo : -1;
}

// Backward of count/fragments/resolve and of the shading, per face. Inputs: gcover, gimage (its
// .w is dL/dA), rec_wg and rec_lgrad (the latter as completed by the shadow backward:
// (dL/ds, dL/dμx, dL/dμy, dL/dd)), rec_lgrad2 (dL/d∇_μ d, soft shadows). Outputs per face
// corner (3F × real4): gface_screen (dL/d screen x, y, depth z), gface_world (dL/d world
// position), gface_albedo; per face
// gface_light F × (6·nl + 1) real4: dL/d light position|direction and dL/d light colour for
// each light, dL/d ambient, then dL/d(eye, fwd, right, up) of each light's frame.
// Through the shading of kept fragment r (weight w, colour gradient gc = dL/dI·w): adds to the
// world, normal, albedo and light sums, and returns in gb dL/d(barycentric) of the fragment.
INLINE void fragment_shading_bwd(int r, int nl, const Fragment* fr, const Face* F,
                                 const ReceiverFace* rf, int receiver_plane, real3 gc,
                                 __global const real* P, __global const real4* rec_light,
                                 __global const real4* rec_lgrad, __global const real4* rec_lgrad2,
                                 real* gb, FaceSums* s) {
  real3 X = fr->b[0] * F->V[0] + fr->b[1] * F->V[1] + fr->b[2] * F->V[2];
  real3 a = fr->b[0] * F->a[0] + fr->b[1] * F->a[1] + fr->b[2] * F->a[2];
  real sign = facing_sign(F->n, X, P);
  real sh[P_MAX_LIGHTS];
  for (int l = 0; l < nl; ++l) sh[l] = shadow_term(r, l, nl, P, rec_light);
  real3 gX = 0, gnf = 0, gaf = 0;
  shade_bwd(X, sign * F->n, a, sh, P, gc, &gX, &gnf, &gaf, &s->gl);
  for (int l = 0; P[P_SHADOWS] > 0 && l < nl; ++l) {
    // s depends on X through (μ, d), and for soft shadows on the face's plane (∇_μ d).
    real3 g = rec_lgrad[r * nl + l].yzw;
    if (receiver_plane)
      g.z += receiver_gradient_bwd(l, &rf[l], F->V, rec_light[r * nl + l].z,
                                   rec_lgrad2[r * nl + l].xy, P, s->gV, &s->gframe[l]);
    gX += light_project_bwd(l, X, g, P, &s->gframe[l]);
  }
  s->gn += sign * gnf;
  for (int k = 0; k < 3; ++k) {
    gb[k] = dot(gX, F->V[k]) + dot(gaf, F->a[k]);
    s->gV[k] += fr->b[k] * gX;
    s->ga[k] += fr->b[k] * gaf;
  }
}

// Whether pixel pix has a gradient (in a light's view, a texel that a lookup window reaches):
// where it has none, every term of pixel_face_bwd is a product with one of these or with dL/ds,
// which is 0 too, and it adds nothing.
inline int pixel_has_gradient(int pix, __global const real4* gimage, __global const real* gdepth) {
  real4 g = gimage[pix];
  return g.x != 0 || g.y != 0 || g.z != 0 || g.w != 0 || gdepth[pix] != 0;
}

// Whether a pixel of rows y0 … y1 of box bb has a gradient that reaches the face: any, where it
// kept a fragment somewhere (`kept`), else one through its coverage alone (gcover: the face is
// hidden, its weights cut off everywhere). A face whose rows have none (most of a light's view,
// where the lookups' windows are flat, and the faces behind others) skips their shapes.
inline int rows_have_gradient(int4 bb, int y0, int y1, int W, int kept,
                              __global const real* gcover, __global const real4* gimage,
                              __global const real* gdepth) {
  for (int py = y0; py <= y1; ++py)
    for (int px = bb.x; px <= bb.z; ++px)
      if (kept ? pixel_has_gradient(py * W + px, gimage, gdepth) : gcover[py * W + px] != 0)
        return 1;
  return 0;
}

// The backward of one face at one pixel of its box (lane `lane` of `block`), added to s; `kept`:
// whether the face kept a fragment at any pixel (else none is searched for).
INLINE void pixel_face_bwd(int px, int py, int lane, int f, int kept, const BlockLanes* block,
                           const Face* F, const ReceiverFace* rf, int receiver_plane,
                           __global const real* P, int W, int H, __global const real* gcover,
                           __global const real4* gimage, __global const real* gdepth,
                           __global const int* pix_offset, __global const int* pix_n,
                           __global const int* rec_face, __global const real4* rec_light,
                           __global const real2* rec_wg, __global const real4* rec_lgrad,
                           __global const real4* rec_lgrad2, FaceSums* s) {
  const int nl = (int)P[P_NLIGHTS];
  int pix = py * W + px;
  if (!pixel_has_gradient(pix, gimage, gdepth)) return;
  real4 gimg = gimage[pix];
  // Only a kept fragment (its depth within [near, far]) has weight and shading terms; a
  // fragment that was not kept, under a silhouette whose 1 − A underflowed to 0 (most of
  // a dense mesh's pixels), has no gradient: every term below would be a product with 0.
  int r = kept ? find_fragment(pix, f, pix_offset, pix_n, rec_face) : -1;
  real gc = gcover[pix];
  if (r < 0 && gc == 0) return;
  real2 q = pixel_centre(px, py, W, H);
  Fragment fr;
  lane_fragment(block, lane, &fr);
  real D = block->D[lane];
  // Silhouette A = 1 − Π(1 − D): dA/du = (1 − A)·D.
  real gu = gc * D;
  real gzf = 0, gb[3] = {0, 0, 0};
  if (r >= 0) {
    fragment_depth(F->z, P, &fr);
    real2 wg = rec_wg[r];
    real w = wg.x, G = wg.y;
    // The weight is D·e^{z̃/γ}/Z: d(log weight)/du = 1 − D, d/dz̃ = 1/γ.
    gu += w * (1 - D) * G;
    gzf = gdepth[pix] * w - w * G / P[P_GAMMA] / (P[P_FAR] - P[P_NEAR]);
    // Through the shading, only with a colour gradient (never in a light's view): without,
    // each term is a product with dL/dI or with dL/ds (then 0 too), so the sums would only
    // add zeros to sums that start at +0, which changes no bit.
    if (gimg.x != 0 || gimg.y != 0 || gimg.z != 0)
      fragment_shading_bwd(r, nl, &fr, F, rf, receiver_plane, gimg.xyz * w, P, rec_light,
                           rec_lgrad, rec_lgrad2, gb, s);
  }
  fragment_bwd(q, F->p, F->z, F->area, P, &fr, gu, gzf, gb, s->gp, s->gz);
}

// With FACE_LANES > 1 a face's bands add their sums at barriers: its body is inlined.
#if FACE_LANES > 1
#define RASTER_BWD_BODY INLINED_KERNEL_BODY
#else
#define RASTER_BWD_BODY KERNEL_BODY
#endif

RASTER_BWD_BODY void raster_bwd_body(int id, __local real4* sum, __global const real4* vscreen,
                                     __global const real4* vworld, __global const int4* faces,
                                     __global const int4* fbbox, __global const real4* fnormal,
                                     __global const real4* albedo, __global const real* P, int W,
                                     int H, int nf, __global const real* gcover,
                                     __global const real4* gimage, __global const real* gdepth,
                                     __global const int* pix_offset, __global const int* pix_n,
                                     __global const int* face_kept, __global const int* rec_face,
                                     __global const real4* rec_light, __global const real2* rec_wg,
                                     __global const real4* rec_lgrad,
                                     __global const real4* rec_lgrad2,
                                     __global real4* gface_screen, __global real4* gface_world,
                                     __global real4* gface_albedo, __global real4* gface_light) {
  // A GPU waits for a launch's longest work-item, and a face as large as the image (a ground
  // plane) is 65536 pixels for one: with FACE_LANES > 1 the face's lanes take bands of at least
  // MIN_BAND_ROWS rows of its box each and add their sums in a fixed order. A box of one band
  // is walked by the face's first work-item alone, as with FACE_LANES = 1.
  const int f = id / FACE_LANES, band = id % FACE_LANES;
  if (f >= nf) return;
  const int nl = (int)P[P_NLIGHTS];
  FaceSums s;
  face_sums_zero(&s, nl);
  int4 bb = fbbox[f];
  const int rows = bb.w - bb.y + 1;
  const int band_rows = max(MIN_BAND_ROWS, (rows + FACE_LANES - 1) / FACE_LANES);
  const int y0 = bb.y + band * band_rows, y1 = min(bb.w, y0 + band_rows - 1);
  const Face F = load_face(f, vscreen, vworld, faces, fnormal, albedo);
  ReceiverFace rf[P_MAX_LIGHTS];  // the face's receiver plane in each light's view
  const int receiver_plane = P[P_SHADOWS] > 0 && P[P_RECEIVER_PLANE] > 0;
  const int kept = face_kept[f];
  const int active = rows_have_gradient(bb, y0, y1, W, kept, gcover, gimage, gdepth);
  if (active)
    for (int l = 0; receiver_plane && l < nl; ++l) rf[l] = receiver_face(l, F.V, P);
  // The box's pixels in rows, their shape computed a block of PPW at a time: as wide as the box
  // (a power of two), and as many rows tall as that leaves lanes, or one row of PPW.
  const int cols = bb.z - bb.x + 1;
  int bw = PPW;
  while (bw > 1 && bw / 2 >= cols) bw /= 2;
  const int bh = cols <= bw ? PPW / bw : 1;
  BlockLanes block;
  for (int py = y0; active && py <= y1; ++py) {
    for (int px = bb.x; px <= bb.z; ++px) {
      int lane = ((py - y0) & (bh - 1)) * bw + ((px - bb.x) & (bw - 1));  // powers of two
      if (lane == 0) lanes_block(px, py, bw, W, H, &F, P, &block);
      if (block.reach[lane] == 0) continue;
      pixel_face_bwd(px, py, lane, f, kept, &block, &F, rf, receiver_plane, P, W, H, gcover,
                     gimage, gdepth, pix_offset, pix_n, rec_face, rec_light, rec_wg, rec_lgrad,
                     rec_lgrad2, &s);
    }
  }
#if FACE_LANES > 1 && defined(BACKWARD_KERNELS)
  if (rows > band_rows) face_sums_across_bands(&s, nl, sum, band);  // alike for a face's items
#endif
  if (band > 0) return;
  store_face_sums(f, nl, bb.x <= bb.z, &F, &s, gface_screen, gface_world, gface_albedo,
                  gface_light);
}

BACKWARD_KERNEL void raster_bwd(__global const real4* vscreen, __global const real4* vworld,
                                __global const int4* faces, __global const int4* fbbox,
                                __global const real4* fnormal, __global const real4* albedo,
                                __global const real* P, int W, int H, int nf,
                                __global const real* gcover, __global const real4* gimage,
                                __global const real* gdepth, __global const int* pix_offset,
                                __global const int* pix_n, __global const int* face_kept,
                                __global const int* rec_face,
                                __global const real4* rec_light, __global const real2* rec_wg,
                                __global const real4* rec_lgrad, __global const real4* rec_lgrad2,
                                __global real4* gface_screen, __global real4* gface_world,
                                __global real4* gface_albedo, __global real4* gface_light) {
#if FACE_LANES > 1 && defined(BACKWARD_KERNELS)
  __local real4 sum[FACE_LANES];
#else
  __local real4* sum = 0;
#endif
  raster_bwd_body(get_global_id(0), sum, vscreen, vworld, faces, fbbox, fnormal, albedo, P, W, H,
                  nf, gcover, gimage, gdepth, pix_offset, pix_n, face_kept, rec_face, rec_light,
                  rec_wg, rec_lgrad, rec_lgrad2, gface_screen, gface_world, gface_albedo,
                  gface_light);
}
