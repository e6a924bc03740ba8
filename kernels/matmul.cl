// Dense matrix products for the exact-sum shadow sampling (SPEC §4), the direct-kernel
// alternative to CLBlast's GEMM. Row-major matrices with leading dimensions:
//   matmul_nt  C (M × N) = A (M × K) · Bᵀ (B is N × K)  + beta·C   (T = Gx·Sᵀ)
//   matmul_tn  C (M × N) = Aᵀ (A is K × M) · B (K × N)  + beta·C   (dL/dS = Gyᵀ·Gx)
//   matmul_nn_rowdot  out_r = Σ_c (A·B)_rc·D_rc (B is K × N), without storing A·B
//                     (Σ_i U_ri·Gx_ri, U = Gy·S); row_dot: the same of a stored C (CLBlast's GEMM)
// Both run along rows in MM_VW-wide vectors, which is what makes them fast on CPUs (PoCL);
// each work-item computes an MM_RB × MM_RB block (nt) or 2·MM_RB rows × 2·MM_VW columns (tn).
// Launch: nt global (ceil(N/MM_RB), ceil(M/MM_RB)); tn global (ceil(N/(2·MM_VW)), ceil(M/(2·MM_RB)));
// nn_rowdot global ceil(M/MM_RB); row_dot global M.
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

__kernel void matmul_nt(int M, int N, int K, __global const real* A, int lda,
                        __global const real* B, int ldb, real beta, __global real* C, int ldc) {
  int n0 = get_global_id(0) * MM_RB, m0 = get_global_id(1) * MM_RB;
  if (m0 >= M || n0 >= N) return;
  // Rows past the edge repeat the last row (their results are not stored).
  __global const real* a[MM_RB];
  __global const real* b[MM_RB];
  for (int r = 0; r < MM_RB; ++r) {
    a[r] = A + (size_t)min(m0 + r, M - 1) * lda;
    b[r] = B + (size_t)min(n0 + r, N - 1) * ldb;
  }
  realV acc[MM_RB][MM_RB];
#pragma unroll
  for (int i = 0; i < MM_RB; ++i)
#pragma unroll
    for (int j = 0; j < MM_RB; ++j) acc[i][j] = 0;
  int kv = K / MM_VW;
  for (int k = 0; k < kv; ++k) {
    realV bv[MM_RB];
#pragma unroll
    for (int j = 0; j < MM_RB; ++j) bv[j] = VLOAD(k, b[j]);
#pragma unroll
    for (int i = 0; i < MM_RB; ++i) {
      realV av = VLOAD(k, a[i]);
#pragma unroll
      for (int j = 0; j < MM_RB; ++j) acc[i][j] += av * bv[j];
    }
  }
  for (int i = 0; i < MM_RB && m0 + i < M; ++i)
    for (int j = 0; j < MM_RB && n0 + j < N; ++j) {
      real s = HSUM(acc[i][j]);
      for (int k = kv * MM_VW; k < K; ++k) s += a[i][k] * b[j][k];
      store(C, ldc, m0 + i, n0 + j, s, beta);
    }
}

// B's columns c .. c + MM_VW − 1 of row k, zeros past column N.
inline realV load_cols(__global const real* row, int c, int N) {
  if (c + MM_VW <= N) return VLOAD(0, row + c);
  real t[MM_VW];
  for (int l = 0; l < MM_VW; ++l) t[l] = c + l < N ? row[c + l] : 0;
  return VLOAD(0, t);
}

// Each work-item takes MM_RB rows and walks the columns of A·B in blocks of 2·MM_VW: a block is
// MM_RB × 2 vectors of accumulators, each step along k one scalar of A times a vector of B (no
// horizontal sums until the last), then multiplied by the same columns of D into a vector per row.
#define NB (2 * MM_VW)
__kernel void matmul_nn_rowdot(int M, int N, int K, __global const real* A, int lda,
                               __global const real* B, int ldb, __global const real* D, int ldd,
                               __global real* out) {
  int m0 = get_global_id(0) * MM_RB;
  if (m0 >= M) return;
  __global const real* a[MM_RB];
  __global const real* d[MM_RB];
  for (int r = 0; r < MM_RB; ++r) {  // rows past the edge repeat the last row (not stored)
    a[r] = A + (size_t)min(m0 + r, M - 1) * lda;
    d[r] = D + (size_t)min(m0 + r, M - 1) * ldd;
  }
  realV dot[MM_RB];
#pragma unroll
  for (int i = 0; i < MM_RB; ++i) dot[i] = 0;
  for (int c = 0; c < N; c += NB) {
    realV acc[MM_RB][2];
#pragma unroll
    for (int i = 0; i < MM_RB; ++i) acc[i][0] = acc[i][1] = 0;
    if (c + NB <= N) {
      for (int k = 0; k < K; ++k) {
        __global const real* b = B + (size_t)k * ldb + c;
        realV b0 = VLOAD(0, b), b1 = VLOAD(1, b);
#pragma unroll
        for (int i = 0; i < MM_RB; ++i) {
          real ak = a[i][k];
          acc[i][0] += ak * b0;
          acc[i][1] += ak * b1;
        }
      }
    } else {  // the ragged right edge
      for (int k = 0; k < K; ++k) {
        __global const real* b = B + (size_t)k * ldb;
        realV b0 = load_cols(b, c, N), b1 = load_cols(b, c + MM_VW, N);
#pragma unroll
        for (int i = 0; i < MM_RB; ++i) {
          real ak = a[i][k];
          acc[i][0] += ak * b0;
          acc[i][1] += ak * b1;
        }
      }
    }
#pragma unroll
    for (int i = 0; i < MM_RB; ++i)
      dot[i] += acc[i][0] * load_cols(d[i], c, N) + acc[i][1] * load_cols(d[i], c + MM_VW, N);
  }
  for (int i = 0; i < MM_RB && m0 + i < M; ++i) out[m0 + i] = HSUM(dot[i]);
}

__kernel void row_dot(int M, int N, __global const real* C, int ldc, __global const real* D,
                      int ldd, __global real* out) {
  int r = get_global_id(0);
  if (r >= M) return;
  real dot = 0;
  for (int j = 0; j < N; ++j) dot += C[(size_t)r * ldc + j] * D[(size_t)r * ldd + j];
  out[r] = dot;
}

// matmul_tn's rows per work-item: its K (fragments) is long, so each row block streams all of
// A and B; twice nt's rows halve that traffic.
#define TN_RB (2 * MM_RB)
__kernel void matmul_tn(int M, int N, int K, __global const real* A, int lda,
                        __global const real* B, int ldb, real beta, __global real* C, int ldc) {
  int n0 = get_global_id(0) * 2 * MM_VW, m0 = get_global_id(1) * TN_RB;
  if (m0 >= M || n0 >= N) return;
  // Two vectors of columns (one where only one fits: the second then repeats the first and is
  // not stored), so that 2·TN_RB independent sums hide the FMA latency.
  int vectors = min((N - n0) / MM_VW, 2), n1 = vectors == 2 ? n0 + MM_VW : n0;
  if (vectors > 0) {
    realV acc[TN_RB][2];
#pragma unroll
    for (int i = 0; i < TN_RB; ++i) acc[i][0] = acc[i][1] = 0;
    for (int k = 0; k < K; ++k) {
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
      for (int k = 0; k < K; ++k) s += A[(size_t)k * lda + m0 + i] * B[(size_t)k * ldb + j];
      store(C, ldc, m0 + i, j, s, beta);
    }
}
