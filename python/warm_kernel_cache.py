"""Fills the kernel cache for every OpenCL device present with the module just built (its
folder: the first argument), as the tool's build does; cmake/WarmKernelCache.cmake runs it and
turns a failure into a warning. Prints one line per device; exits 1 on failure."""
import sys

sys.path.insert(0, sys.argv[1])
import _penumbra  # noqa: E402  (from the folder above)

try:
    for device in _penumbra.list_devices():
        n = _penumbra.warm_kernel_cache(_penumbra.Context(str(device.index)))
        print(f"kernels: {n} programs for {device.name} in the kernel cache")
except _penumbra.Error as e:
    sys.exit(f"penumbra: error: {e}")
