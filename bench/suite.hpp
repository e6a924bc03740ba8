#pragma once
#include <string>
#include <vector>

#include "common.hpp"

// The benchmark groups; main.cpp registers them in this order.
namespace penumbra::bench {

void register_ceiling_benchmarks();     // bench_ceiling.cpp: peak FMA and exp throughput
void register_render_benchmarks();      // bench_render.cpp: forward and backward cases
void register_turnaround_benchmarks();  // bench_turnaround.cpp: the paper's 90-frame orbit
void register_accuracy_benchmarks();    // bench_accuracy.cpp: error against ray tracing
// --build-floor N,N,...: builds programs of N trivial kernels instead of benchmarking
// (bench_build_floor.cpp); returns the exit status.
int run_build_floor(const std::string& counts);
// --host-stages [N]: the host's stage times per render at 1k, 100k and 1M faces instead of
// benchmarking (bench_host_stages.cpp); returns the exit status.
int run_host_stages(const std::string& calls);
// The forward, backward and step cases register_render_benchmarks registers, by their names
// (without Google Benchmark's /manual_time), for --paired.
struct RenderCase {
  enum class Kind { Forward, Backward, Step };
  std::string name;
  Case c;
  Kind kind;
};
const std::vector<RenderCase>& render_cases();
// --paired DIR_A DIR_B REGEX [N]: the render cases matching REGEX, timed with the kernels of two
// directories in turn in one process (bench_paired.cpp); returns the exit status.
int run_paired(const std::vector<std::string>& args);
// After the run: the turnaround ratios beside the paper's (no-op if they did not run).
void print_turnaround_summary();

}  // namespace penumbra::bench
