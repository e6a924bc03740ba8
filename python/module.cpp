// penumbra._penumbra: the C++ library for Python (nanobind). python/penumbra/__init__.py
// re-exports it; docs/api.md documents it.
//
// Scene structs are bound field by field (one def_rw line per field, so a new field is one
// line); vec3 values are tuples of three floats, lists of them (N, 3) float64 arrays, which
// the getters copy out and the setters copy in. Rendered images and gradients leave C++ without
// a copy: their buffers are moved into the NumPy arrays that own them.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <cstring>
#include <string>
#include <vector>

#include "penumbra/context.hpp"
#include "penumbra/error.hpp"
#include "penumbra/image_io.hpp"
#include "penumbra/io.hpp"
#include "penumbra/renderer.hpp"
#include "penumbra/scene.hpp"
#include "penumbra/version.hpp"

namespace nb = nanobind;
using namespace nb::literals;
using namespace penumbra;

static_assert(sizeof(glm::dvec3) == 3 * sizeof(double), "glm::dvec3 must be three packed doubles");
static_assert(sizeof(glm::ivec3) == 3 * sizeof(int), "glm::ivec3 must be three packed ints");

// glm vectors <-> tuples of three numbers.
namespace nanobind::detail {
template <typename Vec, typename Scalar>
struct vec3_caster {
  NB_TYPE_CASTER(Vec, const_name("tuple[float, float, float]"))
  bool from_python(handle src, uint8_t, cleanup_list*) noexcept {
    PyObject* seq = PySequence_Fast(src.ptr(), "");
    if (seq == nullptr) {
      PyErr_Clear();
      return false;
    }
    bool ok = PySequence_Fast_GET_SIZE(seq) == 3 && !PyUnicode_Check(src.ptr());
    for (Py_ssize_t i = 0; ok && i < 3; ++i) {
      PyObject* item = PySequence_Fast_GET_ITEM(seq, i);
      const double v = PyFloat_AsDouble(item);
      if (v == -1.0 && PyErr_Occurred()) {
        PyErr_Clear();
        ok = false;
      }
      value[int(i)] = Scalar(v);
    }
    Py_DECREF(seq);
    return ok;
  }
  static handle from_cpp(const Vec& v, rv_policy, cleanup_list*) noexcept {
    return Py_BuildValue("(ddd)", double(v.x), double(v.y), double(v.z));
  }
};
template <>
struct type_caster<glm::dvec3> : vec3_caster<glm::dvec3, double> {};
}  // namespace nanobind::detail

namespace {

template <typename T>
using Array = nb::ndarray<nb::numpy, T>;
template <typename T>
using Rows3 = nb::ndarray<const T, nb::shape<-1, 3>, nb::c_contig, nb::device::cpu>;

// Moves a buffer into a NumPy array that owns it (no copy); T: the element type it holds
// (double for a vector of glm::dvec3, which is three packed doubles).
template <typename T, typename Elem>
Array<T> adopt(std::vector<Elem>&& data, std::initializer_list<size_t> shape) {
  auto* heap = new std::vector<Elem>(std::move(data));
  nb::capsule owner(heap, [](void* p) noexcept { delete static_cast<std::vector<Elem>*>(p); });
  return Array<T>(reinterpret_cast<T*>(heap->data()), shape, owner);
}
template <typename T>
Array<T> adopt(std::vector<T>&& data, std::initializer_list<size_t> shape) {
  return adopt<T, T>(std::move(data), shape);
}

// (N, 3) arrays out of and into vectors of glm vectors. rows_out takes its vector by value:
// a copy of a scene's, or moved from a result without a copy.
template <typename T, typename Vec>
Array<T> rows_out(std::vector<Vec> v) {
  const size_t n = v.size();
  return adopt<T>(std::move(v), {n, 3});
}
template <typename Vec, typename T>
std::vector<Vec> rows_in(const Rows3<T>& a) {
  std::vector<Vec> v(a.shape(0));
  if (!v.empty()) std::memcpy(static_cast<void*>(v.data()), a.data(), v.size() * sizeof(Vec));
  return v;
}

// An image as (H, W) or (H, W, C), moved out.
Array<double> image_out(Image&& image) {
  const size_t h = size_t(image.height), w = size_t(image.width), c = size_t(image.channels);
  if (c == 1) return adopt(std::move(image.data), {h, w});
  return adopt(std::move(image.data), {h, w, c});
}
// An array of shape (H, W) or (H, W, C) into an image (copied: Image owns its buffer).
Image image_in(const nb::handle& obj, const std::string& what) {
  nb::ndarray<const double, nb::c_contig, nb::device::cpu> a;
  if (!nb::try_cast(obj, a)) {
    throw Error(what + " must be an array of numbers, not " +
                nb::cast<std::string>(nb::str(obj.type().attr("__name__"))));
  }
  if (a.ndim() != 2 && a.ndim() != 3) {
    throw Error(what + " must be an array of shape (H, W) or (H, W, C), not " +
                std::to_string(a.ndim()) + "-dimensional");
  }
  Image image(int(a.shape(1)), int(a.shape(0)), a.ndim() == 3 ? int(a.shape(2)) : 1);
  if (image.size() != 0) std::memcpy(image.data.data(), a.data(), image.size() * sizeof(double));
  return image;
}

nb::dict views_out(RenderOutput&& v) {
  nb::dict d;
  d["color"] = image_out(std::move(v.color));
  d["silhouette"] = image_out(std::move(v.silhouette));
  d["depth"] = image_out(std::move(v.depth));
  return d;
}

// The differentiable parameters of a scene as four flat arrays, the layout of penumbra.torch:
// vertices (V, 3) and albedo (A, 3), every mesh's rows one after the other; lights (L, 7), the
// position (direction for a directional light), the colour and the size D_L, as the tool's
// lights.npy; ambient (3,).
size_t total_rows(const Scene& scene, bool albedo) {
  size_t n = 0;
  for (const Mesh& mesh : scene.meshes) n += albedo ? mesh.albedo.size() : mesh.vertices.size();
  return n;
}

nb::dict get_parameters(const Scene& scene) {
  std::vector<double> vertices, albedo, lights;
  for (const Mesh& mesh : scene.meshes) {
    for (const glm::dvec3& v : mesh.vertices) vertices.insert(vertices.end(), {v.x, v.y, v.z});
    for (const glm::dvec3& a : mesh.albedo) albedo.insert(albedo.end(), {a.x, a.y, a.z});
  }
  for (const Light& light : scene.lights) {
    const glm::dvec3& p = light.type == LightType::Directional ? light.direction : light.position;
    lights.insert(lights.end(),
                  {p.x, p.y, p.z, light.color.x, light.color.y, light.color.z, light.size});
  }
  nb::dict d;
  const size_t nv = vertices.size() / 3, na = albedo.size() / 3, nl = scene.lights.size();
  d["vertices"] = adopt(std::move(vertices), {nv, 3});
  d["albedo"] = adopt(std::move(albedo), {na, 3});
  d["lights"] = adopt(std::move(lights), {nl, 7});
  d["ambient"] = adopt(std::vector<double>{scene.ambient.x, scene.ambient.y, scene.ambient.z}, {3});
  return d;
}

using Flat = nb::ndarray<const double, nb::c_contig, nb::device::cpu>;

void check_shape(const Flat& a, const char* name, size_t rows, size_t cols) {
  const bool vector = cols == 0;
  const bool ok = vector ? a.ndim() == 1 && a.shape(0) == rows
                         : a.ndim() == 2 && a.shape(0) == rows && a.shape(1) == cols;
  if (ok) return;
  std::string got = "(";
  for (size_t i = 0; i < a.ndim(); ++i) got += (i ? ", " : "") + std::to_string(a.shape(i));
  got += a.ndim() == 1 ? ",)" : ")";
  const std::string want = vector ? "(" + std::to_string(rows) + ",)"
                                  : "(" + std::to_string(rows) + ", " + std::to_string(cols) + ")";
  throw Error(std::string(name) + " has shape " + got + "; the scene needs " + want);
}

void set_parameters(Scene& scene, const Flat& vertices, const Flat& albedo, const Flat& lights,
                    const Flat& ambient) {
  check_shape(vertices, "vertices", total_rows(scene, false), 3);
  check_shape(albedo, "albedo", total_rows(scene, true), 3);
  check_shape(lights, "lights", scene.lights.size(), 7);
  check_shape(ambient, "ambient", 3, 0);
  const double* v = vertices.data();
  const double* a = albedo.data();
  for (Mesh& mesh : scene.meshes) {
    std::memcpy(static_cast<void*>(mesh.vertices.data()), v,
                mesh.vertices.size() * sizeof(glm::dvec3));
    std::memcpy(static_cast<void*>(mesh.albedo.data()), a, mesh.albedo.size() * sizeof(glm::dvec3));
    v += 3 * mesh.vertices.size();
    a += 3 * mesh.albedo.size();
  }
  const double* l = lights.data();
  for (Light& light : scene.lights) {
    glm::dvec3& p = light.type == LightType::Directional ? light.direction : light.position;
    p = {l[0], l[1], l[2]};
    light.color = {l[3], l[4], l[5]};
    light.size = l[6];
    l += 7;
  }
  scene.ambient = {ambient.data()[0], ambient.data()[1], ambient.data()[2]};
}

// An enumeration whose words the library keeps in one table (enum_words: the scene format's
// and the tool's words), bound with those words.
template <class E>
void bind_words(nb::module_& m, const char* name) {
  nb::enum_<E> e(m, name);
  for (const auto& [value, word] : enum_words<E>()) e.value(word.c_str(), value);
}

}  // namespace

NB_MODULE(_penumbra, m) {
  m.doc() = "penumbra: differentiable soft rasterizer with shadows (C++ core)";
  m.attr("__version__") = PENUMBRA_VERSION;
  // torch keeps autograd graphs (and the renderers their nodes hold) alive until after this
  // module is torn down at interpreter exit; nanobind would report them as leaks.
  nb::set_leak_warnings(false);
  nb::exception<Error>(m, "Error", PyExc_RuntimeError);

  // Enumerations: the words of the scene format and the tool (Shadows.hard, Sampling.exact).
  nb::enum_<AlbedoMode>(m, "AlbedoMode")
      .value("per_vertex", AlbedoMode::PerVertex)
      .value("per_face", AlbedoMode::PerFace);
  bind_words<Projection>(m, "Projection");
  bind_words<LightType>(m, "LightType");
  bind_words<Shadows>(m, "Shadows");
  bind_words<Sampling>(m, "Sampling");
  bind_words<ExactBackend>(m, "ExactBackend");
  bind_words<ShadowModel>(m, "ShadowModel");
  nb::enum_<Precision>(m, "Precision")
      .value("float", Precision::Float)
      .value("double", Precision::Double);

  nb::class_<Mesh>(m, "Mesh")
      .def(nb::init<>())
      .def_rw("name", &Mesh::name)
      .def_prop_rw(
          "vertices", [](const Mesh& mesh) { return rows_out<double>(mesh.vertices); },
          [](Mesh& mesh, const Rows3<double>& a) { mesh.vertices = rows_in<glm::dvec3>(a); },
          nb::for_getter(nb::rv_policy::automatic),
          "(N, 3) float64 vertex positions (a copy; assign to change)")
      .def_prop_rw(
          "faces", [](const Mesh& mesh) { return rows_out<int>(mesh.faces); },
          [](Mesh& mesh, const Rows3<int>& a) { mesh.faces = rows_in<glm::ivec3>(a); },
          nb::for_getter(nb::rv_policy::automatic),
          "(F, 3) int32 vertex indices, counter-clockwise (a copy; assign to change)")
      .def_prop_rw(
          "albedo", [](const Mesh& mesh) { return rows_out<double>(mesh.albedo); },
          [](Mesh& mesh, const Rows3<double>& a) { mesh.albedo = rows_in<glm::dvec3>(a); },
          nb::for_getter(nb::rv_policy::automatic),
          "(A, 3) float64 albedo, one row per vertex or per face (a copy; assign to change)")
      .def_rw("albedo_mode", &Mesh::albedo_mode);

  nb::class_<Camera>(m, "Camera")
      .def(nb::init<>())
      .def_rw("eye", &Camera::eye)
      .def_rw("target", &Camera::target)
      .def_rw("up", &Camera::up)
      .def_rw("projection", &Camera::projection)
      .def_rw("fov_deg", &Camera::fov_deg)
      .def_rw("half_height", &Camera::half_height)
      .def_rw("near", &Camera::near)
      .def_rw("far", &Camera::far)
      .def_rw("width", &Camera::width)
      .def_rw("height", &Camera::height);

  nb::class_<LightFrustum>(m, "LightFrustum")
      .def(nb::init<>())
      .def_rw("fitted", &LightFrustum::fitted)
      .def_rw("automatic", &LightFrustum::automatic)
      .def_rw("target", &LightFrustum::target)
      .def_rw("up", &LightFrustum::up)
      .def_rw("fov_deg", &LightFrustum::fov_deg)
      .def_rw("half_size", &LightFrustum::half_size)
      .def_rw("distance", &LightFrustum::distance)
      .def_rw("near", &LightFrustum::near)
      .def_rw("far", &LightFrustum::far)
      .def_rw("search_sigma", &LightFrustum::search_sigma);

  nb::class_<Light>(m, "Light")
      .def(nb::init<>())
      .def_rw("type", &Light::type)
      .def_rw("position", &Light::position)
      .def_rw("direction", &Light::direction)
      .def_rw("color", &Light::color)
      .def_rw("size", &Light::size)
      .def_rw("frustum", &Light::frustum);

  // The optional parameters read None where the shadow model's default applies, and take None
  // to go back to it.
  const auto unset_by_none = nb::for_setter(nb::arg("value").none());
  nb::class_<RenderParams>(m, "RenderParams")
      .def(nb::init<>())
      .def_rw("sigma", &RenderParams::sigma)
      .def_rw("gamma", &RenderParams::gamma)
      .def_rw("eps", &RenderParams::eps)
      .def_rw("dist_eps", &RenderParams::dist_eps)
      .def_rw("sigma_s", &RenderParams::sigma_s, unset_by_none)
      .def_rw("lambda_eps", &RenderParams::lambda_eps)
      .def_rw("gamma_s", &RenderParams::gamma_s, unset_by_none)
      .def_rw("beta", &RenderParams::beta, unset_by_none)
      .def_rw("gamma_p", &RenderParams::gamma_p)
      .def_rw("cull_backfaces", &RenderParams::cull_backfaces)
      .def_rw("shadows", &RenderParams::shadows)
      .def_rw("sampling", &RenderParams::sampling)
      .def_rw("exact_backend", &RenderParams::exact_backend)
      .def_rw("shadow_model", &RenderParams::shadow_model)
      .def_rw("shadow_map_size", &RenderParams::shadow_map_size, unset_by_none)
      .def_rw("light_sigma", &RenderParams::light_sigma)
      .def_rw("light_gamma", &RenderParams::light_gamma)
      .def_rw("weight_eps", &RenderParams::weight_eps)
      .def_rw("depth_unit", &RenderParams::depth_unit);

  // meshes, cameras and lights are lists of copies: assign the whole list to change them
  // (scene.meshes = meshes). params is a reference: scene.params.sigma = 1e-4 changes the scene.
  nb::class_<Scene>(m, "Scene")
      .def(nb::init<>())
      .def(nb::init<const Scene&>(), "other"_a, "A copy of another scene.")
      .def("__copy__", [](const Scene& s) { return Scene(s); })
      .def(
          "__deepcopy__", [](const Scene& s, nb::handle) { return Scene(s); }, "memo"_a)
      .def_rw("meshes", &Scene::meshes)
      .def_rw("cameras", &Scene::cameras)
      .def_rw("lights", &Scene::lights)
      .def_rw("ambient", &Scene::ambient)
      .def_rw("background", &Scene::background)
      .def_rw("params", &Scene::params)
      .def("parameters", &get_parameters,
           "The differentiable parameters as a dict of float64 arrays: vertices (V, 3) and "
           "albedo (A, 3), the rows of every mesh in turn; lights (L, 7), position (direction "
           "for a directional light), colour and size; ambient (3,).")
      .def("set_parameters", &set_parameters, "vertices"_a, "albedo"_a, "lights"_a, "ambient"_a,
           "Sets the parameters from arrays laid out as parameters() returns them.");

  m.def("load_scene", &load_scene, "path"_a, "A scene file (docs/scene-format.md), validated.");
  m.def("parse_scene", &parse_scene, "json_text"_a, "base_dir"_a);
  m.def("load_obj", &load_obj, "path"_a, "default_albedo"_a = glm::dvec3(0.8, 0.8, 0.8));
  m.def("validate", nb::overload_cast<const Scene&>(&validate), "scene"_a,
        "Raises penumbra.Error naming the first problem of the scene.");
  m.def("fit_light_frusta", &fit_light_frusta, "scene"_a,
        "Fits the shadow-map frustum of every light not fitted yet, in place.");
  m.def("refit_light_frusta", &refit_light_frusta, "scene"_a,
        "Fits again every frustum that was fitted rather than given, in place: after changing "
        "the shadow settings (the fit depends on them), as the tool does after its options.");
  m.def("framed_scene", &framed_scene, "mesh"_a, "width"_a = 256, "height"_a = 256);
  m.def(
      "save_png",
      [](nb::handle image, const std::string& path) { save_png(image_in(image, "image"), path); },
      "image"_a, "path"_a, "Writes an (H, W) or (H, W, C) float array, clamped to [0, 1].");

  nb::class_<DeviceInfo>(m, "DeviceInfo")
      .def_ro("index", &DeviceInfo::index)
      .def_ro("platform", &DeviceInfo::platform)
      .def_ro("name", &DeviceInfo::name)
      .def_ro("vendor", &DeviceInfo::vendor)
      .def_ro("version", &DeviceInfo::version)
      .def_ro("is_gpu", &DeviceInfo::is_gpu)
      .def_ro("fp64", &DeviceInfo::fp64)
      .def_ro("global_mem", &DeviceInfo::global_mem)
      .def_ro("shares_host_memory", &DeviceInfo::shares_host_memory)
      .def("__repr__", [](const DeviceInfo& d) {
        return "<DeviceInfo " + std::to_string(d.index) + ": " + d.name + " (" + d.platform + ")>";
      });
  m.def("list_devices", &list_devices);

  nb::class_<Context>(m, "Context")
      .def(nb::init<const std::string&>(), "device"_a = "",
           "An OpenCL device: an index from list_devices() or part of a device or platform name; "
           "empty: $PENUMBRA_DEVICE, else the first GPU, else the first device.")
      .def_prop_ro("info", &Context::info)
      .def_prop_ro("copy_transfers", &Context::copy_transfers,
                   "Whether results and inputs move through copies rather than mapped buffers: "
                   "$PENUMBRA_TRANSFERS, else copies where the device's memory is not the host's.");

  nb::class_<Renderer>(m, "Renderer")
      .def(nb::init<Context&, Precision>(), "context"_a, "precision"_a = Precision::Float,
           nb::keep_alive<1, 2>())
      .def_prop_ro("precision", &Renderer::precision)
      .def(
          "render",
          [](Renderer& r, const Scene& scene) {
            std::vector<RenderOutput> views;
            {
              nb::gil_scoped_release released;
              views = r.render(scene);
            }
            nb::list out;
            for (RenderOutput& v : views) out.append(views_out(std::move(v)));
            return out;
          },
          "scene"_a,
          "Renders every camera: a list of dicts with color (H, W, 3), silhouette (H, W) and "
          "depth (H, W), float64 arrays.")
      .def(
          "backward",
          [](Renderer& r, const Scene& scene, const nb::list& grads) {
            std::vector<OutputGrads> dL(nb::len(grads));
            for (size_t i = 0; i < dL.size(); ++i) {
              nb::handle g = grads[i];
              if (g.is_none()) continue;
              const std::string camera = "camera " + std::to_string(i);
              if (!nb::isinstance<nb::dict>(g)) {
                throw Error("the gradients of " + camera + " must be a dict or None");
              }
              for (auto [key, value] : nb::borrow<nb::dict>(g)) {
                const std::string name = nb::cast<std::string>(nb::str(key));
                Image* image = name == "color"        ? &dL[i].color
                               : name == "silhouette" ? &dL[i].silhouette
                               : name == "depth"      ? &dL[i].depth
                                                      : nullptr;
                if (image == nullptr) {
                  throw Error("unknown output '" + name +
                              "' in the gradients (color, silhouette, depth)");
                }
                if (!value.is_none()) *image = image_in(value, name + " of " + camera);
              }
            }
            SceneGrads g;
            {
              nb::gil_scoped_release released;
              g = r.backward(scene, dL);
            }
            nb::dict out;
            nb::list vertices, albedo;
            for (auto& v : g.vertices) vertices.append(rows_out<double>(std::move(v)));
            for (auto& a : g.albedo) albedo.append(rows_out<double>(std::move(a)));
            out["vertices"] = vertices;
            out["albedo"] = albedo;
            out["light_position"] = rows_out<double>(std::move(g.light_position));
            out["light_color"] = rows_out<double>(std::move(g.light_color));
            const size_t lights = g.light_size.size();
            out["light_size"] = adopt(std::move(g.light_size), {lights});
            out["ambient"] = adopt(std::vector<double>{g.ambient.x, g.ambient.y, g.ambient.z}, {3});
            return out;
          },
          "scene"_a, "grads"_a,
          "Gradients of a loss given dL/d(outputs) per camera (dicts like render's; a missing "
          "key or None is zero), by the derivative of the most recent render of this scene: a "
          "dict of vertices and albedo (lists of (N, 3) per mesh), light_position, light_color "
          "(L, 3), light_size (L,) and ambient (3,).")
      .def(
          "shadow_maps",
          [](const Renderer& r) {
            nb::list out;
            for (Image& s : r.shadow_maps()) out.append(image_out(std::move(s)));
            return out;
          },
          "The shadow map of every light from the most recent render with shadows on.")
      .def(
          "penumbra_maps",
          [](const Renderer& r) {
            nb::list out;
            for (Image& s : r.penumbra_maps()) out.append(image_out(std::move(s)));
            return out;
          },
          "The penumbra map of every light from the most recent render with soft shadows.")
      .def("fragment_counts", &Renderer::fragment_counts,
           "How many fragments each camera's view kept in the most recent render (empty before "
           "one): the (pixel, face) pairs whose aggregation weight is at least weight_eps times "
           "the pixel's largest.");
}
