// Host side of kernels/matmul.cl: dense products for the exact-sum shadow sampling, by the
// direct kernels or by CLBlast's GEMM (the same numbers up to summation order).
#include <clblast.h>

#include "ops/ops.hpp"
#include "penumbra/error.hpp"

namespace penumbra::detail {

namespace {

void clblast_gemm(Kernels& k, bool ta, bool tb, size_t m, size_t n, size_t kk,
                  const cl::Buffer& A, size_t lda, const cl::Buffer& B, size_t ldb, double beta,
                  cl::Buffer& C, size_t ldc) {
  // CLBlast computes β·C even for β = 0: C must not hold NaN from old memory.
  cl_command_queue q = k.ctx().queue()();
  auto t = [](bool x) { return x ? clblast::Transpose::kYes : clblast::Transpose::kNo; };
  clblast::StatusCode status =
      k.precision() == Precision::Double
          ? clblast::Gemm<double>(clblast::Layout::kRowMajor, t(ta), t(tb), m, n, kk, 1.0, A(), 0,
                                  lda, B(), 0, ldb, beta, C(), 0, ldc, &q)
          : clblast::Gemm<float>(clblast::Layout::kRowMajor, t(ta), t(tb), m, n, kk, 1.0f, A(),
                                 0, lda, B(), 0, ldb, float(beta), C(), 0, ldc, &q);
  if (status != clblast::StatusCode::kSuccess)
    throw Error("CLBlast GEMM failed with status " + std::to_string(int(status)));
}

void direct(Kernels& k, const char* name, size_t m, size_t n, size_t kk, const cl::Buffer& A,
            size_t lda, const cl::Buffer& B, size_t ldb, double beta, cl::Buffer& C, size_t ldc,
            size_t cols_per_item) {
  auto& mm = k.get("matmul.cl", name);  // MM_VW and MM_RB come from the tuning
  set_args(mm, int(m), int(n), int(kk), A, int(lda), B, int(ldb));
  if (k.precision() == Precision::Double)
    mm.setArg(7, beta);
  else
    mm.setArg(7, float(beta));
  mm.setArg(8, C);
  mm.setArg(9, int(ldc));
  const size_t rows_per_item = size_t(k.tuning().exact.row_block);
  launch(k.ctx(), mm,
         cl::NDRange((n + cols_per_item - 1) / cols_per_item,
                     (m + rows_per_item - 1) / rows_per_item),
         cl::NDRange(8, 8));  // no barriers: the group size only sets scheduling
}

}  // namespace

void matmul_nt(Kernels& k, bool clblast, size_t m, size_t n, size_t kk, const cl::Buffer& A,
               size_t lda, const cl::Buffer& B, size_t ldb, double beta, cl::Buffer& C,
               size_t ldc) {
  if (clblast) return clblast_gemm(k, false, true, m, n, kk, A, lda, B, ldb, beta, C, ldc);
  direct(k, "matmul_nt", m, n, kk, A, lda, B, ldb, beta, C, ldc, k.tuning().exact.row_block);
}

void matmul_tn(Kernels& k, bool clblast, size_t m, size_t n, size_t kk, const cl::Buffer& A,
               size_t lda, const cl::Buffer& B, size_t ldb, double beta, cl::Buffer& C,
               size_t ldc) {
  if (clblast) return clblast_gemm(k, true, false, m, n, kk, A, lda, B, ldb, beta, C, ldc);
  direct(k, "matmul_tn", m, n, kk, A, lda, B, ldb, beta, C, ldc, k.tuning().exact.vector_width);
}

}  // namespace penumbra::detail
