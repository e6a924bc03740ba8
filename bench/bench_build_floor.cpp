// penumbra_bench --build-floor N,N,...: the least a cold first call can spend building its
// programs on this device. One program per count, of that many trivial kernels, each built as
// penumbra builds a stage's program (clBuildProgram, then its binary for the kernel cache), one
// after another in this new process; prints each program's milliseconds as JSON. With an empty
// POCL_CACHE_DIR, PoCL pays here what it pays for any first program (loading its kernel
// library), any program (the front end) and any kernel (work-group and code generation), and
// nothing for the kernels' own code. bench/first_call.py runs it with the counts of the programs
// a first render builds.
#include <chrono>
#include <cstdio>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "common.hpp"
#include "suite.hpp"

namespace penumbra::bench {
namespace {

std::vector<int> parse_counts(const std::string& text) {
  std::vector<int> counts;
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) {
    int n = 0;
    if (!parse_int(item, 1, 64, &n))
      throw std::invalid_argument("--build-floor wants kernel counts 1-64, comma-separated: '" +
                                  text + "'");
    counts.push_back(n);
  }
  if (counts.empty()) throw std::invalid_argument("--build-floor wants at least one count");
  return counts;
}

// `kernels` kernels that each store a constant; the program index in their names keeps every
// program's source (and so PoCL's cache key) distinct.
std::string trivial_source(int program, int kernels) {
  std::string src;
  for (int k = 0; k < kernels; ++k)
    src += "__kernel void floor_" + std::to_string(program) + "_" + std::to_string(k) +
           "(__global float* a) { a[get_global_id(0)] = " + std::to_string(k) + "; }\n";
  return src;
}

}  // namespace

int run_build_floor(const std::string& counts_text) {
  try {
    const std::vector<int> counts = parse_counts(counts_text);
    Context& ctx = context();
    std::string json = "{\"kernels\": [";
    std::string times = "], \"programs_ms\": [";
    for (std::size_t p = 0; p < counts.size(); ++p) {
      auto start = std::chrono::steady_clock::now();
      cl::Program program(ctx.cl_context(), trivial_source(int(p), counts[p]));
      program.build("-cl-std=CL1.2");
      program.getInfo<CL_PROGRAM_BINARIES>();
      std::chrono::duration<double, std::milli> ms = std::chrono::steady_clock::now() - start;
      json += (p ? ", " : "") + std::to_string(counts[p]);
      times += (p ? ", " : "") + std::to_string(ms.count());
    }
    if (std::printf("%s%s]}\n", json.c_str(), times.c_str()) < 0 || std::fflush(stdout) != 0)
      throw std::runtime_error("cannot write to standard output");
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "penumbra_bench: %s\n", e.what());
    return 1;
  }
}

}  // namespace penumbra::bench
