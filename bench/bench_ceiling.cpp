// The machine's ceiling through the same OpenCL device: peak single-precision FMA throughput
// and exp throughput of small compute-bound kernels (explicit float16 vectors, several
// independent chains per work-item so neither latency nor memory limits them). The render
// figures are reported against these.
#include <CL/opencl.hpp>

#include <string>

#include "common.hpp"
#include "ops/args.hpp"
#include "suite.hpp"

namespace penumbra::bench {

namespace {

// kChains independent float16 chains per work-item.
constexpr int kChains = 12;
constexpr int kItems = 64;  // work-items (local size 1: each is one vector "thread")

const char* kSource = R"CLC(
#define DECL(k) float16 x##k = (float16)(seed + 0.001f * k);
#define SUM(k) acc += x##k;
#define COMMA ,
#define ALL(M) M(0) M(1) M(2) M(3) M(4) M(5) M(6) M(7) M(8) M(9) M(10) M(11)

// A kernel of kChains (12) independent chains x = STEP(x), `iters` steps each, summed into out.
#define PEAK_KERNEL(name, PARAMS, STEP)                         \
  __kernel void name(__global float16* out, int iters PARAMS) { \
    float seed = get_global_id(0) * 1e-6f;                      \
    ALL(DECL)                                                   \
    for (int i = 0; i < iters; ++i) {                           \
      ALL(STEP)                                                 \
    }                                                           \
    float16 acc = 0;                                            \
    ALL(SUM)                                                    \
    out[get_global_id(0)] = acc;                                \
  }
#define FMA_STEP(k) x##k = fma(x##k, a, b);
#define EXP_STEP(k) x##k = exp(-x##k);
#define NATIVE_EXP_STEP(k) x##k = native_exp(-x##k);
PEAK_KERNEL(fma_peak, COMMA float a COMMA float b, FMA_STEP)
PEAK_KERNEL(exp_peak, , EXP_STEP)
PEAK_KERNEL(native_exp_peak, , NATIVE_EXP_STEP)
)CLC";

// The kernels' arguments, bound as the library binds its own (ops/args.hpp).
struct FmaPeakArgs {
  static constexpr const char* file = "bench_ceiling.cpp";
  static constexpr const char* kernel = "fma_peak";
  const cl::Buffer& out;
  cl_int iters;
  detail::Real a, b;
  auto fields() const { return std::tie(out, iters, a, b); }
};

struct ExpPeakArgs {  // exp_peak and native_exp_peak
  static constexpr const char* file = "bench_ceiling.cpp";
  const char* kernel;
  const cl::Buffer& out;
  cl_int iters;
  auto fields() const { return std::tie(out, iters); }
};

// Built by each case (outside its timing), so no OpenCL object outlives main().
cl::Program build_program() {
  cl::Program prog(context().cl_context(), std::string(kSource));
  prog.build("-cl-std=CL1.2");
  return prog;
}

// ops: floating-point operations (or exps) per chain step.
void run_ceiling(benchmark::State& state, const char* kernel, int iters, double ops,
                 const char* counter) {
  Context& ctx = context();
  cl::Program program;
  cl::Kernel k;
  cl::Buffer out;
  try {
    program = build_program();
    k = cl::Kernel(program, kernel);
    out = cl::Buffer(ctx.cl_context(), CL_MEM_WRITE_ONLY, sizeof(float) * 16 * kItems);
    if (std::string(kernel) == "fma_peak")
      detail::bind_args(k, FmaPeakArgs{out, iters, 0.9999999f, 1e-7f}, Precision::Float);
    else
      detail::bind_args(k, ExpPeakArgs{kernel, out, iters}, Precision::Float);
    ctx.queue().enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(kItems), cl::NDRange(1));
    ctx.queue().finish();  // warm-up
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
    return;
  }
  const double med = timed_frames(state, [&] {
    ctx.queue().enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(kItems), cl::NDRange(1));
    ctx.queue().finish();
  });
  const double total = double(kItems) * iters * kChains * 16 * ops;
  state.counters[counter] = med > 0 ? total / med / 1e9 : 0;
}

}  // namespace

void register_ceiling_benchmarks() {
  benchmark::RegisterBenchmark(
      "ceiling/fma",
      [](benchmark::State& st) { run_ceiling(st, "fma_peak", 100000, 2.0, "gflops"); })
      ->UseManualTime()
      ->Unit(benchmark::kMillisecond);
  benchmark::RegisterBenchmark(
      "ceiling/exp",
      [](benchmark::State& st) { run_ceiling(st, "exp_peak", 10000, 1.0, "gexp_per_s"); })
      ->UseManualTime()
      ->Unit(benchmark::kMillisecond);
  benchmark::RegisterBenchmark(
      "ceiling/native_exp",
      [](benchmark::State& st) { run_ceiling(st, "native_exp_peak", 10000, 1.0, "gexp_per_s"); })
      ->UseManualTime()
      ->Unit(benchmark::kMillisecond);
}

}  // namespace penumbra::bench
