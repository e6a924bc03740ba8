#pragma once
// Kernel arguments as structs, and bind_args(), the one place that sets them.
//
// Every kernel has one struct naming its parameters in the kernel's order, which kernel it
// belongs to, and fields(): the same names once more, in that order, for bind_args():
//
//   struct BinCountArgs {
//     static constexpr const char* file = "bin.cl";
//     static constexpr const char* kernel = "bin_count";
//     const cl::Buffer& boxes;
//     cl_int n, tiles_x;
//     const cl::Buffer& counts;
//     auto fields() const { return std::tie(boxes, n, tiles_x, counts); }
//   };
//   auto& count = bind_args(k, BinCountArgs{boxes, n, b.tiles_x, b.counts}, variant);
//   launch_1d(ctx, count, n);
//
// A struct lives next to the only code that binds it, in its stage's ops file; the pieces that
// several stages share (MapLookup, BinLists, Real) live here. The fields are typed: a size_t
// does not narrow silently into an int, a number cannot take a buffer's place. bind_args()
// also checks, on a kernel object's first use, that the struct gives exactly as many arguments
// as the kernel takes. Argument kinds are checked where the device reports address qualifiers;
// OpenCL 1.2 reports them only for programs built with -cl-kernel-arg-info, which penumbra does
// not set (PoCL then reports none). There a buffer given for an int still fails
// clSetKernelArg by its size, and the error names the kernel and the argument.
#include <CL/opencl.hpp>
#include <array>
#include <string>
#include <tuple>
#include <type_traits>

#include "ops/ops.hpp"

namespace penumbra::detail {

// A real scalar: float or double on the device, as the kernels' precision.
struct Real {
  Real(double v) : value(v) {}  // implicit: a double is passed as the precision's real
  double value;
};

// A Bins' lists (offsets, counts, items), as the raster's tiles (TILE_ARGS), the penumbra
// map's (TEXEL_FACES) and the gathers' texel buckets take them.
struct BinLists {
  BinLists(const Bins& b) : offsets(b.offsets), counts(b.counts), items(b.items) {}  // implicit
  const cl::Buffer &offsets, &counts, &items;
  auto fields() const { return std::tie(offsets, counts, items); }
};

// The head of every per-fragment lookup of a light's map (paper_lookups.cl, accurate_lookups.cl).
struct MapLookup {
  const cl::Buffer& P;             // the camera view's parameters
  cl_int nrec, light, nl, Wm, Hm;  // fragments, the light and lights, the map's size
  auto fields() const { return std::tie(P, nrec, light, nl, Wm, Hm); }
};

namespace args {

// The argument types a struct may hold, and whether each is a buffer; any other type (size_t,
// bool, double) fails to compile rather than reaching the kernel in the wrong size.
template <class T>
struct Kind;
template <>
struct Kind<cl::Buffer> : std::true_type {};
template <>
struct Kind<cl_int> : std::false_type {};
template <>
struct Kind<Real> : std::false_type {};

template <class T, class = void>
struct HasFields : std::false_type {};
template <class T>
struct HasFields<T, std::void_t<decltype(std::declval<const T&>().fields())>> : std::true_type {};

// The struct's arguments as one flat tuple of references: a field that has fields() itself
// (MapLookup, BinLists) stands for its own arguments, in its place.
template <class T>
auto flatten(const T& x) {
  if constexpr (HasFields<T>::value)
    return std::apply([](const auto&... f) { return std::tuple_cat(flatten(f)...); }, x.fields());
  else
    return std::tie(x);
}

template <class... T>
constexpr std::array<bool, sizeof...(T)> buffers(const std::tuple<T...>&) {
  return {Kind<std::decay_t<T>>::value...};
}

// Throws penumbra::Error unless `kernel` takes `count` arguments (and, where reported, of the
// kinds `buffer` says).
void check(cl::Kernel& kernel, const char* file, const char* name, const bool* buffer,
           size_t count);
// Throws penumbra::Error naming the kernel and argument for a failed clSetKernelArg.
[[noreturn]] void set_failed(const cl::Error& e, const char* file, const char* name, cl_uint i);

inline void set(cl::Kernel& k, cl_uint i, const cl::Buffer& b, Precision) { k.setArg(i, b); }
inline void set(cl::Kernel& k, cl_uint i, cl_int v, Precision) { k.setArg(i, v); }
inline void set(cl::Kernel& k, cl_uint i, Real r, Precision p) {
  if (p == Precision::Double)
    k.setArg(i, r.value);
  else
    k.setArg(i, float(r.value));
}

// Sets `kernel`'s arguments to those of `a`, after checking them against it when `check`.
template <class A>
void apply(cl::Kernel& kernel, const A& a, Precision p, bool check) {
  const auto values = flatten(a);
  if (check) {
    const auto buffer = buffers(values);
    args::check(kernel, A::file, a.kernel, buffer.data(), buffer.size());
  }
  cl_uint i = 0;  // the argument being set, should one fail
  try {
    std::apply([&](const auto&... v) { ((set(kernel, i, v, p), ++i), ...); }, values);
  } catch (const cl::Error& err) {
    set_failed(err, A::file, a.kernel, i);
  }
}

// The part of its file a kernel is in: A::part where the struct says (a backward kernel's
// `static constexpr KernelPart part = KernelPart::Backward;`), else forward.
template <class A, class = void>
struct PartOf {
  static constexpr KernelPart value = KernelPart::Forward;
};
template <class A>
struct PartOf<A, std::void_t<decltype(A::part)>> {
  static constexpr KernelPart value = A::part;
};

}  // namespace args

// Sets the kernel A names (A::file, a.kernel; built with `variant` as part A::part, see
// Kernels) to the arguments of `a`, after checking them against the kernel on its first use,
// and returns it for launching.
template <class A>
cl::Kernel& bind_args(Kernels& k, const A& a, const std::string& variant = "") {
  Kernels::Entry& e = k.get(A::file, a.kernel, variant, args::PartOf<A>::value);
  args::apply(e.kernel, a, k.precision(), !e.checked);
  e.checked = true;
  return e.kernel;
}

// The same for a kernel of a program built outside Kernels (the benchmarks' own), checked on
// every call.
template <class A>
void bind_args(cl::Kernel& kernel, const A& a, Precision p) {
  args::apply(kernel, a, p, true);
}

}  // namespace penumbra::detail
