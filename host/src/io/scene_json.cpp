// JSON scene files: load_scene / parse_scene (io.hpp). The format is documented in
// docs/scene-format.md; keep the two in step.
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <limits>
#include <sstream>
#include <string>

#include <nlohmann/json.hpp>

#include "penumbra/error.hpp"
#include "penumbra/io.hpp"
#include "text.hpp"

namespace penumbra {
namespace {

using json = nlohmann::json;

// Everything below throws SceneError with a message relative to the document; the entry
// points prefix it with the file (or "scene") once.
struct SceneError {
  std::string message;
};

[[noreturn]] void fail(const std::string& message) { throw SceneError{message}; }

const char* type_name(const json& j) {
  switch (j.type()) {
    case json::value_t::null:
      return "null";
    case json::value_t::boolean:
      return "a boolean";
    case json::value_t::number_integer:
    case json::value_t::number_unsigned:
    case json::value_t::number_float:
      return "a number";
    case json::value_t::string:
      return "a string";
    case json::value_t::array:
      return "an array";
    case json::value_t::object:
      return "an object";
    default:
      return "an unsupported value";
  }
}

std::string join(std::initializer_list<const char*> keys) {
  std::string out;
  for (const char* k : keys) {
    if (!out.empty()) out += ", ";
    out += k;
  }
  return out;
}

// The object at `where` must be an object whose keys are all in `allowed`.
void check_object(const json& j, const std::string& where,
                  std::initializer_list<const char*> allowed) {
  if (!j.is_object()) fail("'" + where + "' must be an object, got " + type_name(j));
  for (auto it = j.begin(); it != j.end(); ++it) {
    bool known = false;
    for (const char* k : allowed) known = known || it.key() == k;
    if (!known)
      fail("unknown key '" + (where.empty() ? it.key() : where + "." + it.key()) +
           "' (expected one of: " + join(allowed) + ")");
  }
}

std::string child(const std::string& where, const char* key) {
  return where.empty() ? std::string(key) : where + "." + key;
}

double get_number(const json& j, const std::string& where) {
  if (!j.is_number()) fail("'" + where + "' must be a number, got " + type_name(j));
  const double v = j.get<double>();
  if (!std::isfinite(v)) fail("'" + where + "' must be a finite number");
  return v;
}

int get_int(const json& j, const std::string& where) {
  if (!j.is_number_integer())
    fail("'" + where + "' must be an integer, got " +
         (j.is_number() ? j.dump() : std::string(type_name(j))));
  const double v = j.get<double>();
  if (v < std::numeric_limits<int>::min() || v > std::numeric_limits<int>::max())
    fail("'" + where + "' = " + j.dump() + " is out of range");
  return static_cast<int>(j.get<long long>());
}

bool get_bool(const json& j, const std::string& where) {
  if (!j.is_boolean()) fail("'" + where + "' must be true or false, got " + type_name(j));
  return j.get<bool>();
}

std::string get_string(const json& j, const std::string& where) {
  if (!j.is_string()) fail("'" + where + "' must be a string, got " + type_name(j));
  return j.get<std::string>();
}

glm::dvec3 get_vec3(const json& j, const std::string& where) {
  if (!j.is_array() || j.size() != 3)
    fail("'" + where + "' must be an array of 3 numbers, got " +
         (j.is_array() ? "an array of " + std::to_string(j.size()) : std::string(type_name(j))));
  glm::dvec3 v;
  for (int k = 0; k < 3; ++k) v[k] = get_number(j[k], where + "[" + std::to_string(k) + "]");
  return v;
}

// A number n (meaning [n, n, n]) or an array of 3 numbers.
glm::dvec3 get_scalar_or_vec3(const json& j, const std::string& where) {
  if (j.is_number()) return glm::dvec3(get_number(j, where));
  if (!j.is_array())
    fail("'" + where + "' must be a number or an array of 3 numbers, got " + type_name(j));
  return get_vec3(j, where);
}

// Reads an optional key into `out` with the reader `read`.
template <class T, class Read>
void opt(const json& obj, const std::string& where, const char* key, T& out, Read read) {
  auto it = obj.find(key);
  if (it != obj.end()) out = read(*it, child(where, key));
}

// The value of a key that must be present; `expected` says what it should hold.
const json& require(const json& obj, const std::string& where, const char* key,
                    const std::string& expected) {
  auto it = obj.find(key);
  if (it == obj.end())
    fail("the required key '" + child(where, key) + "' is missing (expected " + expected + ")");
  return *it;
}

const json& require_array(const json& obj, const std::string& where, const char* key,
                          const std::string& expected) {
  const json& a = require(obj, where, key, expected);
  if (!a.is_array()) fail("'" + child(where, key) + "' must be an array, got " + type_name(a));
  return a;
}

std::string item(const char* key, size_t i) {
  return std::string(key) + "[" + std::to_string(i) + "]";
}

Mesh parse_mesh(const json& j, const std::string& where, const std::filesystem::path& base) {
  check_object(j, where, {"file", "name", "translate", "scale", "albedo", "refuse_degenerate"});
  const std::string file =
      get_string(require(j, where, "file", "the path of a mesh file"), child(where, "file"));
  if (file.empty()) fail("'" + child(where, "file") + "' is empty");
  std::filesystem::path path(file);
  if (path.is_relative()) path = base / path;

  glm::dvec3 translate(0), scale(1);
  opt(j, where, "translate", translate, get_vec3);
  opt(j, where, "scale", scale, get_scalar_or_vec3);
  bool has_albedo = false;
  glm::dvec3 albedo(0.8);
  if (j.contains("albedo")) {
    albedo = get_vec3(j["albedo"], child(where, "albedo"));
    has_albedo = true;
  }

  bool refuse_degenerate = false;
  opt(j, where, "refuse_degenerate", refuse_degenerate, get_bool);
  Mesh mesh;
  try {
    mesh = load_mesh(path.string(), glm::dvec3(0.8),
                     refuse_degenerate ? DegenerateFacePolicy::Refuse : DegenerateFacePolicy::Drop);
  } catch (const Error& e) {
    fail(where + ": " + e.what());
  }
  opt(j, where, "name", mesh.name, get_string);

  for (glm::dvec3& v : mesh.vertices) v = v * scale + translate;
  // A mirroring scale (odd number of negative factors) would turn the faces inside out:
  // swap two corners so that the winding stays counter-clockwise seen from outside.
  if (scale.x * scale.y * scale.z < 0)
    mesh.faces.edit([](std::vector<glm::ivec3>& faces) {
      for (glm::ivec3& f : faces) std::swap(f.y, f.z);
    });
  if (has_albedo) {
    mesh.albedo_mode = AlbedoMode::PerVertex;
    mesh.albedo.assign(mesh.vertices.size(), albedo);
  }
  return mesh;
}

// A string naming a value of enum E (its enum_words), as that value.
template <class E>
E get_enum(const json& j, const std::string& where) {
  const std::string v = get_string(j, where);
  E value{};
  if (!from_word(v, &value))
    fail("'" + where + "' is \"" + v + "\" (expected " + word_choices<E>() + ")");
  return value;
}

Camera parse_camera(const json& j, const std::string& where) {
  check_object(j, where,
               {"eye", "target", "up", "projection", "fov", "half_height", "near", "far", "width",
                "height"});
  Camera c;
  opt(j, where, "eye", c.eye, get_vec3);
  opt(j, where, "target", c.target, get_vec3);
  opt(j, where, "up", c.up, get_vec3);
  opt(j, where, "projection", c.projection, get_enum<Projection>);
  opt(j, where, "fov", c.fov_deg, get_number);
  opt(j, where, "half_height", c.half_height, get_number);
  opt(j, where, "near", c.near, get_number);
  opt(j, where, "far", c.far, get_number);
  opt(j, where, "width", c.width, get_int);
  opt(j, where, "height", c.height, get_int);
  return c;
}

LightFrustum parse_frustum(const json& j, const std::string& where) {
  check_object(j, where, {"target", "up", "fov", "half_size", "distance", "near", "far"});
  LightFrustum f;
  f.fitted = true;
  opt(j, where, "target", f.target, get_vec3);
  opt(j, where, "up", f.up, get_vec3);
  opt(j, where, "fov", f.fov_deg, get_number);
  opt(j, where, "half_size", f.half_size, get_number);
  opt(j, where, "distance", f.distance, get_number);
  opt(j, where, "near", f.near, get_number);
  opt(j, where, "far", f.far, get_number);
  return f;
}

Light parse_light(const json& j, const std::string& where) {
  check_object(
      j, where,
      {"type", "position", "direction", "color", "intensity", "size", "shadow_map", "frustum"});
  Light l;
  opt(j, where, "type", l.type, get_enum<LightType>);
  opt(j, where, "position", l.position, get_vec3);
  opt(j, where, "direction", l.direction, get_vec3);
  opt(j, where, "color", l.color, get_vec3);
  double intensity = 1.0;
  opt(j, where, "intensity", intensity, get_number);
  l.color *= intensity;
  opt(j, where, "size", l.size, get_number);
  opt(j, where, "shadow_map", l.shadow_map, get_enum<ShadowMapShape>);
  if (j.contains("frustum")) l.frustum = parse_frustum(j["frustum"], child(where, "frustum"));
  return l;
}

RenderParams parse_render(const json& j, const std::string& where) {
  check_object(j, where,
               {"sigma", "gamma", "eps", "dist_eps", "sigma_s", "lambda_eps", "gamma_s", "beta",
                "gamma_p", "cull_backfaces", "shadows", "sampling", "exact_backend", "shadow_model",
                "shadow_map_size", "light_sigma", "light_gamma", "weight_eps"});
  RenderParams p;
  opt(j, where, "sigma", p.sigma, get_number);
  opt(j, where, "gamma", p.gamma, get_number);
  opt(j, where, "eps", p.eps, get_number);
  opt(j, where, "dist_eps", p.dist_eps, get_number);
  opt(j, where, "sigma_s", p.sigma_s, get_number);
  opt(j, where, "lambda_eps", p.lambda_eps, get_number);
  opt(j, where, "gamma_s", p.gamma_s, get_number);
  opt(j, where, "beta", p.beta, get_number);
  opt(j, where, "gamma_p", p.gamma_p, get_number);
  opt(j, where, "cull_backfaces", p.cull_backfaces, get_bool);
  opt(j, where, "shadows", p.shadows, get_enum<Shadows>);
  std::optional<ExactBackend> implied;  // by "sampling": "gemm"
  if (j.contains("sampling")) {
    const std::string w = get_string(j["sampling"], child(where, "sampling"));
    if (!sampling_from_word(w, &p.sampling, &implied))
      fail("'" + child(where, "sampling") + "' is \"" + w + "\" (expected " +
           sampling_word_choices() + ")");
  }
  opt(j, where, "exact_backend", p.exact_backend, get_enum<ExactBackend>);
  if (implied) {
    if (j.contains("exact_backend") && p.exact_backend != *implied)
      fail("'" + child(where, "sampling") + "' is \"" + gemm_shorthand() +
           "\", exact sampling with exact backend 'clblast', but '" +
           child(where, "exact_backend") + "' is \"" + word(p.exact_backend) + "\"");
    p.exact_backend = *implied;
  }
  opt(j, where, "shadow_model", p.shadow_model, get_enum<ShadowModel>);
  opt(j, where, "shadow_map_size", p.shadow_map_size, get_int);
  opt(j, where, "light_sigma", p.light_sigma, get_number);
  opt(j, where, "light_gamma", p.light_gamma, get_number);
  opt(j, where, "weight_eps", p.weight_eps, get_number);
  return p;
}

Scene parse_document(const json& doc, const std::filesystem::path& base) {
  if (!doc.is_object()) fail(std::string("the document must be an object, got ") + type_name(doc));
  check_object(doc, "", {"meshes", "cameras", "lights", "ambient", "background", "render"});
  Scene scene;
  const json& meshes =
      require_array(doc, "", "meshes", "an array of meshes, each {\"file\": \"x.obj\"}");
  for (size_t i = 0; i < meshes.size(); ++i)
    scene.meshes.push_back(parse_mesh(meshes[i], item("meshes", i), base));
  const json& cameras = require_array(doc, "", "cameras",
                                      "an array of cameras, each an object such as "
                                      "{\"eye\": [0, 0, 3]}");
  for (size_t i = 0; i < cameras.size(); ++i)
    scene.cameras.push_back(parse_camera(cameras[i], item("cameras", i)));
  if (doc.contains("lights")) {
    const json& lights = doc["lights"];
    if (!lights.is_array())
      fail(std::string("'lights' must be an array, got ") + type_name(lights));
    for (size_t i = 0; i < lights.size(); ++i)
      scene.lights.push_back(parse_light(lights[i], item("lights", i)));
  }
  opt(doc, "", "ambient", scene.ambient, get_scalar_or_vec3);
  opt(doc, "", "background", scene.background, get_scalar_or_vec3);
  if (doc.contains("render")) scene.params = parse_render(doc["render"], "render");
  validate(scene);  // before the fit, which needs sound values to name its own problems
  fit_light_frusta(scene);
  return scene;
}

// nlohmann's messages start with "[json.exception.parse_error.101] "; drop that prefix.
std::string json_message(const std::exception& e) {
  std::string m = e.what();
  if (!m.empty() && m[0] == '[') {
    const size_t close = m.find("] ");
    if (close != std::string::npos) m = m.substr(close + 2);
  }
  for (char& c : m)
    if (c == '\n' || c == '\r') c = ' ';
  return m;
}

// The error thrown for a scene: one line whatever the document holds. Strings from the document
// (keys, names, file names, enum values) are quoted in messages and may contain line breaks
// ("a\nb" in JSON); control characters are written as escapes.
Error scene_error(const std::string& label, const std::string& message) {
  const std::string text = label + ": " + message;
  static const char* hex = "0123456789abcdef";
  std::string out;
  for (char ch : text) {
    const unsigned char c = static_cast<unsigned char>(ch);
    if (c == '\n') {
      out += "\\n";
    } else if (c == '\r') {
      out += "\\r";
    } else if (c == '\t') {
      out += "\\t";
    } else if (c < 0x20 || c == 0x7f) {
      out += "\\x";
      out += hex[c >> 4];
      out += hex[c & 15];
    } else {
      out += ch;
    }
  }
  return Error(out);
}

Scene parse(const std::string& text, const std::filesystem::path& base, const std::string& label) {
  json doc;
  try {
    doc = parse_json(text);
  } catch (const Error& e) {
    throw scene_error(label, e.what());  // a duplicate key
  } catch (const json::parse_error& e) {
    throw scene_error(label, "JSON syntax error: " + json_message(e));
  } catch (const json::exception& e) {
    // Well-formed text nlohmann cannot represent, e.g. a number beyond double's range (1e999).
    throw scene_error(label, "invalid JSON: " + json_message(e));
  }
  Scene scene;
  try {
    scene = parse_document(doc, base);
  } catch (const SceneError& e) {
    throw scene_error(label, e.message);
  } catch (const json::exception& e) {
    throw scene_error(label, json_message(e));
  } catch (const Error& e) {
    throw scene_error(label, e.what());  // from validate or fit_light_frusta
  }
  return scene;
}

}  // namespace

Scene parse_scene(const std::string& json_text, const std::string& base_dir) {
  return parse(json_text, std::filesystem::path(base_dir.empty() ? "." : base_dir), "scene");
}

Scene load_scene(const std::string& path) {
  const std::string text = read_whole_file(path, "scene file");
  std::filesystem::path base = std::filesystem::path(path).parent_path();
  if (base.empty()) base = ".";
  return parse(text, base, "'" + path + "'");
}

}  // namespace penumbra
