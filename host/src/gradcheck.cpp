// Gradient check of Renderer::backward against central finite differences of Renderer::render.
#include "penumbra/gradcheck.hpp"

#include <algorithm>
#include <cmath>
#include <glm/gtc/matrix_transform.hpp>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <sstream>

#include "penumbra/error.hpp"

namespace penumbra {

namespace {

constexpr const char* kAxis[3] = {"x", "y", "z"};
constexpr const char* kChannel[3] = {"r", "g", "b"};

// One scalar parameter of the scene.
struct Param {
  enum Kind {
    Vertex,
    Albedo,
    LightPosition,
    LightDirection,
    LightColor,
    LightSize,
    Ambient
  } kind = Ambient;
  int mesh = 0;   // Vertex, Albedo
  int index = 0;  // vertex / albedo entry / light
  int axis = 0;   // coordinate or colour channel
  std::string name;
  // Geometric entries (positions, directions) may go negative; colours may not.
  bool positional() const {
    return kind == Vertex || kind == LightPosition || kind == LightDirection;
  }
};

// The light entry of light `l`: its position (point light) or direction (directional light).
Param light_param(const Scene& scene, int l, int axis) {
  Param p;
  p.index = l;
  p.axis = axis;
  const bool point = scene.lights[l].type == LightType::Point;
  p.kind = point ? Param::LightPosition : Param::LightDirection;
  p.name = "light" + std::to_string(l) + (point ? ".position." : ".direction.") + kAxis[axis];
  return p;
}

// Calls f(double&) on entry p of `scene` (an albedo entry through SharedArray::edit).
template <class F>
void with_parameter(Scene& scene, const Param& p, F&& f) {
  switch (p.kind) {
    case Param::Vertex:
      return f(scene.meshes[p.mesh].vertices[p.index][p.axis]);
    case Param::Albedo:
      return scene.meshes[p.mesh].albedo.edit(
          [&](std::vector<glm::dvec3>& a) { f(a[p.index][p.axis]); });
    case Param::LightPosition:
      return f(scene.lights[p.index].position[p.axis]);
    case Param::LightDirection:
      return f(scene.lights[p.index].direction[p.axis]);
    case Param::LightColor:
      return f(scene.lights[p.index].color[p.axis]);
    case Param::LightSize:
      return f(scene.lights[p.index].size);
    case Param::Ambient:
      break;
  }
  f(scene.ambient[p.axis]);
}

template <class T>
const T& checked_at(const std::vector<T>& v, size_t i, const char* what) {
  if (i >= v.size()) {
    std::ostringstream msg;
    msg << "gradcheck: the gradient has " << v.size() << " " << what << " entries, entry " << i
        << " was asked for";
    throw Error(msg.str());
  }
  return v[i];
}

double gradient(const SceneGrads& g, const Param& p) {
  switch (p.kind) {
    case Param::Vertex:
      return checked_at(checked_at(g.vertices, p.mesh, "mesh (vertices)"), p.index,
                        "vertex")[p.axis];
    case Param::Albedo:
      return checked_at(checked_at(g.albedo, p.mesh, "mesh (albedo)"), p.index, "albedo")[p.axis];
    case Param::LightPosition:
    case Param::LightDirection:  // SceneGrads::light_position holds the direction's gradient
      return checked_at(g.light_position, p.index, "light position")[p.axis];
    case Param::LightColor:
      return checked_at(g.light_color, p.index, "light colour")[p.axis];
    case Param::LightSize:
      return checked_at(g.light_size, p.index, "light size");
    case Param::Ambient:
      break;
  }
  return g.ambient[p.axis];
}

// Whether a face may show in a view: every vertex in front of the near plane, some vertex
// before the far plane, and its projected bounding box overlapping the image (math.md §1 units).
// `facing` tells whether its counter-clockwise side faces the camera (for a closed mesh the
// other faces are hidden behind it).
bool face_in_view(const Camera& cam, const glm::dvec3 (&p)[3], bool* facing) {
  const glm::dmat4 view = glm::lookAt(cam.eye, cam.target, cam.up);
  const double aspect = double(cam.width) / std::max(cam.height, 1);
  const double t = std::tan(glm::radians(cam.fov_deg) * 0.5);
  double xlo = 1e300, xhi = -1e300, ylo = 1e300, yhi = -1e300, zlo = 1e300;
  for (const auto& v : p) {
    const glm::dvec4 q = view * glm::dvec4(v, 1.0);
    const double z = -q.z;
    if (!(z >= cam.near)) return false;
    zlo = std::min(zlo, z);
    double x, y;
    if (cam.projection == Projection::Perspective) {
      x = q.x / (z * t);
      y = q.y / (z * t);
    } else {
      x = q.x / cam.half_height;
      y = q.y / cam.half_height;
    }
    xlo = std::min(xlo, x), xhi = std::max(xhi, x);
    ylo = std::min(ylo, y), yhi = std::max(yhi, y);
  }
  const glm::dvec3 n = glm::cross(p[1] - p[0], p[2] - p[0]);
  const glm::dvec3 to_camera = cam.projection == Projection::Perspective
                                   ? cam.eye - (p[0] + p[1] + p[2]) / 3.0
                                   : cam.eye - cam.target;
  *facing = glm::dot(n, to_camera) > 0;
  return zlo <= cam.far && xhi >= -aspect && xlo <= aspect && yhi >= -1.0 && ylo <= 1.0;
}

struct FaceRef {
  int mesh, face;
};

// Faces likely to show: per mesh, the faces in some view that face that camera, else the faces
// in some view; every face when no mesh has one in view.
std::vector<FaceRef> candidate_faces(const Scene& scene) {
  std::vector<FaceRef> all, chosen;
  for (size_t m = 0; m < scene.meshes.size(); ++m) {
    const Mesh& mesh = scene.meshes[m];
    std::vector<FaceRef> front, in_view;
    for (size_t f = 0; f < mesh.faces.size(); ++f) {
      const glm::ivec3 F = mesh.faces[f];
      const glm::dvec3 p[3] = {mesh.vertices[F.x], mesh.vertices[F.y], mesh.vertices[F.z]};
      all.push_back({int(m), int(f)});
      bool seen = false, seen_front = false;
      for (const Camera& cam : scene.cameras) {
        bool facing = false;
        if (face_in_view(cam, p, &facing)) {
          seen = true;
          seen_front = seen_front || facing;
        }
      }
      if (seen) in_view.push_back({int(m), int(f)});
      if (seen_front) front.push_back({int(m), int(f)});
    }
    const auto& use = front.empty() ? in_view : front;
    chosen.insert(chosen.end(), use.begin(), use.end());
  }
  return chosen.empty() ? all : chosen;
}

std::string vertex_name(int mesh, int vertex, int axis) {
  return "mesh" + std::to_string(mesh) + ".v" + std::to_string(vertex) + "." + kAxis[axis];
}

// Chooses `samples` distinct parameters spread over vertices of every mesh (at corners of
// visible faces), albedo entries, light positions (point lights) and directions (directional
// lights), light colours and the ambient term. With shadows on, the first entries are one
// vertex of every mesh (a visible corner where the mesh has one) and the position or direction
// of every light, so that every caster, receiver and light is checked through the shadow path.
std::vector<Param> choose_parameters(const Scene& scene, int samples, std::mt19937_64& rng) {
  const std::vector<FaceRef> faces = candidate_faces(scene);
  std::map<int, std::vector<FaceRef>> faces_of_mesh;
  for (const FaceRef& f : faces) faces_of_mesh[f.mesh].push_back(f);
  const int lights = int(scene.lights.size());

  auto uniform = [&rng](size_t n) { return std::uniform_int_distribution<size_t>(0, n - 1)(rng); };
  std::vector<int> meshes_with_faces;
  meshes_with_faces.reserve(faces_of_mesh.size());
  for (const auto& kv : faces_of_mesh) meshes_with_faces.push_back(kv.first);

  std::vector<Param> chosen;
  std::set<std::string> names;
  if (scene.params.shadows != Shadows::None) {
    std::vector<Param> required;
    for (size_t m = 0; m < scene.meshes.size(); ++m) {
      const Mesh& mesh = scene.meshes[m];
      if (mesh.faces.empty()) continue;
      const auto it = faces_of_mesh.find(int(m));
      const int face = it != faces_of_mesh.end() ? it->second[uniform(it->second.size())].face
                                                 : int(uniform(mesh.faces.size()));
      Param p;
      p.kind = Param::Vertex;
      p.mesh = int(m);
      p.index = mesh.faces[face][int(uniform(3))];
      p.axis = int(uniform(3));
      p.name = vertex_name(p.mesh, p.index, p.axis);
      required.push_back(p);
    }
    for (int l = 0; l < lights; ++l) required.push_back(light_param(scene, l, int(uniform(3))));
    for (int l = 0; l < lights && scene.params.shadows == Shadows::Soft; ++l)
      if (scene.lights[l].size > 0) {  // D_L shapes every penumbra
        Param p;
        p.kind = Param::LightSize;
        p.index = l;
        p.name = "light" + std::to_string(l) + ".size";
        required.push_back(p);
      }
    for (const Param& p : required) {
      if (int(chosen.size()) >= samples) break;
      if (names.insert(p.name).second) chosen.push_back(p);
    }
  }
  const int remaining = samples - int(chosen.size());

  // The mix of kinds, repeated: half vertices, then albedo, light position (or direction), light
  // colour, ambient.
  const Param::Kind pattern[] = {
      Param::Vertex,     Param::Albedo, Param::Vertex,  Param::LightPosition, Param::Vertex,
      Param::LightColor, Param::Vertex, Param::Ambient, Param::Vertex,        Param::Albedo};
  int vertex_samples = 0;
  for (int i = 0; i < remaining; ++i) {
    Param::Kind kind = pattern[i % 10];
    if (kind == Param::LightPosition && lights == 0) kind = Param::Vertex;
    if (kind == Param::LightColor && scene.lights.empty()) kind = Param::Vertex;
    if (kind == Param::Vertex && faces.empty()) kind = Param::Ambient;
    if (kind == Param::Albedo && faces.empty()) kind = Param::Ambient;
    Param p;
    for (int attempt = 0; attempt < 64; ++attempt) {
      // Kinds with few entries (ambient, a single light) run out: take a vertex instead.
      if (attempt == 32 && !faces.empty()) kind = Param::Vertex;
      p = Param();
      p.kind = kind;
      std::ostringstream name;
      switch (kind) {
        case Param::Vertex:
        case Param::Albedo: {
          FaceRef f;
          if (kind == Param::Vertex && vertex_samples < int(meshes_with_faces.size())) {
            // The first vertex samples visit every mesh once.
            const auto& list = faces_of_mesh[meshes_with_faces[vertex_samples]];
            f = list[uniform(list.size())];
          } else {
            f = faces[uniform(faces.size())];
          }
          const Mesh& mesh = scene.meshes[f.mesh];
          const int corner = int(uniform(3));
          const int vertex = mesh.faces[f.face][corner];
          p.mesh = f.mesh;
          p.axis = int(uniform(3));
          if (kind == Param::Vertex) {
            p.index = vertex;
            name << vertex_name(p.mesh, p.index, p.axis);
          } else {
            p.index = mesh.albedo_mode == AlbedoMode::PerFace ? f.face : vertex;
            name << "mesh" << p.mesh << ".albedo" << p.index << "." << kChannel[p.axis];
          }
          break;
        }
        case Param::LightPosition:
        case Param::LightDirection: {
          const int l = int(uniform(size_t(lights)));
          p = light_param(scene, l, int(uniform(3)));
          name << p.name;
          break;
        }
        case Param::LightSize:  // only among the required entries
        case Param::LightColor:
          p.kind = Param::LightColor;
          p.index = int(uniform(scene.lights.size()));
          p.axis = int(uniform(3));
          name << "light" << p.index << ".color." << kChannel[p.axis];
          break;
        case Param::Ambient:
          p.axis = int(uniform(3));
          name << "ambient." << kChannel[p.axis];
          break;
      }
      p.name = name.str();
      if (!names.count(p.name)) break;
    }
    if (kind == Param::Vertex) ++vertex_samples;
    if (names.insert(p.name).second) chosen.push_back(p);
  }
  return chosen;
}

double default_step(Precision precision) { return precision == Precision::Double ? 1e-6 : 1e-3; }
double default_rtol(Precision precision) { return precision == Precision::Double ? 1e-3 : 5e-2; }

}  // namespace

bool gradients_agree(double analytic, double numeric, double atol, double rtol) {
  if (!std::isfinite(analytic) || !std::isfinite(numeric)) return false;
  return std::abs(analytic - numeric) <=
         atol + rtol * std::max(std::abs(analytic), std::abs(numeric));
}

double gradient_relative_error(double analytic, double numeric, double atol) {
  const double diff = std::abs(analytic - numeric);
  if (!std::isfinite(diff)) return std::numeric_limits<double>::infinity();
  const double denom = std::max({std::abs(analytic), std::abs(numeric), atol});
  return denom > 0 ? diff / denom : 0.0;
}

std::vector<OutputGrads> random_loss_weights(const Scene& scene, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::vector<OutputGrads> weights;
  weights.reserve(scene.cameras.size());
  for (const Camera& cam : scene.cameras) {
    OutputGrads g;
    g.color = Image(cam.width, cam.height, 3);
    g.silhouette = Image(cam.width, cam.height, 1);
    g.depth = Image(cam.width, cam.height, 1);
    for (double& v : g.color.data) v = normal(rng);
    for (double& v : g.silhouette.data) v = normal(rng);
    for (double& v : g.depth.data) v = normal(rng) / cam.far;
    weights.push_back(std::move(g));
  }
  return weights;
}

double linear_loss(const std::vector<RenderOutput>& outputs,
                   const std::vector<OutputGrads>& weights) {
  if (outputs.size() != weights.size()) {
    throw Error("gradcheck: " + std::to_string(outputs.size()) + " rendered views but " +
                std::to_string(weights.size()) + " sets of loss weights");
  }
  long double sum = 0.0L;
  auto dot = [&sum](const Image& out, const Image& w, const char* what, size_t view) {
    if (w.size() == 0) return;
    if (out.size() != w.size()) {
      throw Error("gradcheck: view " + std::to_string(view) + " " + what + " has " +
                  std::to_string(out.size()) + " values, its loss weights " +
                  std::to_string(w.size()));
    }
    for (size_t i = 0; i < w.size(); ++i) sum += (long double)w.data[i] * out.data[i];
  };
  for (size_t v = 0; v < outputs.size(); ++v) {
    dot(outputs[v].color, weights[v].color, "colour", v);
    dot(outputs[v].silhouette, weights[v].silhouette, "silhouette", v);
    dot(outputs[v].depth, weights[v].depth, "depth", v);
  }
  return double(sum);
}

double max_abs_gradient(const SceneGrads& g) {
  double m = 0.0;
  auto take = [&m](const glm::dvec3& v) {
    for (int k = 0; k < 3; ++k)
      if (std::isfinite(v[k])) m = std::max(m, std::abs(v[k]));
  };
  for (const auto& mesh : g.vertices)
    for (const auto& v : mesh) take(v);
  for (const auto& mesh : g.albedo)
    for (const auto& v : mesh) take(v);
  for (const auto& v : g.light_position) take(v);
  for (const auto& v : g.light_color) take(v);
  take(g.ambient);
  return m;
}

namespace {

// The finite-difference step of entry `p`: positions step by step·(scene radius), directions
// by step·|direction|, colours by step.
double entry_step(const Scene& work, const Param& p, double step, double scale) {
  if (p.kind == Param::LightDirection) {
    const double len = glm::length(work.lights[p.index].direction);
    return step * (len > 0 && std::isfinite(len) ? len : 1.0);
  }
  return p.positional() || p.kind == Param::LightSize ? step * scale : step;
}

// dL/d(entry p) by a central difference of step h, `perturbed` left as it was.
double finite_difference(Renderer& renderer, Scene& perturbed,
                         const std::vector<OutputGrads>& weights, const Param& p, double h) {
  double x0 = 0;
  with_parameter(perturbed, p, [&](double& x) { x0 = x; });
  const auto set = [&](double value) {
    with_parameter(perturbed, p, [&](double& x) { x = value; });
  };
  double xp = x0 + h, xm = x0 - h;
  if (!p.positional() && xm < 0) {
    // Colours may not go negative. The outputs are linear in albedo, light colour and
    // ambient, so a one-sided difference over [x0, x0 + 2h] is as exact as a central one.
    xm = x0;
    xp = x0 + 2 * h;
  }
  set(xp);
  const double lp = linear_loss(renderer.render(perturbed), weights);
  set(xm);
  const double lm = linear_loss(renderer.render(perturbed), weights);
  set(x0);
  return (lp - lm) / (xp - xm);
}

}  // namespace

GradCheckResult compare_with_finite_differences(Renderer& renderer, const Scene& scene,
                                                const std::vector<OutputGrads>& weights,
                                                const SceneGrads& analytic,
                                                const GradCheckOptions& options) {
  if (options.samples < 0) throw Error("gradcheck: samples must be non-negative");
  // The light frusta are fitted once, to the unperturbed scene, and shared by every perturbed
  // copy (math.md §4.1): refitting them to each copy would difference another function.
  Scene work = scene;
  fit_light_frusta(work);
  validate(work);
  const double step = options.step > 0 ? options.step : default_step(renderer.precision());
  const double rtol = options.rtol > 0 ? options.rtol : default_rtol(options.precision);
  const double radius = bounds(work).radius();
  const double scale = radius > 0 && std::isfinite(radius) ? radius : 1.0;

  GradCheckResult result;
  result.rtol = rtol;
  result.atol = options.atol_fraction * max_abs_gradient(analytic);
  result.max_failure_fraction = options.max_failure_fraction;

  // A separate stream from the loss weights, so that the entries do not depend on image size.
  std::mt19937_64 rng(options.seed ^ 0x9e3779b97f4a7c15ULL);
  const std::vector<Param> params = choose_parameters(work, options.samples, rng);
  Scene perturbed = work;
  for (const Param& p : params) {
    if (options.progress) {
      const int done = int(result.entries.size()), count = int(params.size());
      options.progress({"finite differences", "entry", done + 1, count, p.name.c_str(), 0, 0,
                        double(done) / count});
    }
    GradCheckEntry e;
    e.name = p.name;
    e.analytic = gradient(analytic, p);
    e.numeric =
        finite_difference(renderer, perturbed, weights, p, entry_step(work, p, step, scale));
    e.rel_err = gradient_relative_error(e.analytic, e.numeric, result.atol);
    e.ok = gradients_agree(e.analytic, e.numeric, result.atol, rtol);
    result.checked += 1;
    result.failed += e.ok ? 0 : 1;
    result.max_rel_err = std::max(result.max_rel_err, e.rel_err);
    result.entries.push_back(std::move(e));
  }
  return result;
}

GradCheckResult gradcheck(Renderer& renderer, const Scene& scene, const GradCheckOptions& options) {
  GradCheckOptions o = options;
  o.precision = renderer.precision();
  Scene work = scene;
  fit_light_frusta(work);  // before anything: the perturbed copies share these frusta
  const std::vector<OutputGrads> weights = random_loss_weights(work, o.seed);
  renderer.render(work);
  const SceneGrads analytic = renderer.backward(work, weights);
  return compare_with_finite_differences(renderer, work, weights, analytic, o);
}

GradCheckResult gradcheck(Context& context, const Scene& scene, const GradCheckOptions& options) {
  Renderer renderer(context, options.precision, options.tuning);
  if (options.precision == Precision::Double || !options.double_differences ||
      !context.info().fp64) {
    return gradcheck(renderer, scene, options);
  }
  Scene work = scene;
  fit_light_frusta(work);  // before anything: the perturbed copies share these frusta
  const std::vector<OutputGrads> weights = random_loss_weights(work, options.seed);
  renderer.render(work);
  const SceneGrads analytic = renderer.backward(work, weights);
  Renderer reference(context, Precision::Double, options.tuning);
  return compare_with_finite_differences(reference, work, weights, analytic, options);
}

}  // namespace penumbra
