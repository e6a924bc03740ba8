// penumbra._penumbra: the C++ library for Python (nanobind). python/penumbra/__init__.py
// re-exports it; docs/api.md documents it.
//
// Nothing handed to Python aliases memory that C++ may free: lists of meshes, cameras and lights
// are copies, arrays are copies (read-only, so that changing one in place fails rather than doing
// nothing) or own the buffers moved out of a render; a struct's nested fields (scene.params,
// light.frustum) are handles that keep their owner alive. Arrays coming in go through arrays.hpp,
// which checks every dtype one way.
#include <nanobind/nanobind.h>
#include <nanobind/stl/function.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <string>
#include <vector>

#include "arrays.hpp"
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
using namespace penumbra::python;

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
      const double v = PyFloat_AsDouble(PySequence_Fast_GET_ITEM(seq, i));
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

// An enumeration whose words the library keeps in one table (enum_words: the scene format's
// and the tool's words), bound with those words.
template <class E>
void bind_words(nb::module_& m, const char* name) {
  nb::enum_<E> e(m, name);
  for (const auto& [value, word] : enum_words<E>()) e.value(word.c_str(), value);
}

void bind_enums(nb::module_& m) {
  nb::enum_<AlbedoMode>(m, "AlbedoMode")
      .value("per_vertex", AlbedoMode::PerVertex)
      .value("per_face", AlbedoMode::PerFace);
  bind_words<Projection>(m, "Projection");
  bind_words<LightType>(m, "LightType");
  bind_words<ShadowMapShape>(m, "ShadowMapShape");
  bind_words<Shadows>(m, "Shadows");
  bind_words<Sampling>(m, "Sampling");
  bind_words<ExactBackend>(m, "ExactBackend");
  bind_words<ShadowModel>(m, "ShadowModel");
  nb::enum_<Precision>(m, "Precision")
      .value("float", Precision::Float)
      .value("double", Precision::Double);
}

// A list-valued field of Scene, read as a list of copies and assigned whole.
template <class T>
auto list_field(std::vector<T> Scene::*field) {
  return std::make_pair([field](const Scene& s) { return s.*field; },
                        [field](Scene& s, const std::vector<T>& v) { s.*field = v; });
}

Mesh make_mesh(nb::handle vertices, nb::handle faces, nb::handle albedo, AlbedoMode mode,
               const std::string& name) {
  Mesh mesh;
  mesh.name = name;
  mesh.albedo_mode = mode;
  if (!vertices.is_none()) mesh.vertices = real_rows(any_array(vertices, "vertices"), "vertices");
  if (!faces.is_none()) mesh.faces = index_rows(any_array(faces, "faces"), "faces");
  if (!albedo.is_none())
    mesh.albedo = real_rows(any_array(albedo, "albedo"), "albedo");
  else  // the OBJ loader's default grey, one row per vertex or face
    mesh.albedo.assign(mode == AlbedoMode::PerVertex ? mesh.vertices.size() : mesh.faces.size(),
                       glm::dvec3(0.8));
  return mesh;
}

void bind_mesh(nb::module_& m) {
  nb::class_<Mesh>(m, "Mesh")
      .def(
          "__init__",
          [](Mesh* self, nb::handle v, nb::handle f, nb::handle a, AlbedoMode mode,
             const std::string& name) { new (self) Mesh(make_mesh(v, f, a, mode, name)); },
          nb::kw_only(), "vertices"_a = nb::none(), "faces"_a = nb::none(), "albedo"_a = nb::none(),
          "albedo_mode"_a = AlbedoMode::PerVertex, "name"_a = "",
          "A mesh from (V, 3) float vertices, (F, 3) integer faces (counter-clockwise) and "
          "albedo, one row per vertex or face (default: 0.8 grey).")
      .def_rw("name", &Mesh::name)
      .def_prop_rw(
          "vertices", [](const Mesh& mesh) { return rows_out<double>(mesh.vertices); },
          [](Mesh& mesh, nb::handle a) {
            mesh.vertices = real_rows(any_array(a, "vertices"), "vertices");
          },
          nb::for_getter(nb::rv_policy::automatic),
          "(V, 3) float64 vertex positions (a read-only copy; assign to change)")
      .def_prop_rw(
          "faces", [](const Mesh& mesh) { return rows_out<int>(mesh.faces.values()); },
          [](Mesh& mesh, nb::handle a) { mesh.faces = index_rows(any_array(a, "faces"), "faces"); },
          nb::for_getter(nb::rv_policy::automatic),
          "(F, 3) int32 vertex indices, counter-clockwise (a read-only copy; assign to change)")
      .def_prop_rw(
          "albedo", [](const Mesh& mesh) { return rows_out<double>(mesh.albedo.values()); },
          [](Mesh& mesh, nb::handle a) {
            mesh.albedo = real_rows(any_array(a, "albedo"), "albedo");
          },
          nb::for_getter(nb::rv_policy::automatic),
          "(A, 3) float64 albedo, one row per vertex or per face (a read-only copy; assign to "
          "change)")
      .def_rw("albedo_mode", &Mesh::albedo_mode);
}

Camera look_at(glm::dvec3 eye, glm::dvec3 target, glm::dvec3 up, double fov, int width, int height,
               double near, double far) {
  Camera c;
  c.eye = eye, c.target = target, c.up = up, c.fov_deg = fov;
  c.width = width, c.height = height, c.near = near, c.far = far;
  return c;
}

void bind_camera(nb::module_& m) {
  const Camera d;
  nb::class_<Camera>(m, "Camera")
      .def(
          "__init__",
          [](Camera* self, glm::dvec3 eye, glm::dvec3 target, glm::dvec3 up, Projection projection,
             double fov_deg, double half_height, double near, double far, int width, int height) {
            new (self)
                Camera{eye, target, up, projection, fov_deg, half_height, near, far, width, height};
          },
          nb::kw_only(), "eye"_a = d.eye, "target"_a = d.target, "up"_a = d.up,
          "projection"_a = d.projection, "fov_deg"_a = d.fov_deg, "half_height"_a = d.half_height,
          "near"_a = d.near, "far"_a = d.far, "width"_a = d.width, "height"_a = d.height)
      .def_static("look_at", &look_at, "eye"_a, "target"_a, "up"_a = d.up, nb::kw_only(),
                  "fov"_a = d.fov_deg, "width"_a = d.width, "height"_a = d.height,
                  "near"_a = d.near, "far"_a = d.far,
                  "A perspective camera at `eye` looking at `target`, `fov` degrees vertically.")
      .def_rw("eye", &Camera::eye)
      .def_rw("target", &Camera::target)
      .def_rw("up", &Camera::up)
      .def_rw("projection", &Camera::projection)
      .def_rw("fov_deg", &Camera::fov_deg)
      .def_rw("half_height", &Camera::half_height)
      .def_rw("near", &Camera::near)
      .def_rw("far", &Camera::far)
      .def_rw("width", &Camera::width)
      .def_rw("height", &Camera::height)
      .def("__repr__", [](const Camera& c) {
        return "<Camera " + std::to_string(c.width) + "x" + std::to_string(c.height) + ">";
      });
}

void bind_frustum(nb::module_& m) {
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
      .def_rw("search_sigma", &LightFrustum::search_sigma)
      .def_ro("cube", &LightFrustum::cube)
      .def_ro("cube_face", &LightFrustum::cube_face);
}

Light make_light(LightType type, glm::dvec3 position, glm::dvec3 direction, glm::dvec3 color,
                 double size, ShadowMapShape shadow_map,
                 const std::optional<LightFrustum>& frustum) {
  Light l;
  l.type = type, l.position = position, l.direction = direction, l.color = color, l.size = size;
  l.shadow_map = shadow_map;
  if (frustum) l.frustum = *frustum;
  return l;
}

void bind_light(nb::module_& m) {
  const Light d;
  nb::class_<Light>(m, "Light")
      .def(nb::init<>())
      .def(
          "__init__",
          [](Light* self, LightType t, glm::dvec3 p, glm::dvec3 dir, glm::dvec3 c, double size,
             ShadowMapShape shape, const std::optional<LightFrustum>& f) {
            new (self) Light(make_light(t, p, dir, c, size, shape, f));
          },
          nb::kw_only(), "type"_a = d.type, "position"_a = d.position, "direction"_a = d.direction,
          "color"_a = d.color, "size"_a = d.size, "shadow_map"_a = d.shadow_map,
          "frustum"_a = nb::none())
      .def_static(
          "point",
          [](glm::dvec3 p, glm::dvec3 c, double size, ShadowMapShape shape,
             const std::optional<LightFrustum>& f) {
            return make_light(LightType::Point, p, Light{}.direction, c, size, shape, f);
          },
          "position"_a, nb::kw_only(), "color"_a = d.color, "size"_a = d.size,
          "shadow_map"_a = d.shadow_map, "frustum"_a = nb::none(),
          "A point light (a sphere of diameter `size` for soft shadows); `shadow_map` 'auto' maps "
          "its shadows on a cube where one frustum cannot hold its casters.")
      .def_static(
          "directional",
          [](glm::dvec3 dir, glm::dvec3 c, double size, const std::optional<LightFrustum>& f) {
            return make_light(LightType::Directional, Light{}.position, dir, c, size,
                              ShadowMapShape::Auto, f);
          },
          "direction"_a, nb::kw_only(), "color"_a = d.color, "size"_a = d.size,
          "frustum"_a = nb::none(), "A directional light travelling along `direction`.")
      .def_rw("type", &Light::type)
      .def_rw("position", &Light::position)
      .def_rw("direction", &Light::direction)
      .def_rw("color", &Light::color)
      .def_rw("size", &Light::size)
      .def_rw("shadow_map", &Light::shadow_map)
      .def_rw("frustum", &Light::frustum);
}

void bind_params(nb::module_& m) {
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
      .def_rw("depth_unit", &RenderParams::depth_unit)
      .def("__copy__", [](const RenderParams& p) { return RenderParams(p); });
}

nb::dict get_parameters(const Scene& scene) {
  std::vector<glm::dvec3> vertices, albedo;
  for (const Mesh& mesh : scene.meshes) {
    vertices.insert(vertices.end(), mesh.vertices.begin(), mesh.vertices.end());
    albedo.insert(albedo.end(), mesh.albedo.begin(), mesh.albedo.end());
  }
  std::vector<double> lights;
  for (const Light& light : scene.lights) {
    const glm::dvec3& p = light.type == LightType::Directional ? light.direction : light.position;
    lights.insert(lights.end(),
                  {p.x, p.y, p.z, light.color.x, light.color.y, light.color.z, light.size});
  }
  nb::dict d;
  const size_t nv = vertices.size(), na = albedo.size(), nl = scene.lights.size();
  d["vertices"] = adopt<double>(std::move(vertices), {nv, 3});
  d["albedo"] = adopt<double>(std::move(albedo), {na, 3});
  d["lights"] = adopt<double>(std::move(lights), {nl, 7});
  d["ambient"] =
      adopt<double>(std::vector<double>{scene.ambient.x, scene.ambient.y, scene.ambient.z}, {3});
  return d;
}

void bind_scene(nb::module_& m) {
  const auto [meshes_get, meshes_set] = list_field(&Scene::meshes);
  const auto [cameras_get, cameras_set] = list_field(&Scene::cameras);
  const auto [lights_get, lights_set] = list_field(&Scene::lights);
  nb::class_<Scene>(m, "Scene")
      .def(nb::init<>())
      .def(nb::init<const Scene&>(), "other"_a, "A copy of another scene.")
      .def("__copy__", [](const Scene& s) { return Scene(s); })
      .def(
          "__deepcopy__", [](const Scene& s, nb::handle) { return Scene(s); }, "memo"_a)
      .def_prop_rw("meshes", meshes_get, meshes_set,
                   "The meshes (a list of copies; assign to change).")
      .def_prop_rw("cameras", cameras_get, cameras_set,
                   "The cameras (a list of copies; assign to change).")
      .def_prop_rw("lights", lights_get, lights_set,
                   "The lights (a list of copies; assign to change).")
      .def_rw("ambient", &Scene::ambient)
      .def_rw("background", &Scene::background)
      .def_rw("params", &Scene::params)
      .def("parameters", &get_parameters,
           "The differentiable parameters as a dict of float64 arrays: vertices (V, 3) and "
           "albedo (A, 3), the rows of every mesh in turn; lights (L, 7), position (direction "
           "for a directional light), colour and size; ambient (3,).")
      .def("set_parameters", &set_parameters, "vertices"_a, "albedo"_a, "lights"_a, "ambient"_a,
           "Sets the parameters from float32 or float64 arrays laid out as parameters() "
           "returns them.");
}

void bind_io(nb::module_& m) {
  m.def("load_scene", &load_scene, "path"_a, "A scene file (docs/scene-format.md), validated.");
  m.def("parse_scene", &parse_scene, "json_text"_a, "base_dir"_a,
        "A scene from JSON text; relative mesh paths are read from `base_dir`.");
  const auto policy = [](bool refuse) {
    return refuse ? DegenerateFacePolicy::Refuse : DegenerateFacePolicy::Drop;
  };
  m.def(
      "load_mesh",
      [policy](const std::string& path, glm::dvec3 albedo, bool refuse_degenerate) {
        return load_mesh(path, albedo, policy(refuse_degenerate));
      },
      "path"_a, "default_albedo"_a = glm::dvec3(0.8, 0.8, 0.8), "refuse_degenerate"_a = false,
      "A mesh file (.obj, .ply, .stl, .gltf, .glb, .off; docs/scene-format.md), validated; "
      "albedo from its vertex colours, else the default. Zero-area faces are dropped with a "
      "warning, or refused.");
  m.def(
      "load_obj",
      [policy](const std::string& path, glm::dvec3 albedo, bool refuse_degenerate) {
        return load_obj(path, albedo, policy(refuse_degenerate));
      },
      "path"_a, "default_albedo"_a = glm::dvec3(0.8, 0.8, 0.8), "refuse_degenerate"_a = false,
      "A mesh from an OBJ file, vertices in the file's order, as load_mesh reads it.");
  m.def(
      "validate", [](const Scene& s) { validate(s); }, "scene"_a,
      "Raises penumbra.Error naming the first problem of the scene.");
  m.def("fit_light_frusta", &fit_light_frusta, "scene"_a,
        "Fits the shadow-map frustum of every light not fitted yet, in place.");
  m.def("refit_light_frusta", &refit_light_frusta, "scene"_a,
        "Fits again every frustum that was fitted rather than given, in place: after changing "
        "the shadow settings (the fit depends on them), as the tool does after its options.");
  m.def("frustum_holds_casters", &frustum_holds_casters, "scene"_a, "light"_a,
        "Whether the light's frustum holds every face of the scene that can cast its shadow.");
  m.def("framed_scene", &framed_scene, "mesh"_a, "width"_a = 256, "height"_a = 256,
        "A scene around one mesh, with a camera and a light that frame it.");
  m.def(
      "save_png",
      [](nb::handle image, const std::string& path) { save_png(image_in(image, "image"), path); },
      "image"_a, "path"_a, "Writes an (H, W) or (H, W, C) float array, clamped to [0, 1].");
}

void bind_devices(nb::module_& m) {
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
  m.def(
      "warm_kernel_cache", [](Context& context) { return warm_kernel_cache(context).size(); },
      "context"_a, nb::call_guard<nb::gil_scoped_release>(),
      "Fills the kernel cache with every program a renderer on the context's device builds by "
      "itself, so that later processes load them instead of compiling (as the build and `pip "
      "install` do). Returns how many; raises penumbra.Error when the cache is off.");
  nb::class_<Context>(m, "Context")
      .def(nb::init<const std::string&>(), "device"_a = "",
           "An OpenCL device: an index from list_devices() or part of a device or platform name; "
           "empty: $PENUMBRA_DEVICE, else the first GPU, else the first device.")
      .def_prop_ro("info", &Context::info)
      .def_prop_ro("copy_transfers", &Context::copy_transfers,
                   "Whether results and inputs move through copies rather than mapped buffers: "
                   "$PENUMBRA_TRANSFERS, else copies where the device's memory is not the host's.");
}

}  // namespace

NB_MODULE(_penumbra, m) {
  m.doc() = "penumbra: differentiable soft rasterizer with shadows (C++ core)";
  m.attr("__version__") = PENUMBRA_VERSION;
  // torch keeps autograd graphs (and the renderers their nodes hold) alive until after this
  // module is torn down at interpreter exit; nanobind would report them as leaks.
  nb::set_leak_warnings(false);
  // Registers penumbra.Error and the translation of every C++ Error into it.
  [[maybe_unused]] const nb::exception<Error> error_type(m, "Error", PyExc_RuntimeError);
  bind_enums(m);
  bind_mesh(m);
  bind_camera(m);
  bind_frustum(m);
  bind_light(m);
  bind_params(m);
  bind_scene(m);
  bind_io(m);
  bind_devices(m);
  bind_renderer(m);
}
