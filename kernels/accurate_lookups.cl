// Stage 5 (accurate model) — lookups: the shadow term s of every kept fragment for one light by
// percentage-closer filtering (compare, then filter) of the light's shadow map S, forward and
// backward (math.md §7, §8.4; docs/shadows.md, "The accurate model"):
//   d_ij = d + ∇_μ d·((i, j) − μ)            receiver-plane depth at texel (i, j) (slope
//                                            limited for faces nearly edge-on: slope_limit)
//   c_ij = 1 − A_ij·smoothstep(β − 2γ_s, β + 2γ_s, d_ij − S_ij)   1 lit … 0 behind an occluder
//   s    = Σ g'_ij(σ)·c_ij / Σ g'_ij(σ)      Gaussian weights of variance σ around μ
// A_ij is the casters' coverage of texel (i, j) (the light pass's silhouette, only faces that
// can cast a shadow in the map): a texel an outline crosses occludes in part, which puts the
// shadow's edge where the outline is, not where the soft depth S first reaches the caster.
// Hard shadows filter with σ = σ_s. Soft shadows (PCSS) first search for blockers with weights
// h' of variance σ_b (the light's L_SEARCH_SIGMA): o = 1 − c, κ = PCF_KAPPA,
//   z_b = (Σ h'·o·S + κ·d·Σh') / (Σ h'·o + κ·Σh')   mean blocker depth (→ d with no blocker)
//   w   = D_L·k·(1/z_b − 1/d)  (point light; k = H_s / (2·tan(θ_L/2)): texels per unit of
//         lateral distance over depth), w = D_L·k·(d − z_b) (directional: D_L an angle)
//   σ   = min(σ_s + w²/16, σ_b)             a disc of diameter w has variance w²/16 per axis
// so the penumbra straddles the hard edge with the width a sphere light of diameter D_L casts.
// The search sums over every st-th texel of each axis (st the light's L_SEARCH_STRIDE: its
// Gaussian's standard deviation spans two strides or more), texels (st·I, st·J): a copy of
// them, the search map (Sb, Ab: Wb × Hb), is made by pcf_search_map, where a receiver has
// μ/st, slope st·∇_μ d and the search variance σ_b/st² (search_receiver).
// Truncated sampling cuts each Gaussian at ε_λ (g' = max(0, g − ε_λ)); exact (EXACT) sums
// g over the whole map.
// Buffers (K fragments, nl lights, this light l):
//   rec_shade   K·(1+nl) × real4 (raster.cl): the w of entry 1 + l, whether the fragment faces l
//   rec_light   K·nl × real4 (μx, μy, d, s): s is written here
//   rec_light2  K·nl × real4 (∇_μ d, σ, z_b): σ and z_b are written here, σ negated where the
//               filter is flat (filter_flat; stored_sigma, stored_flat), which the backward skips
//   rec_lgrad   K·nl × real4: in (dL/ds, ·, ·, ·); out (dL/ds / Σg', dL/dμx, dL/dμy, dL/dd),
//               all 0 where the filter is flat (filter_flat: pcf_gather would add only zeros)
//   rec_lgrad2  K·nl × real4: out (dL/d∇_μ d, dL/dz_b / V, dL/dD_L)  (V the search's denominator)
//   S, gS       W_s·H_s × real: the light's shadow map and its gradient
//   A, gA       W_s·H_s × real: the map's caster coverage and its gradient
//   Sb, Ab      Wb·Hb × real: the search map
// The backward's gather runs in passes (pcf_gather): over the map, each fragment with its
// filter's window; for soft shadows over the search map, with its search's window there. Per
// pass, of its map's texels:
//   bucket_radius  per texel bucket, how far pcf_gather looks for its fragments
//   grec, gslope   per gather entry (window.clh: a texel bucket's place in bucket_recs when
//               truncated, the fragment when exact) × real8 (μx, μy, σ, dL/ds / Σg', dL/dz_b / V,
//               d, z_b, 0) and × real2 (∇_μ d, slope limited), of the filter (dL/dz_b / V 0) or
//               of the search as the search map sees it (μ/st, σ_b/st², st·∇_μ d; dL/ds 0): what
//               pcf_gather and pcf_bucket_radius read of a fragment, in the order they visit
//               fragments
//   logs        2 × real: log(1/ε) of the filter's and the search's cuts (pcf_window_logs)
// Launch: one work-item per fragment (pcf_sample, pcf_sample_bwd, pcf_boxes), one per
// ROW texels of GATHER_ROWS rows (pcf_gather), one per texel of the search map
// (pcf_search_map) or of the pass's map (pcf_bucket_radius), one per
// fragment (pcf_gather_records) or per bucket entry (pcf_gather_entry_of), a single one
// (pcf_window_logs).
#include "common/window.clh"
#include "common/accurate_filter.clh"

// The light's soft-shadow constants: D_L, k (texels per lateral unit over depth), σ_b, ortho,
// the search's stride st.
typedef struct {
  real size, k, sigma_b;
  int ortho, stride;
} LightDisc;

inline LightDisc light_disc(__global const real* P, int light) {
  int at = P_LIGHTS + light * P_LIGHT_STRIDE;
  LightDisc L = {P[at + L_SIZE], P[at + L_MAP_H] / (2 * P[at + L_FRAME + FR_SCALE]),
                 P[at + L_SEARCH_SIGMA], P[at + L_FRAME + FR_ORTHO] > 0,
                 (int)P[at + L_SEARCH_STRIDE]};
  return L;
}

// rec_light2's σ, and whether pcf_sample found the filter flat (filter_flat), stored as −σ: the
// backward then knows without testing it again.
inline real stored_sigma(real4 x2) { return fabs(x2.z); }
inline int stored_flat(real4 x2) { return x2.z < 0; }

// The search map's texel (I, J): the map's (st·I, st·J).
FORWARD_KERNEL void pcf_search_map(int Wm, __global const real* S, __global const real* A, int st,
                                   __global real* Sb, __global real* Ab, int Wb, int Hb) {
  int t = get_global_id(0);
  if (t >= Wb * Hb) return;
  int at = (t / Wb) * st * Wm + (t % Wb) * st;
  Sb[t] = S[at];
  Ab[t] = A[at];
}

// Receiver x as the search map sees it, and the search's variance there.
inline Receiver search_receiver(Receiver x, LightDisc L) {
  Receiver r = {x.mu / L.stride, x.d, x.grad * L.stride};
  return r;
}
inline real search_variance(LightDisc L) { return L.sigma_b / (L.stride * L.stride); }

// The search's window in the search map (empty where μ lies outside the map).
INLINE Window search_window(Receiver x, LightDisc L, WindowLogs logs, __global const real* P,
                            int Wm, int Hm, int Wb, int Hb) {
  real eps = window_eps(P, 1), st = L.stride;
  if (!inside_map(x.mu, Wm, Hm)) return no_window();
  return clipped_window(x.mu / st, window_radius(L.sigma_b, logs[1]) / st, eps, Wb, Hb);
}

// Penumbra width w (texels) for blocker depth zb and receiver depth d, with ∂w/∂zb, ∂w/∂d and
// ∂w/∂D_L; 0 where the blocker is not in front.
inline real penumbra_width(LightDisc L, real zb, real d, real* dzb, real* dd, real* dsize) {
  real u = L.ortho ? d - zb : 1 / zb - 1 / d;
  *dzb = L.ortho ? -1 : -1 / (zb * zb);
  *dd = L.ortho ? 1 : 1 / (d * d);
  if (!(u > 0)) u = 0, *dzb = 0, *dd = 0;
  *dsize = L.k * u;
  *dzb *= L.size * L.k;
  *dd *= L.size * L.k;
  return L.size * L.k * u;
}

// Filter variance σ = min(σ_s + w²/16, σ_b) and dσ/dw (0 where capped).
inline real filter_sigma(real w, real sigma_s, real sigma_b, real* dw) {
  real s = sigma_s + w * w / 16;
  *dw = s < sigma_b ? w / 8 : 0;
  return min(s, sigma_b);
}

inline int soft_mode(__global const real* P) { return P[P_SHADOWS] > 1; }

// Mean blocker depth z_b = U / V from the search sums (Σh', Σh'c, Σh'S, Σh'cS).
inline real blocker_depth(real4 sums, real d, real* V) {
  real B = sums.x - sums.y, Z = sums.z - sums.w, k = PCF_KAPPA * sums.x;
  *V = B + k;
  return *V > 0 ? (Z + k * d) / *V : d;
}

// log(1/ε) of the filter's and the search's cuts (WindowLogs), as every fragment computed them.
FORWARD_KERNEL void pcf_window_logs(__global const real* P, __global real* logs) {
  if (get_global_id(0) > 0) return;
  logs[0] = log(1 / window_eps(P, 0));
  logs[1] = log(1 / window_eps(P, 1));
}

// s, σ and z_b of every fragment. A fragment facing away from the light (faces_away_in_map)
// needs no lookup: pcf_sample_bwd, as dL/ds = ±0, leaves it no gradient for the gather to add.
// Its σ then changes no result but the gather's reach (gather_reach: the widest σ), which must
// not fall short of the widest filter with a gradient and does not: it gets s = 1, σ = σ_s and
// z_b = d.
FORWARD_KERNEL void pcf_sample(__global const real* P, int nrec, int light, int nl, int Wm, int Hm,
                               WindowLogs logs, __global const real* S, __global const real* A,
                               __global const real* Sb, __global const real* Ab, int Wb, int Hb,
                               __global const real4* rec_shade, __global real4* rec_light,
                               __global real4* rec_light2) {
  int r = get_global_id(0);
  if (r >= nrec) return;
  int at = r * nl + light;
  Receiver x = receiver_at(rec_light, rec_light2, at, P, light);
  real sigma = P[P_SIGMA_S], zb = x.d, V, dzb, dd, dsize, dw;
  if (faces_away_in_map(x.mu, Wm, Hm, rec_shade, r, nl, light)) {
    rec_light[at].w = 1;
    rec_light2[at].zw = (real2)(sigma, zb);
    return;
  }
  if (soft_mode(P)) {  // the search's sums (Σh', Σh'c, Σh'S, Σh'cS); flat: no blocker, z_b = d
    LightDisc L = light_disc(P, light);
    Receiver xb = search_receiver(x, L);
    real sb = search_variance(L);
    Window wb = search_window(x, L, logs, P, Wm, Hm, Wb, Hb);
    if (!window_flat(xb, nonzero_part(wb, xb.mu, sb), P, Sb, Wb))
      zb = blocker_depth(window_sums(wb, xb, sb, P, Sb, Ab, Wb), x.d, &V);
    real w = penumbra_width(L, zb, x.d, &dzb, &dd, &dsize);
    sigma = filter_sigma(w, sigma, L.sigma_b, &dw);
  }
  // Flat over every texel the backward could weigh (filter_flat, a superset of the window):
  // s = 1 exactly, as the sums give it there, and the backward gives no gradient.
  Window fw = filter_window(x.mu, sigma, logs, P, Wm, Hm);
  const int flat = filter_flat(x, sigma, fw, logs, P, S, Wm, Hm);
  real4 f = flat ? (real4)(1, 1, 0, 0) : window_sums(fw, x, sigma, P, S, A, Wm);
  rec_light[at].w = f.x > 0 ? f.y / f.x : 1;
  rec_light2[at].zw = (real2)(flat ? -sigma : sigma, zb);
}

// The search's moments over the search map, in the map's texels: .mu (Σ over offsets / σ_b)
// and .qoff (Σ over offsets) scale with the stride.
INLINE Moments search_moments(Receiver x, LightDisc L, real zb, WindowLogs logs,
                              __global const real* P, __global const real* Sb,
                              __global const real* Ab, int Wm, int Hm, int Wb, int Hb) {
  Moments m = window_moments(search_window(x, L, logs, P, Wm, Hm, Wb, Hb), search_receiver(x, L),
                             search_variance(L), 1, zb, P, Sb, Ab, Wb);
  m.mu /= L.stride;
  m.qoff *= L.stride;
  return m;
}

// Backward per fragment: dL/dμ, dL/dd, dL/d∇_μ d, dL/dD_L, and the scales the gather needs.
BACKWARD_KERNEL void pcf_sample_bwd(__global const real* P, int nrec, int light, int nl, int Wm,
                                    int Hm, WindowLogs logs, __global const real* S,
                                    __global const real* A,
                                    __global const real* Sb, __global const real* Ab, int Wb,
                                    int Hb, __global const real4* rec_light,
                                    __global const real4* rec_light2, __global real4* rec_lgrad,
                                    __global real4* rec_lgrad2) {
  int r = get_global_id(0);
  if (r >= nrec) return;
  int at = r * nl + light;
  Receiver x = receiver_at(rec_light, rec_light2, at, P, light);
  const real4 x2 = rec_light2[at];
  real G = rec_lgrad[at].x, s = rec_light[at].w, sigma = stored_sigma(x2), zb = x2.w;
  // Through the filter, σ held: s = Σ w·c / Σ w. Nothing to do where dL/ds = 0 (a fragment
  // unlit from this light, or outside the loss): every gradient is 0.
  // Nor where the filter is flat (pcf_sample found it so): every gradient is 0 there too.
  Moments f;
  if (G != 0) {
    if (stored_flat(x2)) G = 0;
    else f = window_moments(filter_window(x.mu, sigma, logs, P, Wm, Hm), x, sigma, 0, s, P, S, A, Wm);
  }
  if (G == 0 || !(f.w > 0)) {
    rec_lgrad[at] = 0;
    rec_lgrad2[at] = 0;
    return;
  }
  real k = G / f.w;
  real2 gmu = k * (f.mu - x.grad * f.q), ggrad = k * f.qoff;
  real gd = k * f.q, gzb_v = 0, gsize = 0;
  if (soft_mode(P)) {  // through σ(w(z_b, d, D_L)) and z_b(μ, d, ∇_μ d, S)
    LightDisc L = light_disc(P, light);
    real dzb, dd, dsize, dw;
    real w = penumbra_width(L, zb, x.d, &dzb, &dd, &dsize);
    filter_sigma(w, P[P_SIGMA_S], L.sigma_b, &dw);
    real gw = k * f.r2 / (2 * sigma * sigma) * dw;  // dL/dw
    gsize = gw * dsize;
    gd += gw * dd;
    real gzb = gw * dzb;
    Moments b;
    if (gzb != 0) b = search_moments(x, L, zb, logs, P, Sb, Ab, Wm, Hm, Wb, Hb);
    real V = gzb != 0 ? b.wo + PCF_KAPPA * b.w : 0;  // blocker_depth's denominator
    if (V > 0) {
      gzb_v = gzb / V;
      gmu += gzb_v * (b.mu - x.grad * b.q);
      gd += gzb_v * (b.q + PCF_KAPPA * b.w);
      ggrad += gzb_v * b.qoff;
    }
  }
  ggrad = slope_limit_bwd(P, light, x.d, rec_light2[at].xy, ggrad, &gd);
  rec_lgrad[at] = (real4)(k, gmu, gd);
  rec_lgrad2[at] = (real4)(ggrad, gzb_v, gsize);
}

// The gather entries' copies of their fragments (grec, gslope above): the gather visits a
// fragment from every block of texels its windows reach, and reading its four records where
// the fragment order put them, far apart, missed the cache at every visit. Written in fragment
// order (reading the records in turn) to entry entry_of[r] (pcf_gather_entry_of; r itself
// when exact, or −1: in no bucket). An entry outside the map (exact: the chunks hold every
// fragment) gets no gradient, so that the gather skips it. Each pass copies one of a
// fragment's two windows (the host's gather_pass): the filter's, in the map, or the search's,
// as the search map sees the fragment (search_receiver, search_variance).
BACKWARD_KERNEL void pcf_gather_records(__global const real* P, int nrec, int light, int nl,
                                        int Wm, int Hm, int search,
                                        __global const int* entry_of,
                                        __global const real4* rec_light,
                                        __global const real4* rec_light2,
                                        __global const real4* rec_lgrad,
                                        __global const real4* rec_lgrad2, __global real8* grec,
                                        __global real2* gslope) {
  int r = get_global_id(0);
  if (r >= nrec) return;
  int e = EXACT ? r : entry_of[r], at = r * nl + light;
  if (e < 0) return;
  Receiver x = receiver_at(rec_light, rec_light2, at, P, light);
  real4 x2 = rec_light2[at];
  int inside = inside_map(x.mu, Wm, Hm);
  real sigma = stored_sigma(x2), a = inside && !search ? rec_lgrad[at].x : 0,
       b = inside && search ? rec_lgrad2[at].z : 0;
  if (search) {
    LightDisc L = light_disc(P, light);
    x = search_receiver(x, L);
    sigma = search_variance(L);
  }
  grec[e] = (real8)(x.mu, sigma, a, b, x.d, x2.w, 0);
  gslope[e] = x.grad;
}

// Each fragment's texel bucket (texel_box, window.clh) for a gather pass: on the light's map,
// with its filter's dL/ds as the gradient that passes, or on the search map (μ/st), with dL/dz_b.
BACKWARD_KERNEL void pcf_boxes(__global const real* P, int nrec, int light, int nl, int Wm, int Hm,
                               int search, int Wb, int Hb, __global const real4* rec_light,
                               __global const real4* rec_lgrad, __global const real4* rec_lgrad2,
                               __global int4* boxes) {
  int r = get_global_id(0);
  if (r >= nrec) return;
  const int at = r * nl + light;
  const real g = search ? rec_lgrad2[at].z : rec_lgrad[at].x;
  boxes[r] = texel_box(rec_light[at].xy, Wm, Hm, g, search ? light_disc(P, light).stride : 1, Wb,
                       Hb);
}

// The entry of each bucketed fragment: its place in bucket_recs (entry_of: nrec × int, −1
// before).
BACKWARD_KERNEL void pcf_gather_entry_of(int entries, __global const int* bucket_recs,
                                         __global int* entry_of) {
  int e = get_global_id(0);
  if (e < entries) entry_of[bucket_recs[e]] = e;
}

// An entry's window (grec: variance .s2; a filter's where .s3 = dL/ds / Σg' ≠ 0, a search's
// where .s4 = dL/dz_b / V ≠ 0): its squared radius widened by GATHER_MARGIN, beyond which its
// weights are exactly 0; −1 for an entry that adds nothing.
inline real entry_r2(real8 g, WindowLogs logs) {
  if (g.s3 == 0 && g.s4 == 0) return -1;
  return window_r2(g.s2, logs[g.s3 != 0 ? 0 : 1]) * GATHER_MARGIN;
}

// pcf_gather's reach of each texel bucket: the radius (texels) of the widest window of its
// entries (entry_r2), plus one texel (a fragment lies within half a texel of its bucket's);
// −1 where none adds anything. The gather skips a bucket beyond it before reading any of its
// fragments.
BACKWARD_KERNEL void pcf_bucket_radius(int Wm, int Hm, WindowLogs logs, __global const real8* grec,
                                       __global const int* bucket_offsets,
                                       __global const int* bucket_counts,
                                       __global real* bucket_radius) {
  int t = get_global_id(0);
  if (t >= Wm * Hm) return;
  real r2 = -1;
  for (int e = bucket_offsets[t]; e < bucket_offsets[t] + bucket_counts[t]; ++e)
    r2 = max(r2, entry_r2(grec[e], logs));
  bucket_radius[t] = r2 < 0 ? -1 : sqrt(r2) + 1;
}

// One entry's terms in one row of a gather block (pcf_gather's sums), of weight k times
// g' = max(0, gx·gy − ε): the filter's, or the search's on the search map (`search`), at
// receiver depths d against the row's S and A.
inline void pcf_gather_row(realR S, realR A, realR d, real zb, __global const real* P, int search,
                           real k, realR gx, real gy, real eps, realR* acc, realR* accA) {
  realR dc, step;
  realR lit = lit_term(S, A, d, P, &dc, &step);
  realR g = k * fmax(gx * gy - eps, (realR)0);
  if (search) {
    *acc += g * ((1 - lit) + (S - zb) * dc);
    *accA += g * step * (S - zb);
  } else {
    *acc -= g * dc;
    *accA -= g * step;
  }
}

// Adds sums of the search map's texels i0 .. i0 + n − 1 of rows j0 .. j0 + rows − 1 (store_rows)
// to the map's texels (st·i, st·j) of `out`, Wg texels wide (pcf_search_map's).
INLINE void add_search_rows(const realR* acc, int rows, int n, int i0, int j0, int st, int Wg,
                            __global real* out) {
  FOR_ROWS(t, rows) {
    real v[ROW];
    vstoreR(acc[t], 0, v);
    for (int l = 0; l < n; ++l) out[(j0 + t) * st * Wg + (i0 + l) * st] += v[l];
  }
}

// dL/dS and dL/dA per texel, gathered in a fixed order (no atomics) from the entries whose
// window holds it (from the nearby texel buckets when truncated; every fragment when exact),
// with o = 1 − c and `step` the compare's smooth step. A pass over the map gathers the filters'
// terms into gS, gA; for soft shadows a second pass (`search`) over the search map gathers the
// searches' (their texels are the search map's alone) and adds them to those of gS, gA
// (Wg texels wide) at the map's texels (st·I, st·J):
//   dL/dS = Σ (dL/ds / Σg')·g'·(−dc/dΔ) + Σ (dL/dz_b / V)·h'·(o + (S − z_b)·dc/dΔ)
//   dL/dA = −Σ (dL/ds / Σg')·g'·step    + Σ (dL/dz_b / V)·h'·step·(S − z_b)
GATHER_BODY void pcf_gather_body(int i0, int j0, GATHER_STAGE_PARAMS __global const real* P,
                                 int nrec, int light, int nl, int Wm, int Hm, WindowLogs logs,
                                 int reach, __global const real* S, __global const real* A,
                                 __global const real8* grec, __global const real2* gslope,
                                 __global const int* bucket_offsets,
                                 __global const int* bucket_counts, __global const int* bucket_recs,
                                 __global const real* bucket_radius, __global const int4* chunks,
                                 __global real* gS, __global real* gA, int search, int Wg) {
  RETURN_PAST_MAP(i0, j0);
  const int n = min(ROW, Wm - i0), rows = gather_rows(i0, j0, Wm, Hm);
  realR Sv[GATHER_ROWS], Av[GATHER_ROWS], acc[GATHER_ROWS], accA[GATHER_ROWS];
  FOR_ROWS(t, rows) {
    Sv[t] = loadR(S, (j0 + t) * Wm + i0, n);
    Av[t] = loadR(A, (j0 + t) * Wm + i0, n);
    acc[t] = accA[t] = 0;
  }
  const real eps = window_eps(P, 0), eps_b = window_eps(P, 1);
  // An entry reaches the texels within its window's r2; one without a gradient (entry_r2 −1)
  // adds exactly 0, and the gather skips it.
  FOR_EACH_NEAR_GATHER_ENTRY(e, reach, bucket_radius) {
    const real8 g = grec[e];
    if (entry_r2(g, logs) < 0) continue;
    const int search_entry = g.s3 == 0;
    const real2 mu = g.s01;
    const real sigma = g.s2;
    const real r2 = sampling_r2(window_r2(sigma, logs[search_entry]), sigma);
    if (!window_reaches(mu, i0, j0, rows, r2)) continue;
    const Receiver x = {mu, g.s5, gslope[e]};
    const realR offx = (real)i0 + LANER - x.mu.x, gx = axis_weight(offx, sigma);
    real gy[GATHER_LANES];  // the rows' weights (realG)
    vstoreG(axis_weight((real)j0 + LANEG - x.mu.y, sigma), 0, gy);
    FOR_ROWS(t, rows) {
      real offy = j0 + t - x.mu.y;
      if (!(offy * offy < r2)) continue;
      pcf_gather_row(Sv[t], Av[t], x.d + x.grad.x * offx + x.grad.y * offy, g.s6, P,
                     search_entry, search_entry ? g.s4 : g.s3, gx, gy[t],
                     search_entry ? eps_b : eps, &acc[t], &accA[t]);
    }
  }
  if (search) {
    const int st = light_disc(P, light).stride;
    add_search_rows(acc, rows, n, i0, j0, st, Wg, gS);
    add_search_rows(accA, rows, n, i0, j0, st, Wg, gA);
  } else {
    store_rows(acc, rows, n, i0, j0, Wm, gS);
    store_rows(accA, rows, n, i0, j0, Wm, gA);
  }
}

GATHER_KERNEL void pcf_gather(__global const real* P, int nrec, int light, int nl, int Wm, int Hm,
                                WindowLogs logs, int reach, __global const real* S,
                                __global const real* A,
                                __global const real8* grec, __global const real2* gslope,
                                __global const int* bucket_offsets,
                                __global const int* bucket_counts, __global const int* bucket_recs,
                                __global const real* bucket_radius, __global const int4* chunks,
                                __global real* gS, __global real* gA, int search, int Wg) {
  GATHER_STAGE_MEMORY;
  pcf_gather_body(get_global_id(0) * ROW, get_global_id(1) * GATHER_ROWS, GATHER_STAGE_ARGS P, nrec,
                  light, nl, Wm, Hm, logs, reach, S, A, grec, gslope, bucket_offsets, bucket_counts,
                  bucket_recs, bucket_radius, chunks, gS, gA, search, Wg);
}

// pcf_gather's chunks (window.clh): the texels within the exact weights' zero_radius of each
// fragment inside the map, its filter's where dL/ds ≠ 0, or in the search pass its search's
// in the search map where dL/dz_b ≠ 0 (pcf_gather skips a fragment without).
BACKWARD_KERNEL void pcf_gather_chunks(__global const real* P, int nrec, int light, int nl, int Wm,
                                       int Hm, int search, __global const real4* rec_light,
                                       __global const real4* rec_light2,
                                       __global const real4* rec_lgrad,
                                       __global const real4* rec_lgrad2, __global int4* chunks) {
  int c = get_global_id(0);
  if (c * GATHER_CHUNK >= nrec) return;
  const LightDisc L = light_disc(P, light);
  int4 box = empty_box();
  for (int r = c * GATHER_CHUNK; r < min(nrec, (c + 1) * GATHER_CHUNK); ++r) {
    int at = r * nl + light;
    const real2 mu = rec_light[at].xy;
    if (!inside_map(mu, Wm, Hm)) continue;
    if (!search && rec_lgrad[at].x != 0)
      box = grow_box(box, mu, zero_radius(stored_sigma(rec_light2[at])));
    if (search && rec_lgrad2[at].z != 0)
      box = grow_box(box, mu / L.stride, zero_radius(search_variance(L)));
  }
  chunks[c] = box;
}
