// Preloaded ahead of Oclgrind's runtime by scripts/oclgrind.sh for its `--uninitialized` cases,
// around two faults of Oclgrind 21.10's plugin (docs/faults.md, "Oclgrind's --uninitialized"):
// a released buffer's address goes to the next buffer made while the plugin keeps the old
// buffer's state for it, and after a fill nothing counts as written (each pattern's store
// remakes the record at one pattern's size). So buffers are never released here (the process
// is short) and a fill is one blocking write of the whole range.
#define CL_TARGET_OPENCL_VERSION 120
#include <CL/cl.h>
#include <stdlib.h>
#include <string.h>

cl_int clReleaseMemObject(cl_mem buffer) {
  (void)buffer;
  return CL_SUCCESS;
}

cl_int clEnqueueFillBuffer(cl_command_queue queue, cl_mem buffer, const void* pattern,
                           size_t pattern_size, size_t offset, size_t size, cl_uint wait_count,
                           const cl_event* wait_list, cl_event* event) {
  unsigned char* bytes = malloc(size);
  if (!bytes) return CL_OUT_OF_HOST_MEMORY;
  for (size_t at = 0; at < size; at += pattern_size) memcpy(bytes + at, pattern, pattern_size);
  const cl_int status = clEnqueueWriteBuffer(queue, buffer, CL_TRUE, offset, size, bytes,
                                             wait_count, wait_list, event);
  free(bytes);
  return status;
}
