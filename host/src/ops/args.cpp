// The checks of bind_args() (ops/args.hpp), out of line: they run once per kernel object.
#include "ops/args.hpp"

#include "penumbra/error.hpp"

namespace penumbra::detail::args {

namespace {
std::string where(const char* file, const char* name) {
  return std::string("kernel '") + name + "' of " + file;
}
}  // namespace

void check(cl::Kernel& kernel, const char* file, const char* name, const bool* buffer,
           size_t count) {
  const cl_uint takes = kernel.getInfo<CL_KERNEL_NUM_ARGS>();
  if (takes != count)
    throw Error(where(file, name) + ": the host binds " + std::to_string(count) +
                " arguments, the kernel takes " + std::to_string(takes));
  for (cl_uint i = 0; i < takes; ++i) {
    cl_kernel_arg_address_qualifier q = 0;
    // Without -cl-kernel-arg-info an OpenCL 1.2 device may report nothing: then only the count
    // is checked.
    if (clGetKernelArgInfo(kernel(), i, CL_KERNEL_ARG_ADDRESS_QUALIFIER, sizeof q, &q, nullptr) !=
        CL_SUCCESS)
      return;
    const bool pointer = q == CL_KERNEL_ARG_ADDRESS_GLOBAL || q == CL_KERNEL_ARG_ADDRESS_CONSTANT;
    if (pointer != buffer[i])
      throw Error(where(file, name) + ": argument " + std::to_string(i) + " is " +
                  (pointer ? "a pointer" : "not a pointer") + ", the host binds " +
                  (buffer[i] ? "a buffer" : "a number"));
  }
}

void set_failed(const cl::Error& e, const char* file, const char* name, cl_uint i) {
  throw Error(where(file, name) + ": setting argument " + std::to_string(i) + " failed (" +
              e.what() + ", " + std::to_string(e.err()) + ")");
}

}  // namespace penumbra::detail::args
