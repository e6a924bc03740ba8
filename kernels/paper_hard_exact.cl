// Stage 5 (paper model, hard shadows, exact sampling) — the lookups' matrix products
// (math.md §6.2, §8.3), the direct-kernel alternative to CLBlast's GEMM. Row-major matrices with
// leading dimensions:
//   matmul_tn  C (M × N) = Aᵀ (A is K × M) · B (K × N)  + beta·C   (dL/dS = Gyᵀ·Gx)
//   matmul_nn_rowdots out_r = (Σ_c (A·B)_rc·D_rc, Σ_c (A·B)_rc·Dd_rc, Σ_c (Ad·B)_rc·D_rc, 0)
//                     (B is K × N) without storing A·B or Ad·B: with U = Gy·S, the exact sums
//                     Σ_i U_ri·Gx_ri and the backward's Σ_i U_ri·Gxd_ri, Σ_i (Gyd·S)_ri·Gx_ri;
//                     matmul_nn_rowdot the first alone (.y, .z 0); row_dot(s) of stored products
// support: per fragment r (a row of A, D in nn; of A, B in tn's chunks), int4: the first and last
// nonzero column of its row of Gx, Gxd (.xy: D, Dd in nn, B in tn) and of Gy, Gyd (.zw: A,
// Ad); first > last where the row is all 0 (exact_weights, paper_lookups.cl). The products skip the
// zeros outside: the terms they would add are exact zeros (every matrix is finite), and adding
// ±0 to a sum that starts at +0 changes no bit of it.
// The products run along rows in MM_VW-wide vectors, which is what makes them fast on CPUs
// (PoCL): a work-item computes 2·MM_RB rows × 2·MM_VW columns (tn), or MM_RB rows of A·B in
// blocks of 2·MM_VW columns (nn_rowdot(s)). Launch: tn global (ceil(N/(2·MM_VW)),
// ceil(M/(2·MM_RB))); nn_rowdot(s) global ceil(M/MM_RB); row_dot(s) global M.
// The loops over a work-item's accumulators are unrolled (#pragma unroll) so that the
// accumulators live in registers: left as loops, PoCL kept them in memory, a load and a store
// around every FMA (both products 2x slower on the 2-core AVX-512 CPU of docs/benchmarks.md).
#include "common/real.clh"

#ifndef MM_VW
#define MM_VW 8  // vector width along rows: 1, 2, 4, 8 or 16
#endif
#ifndef MM_RB
#define MM_RB 4  // rows of C per work-item
#endif

#if MM_VW == 1
#define realV real
#define VLOAD(i, p) (p)[i]
#define VSTORE(v, p) ((p)[0] = (v))
#define HSUM(v) (v)
#else
#define realV CAT(real, MM_VW)
#define VLOAD(i, p) CAT(vload, MM_VW)(i, p)
#define VSTORE(v, p) CAT(vstore, MM_VW)(v, 0, p)
#endif
#if MM_VW == 2
#define HSUM(v) ((v).s0 + (v).s1)
#elif MM_VW == 4
#define HSUM(v) ((v).s0 + (v).s1 + (v).s2 + (v).s3)
#elif MM_VW == 8
#define HSUM(v) (HSUM4((v).lo) + HSUM4((v).hi))
#elif MM_VW == 16
#define HSUM(v) (HSUM4((v).lo.lo) + HSUM4((v).lo.hi) + HSUM4((v).hi.lo) + HSUM4((v).hi.hi))
#endif
#define HSUM4(v) ((v).s0 + (v).s1 + (v).s2 + (v).s3)

inline void store(__global real* C, int ldc, int row, int col, real v, real beta) {
  __global real* c = C + (size_t)row * ldc + col;
  *c = beta == 0 ? v : v + beta * *c;
}

// B's columns c .. c + MM_VW − 1 of row k, zeros past column N.
inline realV load_cols(__global const real* row, int c, int N) {
  if (c + MM_VW <= N) return VLOAD(0, row + c);
  real t[MM_VW];
  for (int l = 0; l < MM_VW; ++l) t[l] = c + l < N ? row[c + l] : 0;
  return VLOAD(0, t);
}

// One step along k of a column block: row i's scalar of A (and of Ad) times two vectors of B.
inline void nn_step(realV acc[MM_RB][2], realV accd[MM_RB][2], __global const real** a,
                    __global const real** ad, int k, realV b0, realV b1, const int derivatives) {
#pragma unroll
  for (int i = 0; i < MM_RB; ++i) {
    real ak = a[i][k];
    acc[i][0] += ak * b0;
    acc[i][1] += ak * b1;
    if (derivatives) {
      real adk = ad[i][k];
      accd[i][0] += adk * b0;
      accd[i][1] += adk * b1;
    }
  }
}

// MM_RB rows from m0 walk the columns of A·B in blocks of 2·MM_VW: a block is MM_RB × 2 vectors
// of accumulators, each step along k one scalar of A times a vector of B (no horizontal sums
// until the last), then multiplied by the same columns of D into a vector per row: dot[0][i].
// With `derivatives` (a constant: the compiler drops what it does not use) also the rows of
// Ad·B, and dot[1][i] = Σ (A·B)·Dd, dot[2][i] = Σ (Ad·B)·D.
#define NB (2 * MM_VW)
INLINE void nn_rowdots(int m0, int M, int N, int K, __global const real* A,
                       __global const real* Ad, int lda, __global const real* B, int ldb,
                       __global const real* D, __global const real* Dd, int ldd,
                       __global const int4* support, const int derivatives,
                       realV dot[3][MM_RB]) {
  __global const real *a[MM_RB], *ad[MM_RB], *d[MM_RB], *dd[MM_RB];
  int4 on = (int4)(N, -1, K, -1);  // the rows' supports together
  for (int r = 0; r < MM_RB; ++r) {  // rows past the edge repeat the last row (not stored)
    size_t row = (size_t)min(m0 + r, M - 1);
    a[r] = A + row * lda;
    d[r] = D + row * ldd;
    ad[r] = derivatives ? Ad + row * lda : a[r];
    dd[r] = derivatives ? Dd + row * ldd : d[r];
    int4 s = support[row];
    on = (int4)(min(on.x, s.x), max(on.y, s.y), min(on.z, s.z), max(on.w, s.w));
  }
#pragma unroll
  for (int i = 0; i < MM_RB; ++i) dot[0][i] = dot[1][i] = dot[2][i] = 0;
  // Column blocks where D and Dd are zero add nothing to dot, steps along k where A and Ad are
  // zero nothing to acc: both skipped (the blocks keep their places on the grid of NB).
  for (int c = on.x / NB * NB; c <= on.y; c += NB) {
    realV acc[MM_RB][2], accd[MM_RB][2];
#pragma unroll
    for (int i = 0; i < MM_RB; ++i) acc[i][0] = acc[i][1] = accd[i][0] = accd[i][1] = 0;
    if (c + NB <= N) {
      for (int k = on.z; k <= on.w; ++k) {
        __global const real* b = B + (size_t)k * ldb + c;
        nn_step(acc, accd, a, ad, k, VLOAD(0, b), VLOAD(1, b), derivatives);
      }
    } else {  // the ragged right edge
      for (int k = on.z; k <= on.w; ++k) {
        __global const real* b = B + (size_t)k * ldb;
        nn_step(acc, accd, a, ad, k, load_cols(b, c, N), load_cols(b, c + MM_VW, N),
                derivatives);
      }
    }
#pragma unroll
    for (int i = 0; i < MM_RB; ++i) {
      realV g0 = load_cols(d[i], c, N), g1 = load_cols(d[i], c + MM_VW, N);
      dot[0][i] += acc[i][0] * g0 + acc[i][1] * g1;
      if (derivatives) {
        realV e0 = load_cols(dd[i], c, N), e1 = load_cols(dd[i], c + MM_VW, N);
        dot[1][i] += acc[i][0] * e0 + acc[i][1] * e1;
        dot[2][i] += accd[i][0] * g0 + accd[i][1] * g1;
      }
    }
  }
}

// out_r = (dot[0], dot[1], dot[2], 0) of nn_rowdots, each summed across its vector.
inline void nn_rowdots_kernel(int M, int N, int K, __global const real* A,
                              __global const real* Ad, int lda, __global const real* B, int ldb,
                              __global const real* D, __global const real* Dd, int ldd,
                              __global const int4* support, __global real4* out,
                              const int derivatives) {
  int m0 = get_global_id(0) * MM_RB;
  if (m0 >= M) return;
  realV dot[3][MM_RB];
  nn_rowdots(m0, M, N, K, A, Ad, lda, B, ldb, D, Dd, ldd, support, derivatives, dot);
  for (int i = 0; i < MM_RB && m0 + i < M; ++i)
    out[m0 + i] = (real4)(HSUM(dot[0][i]), HSUM(dot[1][i]), HSUM(dot[2][i]), 0);
}

__kernel void matmul_nn_rowdot(int M, int N, int K, __global const real* A,
                               __global const real* Ad, int lda, __global const real* B, int ldb,
                               __global const real* D, __global const real* Dd, int ldd,
                               __global const int4* support, __global real4* out) {
  nn_rowdots_kernel(M, N, K, A, Ad, lda, B, ldb, D, Dd, ldd, support, out, 0);
}

__kernel void matmul_nn_rowdots(int M, int N, int K, __global const real* A,
                                __global const real* Ad, int lda, __global const real* B,
                                int ldb, __global const real* D, __global const real* Dd,
                                int ldd, __global const int4* support, __global real4* out) {
  nn_rowdots_kernel(M, N, K, A, Ad, lda, B, ldb, D, Dd, ldd, support, out, 1);
}

// out_r = (Σ C·D, Σ C·Dd, Σ Cd·D, 0) of stored products (CLBlast's GEMM); row_dot the first
// alone, as nn_rowdots does.
inline void row_dots_kernel(int M, int N, __global const real* C, __global const real* Cd,
                            int ldc, __global const real* D, __global const real* Dd, int ldd,
                            __global real4* out, const int derivatives) {
  int r = get_global_id(0);
  if (r >= M) return;
  real4 dot = 0;
  for (int j = 0; j < N; ++j) {
    real c = C[(size_t)r * ldc + j], d = D[(size_t)r * ldd + j];
    dot.x += c * d;
    if (derivatives) {
      dot.y += c * Dd[(size_t)r * ldd + j];
      dot.z += Cd[(size_t)r * ldc + j] * d;
    }
  }
  out[r] = dot;
}

__kernel void row_dot(int M, int N, __global const real* C, __global const real* Cd, int ldc,
                      __global const real* D, __global const real* Dd, int ldd,
                      __global real4* out) {
  row_dots_kernel(M, N, C, Cd, ldc, D, Dd, ldd, out, 0);
}

__kernel void row_dots(int M, int N, __global const real* C, __global const real* Cd, int ldc,
                       __global const real* D, __global const real* Dd, int ldd,
                       __global real4* out) {
  row_dots_kernel(M, N, C, Cd, ldc, D, Dd, ldd, out, 1);
}

// matmul_tn's rows per work-item: its K (fragments) is long, so each row block streams all of
// A and B; twice nt's rows halve that traffic.
#define TN_RB (2 * MM_RB)
// Whether a chunk's support box s (below) can be nonzero in columns m0 .. m1 of A and
// n0 .. n1 of B.
inline int tn_reaches(int4 s, int m0, int m1, int n0, int n1) {
  return s.z <= m1 && s.w >= m0 && s.x <= n1 && s.y >= n0;
}

// matmul_tn's chunks of TN_CHUNK consecutive rows k (the host's kTnChunk): the union of their
// supports, empty rows left out (all empty: a box that reaches nothing). A work-item of
// matmul_tn tests a chunk before its rows, which, k after k, had been most of its time (every
// row of A and B is zero outside a small part of a big map); it adds every row of a chunk that
// reaches its block, in order: a row that does not reach it adds exact zeros, which change no
// bit of the sums, and a test per row was a branch the CPU mispredicted between its reads of
// the rows. Launch: global ceil(K/TN_CHUNK).
#define TN_CHUNK 16
__kernel void support_chunks(int K, __global const int4* support, __global int4* chunks) {
  int c = get_global_id(0);
  if (c * TN_CHUNK >= K) return;
  int4 box = (int4)(INT_MAX, INT_MIN, INT_MAX, INT_MIN);
  for (int k = c * TN_CHUNK; k < min(K, (c + 1) * TN_CHUNK); ++k) {
    int4 s = support[k];
    if (s.x <= s.y && s.z <= s.w)
      box = (int4)(min(box.x, s.x), max(box.y, s.y), min(box.z, s.z), max(box.w, s.w));
  }
  chunks[c] = box;
}

// The rows k a block of C (columns m0 .. m1 of A, n0 .. n1 of B) visits, in order: those of
// the chunks whose box reaches it.
#define FOR_EACH_TN_ROW(k, m0, m1, n0, n1)              \
  for (int c_ = 0; c_ * TN_CHUNK < K; ++c_)             \
    if (tn_reaches(chunks[c_], m0, m1, n0, n1))         \
      for (int k = c_ * TN_CHUNK; k < min(K, (c_ + 1) * TN_CHUNK); ++k)

__kernel void matmul_tn(int M, int N, int K, __global const real* A, int lda,
                        __global const real* B, int ldb, __global const int4* chunks, real beta,
                        __global real* C, int ldc) {
  int n0 = get_global_id(0) * 2 * MM_VW, m0 = get_global_id(1) * TN_RB;
  if (m0 >= M || n0 >= N) return;
  // Two vectors of columns (one where only one fits: the second then repeats the first and is
  // not stored), so that 2·TN_RB independent sums hide the FMA latency.
  int vectors = min((N - n0) / MM_VW, 2), n1 = vectors == 2 ? n0 + MM_VW : n0;
  const int m_last = min(m0 + TN_RB, M) - 1;
  if (vectors > 0) {
    realV acc[TN_RB][2];
#pragma unroll
    for (int i = 0; i < TN_RB; ++i) acc[i][0] = acc[i][1] = 0;
    FOR_EACH_TN_ROW(k, m0, m_last, n0, n1 + MM_VW - 1) {
      realV b0 = VLOAD(0, B + (size_t)k * ldb + n0), b1 = VLOAD(0, B + (size_t)k * ldb + n1);
      __global const real* a = A + (size_t)k * lda;
#pragma unroll
      for (int i = 0; i < TN_RB; ++i) {
        real ak = a[min(m0 + i, M - 1)];
        acc[i][0] += ak * b0;
        acc[i][1] += ak * b1;
      }
    }
    for (int i = 0; i < TN_RB && m0 + i < M; ++i)
      for (int v = 0; v < vectors; ++v) {
        real out[MM_VW];
        VSTORE(acc[i][v], out);
        for (int j = 0; j < MM_VW; ++j) store(C, ldc, m0 + i, n0 + v * MM_VW + j, out[j], beta);
      }
  }
  for (int i = 0; i < TN_RB && m0 + i < M; ++i)  // the ragged right edge, column by column
    for (int j = n0 + vectors * MM_VW; j < min(n0 + 2 * MM_VW, N); ++j) {
      real s = 0;
      FOR_EACH_TN_ROW(k, m0 + i, m0 + i, j, j) s += A[(size_t)k * lda + m0 + i] * B[(size_t)k * ldb + j];
      store(C, ldc, m0 + i, j, s, beta);
    }
}
