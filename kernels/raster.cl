// Stage 3 — raster: soft coverage, perspective-correct depth, shading and softmax aggregation
// (SPEC §1–§2); backward: exact derivative of all of it (SPEC §5).
//
// Buffers (V vertices, F faces, N = W·H pixels, row 0 at the top):
//   vscreen, vworld  V × real4      from transform_fwd / the scene
//   faces            F × int4
//   fbbox, fnormal   F × int4/real4 from face_setup
//   albedo           3F × real4     albedo per face corner (per-face albedo repeats it)
//   P                per-view parameters (common/layout.h)
//   tile_offsets, tile_counts, tile_faces   from bin.cl (ignored when BRUTE_FORCE)
//   image            N × real4      (R, G, B, silhouette A)
//   aux              N × real4      (soft depth I_z, softmax max m, normaliser Z, Σ log(1−D))
//                                   — what the backward needs to undo the aggregation
// Forward launch: global (ceil(W/TILE)·TILE/PPW, ceil(H/TILE)·TILE), local (TILE/PPW, TILE):
// one work-group per tile; each work-item renders PPW consecutive pixels of one row.
// Backward launch: one work-item per face; it visits the pixels of its bounding box and sums
// its own gradient in a fixed order (a gather: no atomics, bit-reproducible).
#include "common/geometry.clh"
#include "common/shade.clh"

#ifndef TILE
#define TILE 16        // screen tile edge in pixels (must match bin.cl)
#endif
#ifndef PPW
#define PPW 1          // pixels per work-item along x; divides TILE
#endif
#ifndef BRUTE_FORCE
#define BRUTE_FORCE 0  // 1: every pixel visits every face (reference path for tests)
#endif

typedef struct {
  real2 p[3];   // screen positions
  real z[3];    // view depths
  real3 V[3];   // world positions
  real3 a[3];   // albedo at the corners
  real3 n;      // unit world normal (not yet turned to the camera)
  real area;    // signed screen area
} Face;

inline Face load_face(int f, __global const real4* vscreen, __global const real4* vworld,
                      __global const int4* faces, __global const real4* fnormal,
                      __global const real4* albedo) {
  Face F;
  int4 idx = faces[f];
  int id[3] = {idx.x, idx.y, idx.z};
  for (int k = 0; k < 3; ++k) {
    real4 s = vscreen[id[k]];
    F.p[k] = s.xy;
    F.z[k] = s.z;
    F.V[k] = vworld[id[k]].xyz;
    F.a[k] = albedo[3 * f + k].xyz;
  }
  F.n = fnormal[f].xyz;
  F.area = fnormal[f].w;
  return F;
}

inline real2 pixel_centre(int px, int py, int W, int H) {
  return (real2)((real)(2 * px + 1 - W) / H, (real)(H - 2 * py - 1) / H);
}

// Colour of the face at a fragment, with the facing sign it used.
inline real3 fragment_colour(const Face* F, const Fragment* fr, __global const real* P,
                             real* sign) {
  real3 X = fr->b[0] * F->V[0] + fr->b[1] * F->V[1] + fr->b[2] * F->V[2];
  real3 a = fr->b[0] * F->a[0] + fr->b[1] * F->a[1] + fr->b[2] * F->a[2];
  *sign = facing_sign(F->n, X, P);
  real shadow[P_MAX_LIGHTS];
  for (int i = 0; i < P_MAX_LIGHTS; ++i) shadow[i] = 1;
  return shade_fwd(X, *sign * F->n, a, shadow, P);
}

inline int depth_in_range(real z, __global const real* P) {
  return z >= P[P_NEAR] && z <= P[P_FAR];
}

__kernel __attribute__((reqd_work_group_size(TILE / PPW, TILE, 1)))
void raster_fwd(__global const real4* vscreen, __global const real4* vworld,
                __global const int4* faces, __global const int4* fbbox,
                __global const real4* fnormal, __global const real4* albedo,
                __global const real* P, int W, int H, int nf, int tiles_x,
                __global const int* tile_offsets, __global const int* tile_counts,
                __global const int* tile_faces, __global real4* image, __global real4* aux) {
  int px0 = get_global_id(0) * PPW, py = get_global_id(1);
  if (py >= H || px0 >= W) return;
  const real gamma = P[P_GAMMA], nearz = P[P_NEAR], farz = P[P_FAR];
  real m[PPW], Z[PPW], slog[PPW], accz[PPW];
  real3 acc[PPW];
  for (int j = 0; j < PPW; ++j) {
    m[j] = P[P_EPS];  // the background enters with z̃ = ε
    Z[j] = 1;
    acc[j] = p_vec3(P, P_BACKGROUND);
    accz[j] = farz;
    slog[j] = 0;
  }
#if BRUTE_FORCE
  int begin = 0, count = nf;
#else
  int tile = (px0 / TILE) + (py / TILE) * tiles_x;
  int begin = tile_offsets[tile], count = tile_counts[tile];
#endif
  for (int i = 0; i < count; ++i) {
#if BRUTE_FORCE
    int f = i;
#else
    int f = tile_faces[begin + i];
#endif
    int4 bb = fbbox[f];
    if (py < bb.y || py > bb.w || px0 + PPW - 1 < bb.x || px0 > bb.z) continue;
    Face F = load_face(f, vscreen, vworld, faces, fnormal, albedo);
    for (int j = 0; j < PPW; ++j) {
      int px = px0 + j;
      if (px >= W) break;
      Fragment fr;
      if (!fragment_fwd(pixel_centre(px, py, W, H), F.p, F.z, F.area, P, &fr)) continue;
      slog[j] += log1m_sigmoid(fr.u);
      if (!depth_in_range(fr.z, P)) continue;
      real zt = (farz - fr.z) / (farz - nearz);
      if (zt > m[j]) {  // online softmax: rescale what was summed to the new maximum
        real s = exp((m[j] - zt) / gamma);
        Z[j] *= s;
        acc[j] *= s;
        accz[j] *= s;
        m[j] = zt;
      }
      real sign;
      real3 C = fragment_colour(&F, &fr, P, &sign);
      real De = sigmoid(fr.u) * exp((zt - m[j]) / gamma);
      Z[j] += De;
      acc[j] += De * C;
      accz[j] += De * fr.z;
    }
  }
  for (int j = 0; j < PPW; ++j) {
    int px = px0 + j;
    if (px >= W) break;
    image[py * W + px] = (real4)(acc[j] / Z[j], 1 - exp(slog[j]));
    aux[py * W + px] = (real4)(accz[j] / Z[j], m[j], Z[j], slog[j]);
  }
}

// Backward. Inputs: image, aux (from raster_fwd), gimage N × real4 (dL/dR, dL/dG, dL/dB,
// dL/dA), gdepth N × real (dL/dI_z). Outputs per face corner (3F × real4): gface_screen
// (dL/d screen x, y, depth z), gface_world (dL/d world position), gface_albedo; and per face
// gface_light (F × (2·nlights + 1) real4: dL/d light position|direction, dL/d light colour, …,
// dL/d ambient).
__kernel void raster_bwd(__global const real4* vscreen, __global const real4* vworld,
                         __global const int4* faces, __global const int4* fbbox,
                         __global const real4* fnormal, __global const real4* albedo,
                         __global const real* P, int W, int H, int nf,
                         __global const real4* image, __global const real4* aux,
                         __global const real4* gimage, __global const real* gdepth,
                         __global real4* gface_screen, __global real4* gface_world,
                         __global real4* gface_albedo, __global real4* gface_light) {
  int f = get_global_id(0);
  if (f >= nf) return;
  const real gamma = P[P_GAMMA], nearz = P[P_NEAR], farz = P[P_FAR];
  const int nl = (int)P[P_NLIGHTS];
  real2 gp[3] = {0, 0, 0};
  real gz[3] = {0, 0, 0};
  real3 gV[3] = {0, 0, 0}, ga[3] = {0, 0, 0}, gn = 0;
  LightGrads gl;
  for (int i = 0; i < P_MAX_LIGHTS; ++i) gl.pos[i] = gl.color[i] = 0;
  gl.ambient = 0;

  int4 bb = fbbox[f];
  Face F;
  if (bb.x <= bb.z) F = load_face(f, vscreen, vworld, faces, fnormal, albedo);
  for (int py = bb.y; py <= bb.w; ++py) {
    for (int px = bb.x; px <= bb.z; ++px) {
      real2 q = pixel_centre(px, py, W, H);
      Fragment fr;
      if (!fragment_fwd(q, F.p, F.z, F.area, P, &fr)) continue;
      int pix = py * W + px;
      real4 img = image[pix], ax = aux[pix], gimg = gimage[pix];
      real D = sigmoid(fr.u);
      // Silhouette A = 1 − Π(1 − D): dA/du = (1 − A)·D, with 1 − A = exp(Σ log(1 − D)).
      real gu = gimg.w * exp(ax.w) * D;
      real gzf = 0, gb[3] = {0, 0, 0};
      if (depth_in_range(fr.z, P)) {
        real zt = (farz - fr.z) / (farz - nearz);
        real w = D * exp((zt - ax.y) / gamma) / ax.z;
        real sign;
        real3 C = fragment_colour(&F, &fr, P, &sign);
        real gI_z = gdepth[pix];
        real3 gI = gimg.xyz;
        // I = Σ w_f C_f + w_b C_bg with w_f ∝ D_f e^{z̃_f/γ}: dI/d(log w_f) = w_f (C_f − I).
        real G = dot(gI, C - img.xyz) + gI_z * (fr.z - ax.x);
        gu += w * (1 - D) * G;
        gzf = gI_z * w - w * G / gamma / (farz - nearz);
        real3 X = fr.b[0] * F.V[0] + fr.b[1] * F.V[1] + fr.b[2] * F.V[2];
        real3 a = fr.b[0] * F.a[0] + fr.b[1] * F.a[1] + fr.b[2] * F.a[2];
        real shadow[P_MAX_LIGHTS], gshadow[P_MAX_LIGHTS];
        for (int i = 0; i < P_MAX_LIGHTS; ++i) shadow[i] = 1, gshadow[i] = 0;
        real3 gX = 0, gnf = 0, gaf = 0;
        shade_bwd(X, sign * F.n, a, shadow, P, gI * w, &gX, &gnf, &gaf, gshadow, &gl);
        gn += sign * gnf;
        for (int k = 0; k < 3; ++k) {
          gb[k] = dot(gX, F.V[k]) + dot(gaf, F.a[k]);
          gV[k] += fr.b[k] * gX;
          ga[k] += fr.b[k] * gaf;
        }
      }
      fragment_bwd(q, F.p, F.z, F.area, P, &fr, gu, gzf, gb, gp, gz);
    }
  }
  if (bb.x <= bb.z) {  // n = normalize(cross(V1 − V0, V2 − V0))
    real3 e1 = F.V[1] - F.V[0], e2 = F.V[2] - F.V[0];
    real len = length(cross(e1, e2));
    real3 gnr = (gn - F.n * dot(F.n, gn)) / len;
    real3 ge1 = cross(e2, gnr), ge2 = cross(gnr, e1);
    gV[1] += ge1;
    gV[2] += ge2;
    gV[0] -= ge1 + ge2;
  }
  for (int k = 0; k < 3; ++k) {
    gface_screen[3 * f + k] = (real4)(gp[k], gz[k], 0);
    gface_world[3 * f + k] = (real4)(gV[k], 0);
    gface_albedo[3 * f + k] = (real4)(ga[k], 0);
  }
  __global real4* gL = gface_light + f * (2 * nl + 1);
  for (int i = 0; i < nl; ++i) {
    gL[2 * i] = (real4)(gl.pos[i], 0);
    gL[2 * i + 1] = (real4)(gl.color[i], 0);
  }
  gL[2 * nl] = (real4)(gl.ambient, 0);
}
