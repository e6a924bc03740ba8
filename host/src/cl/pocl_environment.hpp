// What penumbra sets in PoCL's environment before the first OpenCL call, when PoCL reads it
// (README, "Environment variables"). A value the user set is left alone.
#pragma once

#include <vector>

namespace penumbra::detail {

// Turns off POCL_TRACING=cq (with a warning), turns off PoCL's work-group specialization and
// pins PoCL's worker threads to the cores where that is safe. Once per process; list_devices()
// calls it before it asks for the platforms.
void prepare_pocl_environment();

// The CPUs this thread may run on (sched_getaffinity; none where it fails).
std::vector<int> allowed_cpus();

// Whether PoCL may pin its worker thread i to CPU i (POCL_AFFINITY=1) without aborting: the
// process may run on every one of the machine's online CPUs, numbered 0 .. online − 1 (`allowed`
// in ascending order, as allowed_cpus() gives it).
bool pocl_threads_may_be_pinned(const std::vector<int>& allowed_cpus, long online_cpus);

}  // namespace penumbra::detail
