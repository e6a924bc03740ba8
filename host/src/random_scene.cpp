// random_scene(): the small random scenes of the gradient checks (penumbra/gradcheck.hpp).
#include <algorithm>
#include <cmath>
#include <glm/gtc/constants.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <map>
#include <random>
#include <utility>

#include "penumbra/gradcheck.hpp"

namespace penumbra {

namespace {

// Icosahedron subdivided once: 42 vertices, 80 faces, counter-clockwise seen from outside.
Mesh unit_icosphere() {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<glm::dvec3> v = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0},
                               {0, -1, t}, {0, 1, t}, {0, -1, -t}, {0, 1, -t},
                               {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  for (auto& p : v) p = glm::normalize(p);
  std::vector<glm::ivec3> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                               {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                               {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                               {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  std::map<std::pair<int, int>, int> midpoint;
  auto mid = [&](int a, int b) {
    const auto key = std::make_pair(std::min(a, b), std::max(a, b));
    const auto it = midpoint.find(key);
    if (it != midpoint.end()) return it->second;
    v.push_back(glm::normalize(v[a] + v[b]));
    return midpoint[key] = int(v.size()) - 1;
  };
  std::vector<glm::ivec3> g;
  for (const auto& F : f) {
    const int a = mid(F.x, F.y), b = mid(F.y, F.z), c = mid(F.z, F.x);
    g.emplace_back(F.x, a, c);
    g.emplace_back(F.y, b, a);
    g.emplace_back(F.z, c, b);
    g.emplace_back(a, b, c);
  }
  Mesh mesh;
  mesh.vertices = std::move(v);
  mesh.faces = std::move(g);
  return mesh;
}

// The random draws of one scene, in the order the scene takes them (the same seed gives the
// same scene).
class Draws {
 public:
  explicit Draws(uint64_t seed) : rng_(seed) {}
  double uniform(double lo, double hi) {
    return std::uniform_real_distribution<double>(lo, hi)(rng_);
  }
  bool chance(double p) { return std::uniform_real_distribution<double>(0, 1)(rng_) < p; }
  glm::dvec3 colour(double lo, double hi) {
    const double r = uniform(lo, hi), g = uniform(lo, hi), b = uniform(lo, hi);
    return glm::dvec3(r, g, b);
  }

 private:
  std::mt19937_64 rng_;
};

// Occluder: a jittered icosphere floating a little above the ground.
Mesh random_occluder(Draws& d) {
  Mesh ball = unit_icosphere();
  ball.name = "occluder";
  const double radius = d.uniform(0.4, 0.7);
  const glm::dvec3 centre(d.uniform(-0.3, 0.3), radius + d.uniform(0.05, 0.3),
                          d.uniform(-0.3, 0.3));
  for (auto& p : ball.vertices) p = centre + radius * d.uniform(0.95, 1.05) * p;
  ball.albedo_mode = AlbedoMode::PerVertex;
  ball.albedo.clear();
  for (size_t i = 0; i < ball.vertices.size(); ++i) ball.albedo.push_back(d.colour(0.2, 0.9));
  return ball;
}

// Ground: a quad in y = 0, normal +y.
Mesh random_ground(Draws& d) {
  Mesh ground;
  ground.name = "ground";
  const double s = d.uniform(1.2, 1.8);
  ground.vertices = {{-s, 0, -s}, {-s, 0, s}, {s, 0, s}, {s, 0, -s}};
  ground.faces = {{0, 1, 2}, {0, 2, 3}};
  if (d.chance(0.5)) {
    ground.albedo_mode = AlbedoMode::PerFace;
    for (size_t i = 0; i < ground.faces.size(); ++i) ground.albedo.push_back(d.colour(0.3, 0.9));
  } else {
    ground.albedo_mode = AlbedoMode::PerVertex;
    for (size_t i = 0; i < ground.vertices.size(); ++i) ground.albedo.push_back(d.colour(0.3, 0.9));
  }
  return ground;
}

// Camera: looks at the occluder from a random direction above the ground, far enough that
// every vertex lies well in front of the near plane.
Camera random_camera(Draws& d) {
  Camera cam;
  const double elevation = glm::radians(d.uniform(15.0, 55.0));
  const double azimuth = d.uniform(0.0, 2.0 * glm::pi<double>());
  const double dist = d.uniform(4.0, 6.0);
  cam.target = glm::dvec3(0.0, d.uniform(0.3, 0.6), 0.0);
  cam.eye =
      cam.target + dist * glm::dvec3(std::cos(elevation) * std::sin(azimuth), std::sin(elevation),
                                     std::cos(elevation) * std::cos(azimuth));
  cam.up = {0, 1, 0};
  if (d.chance(0.6)) {
    cam.projection = Projection::Perspective;
    cam.fov_deg = d.uniform(35.0, 50.0);
  } else {
    cam.projection = Projection::Orthographic;
    cam.half_height = d.uniform(1.2, 1.8);
  }
  cam.near = 0.1;
  cam.far = 20.0;
  cam.width = 40 + int(d.uniform(0, 16));
  cam.height = 32 + int(d.uniform(0, 16));
  return cam;
}

// One light above the scene: a point light or a directional one.
Light random_light(Draws& d) {
  Light light;
  const double el = glm::radians(d.uniform(30.0, 75.0));
  const double az = d.uniform(0.0, 2.0 * glm::pi<double>());
  const glm::dvec3 dir(std::cos(el) * std::sin(az), std::sin(el), std::cos(el) * std::cos(az));
  if (d.chance(0.65)) {
    light.type = LightType::Point;
    light.position = d.uniform(4.0, 8.0) * dir;
  } else {
    light.type = LightType::Directional;
    light.direction = -dir;
  }
  light.color = d.colour(0.4, 1.0);
  light.size = d.uniform(0.1, 0.5);
  return light;
}

}  // namespace

Scene random_scene(uint64_t seed) {
  Draws d(seed);
  Scene scene;
  Mesh ball = random_occluder(d);
  Mesh ground = random_ground(d);
  scene.meshes = {std::move(ball), std::move(ground)};
  scene.cameras = {random_camera(d)};
  const int lights = d.chance(0.5) ? 1 : 2;  // one or two
  for (int l = 0; l < lights; ++l) scene.lights.push_back(random_light(d));
  scene.ambient = d.colour(0.05, 0.3);
  scene.background = d.colour(0.0, 1.0);

  scene.params.sigma = 3e-4 * d.uniform(0.7, 1.3);
  scene.params.gamma = 3e-3 * d.uniform(0.7, 1.3);
  fit_light_frusta(scene);
  return scene;
}

}  // namespace penumbra
