// Stage 1 — transform: world vertices → screen, per-face setup; backward gathers per vertex and
// per albedo entry.
//
// Buffers (V vertices, F faces, P the per-view parameters of common/layout.h):
//   vworld   V × real4   world positions (w unused)
//   vscreen  V × real4   (screen x, screen y, view depth z, 0)
//   faces    F × int4    vertex indices (w unused)
//   fbbox    F × int4    pixel bounding box (x0, y0, x1, y1) of the face's coverage, widened by
//                        the coverage cut-off radius; empty (x0 > x1) for a dropped face
//   fnormal  F × real4   unit world normal (xyz) and signed screen area (w; 0 if dropped:
//                        behind the near plane, edge-on, culled, or casting no shadow)
// Launch: one work-item per vertex (transform_fwd, transform_bwd), per face (face_setup) or per
// albedo entry (albedo_bwd); sum_rows: one per column and part.
#include "common/geometry.clh"

// The scene's bounding box may lie this far (times its diagonal) behind a face's plane and the
// face still count as casting no shadow: rounding of a receiver under everything (a ground).
#define CASTER_TOL RL(1e-5)

// A face facing the light (`to_light`: towards it from V0) with the whole scene on the light's
// side of its plane shadows nothing: a ground under everything, a wall. The accurate model keeps
// such faces out of the light's map, whose coverage is then that of the casters alone.
inline int casts_no_shadow(real3 V0, real3 n, real3 to_light, __global const real* P) {
  if (!(dot(n, to_light) > 0)) return 0;
  real3 lo = p_vec3(P, P_SCENE_LO), hi = p_vec3(P, P_SCENE_HI);
  real tol = CASTER_TOL * length(hi - lo);
  for (int c = 0; c < 8; ++c) {
    real3 corner = (real3)(c & 1 ? hi.x : lo.x, c & 2 ? hi.y : lo.y, c & 4 ? hi.z : lo.z);
    if (dot(n, corner - V0) < -tol) return 0;
  }
  return 1;
}

FORWARD_KERNEL void transform_fwd(__global const real4* vworld, __global const real* P, int nv,
                                  __global real4* vscreen) {
  int v = get_global_id(0);
  if (v >= nv) return;
  vscreen[v] = (real4)(project_fwd(vworld[v].xyz, P + P_FRAME), 0);
}

FORWARD_KERNEL void face_setup(__global const real4* vworld, __global const real4* vscreen,
                               __global const int4* faces, __global const real* P, int nf, int W,
                               int H, __global int4* fbbox, __global real4* fnormal) {
  int f = get_global_id(0);
  if (f >= nf) return;
  int4 idx = faces[f];
  real3 s0 = vscreen[idx.x].xyz, s1 = vscreen[idx.y].xyz, s2 = vscreen[idx.z].xyz;
  real3 V0 = vworld[idx.x].xyz;
  real3 n = cross(vworld[idx.y].xyz - V0, vworld[idx.z].xyz - V0);
  real nlen = length(n);
  n = nlen > 0 ? n / nlen : n;
  real2 e1 = s1.xy - s0.xy, e2 = s2.xy - s0.xy;
  real area = cross2(e1, e2);
#ifdef PENUMBRA_DOUBLE
  real tiny = DBL_EPSILON;
#else
  real tiny = FLT_EPSILON;
#endif
  real nearz = P[P_NEAR];
  int valid = s0.z >= nearz && s1.z >= nearz && s2.z >= nearz && nlen > 0 &&
              fabs(area) > tiny * (dot(e1, e1) + dot(e2, e2));
  __global const real* fr = P + P_FRAME;
  real3 to_view = fr[FR_ORTHO] > 0 ? -p_vec3(fr, FR_FWD) : p_vec3(fr, FR_EYE) - V0;
  if (valid && P[P_CULL] > 0) valid = dot(n, to_view) > 0;
  if (valid && P[P_CASTERS_ONLY] > 0) valid = !casts_no_shadow(V0, n, to_view, P);
  int4 box = (int4)(1, 1, 0, 0);
  if (valid) {
    // Pixel centres: x = (2px + 1 − W)/H, y = (H − 2py − 1)/H. A quarter pixel of margin on
    // each side keeps the box conservative under rounding (float errors here stay below 0.01
    // pixel up to 8192² images); the raster re-tests every pixel exactly.
    // With ε_D > 0.5 the cut-off radius² is negative: no outside pixel is covered, r = 0.
    real r = sqrt(fmax(P[P_CUTOFF_D2], (real)0));
    real xlo = fmin(s0.x, fmin(s1.x, s2.x)) - r, xhi = fmax(s0.x, fmax(s1.x, s2.x)) + r;
    real ylo = fmin(s0.y, fmin(s1.y, s2.y)) - r, yhi = fmax(s0.y, fmax(s1.y, s2.y)) + r;
    real fx0 = clamp((xlo * H + W - 1) / 2 - RL(0.25), R(-1), (real)W);
    real fx1 = clamp((xhi * H + W - 1) / 2 + RL(0.25), R(-1), (real)W);
    real fy0 = clamp((H - 1 - yhi * H) / 2 - RL(0.25), R(-1), (real)H);
    real fy1 = clamp((H - 1 - ylo * H) / 2 + RL(0.25), R(-1), (real)H);
    box = (int4)(max((int)ceil(fx0), 0), max((int)ceil(fy0), 0), min((int)floor(fx1), W - 1),
                 min((int)floor(fy1), H - 1));
    if (box.x > box.z || box.y > box.w) box = (int4)(1, 1, 0, 0);
  }
  fbbox[f] = box;
  fnormal[f] = (real4)(n, valid ? area : 0);  // area 0 marks a dropped face
}

// Backward: each vertex gathers, in a fixed order, the per-corner gradients its faces wrote
// (dL/d screen position and depth, and dL/d world position), so no atomics are needed and the
// result is bit-for-bit reproducible.
//   adj_offsets (V+1) × int, adj (Σ) × int: entries face*3 + corner, sorted
//   gface_screen, gface_world  3F × real4
//   gvworld  V × real4 (added to): dL/d world position, the views' in turn
//   gframe   4V × real4 (output): this vertex's share of dL/d(eye, fwd, right, up) of the
//            view's frame (summed by sum_rows where the frame depends on a light's position)
BACKWARD_KERNEL void transform_bwd(__global const real4* vworld, __global const real4* vscreen,
                                   __global const real* P, int nv, __global const int* adj_offsets,
                                   __global const int* adj, __global const real4* gface_screen,
                                   __global const real4* gface_world, __global real4* gvworld,
                                   __global real4* gframe) {
  int v = get_global_id(0);
  if (v >= nv) return;
  real3 gs = 0, gw = 0;
  for (int i = adj_offsets[v]; i < adj_offsets[v + 1]; ++i) {
    gs += gface_screen[adj[i]].xyz;
    gw += gface_world[adj[i]].xyz;
  }
  FrameGrads gf = {0, 0, 0, 0};
  gvworld[v] += (real4)(project_bwd(vworld[v].xyz, vscreen[v].xyz, gs, P + P_FRAME, &gf) + gw, 0);
  gframe[4 * v] = (real4)(gf.eye, 0);
  gframe[4 * v + 1] = (real4)(gf.fwd, 0);
  gframe[4 * v + 2] = (real4)(gf.right, 0);
  gframe[4 * v + 3] = (real4)(gf.up, 0);
}

// Backward: each albedo entry (a vertex's or a face's, as its mesh has them) gathers, in a fixed
// order, the per-corner dL/d(albedo) of the corners that read it.
//   offsets (A+1) × int, corners (Σ) × int: entries face*3 + corner, sorted
//   gface_albedo  3F × real4;  galbedo  A × real4 (added to: the cameras' in turn)
BACKWARD_KERNEL void albedo_bwd(int na, __global const int* offsets, __global const int* corners,
                                __global const real4* gface_albedo, __global real4* galbedo) {
  int a = get_global_id(0);
  if (a >= na) return;
  real4 g = 0;
  for (int i = offsets[a]; i < offsets[a + 1]; ++i) g += gface_albedo[corners[i]];
  galbedo[a] += g;
}

// Backward: the sum over `rows` rows of n reals (per-face light gradients, per-vertex frame
// gradients), on the device: part p sums rows [p·run, (p + 1)·run) in row order into
// partial[p·n + i], and the host adds the parts in order, so that the sum is the same on every
// device however the launch is scheduled. Launch: parts · n work-items.
BACKWARD_KERNEL void sum_rows(__global const real* in, int rows, int n, int run, int parts,
                              __global real* partial) {
  const int id = get_global_id(0), i = id % n, part = id / n;
  if (part >= parts) return;
  real sum = 0;
  for (int r = part * run; r < min(rows, (part + 1) * run); ++r) sum += in[(size_t)r * n + i];
  partial[(size_t)part * n + i] = sum;
}
