#include "cl/device.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <iterator>
#include <map>
#include <mutex>
#include <string>
#include <type_traits>
#include <vector>

#include "penumbra/error.hpp"

namespace penumbra::detail {

// Bytes of the buffers made below that the OpenCL implementation has not freed yet, and of those
// made since the last reset_device_memory_peak() (its generation) the most at once
// (device_memory_use). A buffer's bytes are counted back by its destructor callback, which may
// run late: the buffers of an earlier generation are not counted against a later one.
std::atomic<size_t> live_bytes{0}, generation_bytes{0}, peak_bytes{0};
std::atomic<unsigned> generation{0};

struct Made {
  size_t bytes;
  unsigned generation;
};

void CL_CALLBACK count_freed(cl_mem, void* data) {
  const Made* made = static_cast<const Made*>(data);
  live_bytes -= made->bytes;
  if (made->generation == generation.load()) generation_bytes -= made->bytes;
  delete made;
}

void count_made(const cl::Buffer& buffer, size_t bytes) {
  Made* made = new Made{bytes, generation.load()};
  if (clSetMemObjectDestructorCallback(buffer(), count_freed, made) != CL_SUCCESS) {
    delete made;  // cannot be counted back: not counted at all
    return;
  }
  live_bytes += bytes;
  const size_t now = generation_bytes += bytes;
  size_t peak = peak_bytes.load();
  while (now > peak && !peak_bytes.compare_exchange_weak(peak, now)) {
  }
}

// Every device buffer is made here, after a check that it fits: a clear error naming the sizes
// rather than an OpenCL failure (or worse) later.
cl::Buffer make_buffer(Context& ctx, size_t bytes, const void* host) {
  const DeviceInfo& d = ctx.info();
  auto mib = [](size_t b) { return std::to_string((b + (1 << 20) - 1) >> 20) + " MiB"; };
  if (bytes > d.max_alloc)
    throw Error("a device buffer of " + mib(bytes) + " is needed, more than the largest '" +
                d.name + "' allows (" + mib(d.max_alloc) +
                "); use a smaller image, shadow map or mesh");
  try {
    cl::Buffer buffer(ctx.cl_context(), CL_MEM_READ_WRITE | (host ? CL_MEM_COPY_HOST_PTR : 0),
                      bytes, const_cast<void*>(host));  // only read (COPY_HOST_PTR)
    count_made(buffer, bytes);
    return buffer;
  } catch (const cl::Error& e) {
    throw Error("cannot allocate " + mib(bytes) + " on '" + d.name + "': " + e.what() + " (" +
                std::to_string(e.err()) + ")");
  }
}

cl::Buffer upload_reals(Context& ctx, Precision p, const std::vector<double>& values) {
  cl::Buffer buf = alloc_reals(ctx, p, values.size());
  write_reals(ctx, p, buf, values);
  return buf;
}

void* staging(size_t bytes) {
  thread_local std::vector<double> memory;
  if (memory.size() * sizeof(double) < bytes) memory.resize((bytes + 7) / 8);
  return memory.data();
}

const void* staged_read(Context& ctx, const cl::Buffer& buf, size_t bytes) {
  void* at = staging(bytes);
  ctx.queue().enqueueReadBuffer(buf, CL_TRUE, 0, bytes, at);
  return at;
}

void write_reals(Context& ctx, Precision p, cl::Buffer& buf, const std::vector<double>& values) {
  fill_reals(ctx, p, buf, values.size(), [&](auto* at) {
    using Real = std::remove_pointer_t<decltype(at)>;
    std::transform(values.begin(), values.end(), at, [](double v) { return Real(v); });
  });
}

std::vector<double> download_reals(Context& ctx, Precision p, const cl::Buffer& buf, size_t count) {
  std::vector<double> out;
  read_reals(ctx, p, buf, count, [&](const auto* r) { out.assign(r, r + count); });
  return out;
}

cl::Buffer upload_ints(Context& ctx, const std::vector<int>& values) {
  static const int none = 0;  // an empty upload is a buffer of one element
  return values.empty() ? make_buffer(ctx, sizeof(int), &none)
                        : make_buffer(ctx, values.size() * sizeof(int), values.data());
}

std::vector<int> download_ints(Context& ctx, const cl::Buffer& buf, size_t count) {
  std::vector<int> out(count);
  if (count) ctx.queue().enqueueReadBuffer(buf, CL_TRUE, 0, count * sizeof(int), out.data());
  return out;
}

cl::Buffer alloc_reals(Context& ctx, Precision p, size_t count) {
  return make_buffer(ctx, std::max<size_t>(count, 1) * real_size(p), nullptr);
}

cl::Buffer alloc_ints(Context& ctx, size_t count) {
  return make_buffer(ctx, std::max<size_t>(count, 1) * sizeof(int), nullptr);
}

cl::Buffer reuse_or_alloc(Context& ctx, cl::Buffer&& spare, size_t count, size_t size) {
  const size_t bytes = std::max<size_t>(count, 1) * size;
  if (spare()) {
    const size_t held = spare.getInfo<CL_MEM_SIZE>();
    if (spare_fits(held, bytes)) return std::move(spare);
    spare = cl::Buffer();
  }
  return make_buffer(ctx, bytes, nullptr);
}

std::string memory_size(size_t bytes) {
  const char* units[] = {"KiB", "MiB", "GiB", "TiB"};
  if (bytes < 1024) return std::to_string(bytes) + " bytes";
  double value = double(bytes) / 1024;
  size_t unit = 0;
  for (; value >= 1024 && unit + 1 < std::size(units); ++unit) value /= 1024;
  char text[32];
  std::snprintf(text, sizeof text, "%.2f %s", value, units[unit]);
  return text;
}

void check_memory(Context& ctx, size_t bytes, const std::string& what) {
  const DeviceInfo& d = ctx.info();
  if (bytes <= ctx.memory_limit()) return;
  const std::string device = "device '" + d.name + "' has";
  throw Error(what + " needs " + memory_size(bytes) + " of device memory, more than " +
              (ctx.memory_limit_by().empty()
                   ? "the " + memory_size(d.global_mem) + " that " + device
                   : "the " + memory_size(ctx.memory_limit()) + " allowed by " +
                         ctx.memory_limit_by() + " (" + device + " " + memory_size(d.global_mem) +
                         ")"));
}

cl::Buffer zero_reals(Context& ctx, Precision p, size_t count) {
  cl::Buffer b = alloc_reals(ctx, p, count);
  ctx.queue().enqueueFillBuffer(b, cl_uchar(0), 0, std::max<size_t>(count, 1) * real_size(p));
  return b;
}

namespace {
// PENUMBRA_PROFILE=1: every launch waits for its kernel and its device time is summed per
// kernel name, and the wall time of the renderer's stages per stage; the tables go to stderr at
// exit. For finding hot spots, not for timing runs.
using Rows = std::map<std::string, std::pair<double, int>>;  // name → (total ms, count)
void print_rows(const char* title, Rows& rows) {
  if (rows.empty()) return;
  std::vector<std::pair<double, std::string>> order;
  for (auto& [name, t] : rows) order.emplace_back(t.first, name);
  std::sort(order.rbegin(), order.rend());
  std::fprintf(stderr, "penumbra profile (%s):\n", title);
  for (auto& [total, name] : order)
    std::fprintf(stderr, "  %-24s %10.2f %6d\n", name.c_str(), total, rows[name].second);
}
struct Profile {
  bool on = std::getenv("PENUMBRA_PROFILE") != nullptr;
  std::mutex mutex;
  Rows ms, stages;  // kernels' device time and launches; renderer stages' wall time and calls
  ~Profile() {
    if (!on) return;
    print_rows("device ms, launches", ms);
    print_rows("wall ms, calls of each renderer stage", stages);
  }
};
Profile& profile() {
  static Profile p;
  return p;
}
}  // namespace

bool profiling() { return profile().on; }

void profile_launch(const std::string& name, const cl::Event& event) {
  event.wait();
  const double ms = double(event.getProfilingInfo<CL_PROFILING_COMMAND_END>() -
                           event.getProfilingInfo<CL_PROFILING_COMMAND_START>()) *
                    1e-6;
  std::lock_guard<std::mutex> lock(profile().mutex);
  auto& row = profile().ms[name];
  row.first += ms;
  row.second += 1;
}

void profile_stage(Context& ctx, const char* call, const char* name) {
  if (!profile().on) return;
  thread_local std::string current;  // the stage this thread is in, "" before the first
  thread_local std::chrono::steady_clock::time_point since;
  clFinish(ctx.queue()());  // the stage's kernels and copies are its time (no throw: a
                            // destructor ends the last stage; a failure shows at the next call)
  const auto now = std::chrono::steady_clock::now();
  if (!current.empty()) {
    std::lock_guard<std::mutex> lock(profile().mutex);
    auto& row = profile().stages[current];
    row.first += std::chrono::duration<double, std::milli>(now - since).count();
    row.second += 1;
  }
  current = name ? std::string(call) + ": " + name : "";
  since = now;
}

Rows profile_stages() {
  std::lock_guard<std::mutex> lock(profile().mutex);
  return profile().stages;
}

Rows profile_kernels() {
  std::lock_guard<std::mutex> lock(profile().mutex);
  return profile().ms;
}

void launch(Context& ctx, cl::Kernel& k, cl::NDRange global, cl::NDRange local) {
  size_t g[3] = {1, 1, 1};
  for (cl_uint d = 0; d < global.dimensions(); ++d) {
    size_t l = local.get()[d];
    g[d] = (global.get()[d] + l - 1) / l * l;
  }
  cl::NDRange padded = global.dimensions() == 1   ? cl::NDRange(g[0])
                       : global.dimensions() == 2 ? cl::NDRange(g[0], g[1])
                                                  : cl::NDRange(g[0], g[1], g[2]);
  try {
    if (!profile().on) {
      ctx.queue().enqueueNDRangeKernel(k, cl::NullRange, padded, local);
      return;
    }
    cl::Event ev;
    ctx.queue().enqueueNDRangeKernel(k, cl::NullRange, padded, local, nullptr, &ev);
    profile_launch(k.getInfo<CL_KERNEL_FUNCTION_NAME>(), ev);
  } catch (const cl::Error& e) {
    throw Error("launch of kernel " + k.getInfo<CL_KERNEL_FUNCTION_NAME>() +
                " failed: " + e.what() + " (" + std::to_string(e.err()) + ")");
  }
}

}  // namespace penumbra::detail

namespace penumbra {

DeviceMemoryUse device_memory_use() {
  return {detail::live_bytes.load(), detail::peak_bytes.load()};
}

void reset_device_memory_peak() {
  ++detail::generation;
  detail::generation_bytes = 0;
  detail::peak_bytes = 0;
}

}  // namespace penumbra
