// Accuracy scenes and metrics against the ray-traced truth (see accuracy.hpp).
#include "accuracy.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <sstream>

#include "penumbra/error.hpp"
#include "penumbra/image_io.hpp"
#include "penumbra/io.hpp"

namespace penumbra::bench {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr int kShadowMargin = 8;         // px around the sphere-light truth's shadow
constexpr int kContactMargin = 3;        // px around the contact
constexpr double kContactHeight = 0.01;  // caster vertices this close to the ground touch it
constexpr double kContactRadius = 0.1;   // surface points this close to one are at the contact

glm::dvec3 knot_point(int p, int q, double R, double r, double t) {
  const double w = R + r * std::cos(q * t);
  return {w * std::cos(p * t), w * std::sin(p * t), r * std::sin(q * t)};
}

glm::dvec3 knot_tangent(int p, int q, double R, double r, double t) {
  const double w = R + r * std::cos(q * t), dw = -r * q * std::sin(q * t);
  return glm::normalize(glm::dvec3(dw * std::cos(p * t) - w * p * std::sin(p * t),
                                   dw * std::sin(p * t) + w * p * std::cos(p * t),
                                   r * q * std::cos(q * t)));
}

// Faces of a segments × sides grid closed in both directions, oriented outward from the
// curve (`centers`, one per segment).
void tube_faces(Mesh& m, int segments, int sides, const std::vector<glm::dvec3>& centers) {
  auto id = [&](int i, int j) { return (i % segments) * sides + (j % sides); };
  for (int i = 0; i < segments; ++i)
    for (int j = 0; j < sides; ++j) {
      m.faces.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
      m.faces.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
    }
  const glm::ivec3 f = m.faces.front();
  const glm::dvec3 n =
      glm::cross(m.vertices[f.y] - m.vertices[f.x], m.vertices[f.z] - m.vertices[f.x]);
  if (glm::dot(n, m.vertices[f.x] - centers.front()) < 0)
    m.faces.edit([](std::vector<glm::ivec3>& faces) {
      for (auto& g : faces) std::swap(g.y, g.z);
    });
}

// Lowest vertex of `m` moved to height `lift`.
void rest_at(Mesh& m, double lift) {
  double lo = 1e300;
  for (const auto& v : m.vertices) lo = std::min(lo, v.y);
  for (auto& v : m.vertices) v.y += lift - lo;
}

double knot_lift(const std::string& name) {
  static const std::map<std::string, double> lift = {
      {"knot_h0", 0.0}, {"knot_h0.3", 0.3}, {"knot_h1", 1.0}};
  return lift.at(name);
}

// The caster (mesh 0) and the light of a scene of accuracy_scene_names().
void set_scene(Scene& s, const std::string& name) {
  Mesh& caster = s.meshes.front();
  const glm::dvec3 albedo = caster.albedo.front();
  Light& L = s.lights.front();
  if (name == "sphere" || name.rfind("sphere_100k", 0) == 0) return;  // (accuracy_scene's)
  if (name == "grazing") {
    caster = icosphere(8, {0, 0.5, 0}, 0.5, albedo);
    rest_at(caster, 0.0);
    const double e = 18.0 * kPi / 180.0;
    const glm::dvec3 h = glm::normalize(glm::dvec3(-1, 0, 0.6));
    L.position = glm::dvec3(0, 0.5, 0) + 8.0 * (std::cos(e) * h + glm::dvec3(0, std::sin(e), 0));
    return;
  }
  if (name == "among" || name == "among_frustum") {
    const glm::dvec3 at[] = {{1.1, 0.3, -0.3}, {0, 0.3, 0.8}, {-1.1, 0.3, -0.3}, {0, 0.3, -1.4}};
    caster = icosphere(8, at[0], 0.3, albedo);
    for (int i = 1; i < 4; ++i)
      s.meshes.insert(s.meshes.begin() + i, icosphere(8, at[i], 0.3, albedo));
    L.position = {0, 0.9, -0.3};
    if (name == "among_frustum") L.shadow_map = ShadowMapShape::Frustum;
    return;
  }
  if (name.rfind("knot_h", 0) == 0) {
    caster = torus_knot(2, 3, 0.9, 0.35, 0.16, 192, 10, knot_lift(name), albedo);
    return;
  }
  throw Error("bench: unknown accuracy scene '" + name + "'");
}

int ground_mesh(const Scene& s) {
  for (size_t i = 0; i < s.meshes.size(); ++i)
    if (s.meshes[i].name == "ground") return int(i);
  return int(s.meshes.size()) - 1;
}

// Caster vertices on the ground (within kContactHeight of its top).
std::vector<glm::dvec3> contact_points(const Scene& s) {
  const int g = ground_mesh(s);
  double top = -1e300;
  for (const auto& v : s.meshes[g].vertices) top = std::max(top, v.y);
  std::vector<glm::dvec3> out;
  for (size_t mi = 0; mi < s.meshes.size(); ++mi)
    if (int(mi) != g)
      for (const auto& v : s.meshes[mi].vertices)
        if (v.y - top <= kContactHeight) out.push_back(v);
  return out;
}

struct Regions {
  std::vector<char> ground, shadow, contact;
};

// Pixels within `margin` px (a square) of a pixel where `seed` holds, restricted to `within`.
std::vector<char> dilate(const std::vector<char>& seed, const std::vector<char>& within, int W,
                         int H, int margin) {
  std::vector<char> out(seed.size(), 0);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      if (!seed[size_t(y) * W + x]) continue;
      for (int v = std::max(0, y - margin); v <= std::min(H - 1, y + margin); ++v)
        for (int u = std::max(0, x - margin); u <= std::min(W - 1, x + margin); ++u)
          out[size_t(v) * W + u] = 1;
    }
  for (size_t p = 0; p < out.size(); ++p) out[p] &= within[p];
  return out;
}

// How far (px, rounded up) the soft rasterizer spreads a face beyond its outline: its coverage
// sigmoid(−d²/σ) stays above the cut-off ε_D out to d = √(σ ln(1/ε_D − 1)) screen units, and
// with a small γ a nearer face wins the pixel wherever it is not cut off.
int silhouette_margin(const Scene& s) {
  const RenderParams& p = s.params;
  const double reach = std::sqrt(p.sigma * std::log(1.0 / p.dist_eps - 1.0));
  return std::max(1, int(std::ceil(reach * s.cameras.front().height / 2.0)));
}

// Ground pixels whose rays, and those of every pixel within `margin` px (a square), hit the
// ground: the pixels where the camera's soft rasterizer blends in no other surface.
std::vector<char> ground_pixels(const GroundTruth& gt, int ground, int margin) {
  std::vector<char> other(gt.mesh.size()), all(gt.mesh.size(), 1), g(gt.mesh.size());
  for (size_t p = 0; p < g.size(); ++p) other[p] = gt.mesh[p] != ground;
  const std::vector<char> near_other = dilate(other, all, gt.W, gt.H, margin);
  for (size_t p = 0; p < g.size(); ++p) g[p] = gt.mesh[p] == ground && !near_other[p];
  return g;
}

Regions make_regions(const Scene& s, const GroundTruth& sphere) {
  Regions r;
  const size_t n = size_t(sphere.W) * sphere.H;
  r.ground = ground_pixels(sphere, ground_mesh(s), silhouette_margin(s));
  std::vector<char> shadowed(n, 0), at_contact(n, 0);
  const std::vector<glm::dvec3> contacts = contact_points(s);
  for (size_t p = 0; p < n; ++p) {
    shadowed[p] = sphere.mesh[p] == ground_mesh(s) && sphere.vis[p] < 0.999;
    for (const auto& c : contacts)
      if (sphere.mesh[p] >= 0 && glm::length(sphere.point[p] - c) <= kContactRadius)
        at_contact[p] = 1;
  }
  r.shadow = dilate(shadowed, r.ground, sphere.W, sphere.H, kShadowMargin);
  r.contact = dilate(at_contact, r.ground, sphere.W, sphere.H, kContactMargin);
  return r;
}

const Regions& regions(const std::string& scene) {
  static std::map<std::string, std::unique_ptr<Regions>> cache;
  auto& slot = cache[scene];
  if (!slot) {
    AccuracyCase c;
    c.scene = scene;
    slot = std::make_unique<Regions>(
        make_regions(accuracy_scene(c), truth(scene, TruthLight::Sphere)));
  }
  return *slot;
}

}  // namespace

Mesh torus_knot(int p, int q, double R, double r, double tube, int segments, int sides, double lift,
                glm::dvec3 albedo) {
  Mesh m;
  m.name = "knot";
  std::vector<glm::dvec3> centers;
  for (int i = 0; i < segments; ++i) {
    const double t = 2 * kPi * i / segments;
    const glm::dvec3 c = knot_point(p, q, R, r, t), T = knot_tangent(p, q, R, r, t);
    const glm::dvec3 n1 = glm::normalize(glm::cross(T, glm::dvec3(0, 0, 1))),
                     n2 = glm::cross(T, n1);
    centers.push_back(c);
    for (int j = 0; j < sides; ++j) {
      const double a = 2 * kPi * j / sides;
      m.vertices.push_back(c + tube * (std::cos(a) * n1 + std::sin(a) * n2));
    }
  }
  tube_faces(m, segments, sides, centers);
  for (auto& v : m.vertices) v = glm::dvec3(v.x, v.z, -v.y);  // z axis to +y: lying flat
  rest_at(m, lift);
  m.albedo.assign(m.vertices.size(), albedo);
  m.albedo_mode = AlbedoMode::PerVertex;
  return m;
}

const std::vector<std::string>& accuracy_scene_names() {
  static const std::vector<std::string> names = {"sphere",  "knot_h0", "knot_h0.3",
                                                 "knot_h1", "grazing", "among"};
  return names;
}

Scene accuracy_scene(const AccuracyCase& c) {
  Case k;
  k.shadows = c.shadows;
  k.sampling = c.sampling;
  k.exact_backend = c.exact_backend;
  k.model = c.model;
  k.image = c.scene == "sphere_100k_512" ? 512 : 256;
  if (c.scene.rfind("sphere_100k", 0) == 0) k.frequency = icosphere_frequency_for(100820);
  Scene s = make_scene(k);
  s.params.shadow_map_size = c.map;
  s.params.sigma_s = c.sigma_s;
  set_scene(s, c.scene);
  for (auto& L : s.lights) L.frustum = LightFrustum{};
  fit_light_frusta(s);
  validate(s);
  return s;
}

const GroundTruth& truth(const std::string& scene, TruthLight light) {
  static std::map<std::pair<std::string, TruthLight>, std::unique_ptr<GroundTruth>> cache;
  auto& slot = cache[{scene, light}];
  if (!slot) {
    AccuracyCase c;
    c.scene = scene;
    slot = std::make_unique<GroundTruth>(ray_trace(accuracy_scene(c), light));
  }
  return *slot;
}

TruthLight truth_for(Shadows shadows) {
  return shadows == Shadows::Soft ? TruthLight::Sphere : TruthLight::Point;
}

Rendered render_visibility(Renderer& r, const Scene& s) {
  Scene unshadowed = s;
  unshadowed.params.shadows = Shadows::None;
  Scene ambient = unshadowed;
  for (Light& L : ambient.lights) L.color = glm::dvec3(0.0);
  Rendered out;
  out.color = r.render(s).front().color;
  const Image U = r.render(unshadowed).front().color, A = r.render(ambient).front().color;
  out.vis.assign(size_t(U.width) * U.height, 1.0);
  for (size_t p = 0; p < out.vis.size(); ++p) {
    double num = 0, den = 0;
    for (int k = 0; k < 3; ++k) {
      num += out.color.data[3 * p + k] - A.data[3 * p + k];
      den += U.data[3 * p + k] - A.data[3 * p + k];
    }
    if (den > 1e-6) out.vis[p] = num / den;
  }
  return out;
}

// Whether a 4-neighbour of pixel p is lit (visibility ≥ 0.5) in the truth.
bool beside_truth_light(const GroundTruth& T, size_t p) {
  const int x = int(p % size_t(T.W)), y = int(p / size_t(T.W));
  const int dx[4] = {-1, 1, 0, 0}, dy[4] = {0, 0, -1, 1};
  for (int k = 0; k < 4; ++k) {
    const int u = x + dx[k], v = y + dy[k];
    if (u >= 0 && v >= 0 && u < T.W && v < T.H && T.vis[size_t(v) * T.W + u] >= 0.5) return true;
  }
  return false;
}

AccuracyMetrics measure(const AccuracyCase& c, const Rendered& rendered) {
  const GroundTruth& T = truth(c.scene, truth_for(c.shadows));
  const Regions& R = regions(c.scene);
  AccuracyMetrics m;
  double se = 0, lit = 0;
  int rendered_shadow = 0, leaking = 0;
  for (size_t p = 0; p < T.vis.size(); ++p) {
    if (!R.ground[p]) continue;
    const double* C = &rendered.color.data[3 * p];
    const double* G = &T.color[3 * p];
    const bool true_shadow = T.vis[p] < 0.5, shadow = rendered.vis[p] < 0.5;
    ++m.ground_pixels;
    m.true_shadow_pixels += true_shadow;
    rendered_shadow += shadow;
    if (T.vis[p] >= 1.0) {
      double num = 0, den = 0;
      for (int k = 0; k < 3; ++k) num += std::abs(C[k] - G[k]), den += G[k];
      lit += num / den;
      ++m.lit_pixels;
    }
    if (R.shadow[p]) {
      for (int k = 0; k < 3; ++k) se += (C[k] - G[k]) * (C[k] - G[k]);
      ++m.shadow_pixels;
    }
    if (R.contact[p]) {
      ++m.contact_pixels;
      m.contact_shadow_pixels += true_shadow;
      leaking += true_shadow && !shadow;
      m.leaking_on_edge += true_shadow && !shadow && beside_truth_light(T, p);
    }
  }
  m.area_ratio = m.true_shadow_pixels ? double(rendered_shadow) / m.true_shadow_pixels : 0.0;
  m.lit_error = m.lit_pixels ? lit / m.lit_pixels : 0.0;
  m.rmse_shadow = m.shadow_pixels ? std::sqrt(se / (3.0 * m.shadow_pixels)) : 0.0;
  if (m.contact_shadow_pixels > 0) m.leak = double(leaking) / m.contact_shadow_pixels;
  return m;
}

void save_comparison(const GroundTruth& truth, const Image& color, const std::string& path) {
  const int W = truth.W, H = truth.H;
  Image strip(3 * W, H, 3);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const size_t p = size_t(y) * W + x;
      double d = 0;
      for (int k = 0; k < 3; ++k) {
        strip.at(x, y, k) = truth.color[3 * p + k];
        strip.at(W + x, y, k) = color.data[3 * p + k];
        d += (color.data[3 * p + k] - truth.color[3 * p + k]) / 3.0;
      }
      const double a = std::min(1.0, 4.0 * std::abs(d));
      const glm::dvec3 diff = d < 0 ? glm::dvec3(1, 1 - a, 1 - a) : glm::dvec3(1 - a, 1 - a, 1);
      for (int k = 0; k < 3; ++k) strip.at(2 * W + x, y, k) = diff[k];
    }
  save_png(strip, path);
}

}  // namespace penumbra::bench

namespace penumbra::bench {

namespace {

// "[x, y, z]", each to the last bit.
std::string json_vec3(const glm::dvec3& v) {
  std::ostringstream o;
  o.precision(17);
  o << '[' << v.x << ", " << v.y << ", " << v.z << ']';
  return o.str();
}

// The scene as a scene file (docs/scene-format.md) with its meshes beside it as OBJ: camera 0
// and light 0, what the comparison needs.
std::vector<FileContent> scene_files(const Scene& s, const std::string& dir,
                                     const std::string& name) {
  std::vector<FileContent> files;
  std::ostringstream json;
  json.precision(17);
  json << "{\n  \"meshes\": [";
  for (size_t i = 0; i < s.meshes.size(); ++i) {
    const Mesh& m = s.meshes[i];
    const std::string obj = name + "_mesh" + std::to_string(i) + ".obj";
    files.push_back({(std::filesystem::path(dir) / obj).string(), obj_text(m), "mesh"});
    json << (i ? ",\n" : "\n") << "    {\"file\": \"" << obj << "\", \"name\": \"" << m.name
         << "\", \"albedo\": " << json_vec3(m.albedo.empty() ? glm::dvec3(0.8) : m.albedo[0])
         << '}';
  }
  const Camera& c = s.cameras.front();
  const Light& L = s.lights.front();
  json << "\n  ],\n  \"cameras\": [{\"eye\": " << json_vec3(c.eye)
       << ", \"target\": " << json_vec3(c.target) << ", \"up\": " << json_vec3(c.up)
       << ", \"fov\": " << c.fov_deg << ", \"near\": " << c.near << ", \"far\": " << c.far
       << ", \"width\": " << c.width << ", \"height\": " << c.height << "}],\n"
       << "  \"lights\": [{\"type\": \"point\", \"position\": " << json_vec3(L.position)
       << ", \"color\": " << json_vec3(L.color) << ", \"size\": " << L.size << "}],\n"
       << "  \"ambient\": " << json_vec3(s.ambient)
       << ",\n  \"background\": " << json_vec3(s.background) << "\n}\n";
  files.push_back({dir + "/" + name + ".json", json.str(), "scene"});
  return files;
}

Image truth_image(const GroundTruth& t) {
  Image out(t.W, t.H, 3);
  out.data = t.color;
  return out;
}

}  // namespace

void save_side_by_side(const std::string& scene, const std::string& dir) {
  AccuracyCase c;
  c.scene = scene;
  std::vector<FileContent> files = scene_files(accuracy_scene(c), dir, scene);
  const GroundTruth& T = truth(scene, TruthLight::Sphere);
  Image region(T.W, T.H, 1);
  const Regions& R = regions(scene);
  for (size_t p = 0; p < R.shadow.size(); ++p) region.data[p] = R.shadow[p] ? 1.0 : 0.0;
  const std::string at = dir + "/" + scene;
  files.push_back({at + "_region.npy", npy_bytes(region, at + "_region.npy"), "array"});
  for (TruthLight light : {TruthLight::Point, TruthLight::Sphere}) {
    const std::string path =
        at + (light == TruthLight::Point ? "_truth_hard" : "_truth_soft") + ".npy";
    files.push_back({path, npy_bytes(truth_image(truth(scene, light)), path), "array"});
  }
  write_files(files);
}

}  // namespace penumbra::bench
