/* Layout of the per-view parameter buffer `P` (an array of `real`), shared verbatim by the
 * host (C++) and the kernels (OpenCL C) so that neither side can drift from the other.
 * Per-view values live in a buffer rather than in -D options: they change between renders
 * (optimisation, sweeps) and must not trigger recompilation. */
#ifndef PENUMBRA_LAYOUT_H
#define PENUMBRA_LAYOUT_H

/* A camera frame (the view's camera, or a light's camera), FR_SIZE reals. */
#define FR_EYE 0         /* eye position */
#define FR_FWD 3         /* unit viewing direction; view depth z = (X − eye)·fwd */
#define FR_RIGHT 6
#define FR_UP 9
#define FR_SCALE 12      /* tan(fov/2) (perspective) or half-height (orthographic) */
#define FR_ORTHO 13      /* 1 orthographic, 0 perspective */
#define FR_SIZE 14

#define P_SIGMA 0        /* coverage sharpness σ */
#define P_GAMMA 1        /* aggregation sharpness γ */
#define P_EPS 2          /* background depth ε */
#define P_CUTOFF_D2 3    /* σ·ln(1/ε_D − 1): outside faces at d² ≥ this are skipped */
#define P_NEAR 4
#define P_FAR 5
#define P_CULL 6         /* 1: skip faces whose normal faces away from the camera */
#define P_NLIGHTS 7
#define P_WEIGHT_LOG 8   /* ln(1/ε_w): fragments with (z̃ − m)/γ below −this are not aggregated */
#define P_SHADOWS 9      /* 0 none, 1 hard, 2 soft */
#define P_SIGMA_S 10     /* shadow-map Gaussian variance σ_s (texel²) */
#define P_LAMBDA_EPS 11  /* truncation threshold ε_λ */
#define P_GAMMA_S 12     /* depth-compare softness γ_s */
#define P_BETA 13        /* depth bias β */
#define P_GAMMA_P 14     /* penumbra soft-minimum sharpness γ_P */
#define P_LIGHT_SIZE 15  /* a light's own view: its diameter D_L (penumbra map) */
#define P_AMBIENT 16     /* RGB */
#define P_BACKGROUND 19  /* RGB */
#define P_WINDOW_R2 22   /* 2σ_s·ln(1/ε_λ): squared radius of the truncated shadow-map window */
#define P_WINDOW_R 23    /* its square root */
#define P_FRAME 24       /* the view's camera frame (FR_SIZE reals) */
#define P_SHADOW_MODEL 38 /* 0 paper (filter then compare, penumbra map), 1 accurate (PCF) */
#define P_RECEIVER_PLANE 39 /* 1: fragments keep their receiver-plane depth gradient ∇_μ d */
#define P_CASTERS_ONLY 40 /* a light's view in the accurate model: 1 drops the faces that cannot
                             cast a shadow (transform.cl's casts_no_shadow) */
#define P_SCENE_LO 41    /* the scene's bounding box, xyz (with P_CASTERS_ONLY) */
#define P_SCENE_HI 44
#define P_NEAREST_TEXEL_COUNTS 47 /* 1: the texel nearest any μ in a map weighs g' > 0 in the
                                     truncated window (paper_lookups.cl's shadow_sample) */
#define P_LIGHTS 48      /* P_LIGHT_STRIDE reals per light: */
#define L_POS 0          /*   position (point) or travel direction (directional), xyz */
#define L_POINT 3        /*   1 point light, 0 directional */
#define L_COLOR 4        /*   RGB intensity */
#define L_SIZE 7         /*   diameter D_L */
#define L_FRAME 8        /*   the light's camera frame (FR_SIZE reals) */
#define L_MAP_W 22       /*   shadow-map size in texels */
#define L_MAP_H 23
#define L_SEARCH_SIGMA 24 /*   accurate soft shadows: variance σ_b (texel²) of the blocker search */
#define L_SEARCH_STRIDE 25 /*   its stride st: it sums over every st-th texel of each axis */
#define L_CUBE_FACE 26   /*   LightFrustum::cube_face: the face of a cube it is (0 … 5), or −1 */
/* A cube's faces hand over across their edges in a band of tangents 1/CUBE_BLEND_TAN …
   CUBE_BLEND_TAN off each face's axis (shade.clh: cube_share), ±2.7° about the edge's 45°. */
#define CUBE_BLEND_TAN 1.1
#define P_LIGHT_STRIDE 32
#define P_MAX_LIGHTS 8
#define P_SIZE (P_LIGHTS + P_LIGHT_STRIDE * P_MAX_LIGHTS)

#endif
