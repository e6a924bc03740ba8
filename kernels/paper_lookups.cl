// Stage 5 (paper model) — lookups: the shadow term s of every kept fragment for one light
// (math.md §6, §8.3; hard shadows, eq. 7: filter then compare; soft shadows with the map P of
// stage 4, paper_soft_map.cl), forward and backward, with Gaussian-weighted sampling
// of the light's shadow map S:
//   truncated  g' = max(0, g − ε_λ) over the window of radius R = sqrt(2σ_s·ln(1/ε_λ)),
//              one work-item per fragment (shadow_sample*), per texel (shadow_gather)
//   exact      g over the whole map; since g_ij = gx_i·gy_j the sums are matrix products
//              (exact_* kernels here, the products by paper_hard_exact.cl, which skips the weights
//              that are exactly 0, or by CLBlast's GEMM)
// Buffers (K fragments, nl lights, this light l, map W_s × H_s row-major, row 0 at the top):
//   rec_light  K·nl × real4 (μx, μy, d, s): s is written here
//   rec_light2 K·nl × real4: truncated hard shadows write (·, ·, v, Σg') to .zw, the filtered
//              depth and the filter's sum, which the backward reads instead of summing again
//   rec_shade  K·(1+nl) × real4 (raster.cl): shadow_sample, soft_sample and exact_weights read
//              each light's flag, 0 where the fragment faces away from it
//   rec_lgrad  K·nl × real4: in (dL/ds, ·, ·, ·); out (dL/dv / Σg, dL/dμx, dL/dμy, dL/dd),
//              where v is the filtered depth
//   S          W_s·H_s × real (the light's soft depth map); gS the same (its gradient)
// Launch: one work-item per fragment (shadow_sample, shadow_sample_bwd, shadow_boxes, soft_*,
// exact_*), one per ROW texels of GATHER_ROWS rows (shadow_gather, soft_gather).

#include "common/window.clh"

// Filtered depth v = Σ g'·S / Σ g'; returns 0 in `*norm` if no texel has weight.
INLINE real filter_depth(real2 mu, Window w, __global const real* P, __global const real* S,
                         int Wm, real* norm) {
  real ss = P[P_SIGMA_S];
  realR sum = 0, acc = 0;
  Columns c;
  columns_init(&c, w, mu, ss);
  w = nonzero_part(w, mu, ss);
  for (int j = w.y0; j <= w.y1; ++j) {
    real gy = row_weight(&c, j, mu.y, ss);
    for (int i0 = w.x0; i0 <= w.x1; i0 += ROW) {
      realR g = window_row(&c, i0, w.x1, gy, mu, ss, w.eps);
      sum += g;
      acc += g * loadR(S, j * Wm + i0, min(ROW, Wm - i0));
    }
  }
  *norm = hsumR(sum);
  return *norm > 0 ? hsumR(acc) / *norm : 0;
}

inline real compare(real v, real d, __global const real* P) {
  return sigmoid((v - d + P[P_BETA]) / P[P_GAMMA_S]);
}

// A fragment facing away from the light (faces_away_in_map) gets s = 1 without a lookup where
// the texel nearest its μ weighs g' > 0 (P_NEAREST_TEXEL_COUNTS, from σ_s and ε_λ), so that
// Σg' > 0: of v and Σg' its backward reads only whether Σg' > 0.
FORWARD_KERNEL void shadow_sample(__global const real* P, int nrec, int light, int nl, int Wm,
                                  int Hm, __global const real* S, __global const real4* rec_shade,
                                  __global real4* rec_light, __global real4* rec_light2) {
  int r = get_global_id(0);
  if (r >= nrec) return;
  real4 x = rec_light[r * nl + light];
  if (faces_away_in_map(x.xy, Wm, Hm, rec_shade, r, nl, light) && P[P_NEAREST_TEXEL_COUNTS] > 0) {
    rec_light[r * nl + light].w = 1;
    rec_light2[r * nl + light].zw = (real2)(x.z, 1);
    return;
  }
  Window w = sample_window(x.xy, P, Wm, Hm);
  real norm = 0, v = w.x0 <= w.x1 ? filter_depth(x.xy, w, P, S, Wm, &norm) : 0;
  rec_light[r * nl + light].w = norm > 0 ? compare(v, x.z, P) : 1;
  rec_light2[r * nl + light].zw = (real2)(v, norm);
}

BACKWARD_KERNEL void shadow_sample_bwd(__global const real* P, int nrec, int light, int nl, int Wm,
                                       int Hm, __global const real* S,
                                       __global const real4* rec_light,
                                       __global const real4* rec_light2, __global real4* rec_lgrad) {
  int r = get_global_id(0);
  if (r >= nrec) return;
  real4 x = rec_light[r * nl + light];
  real gs = rec_lgrad[r * nl + light].x;
  real v = rec_light2[r * nl + light].z, norm = rec_light2[r * nl + light].w;
  if (norm <= 0) {
    rec_lgrad[r * nl + light] = 0;
    return;
  }
  real gv = gs * x.w * (1 - x.w) / P[P_GAMMA_S];
  if (gv == 0) {  // dL/ds = 0, or the compare saturated (s rounds to 1): nothing reaches μ
    rec_lgrad[r * nl + light] = (real4)(gv / norm, 0, 0, -gv);
    return;
  }
  // dv/dμ = Σ ∂g'/∂μ·(S − v)/Σg', with ∂g'/∂μx = g·(i − μx)/σ_s where g' > 0.
  realR dvx = 0, dvy = 0;
  real ss = P[P_SIGMA_S];
  Window w = sample_window(x.xy, P, Wm, Hm);
  Columns c;
  columns_init(&c, w, x.xy, ss);
  w = nonzero_part(w, x.xy, ss);
  for (int j = w.y0; j <= w.y1; ++j) {
    real gy = row_weight(&c, j, x.y, ss);
    for (int i0 = w.x0; i0 <= w.x1; i0 += ROW) {
      realR lam = window_row(&c, i0, w.x1, gy, x.xy, ss, w.eps);
      realR g = select((realR)0, lam + w.eps, lam > 0);  // g where g' > 0
      realR t = g * (loadR(S, j * Wm + i0, min(ROW, Wm - i0)) - v);
      dvx += t * ((real)i0 + LANER - x.x);
      dvy += t * (j - x.y);
    }
  }
  real2 dv = (real2)(hsumR(dvx), hsumR(dvy)) / (norm * ss);
  rec_lgrad[r * nl + light] = (real4)(gv / norm, gv * dv, -gv);
}

// Each fragment's texel bucket (texel_box, window.clh), for the gathers below, which find the
// fragments whose window can cover a texel in the buckets within the window radius. Its
// gradient for the gathers is its gather scale (rec_lgrad.x as the lookups' backward left it):
// ±0 where it faces away from the light or lies outside the loss, and such a fragment, left
// out of the buckets, changes no bit.
BACKWARD_KERNEL void shadow_boxes(__global const real* P, int nrec, int light, int nl, int Wm,
                                  int Hm, __global const real4* rec_light,
                                  __global const real4* rec_lgrad, __global int4* boxes) {
  int r = get_global_id(0);
  if (r >= nrec) return;
  const int at = r * nl + light;
  boxes[r] = texel_box(rec_light[at].xy, Wm, Hm, rec_lgrad[at].x, 1, Wm, Hm);
}

// dL/dS per texel: Σ over the fragments whose window holds it of (dL/dv / Σg')·g', in a fixed
// order (no atomics). A work-item takes ROW consecutive texels of GATHER_ROWS rows, each row
// as one vector: g' = max(0, gx·gy − ε_λ) is zero outside every window by itself, so no
// bounds test is needed. Truncated only: the exact sum of hard shadows is matrix products.
#if !EXACT
GATHER_KERNEL void shadow_gather(__global const real* P, int nrec, int light, int nl, int Wm,
                                   int Hm, __global const real4* rec_light,
                                   __global const real4* rec_lgrad,
                                   __global const int* bucket_offsets,
                                   __global const int* bucket_counts,
                                   __global const int* bucket_recs, __global real* gS) {
  int i0 = get_global_id(0) * ROW, j0 = get_global_id(1) * GATHER_ROWS;
  GATHER_STAGE_MEMORY;
  RETURN_PAST_MAP(i0, j0);
  const real ss = P[P_SIGMA_S], eps = P[P_LAMBDA_EPS], r2 = P[P_WINDOW_R2];
  const int rows = gather_rows(i0, j0, Wm, Hm);
  realR acc[GATHER_ROWS];
  FOR_ROWS(t, rows) acc[t] = 0;
  FOR_EACH_GATHER_FRAGMENT(r, bucket_reach(P)) {
    real4 x = rec_light[r * nl + light];
    real a = rec_lgrad[r * nl + light].x;
    if (a == 0 || !window_reaches(x.xy, i0, j0, rows, r2)) continue;
    realR gx = axis_weight((real)i0 + LANER - x.x, ss);
    real gys[GATHER_LANES];  // the rows' weights (realG)
    vstoreG(axis_weight((real)j0 + LANEG - x.y, ss), 0, gys);
    FOR_ROWS(t, rows) {
      real dy = j0 + t - x.y;
      if (dy * dy < r2) acc[t] += a * fmax(gx * gys[t] - eps, (realR)0);
    }
  }
  store_rows(acc, rows, min(ROW, Wm - i0), i0, j0, Wm, gS);
}
#endif

// ---- exact sum as matrix products (math.md §6.2): g_ij = gx_i·gy_j, so for fragments r0.. r0+n
// U = Gy·S (n × W_s) and v_r = Σ_i U_ri·Gx_ri / (Σgx_r·Σgy_r) (paper_hard_exact.cl). ---------
// Gx n × W_s, Gy n × H_s; Gxd, Gyd (backward only) = Gx ⊙ (i − μx)/σ_s, Gy ⊙ (j − μy)/σ_s;
// norm n × real4 (Σgx, Σgy, looked up?, 0): 0 outside the map and facing away from the light;
// dsum (backward only) n × real2 (Σgxd, Σgyd); support n × int4: the first and last nonzero
// entry of the fragment's row of Gx (.xy) and of Gy (.zw), empty (first > last) where not
// looked up. Far from μ the weights are exactly 0 (exp_or_zero; float: beyond ~19 texels at
// σ_s = 2), and the products (paper_hard_exact.cl) skip them.
// The weight matrices start zero-filled (the host) and hold zeros outside the supports:
// exact_weights writes only the entries within zero_radius of μ, after clearing the support
// the batch before left in the row, and exact_finish_bwd scales only the support.

// The least and the greatest lane of v.
inline real min8(real8 v) {
  real4 a = fmin(v.lo, v.hi);
  return fmin(fmin(a.s0, a.s1), fmin(a.s2, a.s3));
}
inline real max8(real8 v) {
  real4 a = fmax(v.lo, v.hi);
  return fmax(fmax(a.s0, a.s1), fmax(a.s2, a.s3));
}

// One axis of the weights, eight entries at a time: out[i] = g_i (and dout[i] = g_i·(i − c)/σ_s),
// i < n, g_i = exp(−(i − c)²/(2σ_s)), written in the chunks of eight within zero_radius of c
// (none when `on` is 0): the others are 0 and so are their entries already. Returns
// (Σ g_i, Σ dout_i), to which the chunks left out add nothing, and in *support the first and
// last i whose g_i is nonzero (dout_i is 0 where g_i is).
INLINE real2 axis_weights8(real c, int n, real ss, int on, __global real* out,
                           __global real* dout, int2* support) {
  real8 sum = 0, dsum = 0;
  *support = (int2)(n, -1);
  const real r = zero_radius(ss);
  const int from = on ? max(texel_bound(floor(c - r)), 0) / 8 * 8 : n;
  const int to = texel_bound(ceil(c + r));
  for (int i0 = from; i0 < n && i0 <= to; i0 += 8) {
    real8 i = (real)i0 + LANE8, d = i - c;
    real8 g = exp_or_zero(gaussian_arg(d, ss));
    real8 dg = dout ? g * d / ss : 0;  // the forward needs no derivative weights
    if (mask_all((g != 0) & (i < (real)n))) {  // inside the support: no lane to search
      *support = (int2)(min(support->x, i0), i0 + 7);
    } else if (mask_any(g != 0)) {
      real8 lo = select((real8)n, i, (g != 0) & (i < (real)n));
      real8 hi = select((real8)-1, i, (g != 0) & (i < (real)n));
      *support = (int2)(min(support->x, (int)min8(lo)), max(support->y, (int)max8(hi)));
    }
    if (i0 + 8 <= n) {
      vstore8(g, 0, out + i0);
      if (dout) vstore8(dg, 0, dout + i0);
      sum += g;
      dsum += dg;
    } else {
      real t[8], dt[8];
      vstore8(g, 0, t);
      vstore8(dg, 0, dt);
      for (int l = 0; i0 + l < n; ++l) {
        out[i0 + l] = t[l];
        if (dout) dout[i0 + l] = dt[l];
        sum.s0 += t[l];
        dsum.s0 += dt[l];
      }
    }
  }
  return (real2)(hsum8(sum), hsum8(dsum));
}

FORWARD_KERNEL void exact_weights(__global const real* P, int r0, int n, int light, int nl,
                                  int Wm, int Hm, __global const real4* rec_shade,
                                  __global const real4* rec_light,
                                  __global real* Gx, __global real* Gxd, int with_derivative,
                                  __global real* Gy, __global real* Gyd, __global real4* norm,
                                  __global real2* dsum, __global int4* support) {
  int k = get_global_id(0);
  if (k >= n) return;
  const int4 old = support[k];  // what the row's fragment of the batch before left nonzero
  for (int i = old.x; i <= old.y; ++i) {
    Gx[(size_t)k * Wm + i] = 0;
    if (with_derivative) Gxd[(size_t)k * Wm + i] = 0;
  }
  for (int j = old.z; j <= old.w; ++j) {
    Gy[(size_t)k * Hm + j] = 0;
    if (with_derivative) Gyd[(size_t)k * Hm + j] = 0;
  }
  real4 x = rec_light[(r0 + k) * nl + light];
  real ss = P[P_SIGMA_S];
  // A fragment facing away from the light gets a row of zeros, as one outside the map: s = 1
  // (exact_finish) and no gradient (exact_finish_bwd), where its s only multiplies a direct
  // term of 0 and dL/ds is ±0 (faces_away_in_map); the products skip its row.
  const int looked_up = inside_map(x.xy, Wm, Hm) &&
                        !faces_away_in_map(x.xy, Wm, Hm, rec_shade, r0 + k, nl, light);
  int2 nx, ny;
  real2 sx = axis_weights8(x.x, Wm, ss, looked_up, Gx + (size_t)k * Wm,
                           with_derivative ? Gxd + (size_t)k * Wm : 0, &nx);
  real2 sy = axis_weights8(x.y, Hm, ss, looked_up, Gy + (size_t)k * Hm,
                           with_derivative ? Gyd + (size_t)k * Hm : 0, &ny);
  norm[k] = (real4)(sx.x, sy.x, looked_up, 0);
  support[k] = (int4)(nx.x, nx.y, ny.x, ny.y);  // scalar parts, for Oclgrind (docs/faults.md)
  if (with_derivative) dsum[k] = (real2)(sx.y, sy.y);
}

// dot_r.x = Σ_ij gy_rj·S_ji·gx_ri (matmul_nn_rowdot, paper_hard_exact.cl).
FORWARD_KERNEL void exact_finish(__global const real* P, int r0, int n, int light, int nl,
                                 __global const real4* dot, __global const real4* norm,
                                 __global real4* rec_light) {
  int k = get_global_id(0);
  if (k >= n) return;
  real4 nm = norm[k];
  __global real4* x = rec_light + (r0 + k) * nl + light;
  x->w = nm.z == 0 ? 1 : compare(dot[k].x / (nm.x * nm.y), x->z, P);
}

// Backward: dots_r = (A, Ax, Ay) = Σ_ij S_ji·(gx_i·gy_j, gxd_i·gy_j, gx_i·gyd_j) are given
// (matmul_nn_rowdots), and dsum from exact_weights; writes dL/dμ, dL/dd into rec_lgrad and
// scales Gy in place by a_r = dL/dv_r / (Σgx·Σgy), so that dL/dS = (a ⊙ Gy)ᵀ·Gx is one more
// product (its zeros stay 0; a fragment not looked up has a row of zeros already).
BACKWARD_KERNEL void exact_finish_bwd(__global const real* P, int r0, int n, int light, int nl,
                                      int Hm, __global const real4* dots, __global real* Gy,
                                      __global const real4* norm, __global const real2* dsum,
                                      __global const int4* support,
                                      __global const real4* rec_light, __global real4* rec_lgrad) {
  int k = get_global_id(0);
  if (k >= n) return;
  real4 nm = norm[k], x = rec_light[(r0 + k) * nl + light], d = dots[k];
  __global real4* g = rec_lgrad + (r0 + k) * nl + light;
  __global real* gy = Gy + (size_t)k * Hm;
  if (nm.z == 0) {
    *g = 0;
    return;
  }
  real nrm = nm.x * nm.y, v = d.x / nrm, gv = g->x * x.w * (1 - x.w) / P[P_GAMMA_S];
  const real a = gv / nrm;
  const int4 sup = support[k];  // read once: the compiler cannot tell that gy does not alias it
  for (int j = sup.z; j <= sup.w; ++j) gy[j] *= a;
  real2 sd = dsum[k];  // Σgxd, Σgyd
  real dvx = d.y / nrm - v * sd.x / nm.x, dvy = d.z / nrm - v * sd.y / nm.y;
  *g = (real4)(gv / nrm, gv * dvx, gv * dvy, -gv);
}

// ---- soft shadows (math.md §6.3, eq. 11 with a receiver-plane depth bias; compare then filter) --
//   d_ij = d + ∇_μ d·((i, j) − μ),  front_ij = sigmoid((S_ij − d_ij + β)/γ_s),
//   at_ij = sigmoid((d_ij − S_ij + β)/γ_s),  s = Σ λ_ij·front_ij·(1 − at_ij·(1 − P_ij)).
// rec_light2 K·nl × real4 holds ∇_μ d (.xy); rec_lgrad2 receives dL/d∇_μ d (.xy).
// The EXACT build (window.clh) sums over the whole map (O(W_s·H_s) sigmoids per fragment).

// front·(1 − at·(1 − P)) at ROW texels of a row at once, with its derivatives by d_ij and
// by P_ij (its derivative by S_ij is minus the one by d_ij).
// Both sigmoids come from one exponential (the exponentials are most of the cost): with
// x = (S − d_ij)/γ_s and c = e^{−β/γ_s}, front = 1/(1 + c·e^{−x}) and at = 1/(1 + c/e^{−x}).
// x is clamped so that e^{−x} stays finite and nonzero; beyond the clamp each sigmoid is within
// 1e-34 (float; 1e-304 in double) of 0 or 1.
#ifdef PENUMBRA_DOUBLE
#define SIGMOID_CLAMP 700
#else
#define SIGMOID_CLAMP 80
#endif
// γ_s and c = e^{−β/γ_s}, the same for every texel: computed once per work-item.
typedef struct {
  real gs, c;
} SoftCompare;
inline SoftCompare soft_compare(__global const real* P) {
  SoftCompare k = {P[P_GAMMA_S], exp(-P[P_BETA] / P[P_GAMMA_S])};
  return k;
}
inline realR soft_term(realR S, realR Pv, realR dij, SoftCompare k, realR* dd, realR* dP) {
  real gs = k.gs, c = k.c;
  realR e = exp(-clamp((S - dij) / gs, (real)-SIGMOID_CLAMP, (real)SIGMOID_CLAMP));
  realR front = 1 / (1 + c * e), at = 1 / (1 + c / e);
  realR lit = 1 - at * (1 - Pv);
  *dd = -front * (1 - front) / gs * lit - front * at * (1 - at) / gs * (1 - Pv);
  *dP = front * at;
  return front * lit;
}

// A fragment facing away from the light (faces_away_in_map) gets s = 1 without a lookup:
// soft_sample_bwd reads nothing of it.
FORWARD_KERNEL void soft_sample(__global const real* P, int nrec, int light, int nl, int Wm, int Hm,
                                __global const real* S, __global const real* Pmap,
                                __global const real4* rec_shade, __global real4* rec_light,
                                __global const real4* rec_light2) {
  int r = get_global_id(0);
  if (r >= nrec) return;
  real4 x = rec_light[r * nl + light];
  if (faces_away_in_map(x.xy, Wm, Hm, rec_shade, r, nl, light)) {
    rec_light[r * nl + light].w = 1;
    return;
  }
  real2 grad = rec_light2[r * nl + light].xy;
  Window w = sample_window(x.xy, P, Wm, Hm);
  real ss = P[P_SIGMA_S];
  realR sum = 0, acc = 0, dd, dP;
  const SoftCompare cmp = soft_compare(P);
  Columns c;
  columns_init(&c, w, x.xy, ss);
  w = nonzero_part(w, x.xy, ss);
  for (int j = w.y0; j <= w.y1; ++j) {
    real gy = row_weight(&c, j, x.y, ss);
    for (int i0 = w.x0; i0 <= w.x1; i0 += ROW) {
      realR g = window_row(&c, i0, w.x1, gy, x.xy, ss, w.eps);
      realR dij = x.z + grad.x * ((real)i0 + LANER - x.x) + grad.y * (j - x.y);
      int n = min(ROW, Wm - i0);
      realR term = soft_term(loadR(S, j * Wm + i0, n), loadR(Pmap, j * Wm + i0, n), dij, cmp,
                              &dd, &dP);
      sum += g;
      acc += g * term;
    }
  }
  real norm = hsumR(sum);
  rec_light[r * nl + light].w = norm > 0 ? hsumR(acc) / norm : 1;
}

BACKWARD_KERNEL void soft_sample_bwd(__global const real* P, int nrec, int light, int nl, int Wm,
                                     int Hm, __global const real* S, __global const real* Pmap,
                                     __global const real4* rec_light,
                                     __global const real4* rec_light2, __global real4* rec_lgrad,
                                     __global real4* rec_lgrad2) {
  int r = get_global_id(0);
  if (r >= nrec) return;
  real4 x = rec_light[r * nl + light];
  real2 grad = rec_light2[r * nl + light].xy;
  real gs = rec_lgrad[r * nl + light].x, s = x.w, ss = P[P_SIGMA_S];
  if (gs == 0) {  // dL/ds = 0 (unlit from this light, or outside the loss): every gradient is 0
    rec_lgrad[r * nl + light] = 0;
    rec_lgrad2[r * nl + light] = 0;
    return;
  }
  Window w = sample_window(x.xy, P, Wm, Hm);
  Columns c;
  columns_init(&c, w, x.xy, ss);
  w = nonzero_part(w, x.xy, ss);
  // s = Σ g'·term / Σ g': through the weights (∂g'/∂μ = g·((i, j) − μ)/σ_s where g' > 0) and
  // through d_ij (∂d_ij/∂μ = −∇d, ∂d_ij/∂d = 1, ∂d_ij/∂∇d = (i, j) − μ). The sums are scaled
  // by dL/ds / Σg' at the end.
  realR sumR = 0, gmux = 0, gmuy = 0, ggx = 0, ggy = 0, gd = 0, dd, dP;
  const SoftCompare cmp = soft_compare(P);
  for (int j = w.y0; j <= w.y1; ++j) {
    real gy = row_weight(&c, j, x.y, ss), offy = j - x.y;
    for (int i0 = w.x0; i0 <= w.x1; i0 += ROW) {
      realR lam = window_row(&c, i0, w.x1, gy, x.xy, ss, w.eps);
      sumR += lam;
      realR g = select((realR)0, lam + w.eps, lam > 0);
      realR offx = (real)i0 + LANER - x.x;
      int n = min(ROW, Wm - i0);
      realR term = soft_term(loadR(S, j * Wm + i0, n), loadR(Pmap, j * Wm + i0, n),
                              x.z + grad.x * offx + grad.y * offy, cmp, &dd, &dP);
      realR wmu = g * (term - s) / ss;
      gmux += wmu * offx - lam * dd * grad.x;
      gmuy += wmu * offy - lam * dd * grad.y;
      gd += lam * dd;
      ggx += lam * dd * offx;
      ggy += lam * dd * offy;
    }
  }
  real sum = hsumR(sumR);
  if (sum <= 0) {
    rec_lgrad[r * nl + light] = 0;
    rec_lgrad2[r * nl + light] = 0;
    return;
  }
  real k = gs / sum;
  rec_lgrad[r * nl + light] = (real4)(k, k * hsumR(gmux), k * hsumR(gmuy), k * hsumR(gd));
  rec_lgrad2[r * nl + light] = (real4)(k * hsumR(ggx), k * hsumR(ggy), 0, 0);
}

// dL/dS and dL/dP per texel, gathered from the fragments whose window holds it (from the
// nearby texel buckets when truncated; every fragment when exact), in a fixed order; ROW
// texels of GATHER_ROWS rows per work-item.
GATHER_KERNEL void soft_gather(__global const real* P, int nrec, int light, int nl, int Wm,
                                 int Hm, __global const real* S, __global const real* Pmap,
                                 __global const real4* rec_light, __global const real4* rec_light2,
                                 __global const real4* rec_lgrad,
                                 __global const int* bucket_offsets,
                                 __global const int* bucket_counts, __global const int* bucket_recs,
                                 __global const int4* chunks, __global real* gS,
                                 __global real* gPmap) {
  int i0 = get_global_id(0) * ROW, j0 = get_global_id(1) * GATHER_ROWS;
  GATHER_STAGE_MEMORY;
  RETURN_PAST_MAP(i0, j0);
  const real ss = P[P_SIGMA_S];
  const int n = min(ROW, Wm - i0), rows = gather_rows(i0, j0, Wm, Hm);
  realR Sv[GATHER_ROWS], Pv[GATHER_ROWS], accS[GATHER_ROWS], accP[GATHER_ROWS], dd, dP;
  FOR_ROWS(t, rows) {
    Sv[t] = loadR(S, (j0 + t) * Wm + i0, n);
    Pv[t] = loadR(Pmap, (j0 + t) * Wm + i0, n);
    accS[t] = accP[t] = 0;
  }
  const real eps = sampling_eps(P[P_LAMBDA_EPS]), r2 = sampling_r2(P[P_WINDOW_R2], ss);
  const SoftCompare cmp = soft_compare(P);
  FOR_EACH_GATHER_FRAGMENT(r, bucket_reach(P)) {
    if (!window_reaches(rec_light[r * nl + light].xy, i0, j0, rows, r2)) continue;
    real k = rec_lgrad[r * nl + light].x;  // dL/ds / Σg'
    if (k == 0) continue;  // adds nothing (unlit from this light, or outside the loss)
    real4 x = rec_light[r * nl + light];
    realR offx = (real)i0 + LANER - x.x, gx = axis_weight(offx, ss);
    real2 grad = rec_light2[r * nl + light].xy;
    real gys[GATHER_LANES];  // the rows' weights (realG)
    vstoreG(axis_weight((real)j0 + LANEG - x.y, ss), 0, gys);
#pragma unroll
    for (int t = 0; t < GATHER_ROWS; ++t) {  // unrolled: the rows' vectors stay in registers
      real dy = j0 + t - x.y, gy = gys[t];
      if (t >= rows || !(dy * dy < r2) || gy <= eps) continue;
      realR g = fmax(gx * gy - eps, (realR)0);
      soft_term(Sv[t], Pv[t], x.z + grad.x * offx + grad.y * dy, cmp, &dd, &dP);
      realR a = k * g;
      accS[t] -= a * dd;
      accP[t] += a * dP;
    }
  }
  store_rows(accS, rows, n, i0, j0, Wm, gS);
  store_rows(accP, rows, n, i0, j0, Wm, gPmap);
}

// soft_gather's chunks (window.clh): the texels within the exact weights' zero_radius of each
// fragment inside the map with a gradient (soft_gather skips the others).
BACKWARD_KERNEL void soft_gather_chunks(__global const real* P, int nrec, int light, int nl, int Wm,
                                        int Hm, __global const real4* rec_light,
                                        __global const real4* rec_lgrad, __global int4* chunks) {
  int c = get_global_id(0);
  if (c * GATHER_CHUNK >= nrec) return;
  int4 box = empty_box();
  for (int r = c * GATHER_CHUNK; r < min(nrec, (c + 1) * GATHER_CHUNK); ++r)
    if (rec_lgrad[r * nl + light].x != 0 && inside_map(rec_light[r * nl + light].xy, Wm, Hm))
      box = grow_box(box, rec_light[r * nl + light].xy, zero_radius(P[P_SIGMA_S]));
  chunks[c] = box;
}
