// Device selection, queue and program cache (in memory, and on disk through program_cache).
#include "penumbra/context.hpp"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>

#include "cl/pocl_environment.hpp"
#include "cl/program_cache.hpp"
#include "penumbra/error.hpp"

namespace penumbra {
namespace detail {
const std::map<std::string, std::string>& embedded_kernels();
}

namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

std::string trim(const std::string& s) {
  size_t b = s.find_first_not_of(" \t\r\n\0", 0, 5), e = s.find_last_not_of(" \t\r\n\0", s.npos, 5);
  return b == std::string::npos ? "" : s.substr(b, e - b + 1);
}

// Raw text of kernels/<file>: from $PENUMBRA_KERNEL_DIR when set (for development), else the
// copy embedded at build time.
std::string raw_kernel(const std::string& file) {
  if (const char* dir = std::getenv("PENUMBRA_KERNEL_DIR"); dir && *dir) {
    std::ifstream in(std::string(dir) + "/" + file);
    if (!in) throw Error("kernel source '" + file + "' not found in PENUMBRA_KERNEL_DIR=" + dir);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  }
  const auto& m = detail::embedded_kernels();
  auto it = m.find(file);
  if (it == m.end()) throw Error("no embedded kernel source named '" + file + "'");
  return it->second;
}

// Expands `#include "x"` lines (each file once), so the device compiler needs no file system.
void expand(const std::string& file, std::vector<std::string>& seen, std::string& out) {
  if (std::find(seen.begin(), seen.end(), file) != seen.end()) return;
  seen.push_back(file);
  std::istringstream in(raw_kernel(file));
  std::string line;
  while (std::getline(in, line)) {
    auto t = trim(line);
    if (t.rfind("#include \"", 0) == 0) {
      auto end = t.find('"', 10);
      expand(t.substr(10, end - 10), seen, out);
    } else {
      out += line;
      out += '\n';
    }
  }
}

std::string condense(const std::string& log) {
  // The first error lines of a compiler log, on one line.
  std::istringstream in(log);
  std::string line, out;
  int n = 0;
  while (std::getline(in, line) && n < 6) {
    line = trim(line);
    if (line.empty()) continue;
    out += (out.empty() ? "" : " | ") + line;
    ++n;
  }
  return out;
}

// Whether the device's memory is the host's. The query is deprecated since OpenCL 2.0; a driver
// that refuses it is taken to share it, as maps (the transfers it then gets) work everywhere.
bool shares_host_memory(const cl::Device& d) {
  try {
    return d.getInfo<CL_DEVICE_HOST_UNIFIED_MEMORY>() != CL_FALSE;
  } catch (const cl::Error&) {
    return true;
  }
}

}  // namespace

std::vector<DeviceInfo> list_devices() {
  // One thread at a time: the ICD loader and PoCL set themselves up on a process's first
  // calls, and threads that made those calls together found no device (and, four at once,
  // crashed).
  static std::mutex discovery;
  const std::lock_guard<std::mutex> one_at_a_time(discovery);
  detail::prepare_pocl_environment();
  std::vector<cl::Platform> platforms;
  try {
    cl::Platform::get(&platforms);
  } catch (const cl::Error&) {
    platforms.clear();
  }
  std::vector<DeviceInfo> out;
  for (auto& p : platforms) {
    std::vector<cl::Device> devices;
    try {
      p.getDevices(CL_DEVICE_TYPE_ALL, &devices);
    } catch (const cl::Error&) {
      continue;
    }
    for (auto& d : devices) {
      DeviceInfo info;
      info.index = int(out.size());
      info.platform = trim(p.getInfo<CL_PLATFORM_NAME>());
      info.name = trim(d.getInfo<CL_DEVICE_NAME>());
      info.vendor = trim(d.getInfo<CL_DEVICE_VENDOR>());
      info.version = trim(d.getInfo<CL_DEVICE_VERSION>());
      info.is_gpu = (d.getInfo<CL_DEVICE_TYPE>() & CL_DEVICE_TYPE_GPU) != 0;
      info.fp64 = d.getInfo<CL_DEVICE_EXTENSIONS>().find("cl_khr_fp64") != std::string::npos ||
                  d.getInfo<CL_DEVICE_DOUBLE_FP_CONFIG>() != 0;
      info.global_mem = d.getInfo<CL_DEVICE_GLOBAL_MEM_SIZE>();
      info.max_alloc = d.getInfo<CL_DEVICE_MAX_MEM_ALLOC_SIZE>();
      info.max_work_group = d.getInfo<CL_DEVICE_MAX_WORK_GROUP_SIZE>();
      info.shares_host_memory = shares_host_memory(d);
      info.device = d;
      out.push_back(info);
    }
  }
  if (out.empty())
    throw Error(
        "no OpenCL device found (is an OpenCL driver installed? on Debian: "
        "apt-get install pocl-opencl-icd)");
  return out;
}

void Context::set_memory_limit(size_t bytes, const std::string& by) {
  memory_limit_ = bytes;
  memory_limit_by_ = by;
}

Context::Context(const std::string& device) {
  std::string spec = device;
  if (spec.empty())
    if (const char* env = std::getenv("PENUMBRA_DEVICE")) spec = env;
  auto devices = list_devices();
  if (spec.empty()) {
    auto gpu = std::find_if(devices.begin(), devices.end(), [](auto& d) { return d.is_gpu; });
    info_ = gpu != devices.end() ? *gpu : devices.front();
  } else if (std::all_of(spec.begin(), spec.end(), ::isdigit)) {
    size_t i = std::stoul(spec);
    if (i >= devices.size())
      throw Error("device index " + spec + " out of range: " + std::to_string(devices.size()) +
                  " OpenCL device(s) found (see `penumbra devices`)");
    info_ = devices[i];
  } else {
    auto it = std::find_if(devices.begin(), devices.end(), [&](auto& d) {
      return lower(d.name).find(lower(spec)) != std::string::npos ||
             lower(d.platform).find(lower(spec)) != std::string::npos;
    });
    if (it == devices.end())
      throw Error("no OpenCL device matches '" + spec + "' (see `penumbra devices`)");
    info_ = *it;
  }
  copy_transfers_ = !info_.shares_host_memory;
  if (const char* env = std::getenv("PENUMBRA_TRANSFERS")) {
    if (std::string(env) != "map" && std::string(env) != "copy")
      throw Error("PENUMBRA_TRANSFERS must be map or copy, not '" + std::string(env) + "'");
    copy_transfers_ = std::string(env) == "copy";
  }
  try {
    context_ = cl::Context(info_.device);
    queue_ = cl::CommandQueue(context_, info_.device, CL_QUEUE_PROFILING_ENABLE);
  } catch (const cl::Error& e) {
    throw Error("cannot open OpenCL device '" + info_.name + "': " + e.what() + " (" +
                std::to_string(e.err()) + ")");
  }
}

std::string Context::kernel_source(const std::string& file) {
  std::vector<std::string> seen;
  std::string out;
  expand(file, seen, out);
  return out;
}

namespace {

using Clock = std::chrono::steady_clock;

// A program from a cached binary, or nothing when the driver rejects the binary (a damaged or
// foreign entry): the caller then builds from source and replaces the entry.
std::optional<cl::Program> build_from_binary(cl::Context& context, const cl::Device& device,
                                             const std::string& binary, const std::string& flags) {
  try {
    cl::Program::Binaries binaries{std::vector<unsigned char>(binary.begin(), binary.end())};
    cl::Program program(context, {device}, binaries);
    program.build({device}, flags.c_str());
    return program;
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

// The device binary of a built program; "" when the driver gives none (then nothing is cached).
std::string program_binary(const cl::Program& program) {
  try {
    auto binaries = program.getInfo<CL_PROGRAM_BINARIES>();
    if (binaries.size() != 1) return "";
    return std::string(binaries[0].begin(), binaries[0].end());
  } catch (const std::exception&) {
    return "";
  }
}

// PENUMBRA_PROFILE: one line per program, where it came from and how long it took.
void report_build(const std::string& file, const char* how, Clock::time_point start) {
  if (!std::getenv("PENUMBRA_PROFILE")) return;
  const double ms = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
  std::fprintf(stderr, "penumbra profile: program %s %s in %.1f ms\n", file.c_str(), how, ms);
}

}  // namespace

std::string Context::cache_dir() { return detail::program_cache_dir(); }

std::string Context::build_options(const std::string& options) {
  return options + " -cl-std=CL1.2";  // OpenCL C 1.2, whatever else the device supports
}

std::vector<std::pair<std::string, std::string>> Context::programs() const {
  const std::lock_guard<std::mutex> lock(programs_mutex_);
  std::vector<std::pair<std::string, std::string>> out;
  for (const auto& [key, program] : programs_) {
    const size_t cut = key.find('\n');
    out.emplace_back(key.substr(0, cut), build_options(key.substr(cut + 1)));
  }
  return out;
}

cl::Program Context::build_from_source(const std::string& file, const std::string& source,
                                       const std::string& options) {
  cl::Program program(context_, source);
  try {
    program.build({info_.device}, build_options(options).c_str());
  } catch (const cl::BuildError& e) {
    std::string log;
    for (auto& l : e.getBuildLog()) log += l.second;
    throw Error("kernel " + file + " failed to build with '" + options + "': " + condense(log));
  } catch (const cl::Error& e) {
    std::string log = program.getBuildInfo<CL_PROGRAM_BUILD_LOG>(info_.device);
    throw Error("kernel " + file + " failed to build with '" + options + "': " + condense(log));
  }
  return program;
}

// Built once per process; across processes the binary comes from the program cache when it has
// one for this device, source and options (program_cache.hpp).
cl::Program& Context::program(const std::string& file, const std::string& options) {
  const std::lock_guard<std::mutex> lock(programs_mutex_);
  std::string key = file + "\n" + options;
  auto it = programs_.find(key);
  if (it != programs_.end()) return it->second;
  if (options.find("PENUMBRA_DOUBLE") != std::string::npos && !info_.fp64)
    throw Error("device '" + info_.name + "' has no double precision (cl_khr_fp64)");
  const auto start = Clock::now();
  const std::string source = kernel_source(file), flags = build_options(options);
  const std::string dir = detail::program_cache_dir();
  const std::string entry =
      dir.empty() ? "" : detail::program_cache_key(info_.device, source, flags);
  if (!dir.empty())
    if (auto binary = detail::load_program_binary(dir, entry))
      if (auto program = build_from_binary(context_, info_.device, *binary, flags)) {
        report_build(file, "loaded from the cache", start);
        return programs_.emplace(key, std::move(*program)).first->second;
      }
  cl::Program program = build_from_source(file, source, options);
  if (!dir.empty())
    if (std::string binary = program_binary(program); !binary.empty())
      detail::store_program_binary(dir, entry, binary);
  report_build(file, "built from source", start);
  return programs_.emplace(key, std::move(program)).first->second;
}

}  // namespace penumbra
