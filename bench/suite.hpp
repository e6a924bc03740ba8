#pragma once
// The benchmark groups; main.cpp registers them in this order.
namespace penumbra::bench {

void register_ceiling_benchmarks();     // bench_ceiling.cpp: peak FMA and exp throughput
void register_render_benchmarks();      // bench_render.cpp: forward and backward cases
void register_turnaround_benchmarks();  // bench_turnaround.cpp: the paper's 90-frame orbit
void register_accuracy_benchmarks();    // bench_accuracy.cpp: error against ray tracing
// After the run: the turnaround ratios beside the paper's (no-op if they did not run).
void print_turnaround_summary();

}  // namespace penumbra::bench
