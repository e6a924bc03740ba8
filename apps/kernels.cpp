// `penumbra kernels [--kind gpu|cpu|all] [--device D] [--variants DIR]`: every program the
// renderer can build (penumbra::kernel_variants), for a GPU-like and a CPU-like device or for one
// OpenCL device; with --variants, each one's expanded source and build options as files, for
// compiling them offline (scripts/spir_check.sh). Last line:
//   kernels: variants=N files=F
// `penumbra kernels --warm [--device D]`: fills the kernel cache with the programs a renderer on
// that device (default: each device present) builds by itself (penumbra::warm_kernel_cache), as
// the build does, with progress lines on stderr after 2 s (CallProgress). One line per device:
//   kernels: N programs for DEVICE in the kernel cache DIR (T s)
#include <chrono>
#include <cstdio>
#include <memory>
#include <set>

#include "common.hpp"
#include "penumbra/context.hpp"
#include "penumbra/error.hpp"
#include "penumbra/io.hpp"
#include "penumbra/renderer.hpp"

namespace penumbra::cli {

namespace {

struct KernelsArgs {
  std::string kind = "all", device, variants;
  bool warm = false;
};

// A device of the kind, as a renderer sees it: double precision, and the work-group limit of
// typical GPUs (1024) or of PoCL on a CPU (4096).
DeviceInfo device_like(const std::string& kind) {
  DeviceInfo d;
  d.name = kind + "-like";
  d.is_gpu = kind == "gpu";
  d.fp64 = true;
  d.max_work_group = d.is_gpu ? 1024 : 4096;
  return d;
}

// Progress lines of --warm: "kernels: warm device 1/1, programs 12/50, 24 %, 17.3 s".
RenderProgress warm_progress(size_t device, size_t devices, size_t built, size_t programs) {
  RenderProgress p;
  p.call = "warm";
  p.pass = "device";
  p.index = int(device + 1);
  p.count = int(devices);
  p.stage = "programs";
  p.part = int(built);
  p.parts = int(programs);
  p.fraction = double(built) / double(programs);
  return p;
}

// --warm: each device (every one present, without --device) in turn.
int run_warm(const KernelsArgs& a) {
  std::vector<std::string> devices = {a.device};
  if (a.device.empty()) {
    devices.clear();
    for (const DeviceInfo& d : list_devices()) devices.push_back(std::to_string(d.index));
    if (devices.empty()) throw Error("no OpenCL device: no kernel cache to fill");
  }
  CallProgress progress("kernels");
  for (size_t i = 0; i < devices.size(); ++i) {
    const auto start = std::chrono::steady_clock::now();
    Context context(devices[i]);
    progress.start();
    const size_t n = warm_kernel_cache(context, [&](size_t built, size_t programs) {
                       progress.update(warm_progress(i, devices.size(), built, programs));
                     }).size();
    progress.finish();
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::printf("kernels: %zu programs for %s in the kernel cache %s (%.1f s)\n", n,
                context.info().name.c_str(), Context::cache_dir().c_str(), seconds);
  }
  return 0;
}

int run_kernels(const KernelsArgs& a) {
  if (a.warm) return run_warm(a);
  std::vector<DeviceInfo> devices;
  std::unique_ptr<Context> context;
  if (!a.device.empty()) {
    context = std::make_unique<Context>(a.device);
    devices.push_back(context->info());
  } else {
    for (const char* kind : {"gpu", "cpu"})
      if (a.kind == "all" || a.kind == kind) devices.push_back(device_like(kind));
  }
  std::vector<std::pair<std::string, KernelVariant>> all;  // (device name, variant)
  std::set<std::pair<std::string, std::string>> seen;
  for (const DeviceInfo& d : devices)
    for (const KernelVariant& v : kernel_variants(d))
      if (seen.insert({v.file, v.options}).second) all.emplace_back(d.name, v);
  if (!a.variants.empty()) make_dirs(a.variants);
  std::set<std::string> files;
  for (size_t i = 0; i < all.size(); ++i) {
    const auto& [device, v] = all[i];
    files.insert(v.file);
    char stem[32];
    std::snprintf(stem, sizeof stem, "%04zu_", i);
    const std::string base = a.variants + "/" + stem + v.file.substr(0, v.file.size() - 3);
    if (!a.variants.empty()) {
      write_file(base + ".cl", Context::kernel_source(v.file), "kernel source");
      write_file(base + ".options", v.options + "\n", "build options");
    }
    std::printf("%-10s %-12s %s\n", device.c_str(), v.file.c_str(), v.options.c_str());
  }
  std::printf("kernels: variants=%zu files=%zu\n", all.size(), files.size());
  return 0;
}

}  // namespace

Command add_kernels_command(CLI::App& root) {
  auto args = std::make_shared<KernelsArgs>();
  Command c;
  c.app = root.add_subcommand("kernels",
                              "list every kernel program the renderer can build (file and build "
                              "options), optionally writing each as a file for offline compiling");
  CLI::Option* kind =
      c.app
          ->add_option("--kind", args->kind, "for a GPU-like device, a CPU-like one, or both (all)")
          ->check(CLI::IsMember({"gpu", "cpu", "all"}))
          ->capture_default_str();
  c.app
      ->add_option("--device", args->device,
                   "for this OpenCL device instead (index or part of its name)")
      ->excludes(kind);
  CLI::Option* variants =
      c.app->add_option("--variants", args->variants,
                        "folder for NNNN_<stem>.cl (the expanded source) and NNNN_<stem>.options "
                        "(the build options) of every variant");
  c.app
      ->add_flag(
          "--warm", args->warm,
          "instead, fill the kernel cache with the programs a renderer on --device (default: "
          "every device) builds by itself, so that later processes load them")
      ->excludes(kind)
      ->excludes(variants);
  c.run = [args] { return run_kernels(*args); };
  return c;
}

}  // namespace penumbra::cli
