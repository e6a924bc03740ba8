#include "cl/device.hpp"

#include <algorithm>

#include "penumbra/error.hpp"

namespace penumbra::detail {

namespace {
std::vector<unsigned char> to_bytes(Precision p, const std::vector<double>& v) {
  std::vector<unsigned char> bytes(std::max<size_t>(v.size(), 1) * real_size(p));
  if (p == Precision::Double) {
    std::copy(v.begin(), v.end(), reinterpret_cast<double*>(bytes.data()));
  } else {
    auto* f = reinterpret_cast<float*>(bytes.data());
    for (size_t i = 0; i < v.size(); ++i) f[i] = float(v[i]);
  }
  return bytes;
}
}  // namespace

cl::Buffer upload_reals(Context& ctx, Precision p, const std::vector<double>& values) {
  auto bytes = to_bytes(p, values);
  return cl::Buffer(ctx.cl_context(), CL_MEM_READ_WRITE | CL_MEM_COPY_HOST_PTR, bytes.size(),
                    bytes.data());
}

void write_reals(Context& ctx, Precision p, cl::Buffer& buf, const std::vector<double>& values) {
  auto bytes = to_bytes(p, values);
  ctx.queue().enqueueWriteBuffer(buf, CL_TRUE, 0, values.size() * real_size(p), bytes.data());
}

std::vector<double> download_reals(Context& ctx, Precision p, const cl::Buffer& buf,
                                   size_t count) {
  std::vector<double> out(count);
  if (count == 0) return out;
  if (p == Precision::Double) {
    ctx.queue().enqueueReadBuffer(buf, CL_TRUE, 0, count * 8, out.data());
  } else {
    std::vector<float> f(count);
    ctx.queue().enqueueReadBuffer(buf, CL_TRUE, 0, count * 4, f.data());
    std::copy(f.begin(), f.end(), out.begin());
  }
  return out;
}

cl::Buffer upload_ints(Context& ctx, const std::vector<int>& values) {
  std::vector<int> v = values.empty() ? std::vector<int>{0} : values;
  return cl::Buffer(ctx.cl_context(), CL_MEM_READ_WRITE | CL_MEM_COPY_HOST_PTR,
                    v.size() * sizeof(int), v.data());
}

std::vector<int> download_ints(Context& ctx, const cl::Buffer& buf, size_t count) {
  std::vector<int> out(count);
  if (count) ctx.queue().enqueueReadBuffer(buf, CL_TRUE, 0, count * sizeof(int), out.data());
  return out;
}

cl::Buffer alloc_reals(Context& ctx, Precision p, size_t count) {
  return cl::Buffer(ctx.cl_context(), CL_MEM_READ_WRITE, std::max<size_t>(count, 1) * real_size(p));
}

cl::Buffer alloc_ints(Context& ctx, size_t count) {
  return cl::Buffer(ctx.cl_context(), CL_MEM_READ_WRITE, std::max<size_t>(count, 1) * sizeof(int));
}

cl::Buffer zero_reals(Context& ctx, Precision p, size_t count) {
  cl::Buffer b = alloc_reals(ctx, p, count);
  ctx.queue().enqueueFillBuffer(b, cl_uchar(0), 0, std::max<size_t>(count, 1) * real_size(p));
  return b;
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
    ctx.queue().enqueueNDRangeKernel(k, cl::NullRange, padded, local);
  } catch (const cl::Error& e) {
    throw Error("launch of kernel " + k.getInfo<CL_KERNEL_FUNCTION_NAME>() + " failed: " +
                e.what() + " (" + std::to_string(e.err()) + ")");
  }
}

}  // namespace penumbra::detail
