#pragma once
// Arrays between Python and the library, for module.cpp: every array that comes in is checked
// the same way (its dtype named in the error), every one that goes out owns its memory or is
// read-only, so that nothing handed to Python aliases memory that C++ may free.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/string.h>

#include <cstring>
#include <optional>
#include <string>
#include <vector>

#include "penumbra/image.hpp"
#include "penumbra/renderer.hpp"
#include "penumbra/scene.hpp"

namespace penumbra::python {

namespace nb = nanobind;

// Any array-like on the CPU (NumPy, a CPU torch tensor), of any dtype and strides.
using AnyArray = nb::ndarray<nb::ro, nb::device::cpu>;
// A writable array to fill (an output), of any dtype; checked by the functions that fill it.
using OutArray = nb::ndarray<nb::device::cpu>;
template <typename T>
using Owned = nb::ndarray<nb::numpy, T>;

// "float32", "int64", "bool", ...: what an error calls an array's dtype.
std::string dtype_name(nb::dlpack::dtype t);
// "(4, 3)".
std::string shape_text(const AnyArray& a);

// An array argument `name` of `obj`: converted to AnyArray, else an error naming its type.
AnyArray any_array(nb::handle obj, const std::string& name);

// (N, 3) float32 or float64 rows (vertices, albedo) as doubles; `rows` < 0: any N.
std::vector<glm::dvec3> real_rows(const AnyArray& a, const std::string& name, long rows = -1);
// (N, 3) int32 or int64 rows (faces).
std::vector<glm::ivec3> index_rows(const AnyArray& a, const std::string& name);
// The parameters' rows laid out as Scene.parameters(): (V, 3), (A, 3), (L, 7), (3,).
void set_parameters(Scene& scene, nb::handle vertices, nb::handle albedo, nb::handle lights,
                    nb::handle ambient);

// Moves a buffer into a NumPy array that owns it (no copy). T: the element type it holds
// (double for a vector of glm::dvec3, which is three packed doubles).
template <typename T, typename Elem>
Owned<T> adopt(std::vector<Elem>&& data, std::initializer_list<size_t> shape) {
  auto* heap = new std::vector<Elem>(std::move(data));
  nb::capsule owner(heap, [](void* p) noexcept { delete static_cast<std::vector<Elem>*>(p); });
  return Owned<T>(reinterpret_cast<T*>(heap->data()), shape, owner);
}
// (N, 3) rows as a read-only array of their own (a copy: assigning is the way to change them).
template <typename T, typename Vec>
Owned<const T> rows_out(std::vector<Vec> v) {
  const size_t n = v.size();
  return adopt<const T>(std::move(v), {n, 3});
}

// An image as an (H, W) or (H, W, C) float64 array, moved out.
Owned<double> image_out(Image&& image);
// An (H, W) or (H, W, C) float32 or float64 array as an image (a copy).
Image image_in(nb::handle obj, const std::string& name);

// Where Renderer::render_into writes every camera's outputs: in (C, H, W, 3) colour and
// (C, H, W) silhouette and depth arrays of one dtype, float32 (`single`: f32) or float64 (f64),
// C-contiguous and writable, checked against the scene's cameras (one image size).
struct OutputArrays {
  bool single = true;
  std::vector<OutputBuffers<float>> f32;
  std::vector<OutputBuffers<double>> f64;
};
OutputArrays output_arrays(const Scene& scene, const OutArray& colour, const OutArray& silhouette,
                           const OutArray& depth);
// dL/d(outputs) for Renderer::backward from (C, H, W, 3) colour and (C, H, W) silhouette and
// depth arrays (None: zero), checked against the scene's cameras (one image size): read in
// place where all are float32 and C-contiguous (`single`: f32), else as doubles (f64, copies).
struct GradArrays {
  bool single = true;
  bool float32 = true;                // every array given (at least one) is float32
  std::optional<AnyArray> arrays[3];  // colour, silhouette, depth (kept alive for f32)
  std::vector<double> copies[3];
  std::vector<GradBuffers<float>> f32;
  std::vector<GradBuffers<double>> f64;
};
GradArrays grad_arrays(const Scene& scene, nb::handle colour, nb::handle silhouette,
                       nb::handle depth);
// Gradients laid out as Scene.parameters(), as arrays of Real (float or double): vertices
// (V, 3), albedo (A, 3), lights (L, 7) and ambient (3,).
template <class Real>
nb::dict parameter_grads(SceneGrads&& g);

// The Renderer's bindings (renderer.cpp).
void bind_renderer(nb::module_& m);

}  // namespace penumbra::python
