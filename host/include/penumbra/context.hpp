#pragma once
// OpenCL device selection, queue and program cache. One Context per process is typical.
#include <CL/opencl.hpp>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

namespace penumbra {

struct DeviceInfo {
  int index = 0;  // position in list_devices()
  std::string platform, name, vendor, version;
  bool is_gpu = false, fp64 = false;
  bool shares_host_memory = false;  // its memory is the host's (CL_DEVICE_HOST_UNIFIED_MEMORY)
  size_t global_mem = 0, max_alloc = 0, max_work_group = 0;
  cl::Device device;
};

// Every OpenCL device of every platform; throws penumbra::Error if there is none.
std::vector<DeviceInfo> list_devices();

// Releases the compiled programs CLBlast (the exact sampling's GEMM) keeps for every context.
// A program about to exit calls it: left to CLBlast's static destructor, they are released
// after the OpenCL implementation may have torn itself down (Oclgrind: a heap corruption at
// exit, docs/faults.md). Calls into CLBlast made afterwards compile its programs again.
void release_gemm_programs();

// One OpenCL device, its context and queue. Threads may open contexts at once, and several
// renderers, of one thread or many, may share one; each outlives the renderers made on it.
class Context {
 public:
  // `device`: empty → $PENUMBRA_DEVICE → the first GPU, else the first device. Otherwise an
  // index into list_devices() or a case-insensitive substring of the device or platform name.
  explicit Context(const std::string& device = "");

  const DeviceInfo& info() const { return info_; }
  cl::Context& cl_context() { return context_; }
  cl::CommandQueue& queue() { return queue_; }

  // Builds (once per process) kernels/<file> with the given -D options; includes of
  // "common/..." are resolved from the embedded sources, or from $PENUMBRA_KERNEL_DIR when set.
  // A binary compiled by an earlier process is reused from the kernel cache
  // ($PENUMBRA_CACHE_DIR, README "Environment variables") when the device, driver, expanded
  // source and options all match. A build failure throws penumbra::Error carrying the
  // compiler log.
  cl::Program& program(const std::string& file, const std::string& options);

  // The kernel cache's folder (README "Environment variables"); empty when it is off.
  static std::string cache_dir();
  // Source of kernels/<file> with includes expanded (for tests and diagnostics).
  static std::string kernel_source(const std::string& file);
  // What program() gives the OpenCL compiler for `options`: them and -cl-std=CL1.2.
  static std::string build_options(const std::string& options);
  // The (file, build_options) of every program built so far, in file order.
  std::vector<std::pair<std::string, std::string>> programs() const;

  // The device memory a call may use: `bytes`, named `by` in messages ("--max-memory"), or
  // (0, the default) all the device reports. A render or backward that needs more, estimated
  // before anything is allocated, throws penumbra::Error with both amounts (KiB, MiB, GiB).
  void set_memory_limit(size_t bytes, const std::string& by);
  size_t memory_limit() const { return memory_limit_ ? memory_limit_ : info_.global_mem; }
  const std::string& memory_limit_by() const { return memory_limit_by_; }

  // How results are read and inputs written: false, through mapped buffers (no copy where the
  // device's memory is the host's, as PoCL's); true, through reused host memory and copies,
  // which a discrete GPU's driver transfers faster (docs/gpu.md). $PENUMBRA_TRANSFERS (map or
  // copy) chooses; unset, copies where the device's memory is not the host's.
  bool copy_transfers() const { return copy_transfers_; }

 private:
  cl::Program build_from_source(const std::string& file, const std::string& source,
                                const std::string& options);
  size_t memory_limit_ = 0;
  std::string memory_limit_by_;
  bool copy_transfers_ = false;
  DeviceInfo info_;
  cl::Context context_;
  cl::CommandQueue queue_;
  std::map<std::string, cl::Program> programs_;
  mutable std::mutex programs_mutex_;  // renderers of several threads build programs at once
};

// The name of an OpenCL error code ("CL_OUT_OF_RESOURCES"), or "CL_ERROR(<code>)".
std::string opencl_error_name(int code);

}  // namespace penumbra
