// Host side of kernels/paper_hard_exact.cl: dense products for the exact-sum shadow sampling, by
// the direct kernels or by CLBlast's GEMM (the same numbers up to summation order).
#include <clblast.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <mutex>
#include <tuple>
#include <unordered_map>

#include "ops/args.hpp"
#include "penumbra/error.hpp"

namespace penumbra::detail {

namespace {

using ClblastParams = std::unordered_map<std::string, size_t>;

std::string status_name(clblast::StatusCode s) {
  using S = clblast::StatusCode;
  switch (s) {
    case S::kOpenCLBuildProgramFailure:
      return "kOpenCLBuildProgramFailure";
    case S::kInvalidLocalThreadsTotal:
      return "kInvalidLocalThreadsTotal";
    case S::kInvalidLocalThreadsDim:
      return "kInvalidLocalThreadsDim";
    case S::kInvalidOverrideKernel:
      return "kInvalidOverrideKernel";
    case S::kMissingOverrideParameter:
      return "kMissingOverrideParameter";
    case S::kInvalidLocalMemUsage:
      return "kInvalidLocalMemUsage";
    case S::kNoDoublePrecision:
      return "kNoDoublePrecision";
    case S::kDatabaseError:
      return "kDatabaseError";
    case S::kUnexpectedError:
      return "kUnexpectedError";
    default:
      return "status " + std::to_string(int(s));
  }
}

// What is wrong with CLBlast's GEMM under the parameters now set, "" if nothing: a 64³ product of
// small whole numbers (exact in float and double, in any order of summation) against the host's,
// through the Xgemm kernel (routine `min_indirect_size` 1 during the check). CLBlast 1.5 accepts
// sets that compute wrong products (docs/tuning.md, "CLBlast's own tuner").
std::string xgemm_check(Kernels& k) {
  const size_t n = 64;
  std::vector<double> a(n * n), b(n * n), want(n * n, 0.0);
  for (size_t i = 0; i < n * n; ++i) a[i] = double(i * 7 % 5), b[i] = double(i * 3 % 4);
  for (size_t i = 0; i < n; ++i)  // column-major, as asked below
    for (size_t j = 0; j < n; ++j)
      for (size_t l = 0; l < n; ++l) want[j * n + i] += a[l * n + i] * b[j * n + l];
  Context& ctx = k.ctx();
  const cl::Buffer A = upload_reals(ctx, k.precision(), a), B = upload_reals(ctx, k.precision(), b);
  cl::Buffer C = upload_reals(ctx, k.precision(), std::vector<double>(n * n, 0.0));
  cl_command_queue q = ctx.queue()();
  const auto col = clblast::Layout::kColMajor;
  const auto no = clblast::Transpose::kNo;
  const clblast::StatusCode status =
      k.precision() == Precision::Double
          ? clblast::Gemm<double>(col, no, no, n, n, n, 1.0, A(), 0, n, B(), 0, n, 0.0, C(), 0, n,
                                  &q, nullptr)
          : clblast::Gemm<float>(col, no, no, n, n, n, 1.0f, A(), 0, n, B(), 0, n, 0.0f, C(), 0, n,
                                 &q, nullptr);
  if (status != clblast::StatusCode::kSuccess) return "it failed (" + status_name(status) + ")";
  const std::vector<double> got = download_reals(ctx, k.precision(), C, n * n);
  double worst = 0;
  for (size_t i = 0; i < n * n; ++i) worst = std::max(worst, std::abs(got[i] - want[i]));
  if (!(worst == 0))
    return "an error of " + std::to_string(worst) + " in a 64³ product of whole numbers";
  return "";
}

// CLBlast keeps one parameter set per (device, precision, kernel) for the whole process, so
// the tuning's set is applied only when it differs from the one applied last (an unset one
// restores CLBlast's own, read before the first override). Each new set makes the next GEMM
// compile CLBlast's GEMM program cold, about 5 s on PoCL (CLBlast then keeps the program).
void apply_clblast_parameters(Kernels& k) {
  struct Applied {
    ClblastParams defaults, current;
  };
  static std::mutex mutex;
  static std::map<std::tuple<cl_device_id, Precision, std::string>, Applied> applied;

  const ExactSumTuning& e = k.tuning().exact;
  cl_device_id device = k.ctx().info().device();
  const auto precision = k.precision() == Precision::Double ? clblast::Precision::kDouble
                                                            : clblast::Precision::kSingle;
  auto apply = [&](const char* kernel, const ClblastParams* wanted) {
    auto [it, first] = applied.try_emplace({device, k.precision(), kernel});
    Applied& a = it->second;
    if (first) {
      const auto status = clblast::RetrieveParameters(device, kernel, precision, a.defaults);
      if (status != clblast::StatusCode::kSuccess) {
        applied.erase(it);
        throw Error(std::string("CLBlast cannot report its ") + kernel + " parameters (" +
                    status_name(status) + ")");
      }
      a.current = a.defaults;
    }
    const ClblastParams& target = wanted ? *wanted : a.defaults;
    if (target == a.current) return false;
    const auto status = clblast::OverrideParameters(device, kernel, precision, target);
    if (status != clblast::StatusCode::kSuccess)
      throw Error(std::string("CLBlast rejected the ") + kernel + " parameters (" +
                  status_name(status) + ")");
    a.current = target;
    return true;
  };

  std::lock_guard<std::mutex> lock(mutex);
  ClblastParams xgemm, routine;
  if (e.xgemm)
    for (const auto& [name, field] : XgemmParameters::fields())
      xgemm[name] = size_t((*e.xgemm).*field);
  if (e.min_indirect_size > 0) routine["XGEMM_MIN_INDIRECT_SIZE"] = size_t(e.min_indirect_size);
  if (apply("Xgemm", e.xgemm ? &xgemm : nullptr) && e.xgemm) {  // a new set: does it multiply?
    const ClblastParams always{{"XGEMM_MIN_INDIRECT_SIZE", 1}};
    apply("GemmRoutine", &always);
    const std::string wrong = xgemm_check(k);
    if (!wrong.empty()) {
      apply("Xgemm", nullptr);
      throw Error("CLBlast's GEMM computes wrong products with the tuning's Xgemm set (" +
                  e.xgemm->describe() + "): " + wrong +
                  "; remove the set from the tuning database or run penumbra tune");
    }
  }
  apply("GemmRoutine", e.min_indirect_size > 0 ? &routine : nullptr);
}

// C = β·C + op(A)·op(B), row-major; A and B start `a_row` and `b_row` rows into their buffers.
void clblast_gemm(Kernels& k, bool ta, bool tb, size_t m, size_t n, size_t kk, const cl::Buffer& A,
                  size_t a_row, size_t lda, const cl::Buffer& B, size_t b_row, size_t ldb,
                  double beta, cl::Buffer& C, size_t ldc) {
  apply_clblast_parameters(k);
  // CLBlast computes β·C even for β = 0: C must not hold NaN from old memory.
  cl_command_queue q = k.ctx().queue()();
  auto t = [](bool x) { return x ? clblast::Transpose::kYes : clblast::Transpose::kNo; };
  cl_event done = nullptr;
  cl_event* event = detail::profiling() ? &done : nullptr;
  // Asked as the column-major Cᵀ = op(B)ᵀ·op(A)ᵀ: CLBlast's indirect GEMM copies a row-major
  // C, transposed, into a temporary buffer and back, and a row-major A besides. Column-major it
  // leaves C and S in place (the gemm forward: 177-180 ms against 222 on the Xeon of
  // benchmarks.md).
  const auto col = clblast::Layout::kColMajor;
  clblast::StatusCode status =
      k.precision() == Precision::Double
          ? clblast::Gemm<double>(col, t(tb), t(ta), n, m, kk, 1.0, B(), b_row * ldb, ldb, A(),
                                  a_row * lda, lda, beta, C(), 0, ldc, &q, event)
          : clblast::Gemm<float>(col, t(tb), t(ta), n, m, kk, 1.0f, B(), b_row * ldb, ldb, A(),
                                 a_row * lda, lda, float(beta), C(), 0, ldc, &q, event);
  if (status != clblast::StatusCode::kSuccess)
    throw Error("CLBlast GEMM failed (" + status_name(status) + ")");
  if (done) detail::profile_launch("clblast_gemm", cl::Event(done));  // takes the reference
}

struct MatmulTnArgs {
  static constexpr const char* file = "paper_hard_exact.cl";
  static constexpr const char* kernel = "matmul_tn";
  cl_int M, N, K;
  const cl::Buffer& A;
  cl_int lda;
  const cl::Buffer& B;
  cl_int ldb;
  const cl::Buffer& chunks;
  Real beta;
  const cl::Buffer& C;
  cl_int ldc;
  auto fields() const { return std::tie(M, N, K, A, lda, B, ldb, chunks, beta, C, ldc); }
};

struct SupportChunksArgs {
  static constexpr const char* file = "paper_hard_exact.cl";
  static constexpr const char* kernel = "support_chunks";
  cl_int K;
  const cl::Buffer &support, &chunks;
  auto fields() const { return std::tie(K, support, chunks); }
};

constexpr size_t kTnChunk = 16;  // TN_CHUNK of paper_hard_exact.cl
constexpr size_t kClblastTnBytes = size_t(2) << 20;

// matmul_nn_rowdot and matmul_nn_rowdots take the same arguments; `kernel` says which.
struct MatmulRowdotsArgs {
  static constexpr const char* file = "paper_hard_exact.cl";
  const char* kernel;
  cl_int M, N, K;
  const cl::Buffer &A, &Ad;
  cl_int lda;
  const cl::Buffer& B;
  cl_int ldb;
  const cl::Buffer &D, &Dd;
  cl_int ldd;
  const cl::Buffer &support, &out;
  auto fields() const { return std::tie(M, N, K, A, Ad, lda, B, ldb, D, Dd, ldd, support, out); }
};

// row_dot and row_dots take the same arguments; `kernel` says which.
struct RowDotsArgs {
  static constexpr const char* file = "paper_hard_exact.cl";
  const char* kernel;
  cl_int M, N;
  const cl::Buffer &C, &Cd;
  cl_int ldc;
  const cl::Buffer &D, &Dd;
  cl_int ldd;
  const cl::Buffer& out;
  auto fields() const { return std::tie(M, N, C, Cd, ldc, D, Dd, ldd, out); }
};

// `buffer`, made by `make` on first use and whenever it holds fewer than `bytes`.
template <class Make>
cl::Buffer& kept(cl::Buffer& buffer, size_t bytes, Make make) {
  if (!buffer() || buffer.getInfo<CL_MEM_SIZE>() < bytes) buffer = make();
  return buffer;
}

}  // namespace

void matmul_nn_rowdots(Kernels& k, bool clblast, size_t m, size_t n, size_t kk, const cl::Buffer& A,
                       const cl::Buffer* Ad, size_t lda, const cl::Buffer& B, size_t ldb,
                       const cl::Buffer& D, const cl::Buffer* Dd, size_t ldd,
                       const cl::Buffer& support, ProductScratch& scratch, cl::Buffer& out) {
  const bool derivatives = Ad && Dd;
  const cl::Buffer &ad = derivatives ? *Ad : A, &dd = derivatives ? *Dd : D;
  if (clblast) {
    auto make = [&] { return alloc_reals(k.ctx(), k.precision(), m * n); };
    const size_t bytes = m * n * real_size(k.precision());
    cl::Buffer& C = kept(scratch.products, bytes, make);
    clblast_gemm(k, false, false, m, n, kk, A, 0, lda, B, 0, ldb, 0.0, C, n);
    cl::Buffer& Cd = derivatives ? kept(scratch.products_d, bytes, make) : C;
    if (derivatives) clblast_gemm(k, false, false, m, n, kk, ad, 0, lda, B, 0, ldb, 0.0, Cd, n);
    auto& rd = bind_args(k, RowDotsArgs{derivatives ? "row_dots" : "row_dot", int(m), int(n), C, Cd,
                                        int(n), D, dd, int(ldd), out});
    return launch_1d(k.ctx(), rd, m);
  }
  auto& mm = bind_args(
      k, MatmulRowdotsArgs{derivatives ? "matmul_nn_rowdots" : "matmul_nn_rowdot", int(m), int(n),
                           int(kk), A, ad, int(lda), B, int(ldb), D, dd, int(ldd), support, out});
  const size_t rows_per_item = size_t(k.tuning().exact.row_block);  // MM_RB
  launch_1d(k.ctx(), mm, (m + rows_per_item - 1) / rows_per_item, 8);
}

void matmul_tn(Kernels& k, bool clblast, size_t m, size_t n, size_t kk, const cl::Buffer& A,
               size_t lda, const cl::Buffer& B, size_t ldb, const cl::Buffer& support,
               ProductScratch& scratch, double beta, cl::Buffer& C, size_t ldc) {
  if (clblast) {
    // On a CPU in chunks of the k rows whose operands fill about 2 MiB (a core's L2 on the Xeon
    // of benchmarks.md): there dL/dS of a 256² map (k = 8192 fragments) took 41 ms in one GEMM,
    // 16-17 ms in chunks of 1024. GPUs (not measured) keep one GEMM.
    const size_t rows_bytes = (lda + ldb) * real_size(k.precision());
    const size_t chunk =
        k.ctx().info().is_gpu ? kk : std::max<size_t>(1, kClblastTnBytes / rows_bytes);
    for (size_t k0 = 0; k0 < kk; k0 += chunk)
      clblast_gemm(k, true, false, m, n, std::min(chunk, kk - k0), A, k0, lda, B, k0, ldb,
                   k0 ? 1.0 : beta, C, ldc);
    return;
  }
  const size_t nchunks = (kk + kTnChunk - 1) / kTnChunk;
  const size_t boxes = std::max<size_t>(nchunks, 1) * 4;  // an int4 box per chunk
  const cl::Buffer& chunks =
      kept(scratch.chunks, boxes * sizeof(int), [&] { return alloc_ints(k.ctx(), boxes); });
  launch_1d(k.ctx(), bind_args(k, SupportChunksArgs{int(kk), support, chunks}), nchunks);
  auto& mm = bind_args(k, MatmulTnArgs{int(m), int(n), int(kk), A, int(lda), B, int(ldb), chunks,
                                       beta, C, int(ldc)});
  const ExactSumTuning& t = k.tuning().exact;  // 2·MM_RB rows, 2·MM_VW columns per work-item
  const size_t rows = 2 * size_t(t.row_block), cols = 2 * size_t(t.vector_width);
  launch(k.ctx(), mm, cl::NDRange((n + cols - 1) / cols, (m + rows - 1) / rows),
         cl::NDRange(8, 8));  // no barriers: the group size only sets scheduling
}

std::optional<XgemmParameters> clblast_tuned_xgemm(Context& ctx, size_t m, size_t n, size_t k,
                                                   double fraction, std::string* why) {
  ClblastParams found;
  cl_command_queue q = ctx.queue()();
  clblast::StatusCode status;
  try {
    status = clblast::TuneXgemm<float>(&q, m, n, k, fraction, found);
  } catch (const std::exception& e) {  // the API reports by status; be sure nothing escapes
    *why = std::string("CLBlast's Xgemm tuner failed: ") + e.what();
    return std::nullopt;
  }
  if (status != clblast::StatusCode::kSuccess) {
    *why = "CLBlast's Xgemm tuner failed (" + status_name(status) + ")";
    return std::nullopt;
  }
  XgemmParameters x;
  for (const auto& [name, field] : XgemmParameters::fields()) {
    const auto it = found.find(name);
    if (it == found.end()) {
      *why = std::string("CLBlast's Xgemm tuner gave no ") + name;
      return std::nullopt;
    }
    x.*field = int(it->second);
  }
  return x;
}

}  // namespace penumbra::detail

namespace penumbra {

void release_gemm_programs() { clblast::ClearCache(); }

}  // namespace penumbra
