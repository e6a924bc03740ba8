#pragma once
// Small helpers around opencl.hpp: buffers of `real` (float or double on the device, double on
// the host), launches with padded global sizes.
#include <CL/opencl.hpp>
#include <cstddef>
#include <map>
#include <string>
#include <vector>

#include "penumbra/context.hpp"
#include "penumbra/renderer.hpp"

namespace penumbra::detail {

// What depends on the kind of device when no tuning decides, in one place. CPUs (PoCL) give a
// work-item vectors of pixels or texels; GPUs keep the parallelism of one per item.
struct DeviceDefaults {
  int pixels_per_item;  // raster (the tuning's default) and penumbra map: 8 on CPUs
  int shadow_row;       // ROW of paper_lookups.cl/accurate_lookups.cl's lookups: 16 floats fill an
                        // AVX-512 register
  int gather_height;    // GatherTuning::height: on CPUs a fragment's weights and tests shared
                        // by 8 rows (Xeon: pcf_gather 32 -> 22 ms with 8 instead of 4 rows)
  bool exact_on_clblast;  // the heuristic tuning's exact backend: CLBlast on GPUs
  int face_lanes;         // the raster backward's work-items per face: a GPU waits for its
                          // longest work-item (bundled scene, H200: raster_bwd 23 ms with 1)
  int gather_group;       // GatherTuning::group: a GPU work-item reading its texel buckets
                          // alone waits on its own loads (H100: 100k-face hard backward
                          // 235 ms with 1, 142 with 2, 146 with 4, 156 with 8; docs/gpu.md)
  int sort_group;         // bin_sort's work-items per tile list (SORT_GROUP of bin.cl): a GPU's
                          // lists come in no order (H100, 100k faces: 9.6 ms a launch with 1)
  int gather_width;       // GatherTuning::width: on CPUs a run of 16 texels left most lanes of a
                          // fragment's window idle (Xeon: soft_gather 29 -> 18 ms a launch with
                          // 8); on GPUs the shortest run did best (H200, 100k-face hard
                          // backward: 120 ms with 8, 110 with 4; docs/gpu.md)
};
inline DeviceDefaults device_defaults(const DeviceInfo& d) {
  if (d.is_gpu) return {1, 8, 1, true, 32, 2, int(std::min<size_t>(256, d.max_work_group)), 4};
  return {8, 16, 8, false, 1, 1, 1, 8};
}

// Oclgrind (a simulator that checks every access: scripts/oclgrind.sh) builds its kernels with
// -DPENUMBRA_OCLGRIND (kernels/common/real.clh says why); no other device gets the option.
inline bool is_oclgrind(const DeviceInfo& d) { return d.platform == "Oclgrind"; }
// PoCL on a CPU builds long kernels' bodies as functions of their own (-DPENUMBRA_POCL_CPU:
// kernels/common/real.clh says why).
inline bool is_pocl_cpu(const DeviceInfo& d) {
  return !d.is_gpu && d.platform == "Portable Computing Language";
}

inline size_t real_size(Precision p) { return p == Precision::Double ? 8 : 4; }
// Float kernels flush subnormal numbers to zero: the Gaussian weights' products reach them
// (1e-20·1e-20), and on CPUs each subnormal operation is a microcode assist that cost the exact
// backward's dL/dS product most of its time (4.1 -> 1.2 ms a batch, Xeon of
// docs/benchmarks.md). Double stays IEEE-exact, gradient checks run in it.
inline std::string precision_options(Precision p) {
  return p == Precision::Double ? "-DPENUMBRA_DOUBLE" : "-cl-denorms-are-zero";
}

// This thread's staging memory for copied transfers (Context::copy_transfers), at least
// `bytes`: it only grows, so that its pages stay faulted in.
void* staging(size_t bytes);
// Calls fill(float*) or fill(double*), as the precision, to write the first `count` reals of
// `buf`: into the buffer mapped for writing (no host copy), or with Context::copy_transfers into
// staging memory that is then written. `fill` must not call read_reals or write_reals.
template <class Fill>
void fill_reals(Context& ctx, Precision p, cl::Buffer& buf, size_t count, Fill fill) {
  if (count == 0) return;
  const size_t bytes = count * real_size(p);
  const bool map = !ctx.copy_transfers();
  void* at =
      map ? ctx.queue().enqueueMapBuffer(buf, CL_TRUE, CL_MAP_WRITE_INVALIDATE_REGION, 0, bytes)
          : staging(bytes);
  try {
    if (p == Precision::Double)
      fill(static_cast<double*>(at));
    else
      fill(static_cast<float*>(at));
  } catch (...) {
    if (map) clEnqueueUnmapMemObject(ctx.queue()(), buf(), at, 0, nullptr, nullptr);
    throw;
  }
  if (map)
    ctx.queue().enqueueUnmapMemObject(buf, at);
  else
    ctx.queue().enqueueWriteBuffer(buf, CL_TRUE, 0, bytes, at);
}
// Device buffer holding `values` converted to the precision's real type.
cl::Buffer upload_reals(Context& ctx, Precision p, const std::vector<double>& values);
void write_reals(Context& ctx, Precision p, cl::Buffer& buf, const std::vector<double>& values);
std::vector<double> download_reals(Context& ctx, Precision p, const cl::Buffer& buf, size_t count);
// The first `bytes` of `buf` copied into this thread's staging memory, reused from call to call
// (valid until its next call).
const void* staged_read(Context& ctx, const cl::Buffer& buf, size_t bytes);
// Calls read(const float*) or read(const double*), as the precision, on the first `count` reals
// of `buf`: mapped for reading (no host copy: at 100k faces the copies into fresh host memory
// cost ~18 ms of a backward; on PoCL a map is the buffer itself), or with
// Context::copy_transfers copied into reused staging memory (staged_read), which a discrete
// GPU's driver serves faster than a map of each new buffer (docs/gpu.md). `read` must not call
// read_reals or write_reals.
template <class Read>
void read_reals(Context& ctx, Precision p, const cl::Buffer& buf, size_t count, Read read) {
  if (count == 0) return;
  const size_t bytes = count * real_size(p);
  if (ctx.copy_transfers()) {
    const void* at = staged_read(ctx, buf, bytes);
    if (p == Precision::Double)
      read(static_cast<const double*>(at));
    else
      read(static_cast<const float*>(at));
    return;
  }
  void* at = ctx.queue().enqueueMapBuffer(buf, CL_TRUE, CL_MAP_READ, 0, bytes);
  try {
    if (p == Precision::Double)
      read(static_cast<const double*>(at));
    else
      read(static_cast<const float*>(at));
  } catch (...) {
    clEnqueueUnmapMemObject(ctx.queue()(), buf(), at, 0, nullptr, nullptr);  // then rethrow
    throw;
  }
  ctx.queue().enqueueUnmapMemObject(buf, at);  // checked: a failure throws
}
cl::Buffer upload_ints(Context& ctx, const std::vector<int>& values);
std::vector<int> download_ints(Context& ctx, const cl::Buffer& buf, size_t count);
// Uninitialised device buffer of `count` reals (at least one element).
cl::Buffer alloc_reals(Context& ctx, Precision p, size_t count);
cl::Buffer alloc_ints(Context& ctx, size_t count);
// Uninitialised buffer of `count` elements of `size` bytes (at least one element): `spare`
// itself where it holds at least that and at most twice as much, else a new one (`spare`
// released first). On a CPU device a new buffer is new host memory whose pages fault in as the
// kernels first write them; a renderer hands its last render's buffers back here.
cl::Buffer reuse_or_alloc(Context& ctx, cl::Buffer&& spare, size_t count, size_t size);
// Whether a spare of `held` units serves a need of `need`: at least that, at most twice as
// much (reuse_or_alloc's rule).
inline bool spare_fits(size_t held, size_t need) { return held >= need && held / 2 <= need; }
// Throws penumbra::Error "<what> needs 1.25 GiB of device memory, more than ..." when `bytes`
// exceeds the context's memory limit (Context::memory_limit: the device's memory unless set);
// checked before allocating.
void check_memory(Context& ctx, size_t bytes, const std::string& what);
// "512 bytes", "12.50 MiB", "1.25 GiB": in the largest binary unit that keeps a number >= 1.
std::string memory_size(size_t bytes);

// Zero-filled buffer of `count` reals (for accumulators, and for products that must never read
// NaN from old memory).
cl::Buffer zero_reals(Context& ctx, Precision p, size_t count);

// Enqueues `k` with global sizes rounded up to multiples of the local sizes.
void launch(Context& ctx, cl::Kernel& k, cl::NDRange global, cl::NDRange local);
// With PENUMBRA_PROFILE set (launch() above): true, and `profile_launch` waits for an event of
// a launch made elsewhere (CLBlast's) and adds its device time to the row `name`.
bool profiling();
void profile_launch(const std::string& name, const cl::Event& event);
// With PENUMBRA_PROFILE set: waits for the queue, adds the wall time since the calling thread's
// last mark to the row of the stage it then began, and begins "`call`: `name`" (none if `name`
// is null). Wall time holds the stage's kernels, copies and host work.
void profile_stage(Context& ctx, const char* call, const char* name);
// With PENUMBRA_PROFILE set: the stage rows so far, "`call`: `name`" → (wall ms, calls), for a
// tool that compares two moments (penumbra_bench --host-stages).
std::map<std::string, std::pair<double, int>> profile_stages();
// With PENUMBRA_PROFILE set: the kernel rows so far, name → (device ms, launches), likewise
// (penumbra_bench --paired).
std::map<std::string, std::pair<double, int>> profile_kernels();
inline void launch_1d(Context& ctx, cl::Kernel& k, size_t n, size_t local = 64) {
  launch(ctx, k, cl::NDRange(n), cl::NDRange(local));
}

}  // namespace penumbra::detail
