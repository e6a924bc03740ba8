/* Layout of the per-view parameter buffer `P` (an array of `real`), shared verbatim by the
 * host (C++) and the kernels (OpenCL C) so that neither side can drift from the other.
 * Per-view values live in a buffer rather than in -D options: they change between renders
 * (optimisation, sweeps) and must not trigger recompilation. */
#ifndef PENUMBRA_LAYOUT_H
#define PENUMBRA_LAYOUT_H

#define P_SIGMA 0        /* coverage sharpness σ */
#define P_GAMMA 1        /* aggregation sharpness γ */
#define P_EPS 2          /* background depth ε */
#define P_CUTOFF_D2 3    /* σ·ln(1/ε_D − 1): outside faces at d² ≥ this are skipped */
#define P_NEAR 4
#define P_FAR 5
#define P_ORTHO 6        /* 1 orthographic, 0 perspective */
#define P_SCALE 7        /* tan(fov/2) (perspective) or half-height (orthographic) */
#define P_CULL 8         /* 1: skip faces whose normal faces away from the camera */
#define P_NLIGHTS 9
#define P_EYE 12         /* camera frame, 3 reals each */
#define P_RIGHT 15
#define P_UP 18
#define P_FWD 21
#define P_AMBIENT 24
#define P_BACKGROUND 27
#define P_LIGHTS 32      /* P_LIGHT_STRIDE reals per light: */
#define L_POS 0          /*   position (point) or travel direction (directional), xyz */
#define L_POINT 3        /*   1 point light, 0 directional */
#define L_COLOR 4        /*   RGB intensity */
#define L_SIZE 7         /*   diameter D_L */
#define P_LIGHT_STRIDE 8
#define P_MAX_LIGHTS 8
#define P_SIZE (P_LIGHTS + P_LIGHT_STRIDE * P_MAX_LIGHTS)

#endif
