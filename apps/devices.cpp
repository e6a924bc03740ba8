// `penumbra devices`: the OpenCL devices this machine offers, as indices for --device.
#include <cstdio>
#include <iostream>

#include "common.hpp"
#include "penumbra/context.hpp"

namespace penumbra::cli {

namespace {

std::string device_type(const DeviceInfo& d) {
  try {
    if (d.device() != nullptr) {
      const cl_device_type type = d.device.getInfo<CL_DEVICE_TYPE>();
      if (type & CL_DEVICE_TYPE_GPU) return "GPU";
      if (type & CL_DEVICE_TYPE_CPU) return "CPU";
      if (type & CL_DEVICE_TYPE_ACCELERATOR) return "accelerator";
      return "other";
    }
  } catch (const cl::Error&) {
  }
  return d.is_gpu ? "GPU" : "other";
}

}  // namespace

Command add_devices_command(CLI::App& root) {
  Command c;
  c.app = root.add_subcommand("devices",
                              "list the OpenCL devices (index, platform, name, type, "
                              "fp64, memory, transfers: how results and inputs move unless "
                              "$PENUMBRA_TRANSFERS chooses)");
  c.run = [] {
    const std::vector<DeviceInfo> devices = list_devices();
    std::printf("%-5s  %-28s  %-40s  %-11s  %-4s  %10s  %s\n", "index", "platform", "name", "type",
                "fp64", "memory", "transfers");
    for (const DeviceInfo& d : devices) {
      std::printf("%-5d  %-28s  %-40s  %-11s  %-4s  %6zu MiB  %s\n", d.index, d.platform.c_str(),
                  d.name.c_str(), device_type(d).c_str(), d.fp64 ? "yes" : "no",
                  d.global_mem / (1024 * 1024), d.shares_host_memory ? "map" : "copy");
    }
    return 0;
  };
  return c;
}

}  // namespace penumbra::cli
