# Fills the kernel cache (README "Kernel cache") after a build and an install
# (PENUMBRA_WARM_KERNEL_CACHE), so that a user's first render compiles nothing:
#   cmake -DCLI=<the penumbra tool> -P cmake/WarmKernelCache.cmake         `CLI kernels --warm`
#   cmake -DPYTHON=<python> -DMODULE_DIR=<folder of _penumbra> -P ...    python/warm_kernel_cache.py
# A machine without an OpenCL device, the cache off or any other failure (a crash included) is
# a warning: the build and the install do not depend on it.
if(DEFINED PYTHON)
  set(command "${PYTHON}" "${CMAKE_CURRENT_LIST_DIR}/../python/warm_kernel_cache.py" "${MODULE_DIR}")
else()
  set(command "${CLI}" kernels --warm)
endif()
execute_process(COMMAND ${command} RESULT_VARIABLE status OUTPUT_VARIABLE out ERROR_VARIABLE err
                OUTPUT_STRIP_TRAILING_WHITESPACE ERROR_STRIP_TRAILING_WHITESPACE)
string(JOIN " " shown ${command})
if(status EQUAL 0)
  message(STATUS "${out}")
else()
  message(WARNING "the kernel cache was not filled (${shown}: ${status}): ${err}")
endif()
