// penumbra_bench: Google Benchmark suite of the renderer. Usual Google Benchmark flags apply
// (--benchmark_filter, --benchmark_min_time, --benchmark_format=json, --benchmark_out=FILE,
// --benchmark_repetitions, --benchmark_list_tests). Without --benchmark_filter the default
// suite runs: every case whose name does not start with large/; --scaling adds to it the large
// cases of the face and image sweeps (to 1M faces and 2048² images). To run every large case
// too, pass --benchmark_filter=. (everything) or --benchmark_filter=large/ (only them).
// --build-floor N,N,... builds programs of trivial kernels and runs no benchmark
// (bench_build_floor.cpp); --host-stages [N] times the host's stages of a render, and of a
// render and its backward, at 1k, 100k and 1M faces and runs no benchmark
// (bench_host_stages.cpp); --paired DIR_A DIR_B REGEX [N] times the matching forward, backward
// and step cases with the kernels of two directories in turn in one process and runs no
// benchmark (bench_paired.cpp).
#include <benchmark/benchmark.h>

#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include "common.hpp"
#include "suite.hpp"

namespace {

constexpr const char* kDefaultFilter =
    "--benchmark_filter=^(ceiling|fwd|bwd|step|turnaround|accuracy)/";
// The sweeps' large cases (bench_render.cpp): every face count at 256², every image size at the
// bundled scene, truncated sampling.
constexpr const char* kScalingCases =
    "|^large/(fwd|bwd)/[a-z]+/truncated/"
    "img:(256/map:256/faces:[0-9]+|[0-9]+/map:256/faces:1312)/sigma_s:2/lights:1/";

std::string first_line_with(const char* path, const char* prefix) {
  std::ifstream f(path);
  std::string line;
  while (std::getline(f, line))
    if (line.rfind(prefix, 0) == 0) {
      auto colon = line.find(':');
      auto v = colon == std::string::npos ? line : line.substr(colon + 1);
      v.erase(0, v.find_first_not_of(" \t"));
      return v;
    }
  return "";
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<char*> args{argv[0]};
  bool has_filter = false, scaling = false;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--build-floor") == 0)
      return penumbra::bench::run_build_floor(i + 1 < argc ? argv[i + 1] : "");
    if (std::strcmp(argv[i], "--host-stages") == 0)
      return penumbra::bench::run_host_stages(i + 1 < argc ? argv[i + 1] : "");
    if (std::strcmp(argv[i], "--paired") == 0) {
      penumbra::bench::register_render_benchmarks();  // the cases, by name
      return penumbra::bench::run_paired({argv + i + 1, argv + argc});
    }
    if (std::strcmp(argv[i], "--scaling") == 0) {
      scaling = true;
      continue;
    }
    has_filter |= std::strncmp(argv[i], "--benchmark_filter", 18) == 0;
    args.push_back(argv[i]);
  }
  std::string filter = std::string(kDefaultFilter) + (scaling ? kScalingCases : "");
  if (!has_filter) args.insert(args.begin() + 1, filter.data());
  int n = int(args.size());
  benchmark::Initialize(&n, args.data());
  if (benchmark::ReportUnrecognizedArguments(n, args.data())) return 1;

  using namespace penumbra::bench;
  try {
    const auto& info = context().info();
    benchmark::AddCustomContext("device", info.name);
    benchmark::AddCustomContext("device_platform", info.platform);
    benchmark::AddCustomContext("device_version", info.version);
    benchmark::AddCustomContext("cpu_model", first_line_with("/proc/cpuinfo", "model name"));
    benchmark::AddCustomContext("loadavg_at_start", [] {
      std::ifstream f("/proc/loadavg");
      std::string a, b, c;
      f >> a >> b >> c;
      return a + " " + b + " " + c;
    }());
    reset_peak_rss();
    benchmark::AddCustomContext(
        "peak_memory", peak_rss_resettable()
                           ? "host RSS high-water mark per case (VmHWM, reset by "
                             "/proc/self/clear_refs at the case's start, so it includes what "
                             "earlier cases left resident); PoCL device buffers live in host memory"
                           : "host RSS high-water mark of the whole process (ru_maxrss); PoCL "
                             "device buffers live in host memory");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "penumbra_bench: no OpenCL device: %s\n", e.what());
    return 1;
  }

  register_ceiling_benchmarks();
  register_render_benchmarks();
  register_turnaround_benchmarks();
  register_accuracy_benchmarks();
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  release_device();
  print_turnaround_summary();
  return 0;
}
