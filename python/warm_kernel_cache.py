"""Fills the kernel cache for every OpenCL device present with the module just built (its
folder: the first argument), as the tool's build does (cmake/WarmKernelCache.cmake). Never
fails the build: a machine without a device, or with the cache off, gets a warning."""
import sys

sys.path.insert(0, sys.argv[1])
try:
    import _penumbra

    for device in _penumbra.list_devices():
        n = _penumbra.warm_kernel_cache(_penumbra.Context(str(device.index)))
        print(f"kernels: {n} programs for {device.name} in the kernel cache")
except Exception as e:  # noqa: BLE001  any failure is a warning here
    print(f"warning: the kernel cache was not filled: {e}", file=sys.stderr)
