# Fills the kernel cache (README "Kernel cache") by running `CLI kernels --warm`: after the
# tool is built and after it is installed (PENUMBRA_WARM_KERNEL_CACHE), so that a user's first
# render compiles nothing. A machine without an OpenCL device, or with the cache off, gets a
# warning: the build and the install do not depend on it.
#   cmake -DCLI=<path of the penumbra tool> -P cmake/WarmKernelCache.cmake
execute_process(COMMAND "${CLI}" kernels --warm RESULT_VARIABLE status OUTPUT_VARIABLE out
                ERROR_VARIABLE err OUTPUT_STRIP_TRAILING_WHITESPACE ERROR_STRIP_TRAILING_WHITESPACE)
if(status EQUAL 0)
  message(STATUS "${out}")
else()
  message(WARNING "the kernel cache was not filled (${CLI} kernels --warm): ${err}")
endif()
