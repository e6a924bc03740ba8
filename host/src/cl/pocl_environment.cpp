// PoCL's environment, set before the first OpenCL call (pocl_environment.hpp).
#include "cl/pocl_environment.hpp"

#include <sched.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <numeric>
#include <string>

namespace penumbra::detail {

namespace {

// PoCL 3.1's command-queue profiler (POCL_TRACING=cq) corrupts the heap of any program that
// launches a few kernels (docs/faults.md: a 20-line reproduction), so it is turned off, with a
// warning.
void turn_off_pocl_cq_tracing() {
  const char* value = std::getenv("POCL_TRACING");
  if (value == nullptr || std::string(value) != "cq") return;
  ::unsetenv("POCL_TRACING");
  std::fprintf(stderr,
               "penumbra: warning: POCL_TRACING=cq turned off: PoCL's command-queue profiler "
               "corrupts memory (docs/faults.md); PENUMBRA_PROFILE=1 prints the device time "
               "per kernel instead\n");
}

// PoCL compiles each kernel twice in a process that fills the kernel cache: once for any
// work-group size when the program's binary is asked for (the binary holds that code), once
// more at its first launch for that launch's sizes, unless work-group specialization is off —
// then a launch runs the code the binary holds, and a process that loads the cache compiles
// nothing. Measured on the bundled scene (bench/first_call.py): cold first render 3.7 -> 2.6 s,
// with the kernel cache filled and PoCL's empty 1.19 s -> 59 ms; frame times unchanged within
// the noise and outputs bit-identical.
void skip_pocl_work_group_specialization() {
  ::setenv("POCL_WORK_GROUP_SPECIALIZATION", "0", /*overwrite=*/0);
}

// PoCL's worker threads are free to move between cores. With kernels of a millisecond and the
// host waiting on the device between them (a batch of small renders), the scheduler can keep
// both workers of a 2-core machine on one core for seconds at a time, and renders take about
// 1.5 times as long (bench/pocl_pinning.py; README). PoCL pins worker i to
// CPU i when POCL_AFFINITY is 1, and aborts where the process may not run on that CPU (a
// container's cpuset; docs/faults.md), so it is set only where the process may run on all.
void pin_pocl_threads() {
  if (std::getenv("POCL_AFFINITY") != nullptr) return;
  if (pocl_threads_may_be_pinned(allowed_cpus(), ::sysconf(_SC_NPROCESSORS_ONLN)))
    ::setenv("POCL_AFFINITY", "1", /*overwrite=*/0);
}

}  // namespace

std::vector<int> allowed_cpus() {
  std::vector<int> cpus;
  cpu_set_t set;
  CPU_ZERO(&set);
  if (::sched_getaffinity(0, sizeof set, &set) != 0) return cpus;
  for (int i = 0; i < CPU_SETSIZE; ++i)
    if (CPU_ISSET(i, &set)) cpus.push_back(i);
  return cpus;
}

bool pocl_threads_may_be_pinned(const std::vector<int>& allowed, long online) {
  if (online <= 0 || long(allowed.size()) != online) return false;
  std::vector<int> every(allowed.size());
  std::iota(every.begin(), every.end(), 0);
  return allowed == every;
}

void prepare_pocl_environment() {
  static const bool done = [] {
    turn_off_pocl_cq_tracing();
    skip_pocl_work_group_specialization();
    pin_pocl_threads();
    return true;
  }();
  (void)done;
}

}  // namespace penumbra::detail
