// Arrays between Python and the library (arrays.hpp).
#include "arrays.hpp"

#include <algorithm>
#include <cstdint>

#include "penumbra/error.hpp"

namespace penumbra::python {

namespace {

using Code = nb::dlpack::dtype_code;

bool is(nb::dlpack::dtype t, Code code, int bits) {
  return t.code == uint8_t(code) && t.bits == bits && t.lanes == 1;
}
bool is_real(nb::dlpack::dtype t) { return is(t, Code::Float, 32) || is(t, Code::Float, 64); }
bool is_index(nb::dlpack::dtype t) { return is(t, Code::Int, 32) || is(t, Code::Int, 64); }

// Element `i` (in elements from the start, strides applied by the caller) as a T.
template <typename T>
T element(const AnyArray& a, int64_t i) {
  const nb::dlpack::dtype t = a.dtype();
  const void* p = a.data();
  if (is(t, Code::Float, 32)) return T(static_cast<const float*>(p)[i]);
  if (is(t, Code::Float, 64)) return T(static_cast<const double*>(p)[i]);
  if (is(t, Code::Int, 32)) return T(static_cast<const int32_t*>(p)[i]);
  return T(static_cast<const int64_t*>(p)[i]);
}

template <class Array>
bool c_contiguous(const Array& a) {
  int64_t step = 1;
  for (size_t d = a.ndim(); d-- > 0;) {
    if (a.shape(d) != 1 && a.stride(d) != step) return false;
    step *= int64_t(a.shape(d));
  }
  return true;
}

// Every element of a real array in C order, as doubles (any shape, any strides).
std::vector<double> flatten(const AnyArray& a) {
  const size_t n = a.size(), nd = a.ndim();
  std::vector<double> out(n);
  if (c_contiguous(a)) {
    if (is(a.dtype(), Code::Float, 32)) {
      const auto* p = static_cast<const float*>(a.data());
      std::copy(p, p + n, out.begin());
    } else {
      std::memcpy(out.data(), a.data(), n * sizeof(double));
    }
    return out;
  }
  std::vector<size_t> at(nd, 0);
  int64_t offset = 0;
  for (size_t k = 0; k < n; ++k) {
    out[k] = element<double>(a, offset);
    for (size_t d = nd; d-- > 0;) {  // the next index, last axis fastest
      if (++at[d] < a.shape(d)) {
        offset += a.stride(d);
        break;
      }
      offset -= a.stride(d) * int64_t(a.shape(d) - 1);
      at[d] = 0;
    }
  }
  return out;
}

void check_real(const AnyArray& a, const std::string& name) {
  if (!is_real(a.dtype()))
    throw Error(name + " must be float32 or float64, not " + dtype_name(a.dtype()));
}

void check_dims(const AnyArray& a, const std::string& name, size_t ndim, long rows, long cols) {
  const bool ok = a.ndim() == ndim && (rows < 0 || long(a.shape(0)) == rows) &&
                  (ndim < 2 || cols < 0 || long(a.shape(1)) == cols);
  if (ok) return;
  std::string want = "(" + (rows < 0 ? std::string("N") : std::to_string(rows));
  want += ndim == 1 ? ",)" : ", " + (cols < 0 ? std::string("M") : std::to_string(cols)) + ")";
  throw Error(name + " has shape " + shape_text(a) + "; expected " + want);
}

// The rows of an (N, cols) real array (cols 0: an (N,) vector) as doubles, row-major.
std::vector<double> reals(const AnyArray& a, const std::string& name, long rows, long cols) {
  check_real(a, name);
  check_dims(a, name, cols == 0 ? 1 : 2, rows, cols);
  return flatten(a);
}

// Checks that `a` holds (N, 3) float32 or float64 rows, N = `rows` unless it is negative.
void check_rows(const AnyArray& a, const std::string& name, long rows) {
  check_real(a, name);
  check_dims(a, name, 2, rows, 3);
}

// put(i, row) for rows first .. first + count − 1 of checked rows `a` (any strides), read as
// doubles in one pass, the dtype dispatched once: no temporary array, as set_parameters runs
// every call of an optimisation.
template <class Put>
void each_row(const AnyArray& a, size_t first, size_t count, Put&& put) {
  const auto read = [&](const auto* p) {
    const int64_t s0 = a.stride(0), s1 = a.stride(1);
    p += int64_t(first) * s0;
    for (size_t i = 0; i < count; ++i, p += s0) put(i, glm::dvec3(p[0], p[s1], p[2 * s1]));
  };
  if (is(a.dtype(), Code::Float, 32))
    read(static_cast<const float*>(a.data()));
  else
    read(static_cast<const double*>(a.data()));
}

// Rows first .. first + rows.size() − 1 of checked rows `a` written over `rows`; first moves past.
void read_rows(const AnyArray& a, size_t& first, std::vector<glm::dvec3>& rows) {
  each_row(a, first, rows.size(), [&](size_t i, glm::dvec3 x) { rows[i] = x; });
  first += rows.size();
}

size_t total_rows(const Scene& scene, bool albedo) {
  size_t n = 0;
  for (const Mesh& mesh : scene.meshes) n += albedo ? mesh.albedo.size() : mesh.vertices.size();
  return n;
}

}  // namespace

std::string dtype_name(nb::dlpack::dtype t) {
  const char* kinds[] = {"int", "uint", "float", "opaque", "bfloat", "complex", "bool"};
  if (t.code == uint8_t(Code::Bool)) return "bool";
  const std::string kind = t.code < 7 ? kinds[t.code] : "unknown";
  return kind + std::to_string(int(t.bits)) + (t.lanes > 1 ? "x" + std::to_string(t.lanes) : "");
}

template <class Array>
std::string shape_of(const Array& a) {
  std::string s = "(";
  for (size_t i = 0; i < a.ndim(); ++i) s += (i ? ", " : "") + std::to_string(a.shape(i));
  return s + (a.ndim() == 1 ? ",)" : ")");
}
std::string shape_text(const AnyArray& a) { return shape_of(a); }

AnyArray any_array(nb::handle obj, const std::string& name) {
  AnyArray a;
  if (!nb::try_cast(obj, a, false))
    throw Error(name + " must be an array, not " +
                nb::cast<std::string>(nb::str(obj.type().attr("__name__"))));
  return a;
}

std::vector<glm::dvec3> real_rows(const AnyArray& a, const std::string& name, long rows) {
  check_rows(a, name, rows);
  std::vector<glm::dvec3> v(a.shape(0));
  each_row(a, 0, v.size(), [&](size_t i, glm::dvec3 x) { v[i] = x; });
  return v;
}

std::vector<glm::ivec3> index_rows(const AnyArray& a, const std::string& name) {
  if (!is_index(a.dtype()))
    throw Error(name + " must be integers (int32 or int64), not " + dtype_name(a.dtype()));
  check_dims(a, name, 2, -1, 3);
  std::vector<glm::ivec3> v(a.shape(0));
  for (size_t i = 0; i < v.size(); ++i)
    for (int k = 0; k < 3; ++k) {
      const auto x = element<int64_t>(a, int64_t(i) * a.stride(0) + k * a.stride(1));
      if (x < INT32_MIN || x > INT32_MAX)
        throw Error(name + ": index " + std::to_string(x) + " of row " + std::to_string(i) +
                    " is out of range");
      v[i][k] = int(x);
    }
  return v;
}

void set_parameters(Scene& scene, nb::handle vertices, nb::handle albedo, nb::handle lights,
                    nb::handle ambient) {
  const AnyArray v = any_array(vertices, "vertices"), a = any_array(albedo, "albedo");
  check_rows(v, "vertices", long(total_rows(scene, false)));
  check_rows(a, "albedo", long(total_rows(scene, true)));
  const auto l = reals(any_array(lights, "lights"), "lights", long(scene.lights.size()), 7);
  const auto amb = reals(any_array(ambient, "ambient"), "ambient", 3, 0);
  // Every array checked: only now is the scene changed.
  size_t first = 0;
  for (Mesh& mesh : scene.meshes) read_rows(v, first, mesh.vertices);
  first = 0;
  for (Mesh& mesh : scene.meshes) {  // new arrays: a renderer's record keeps the last values
    std::vector<glm::dvec3> albedo(mesh.albedo.size());
    read_rows(a, first, albedo);
    mesh.albedo = std::move(albedo);
  }
  for (size_t i = 0; i < scene.lights.size(); ++i) {
    Light& light = scene.lights[i];
    const double* r = &l[7 * i];
    (light.type == LightType::Directional ? light.direction : light.position) = {r[0], r[1], r[2]};
    light.color = {r[3], r[4], r[5]};
    light.size = r[6];
  }
  scene.ambient = {amb[0], amb[1], amb[2]};
}

Owned<double> image_out(Image&& image) {
  const size_t h = size_t(image.height), w = size_t(image.width), c = size_t(image.channels);
  if (c == 1) return adopt<double>(std::move(image.data), {h, w});
  return adopt<double>(std::move(image.data), {h, w, c});
}

Image image_in(nb::handle obj, const std::string& name) {
  const AnyArray a = any_array(obj, name);
  check_real(a, name);
  if (a.ndim() != 2 && a.ndim() != 3)
    throw Error(name + " must be an array of shape (H, W) or (H, W, C), not " + shape_text(a));
  Image image(int(a.shape(1)), int(a.shape(0)), a.ndim() == 3 ? int(a.shape(2)) : 1);
  image.data = flatten(a);
  return image;
}

namespace {
// The one image size of the scene's cameras (`what`: what needs it, for the error).
const Camera& one_image_size(const Scene& scene, const char* what) {
  const std::vector<Camera>& cams = scene.cameras;
  if (cams.empty()) throw Error("scene has no cameras");
  for (const Camera& c : cams)
    if (c.width != cams[0].width || c.height != cams[0].height)
      throw Error(std::string("every camera must have the same image size to ") + what);
  return cams[0];
}

// An array of shape (C, H, W[, 3]) for the scene's C cameras of `size` (`ordered`: and
// C-contiguous), else an error naming it.
template <class Array>
void check_shape(const Array& a, const std::string& name, size_t cameras, const Camera& size,
                 size_t channels, bool ordered) {
  const size_t nd = channels == 1 ? 3 : 4;
  const bool ok = a.ndim() == nd && a.shape(0) == cameras && a.shape(1) == size_t(size.height) &&
                  a.shape(2) == size_t(size.width) && (nd == 3 || a.shape(3) == channels);
  if (!ok || (ordered && !c_contiguous(a)))
    throw Error(name + " has shape " + shape_of(a) + "; expected " +
                (ordered ? "a C-contiguous (" : "(") + std::to_string(cameras) + ", " +
                std::to_string(size.height) + ", " + std::to_string(size.width) +
                (nd == 4 ? ", 3)" : ")"));
}

constexpr size_t kChannels[3] = {3, 1, 1};  // colour, silhouette, depth

// Each camera's place in the colour, silhouette and depth arrays (of Real, C-contiguous).
template <class Real>
std::vector<OutputBuffers<Real>> views(const OutArray* const (&arrays)[3], size_t cameras,
                                       size_t pixels) {
  std::vector<OutputBuffers<Real>> out;
  const auto at = [&](int k, size_t c) {
    return static_cast<Real*>(arrays[k]->data()) + c * kChannels[k] * pixels;
  };
  for (size_t c = 0; c < cameras; ++c) out.push_back({at(0, c), at(1, c), at(2, c)});
  return out;
}
}  // namespace

OutputArrays output_arrays(const Scene& scene, const OutArray& colour, const OutArray& silhouette,
                           const OutArray& depth) {
  const Camera& size = one_image_size(scene, "fill one array");
  const OutArray* arrays[3] = {&colour, &silhouette, &depth};
  const char* names[3] = {"colour", "silhouette", "depth"};
  for (int k = 0; k < 3; ++k) {
    if (!is_real(arrays[k]->dtype()) || arrays[k]->dtype() != colour.dtype())
      throw Error(std::string(names[k]) + " must be float32 or float64 like colour, not " +
                  dtype_name(arrays[k]->dtype()));
    check_shape(*arrays[k], names[k], scene.cameras.size(), size, kChannels[k], true);
  }
  OutputArrays out;
  out.single = is(colour.dtype(), Code::Float, 32);
  const size_t pixels = size_t(size.width) * size_t(size.height);
  if (out.single)
    out.f32 = views<float>(arrays, scene.cameras.size(), pixels);
  else
    out.f64 = views<double>(arrays, scene.cameras.size(), pixels);
  return out;
}

GradArrays grad_arrays(const Scene& scene, nb::handle colour, nb::handle silhouette,
                       nb::handle depth) {
  const Camera& size = one_image_size(scene, "take one gradient array");
  GradArrays g;
  const nb::handle given[3] = {colour, silhouette, depth};
  const char* names[3] = {"colour", "silhouette", "depth"};
  for (int k = 0; k < 3; ++k) {
    if (given[k].is_none()) continue;
    g.arrays[k] = any_array(given[k], std::string("the gradient of ") + names[k]);
    const AnyArray& a = *g.arrays[k];
    check_real(a, names[k]);
    check_shape(a, std::string("the gradient of ") + names[k], scene.cameras.size(), size,
                kChannels[k], false);
    g.float32 = g.float32 && is(a.dtype(), Code::Float, 32);
    g.single = g.single && g.float32 && c_contiguous(a);
  }
  g.float32 = g.float32 && (g.arrays[0] || g.arrays[1] || g.arrays[2]);
  // float32 C-contiguous arrays are read in place; anything else as doubles (a copy).
  for (int k = 0; k < 3 && !g.single; ++k)
    if (g.arrays[k]) g.copies[k] = flatten(*g.arrays[k]);
  const size_t pixels = size_t(size.width) * size_t(size.height);
  for (size_t c = 0; c < scene.cameras.size(); ++c) {
    const auto at = [&](int k) -> const float* {
      return g.arrays[k]
                 ? static_cast<const float*>(g.arrays[k]->data()) + c * kChannels[k] * pixels
                 : nullptr;
    };
    const auto copy = [&](int k) -> const double* {
      return g.arrays[k] ? g.copies[k].data() + c * kChannels[k] * pixels : nullptr;
    };
    if (g.single)
      g.f32.push_back({at(0), at(1), at(2)});
    else
      g.f64.push_back({copy(0), copy(1), copy(2)});
  }
  return g;
}

template <class Real>
nb::dict parameter_grads(SceneGrads&& g) {
  std::vector<Real> vertices, albedo, lights;
  size_t rows = 0;
  for (const auto& mesh : g.vertices) rows += mesh.size();
  vertices.reserve(rows * 3);
  rows = 0;
  for (const auto& mesh : g.albedo) rows += mesh.size();
  albedo.reserve(rows * 3);
  const auto add = [](std::vector<Real>& to, const glm::dvec3& v) {
    to.insert(to.end(), {Real(v.x), Real(v.y), Real(v.z)});
  };
  for (const auto& mesh : g.vertices)
    for (const glm::dvec3& v : mesh) add(vertices, v);
  for (const auto& mesh : g.albedo)
    for (const glm::dvec3& a : mesh) add(albedo, a);
  for (size_t l = 0; l < g.light_size.size(); ++l) {
    add(lights, g.light_position[l]);
    add(lights, g.light_color[l]);
    lights.push_back(Real(g.light_size[l]));
  }
  nb::dict d;
  const size_t nv = vertices.size() / 3, na = albedo.size() / 3, nl = g.light_size.size();
  d["vertices"] = adopt<Real>(std::move(vertices), {nv, 3});
  d["albedo"] = adopt<Real>(std::move(albedo), {na, 3});
  d["lights"] = adopt<Real>(std::move(lights), {nl, 7});
  std::vector<Real> ambient;
  add(ambient, g.ambient);
  d["ambient"] = adopt<Real>(std::move(ambient), {3});
  return d;
}
template nb::dict parameter_grads<float>(SceneGrads&& g);
template nb::dict parameter_grads<double>(SceneGrads&& g);

}  // namespace penumbra::python
