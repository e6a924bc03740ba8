// Shadows on walls: the scene of one directional light, a wall and a camera looking at the wall
// (the paper's Figure 7, one light at a time), and the shadow images read from it.
#include <algorithm>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "optim/stages.hpp"
#include "penumbra/error.hpp"
#include "penumbra/optim.hpp"

namespace penumbra::optim {

Scene wall_scene(const Mesh& shape, const glm::dvec3& direction, int size,
                 const RenderParams& params, const WallSetup& w, bool with_shape) {
  const glm::dvec3 d = glm::normalize(direction);
  const glm::dvec3 up = view_up(d);
  const glm::dvec3 right = glm::normalize(glm::cross(d, up));
  const glm::dvec3 wup = glm::cross(right, d);
  Scene scene;
  if (with_shape) scene.meshes.push_back(shape);
  // The wall: a square across the light, facing it (counter-clockwise seen from the light).
  Mesh wall;
  wall.name = "wall";
  const glm::dvec3 c = w.wall_distance * d;
  const double h = w.wall_half_size;
  wall.vertices = {c - h * right - h * wup, c + h * right - h * wup, c + h * right + h * wup,
                   c - h * right + h * wup};
  wall.faces = {{0, 2, 1}, {0, 3, 2}};
  wall.albedo.assign(4, glm::dvec3(1.0));
  scene.meshes.push_back(wall);
  // The camera between the shape and the wall, looking at the wall.
  Camera cam = ortho_camera(d, w.half_height, size, (w.camera_distance + 1.0) * d, 1.0, 0.05,
                            w.wall_distance - w.camera_distance + 1.0);
  scene.cameras.push_back(cam);
  Light light;
  light.type = LightType::Directional;
  light.direction = d;
  light.color = {1, 1, 1};
  light.size = 0.0;
  LightFrustum& f = light.frustum;
  f.fitted = true;
  f.target = glm::dvec3(0.0);
  f.up = up;
  f.half_size = w.map_half_size;
  f.distance = w.light_distance;
  f.near = 0.2 * w.light_distance;
  f.far = w.light_distance + w.wall_distance + 0.5;
  scene.lights.push_back(light);
  scene.ambient = {0, 0, 0};
  scene.background = {1, 1, 1};
  scene.params = params;
  return scene;
}

Image shadow_image(const Image& color, const Image& reference) {
  if (color.width != reference.width || color.height != reference.height ||
      color.channels != reference.channels)
    throw Error("shadow_image: colour and reference images differ in size");
  Image out(color.width, color.height, 1);
  const int ch = color.channels;
  for (size_t i = 0; i < out.data.size(); ++i) {
    double c = 0, r = 0;
    for (int k = 0; k < ch; ++k) {
      c += color.data[i * size_t(ch) + size_t(k)];
      r += reference.data[i * size_t(ch) + size_t(k)];
    }
    out.data[i] = r > 0 ? 1.0 - c / r : 0.0;
  }
  return out;
}

Image shadow_image_backward(const Image& g, const Image& reference) {
  const int ch = reference.channels;
  Image out(reference.width, reference.height, ch, 0.0);
  for (size_t i = 0; i < g.data.size(); ++i) {
    double r = 0;
    for (int k = 0; k < ch; ++k) r += reference.data[i * size_t(ch) + size_t(k)];
    if (!(r > 0)) continue;
    for (int k = 0; k < ch; ++k) out.data[i * size_t(ch) + size_t(k)] = -g.data[i] / r;
  }
  return out;
}

RenderParams hard_shadow_params(int map_size) {
  RenderParams p;
  p.sigma = 1e-9;
  p.light_sigma = 1e-9;
  p.gamma = 1e-4;
  p.light_gamma = 1e-4;
  p.shadows = Shadows::Hard;
  p.sampling = Sampling::Truncated;
  p.shadow_map_size = map_size;
  p.sigma_s = 0.1;  // texel²: the filter reads about one texel
  p.gamma_s = 0.01;
  p.beta = 0.2;
  return p;
}

std::vector<Image> hard_shadows(Renderer& renderer, const Mesh& shape,
                                const std::vector<glm::dvec3>& directions, int size,
                                const WallSetup& setup) {
  const RenderParams p = hard_shadow_params(std::min(4 * size, 4096));
  std::vector<Image> masks;
  for (const glm::dvec3& d : directions) {
    const Image ref = renderer.render(wall_scene(shape, d, size, p, setup, false)).front().color;
    const Image col = renderer.render(wall_scene(shape, d, size, p, setup, true)).front().color;
    masks.push_back(binarize(shadow_image(col, ref)));
  }
  return masks;
}

}  // namespace penumbra::optim

namespace penumbra::optim {

RenderParams ShadowProblem::default_shadow_fit_params(ShadowModel model) {
  RenderParams p;
  p.shadows = Shadows::Hard;
  p.shadow_model = model;
  p.sampling = Sampling::Truncated;
  p.sigma = 1e-4;
  p.gamma = 1e-4;
  // γ_L large enough that the soft depth S blends from the wall's depth to the occluder's over
  // the occluder's coverage falling from 1 to 0 (with a small γ_L the nearer occluder wins as
  // soon as it covers a texel at all, S jumps at the coverage cut-off and the shadow's edge has
  // no gradient). The soft depth S blends over the occluder's outline, and the accurate model's
  // shadow edge lies where S has come β in front of the wall: β = 2.2, about two thirds of the
  // gap between the occluder's lit side and the wall (≈ 3.25), puts it near the outline, so the
  // fitted shape is not drawn too small; the compare's band [β − 2γ_s, β + 2γ_s] = [1.5, 2.9]
  // stays within the gap (docs/applications.md has the IoUs each choice fits to). The paper
  // model filters S before the compare, which moves its edge outwards by itself: its own
  // β = 1.5, γ_s = 0.3.
  const bool paper = model == ShadowModel::Paper;
  p.light_gamma = 0.1;
  p.sigma_s = 2.0;
  p.gamma_s = paper ? 0.3 : 0.35;
  p.beta = paper ? 1.5 : 2.2;
  return p;
}

namespace {

// One stage's loss of fit_shadows: the mean squared error of each light's shadow on its wall
// with its target, at the stage's resolution. The walls without the shape, rendered once, are
// the references the shadows are measured against.
class ShadowLoss {
 public:
  ShadowLoss(Renderer& renderer, const ShadowProblem& problem, const ShadowStage& stage,
             const Mesh& mesh)
      : renderer_(renderer) {
    const int full = problem.targets.front().width;
    RenderParams params = problem.params;
    params.light_sigma = stage.light_sigma;
    params.shadow_map_size = stage.map_size;
    for (size_t l = 0; l < problem.directions.size(); ++l) {
      targets_.push_back(downsample(problem.targets[l], full / stage.resolution));
      Scene wall =
          wall_scene(mesh, problem.directions[l], stage.resolution, params, problem.setup, false);
      wall.lights.front().size = stage.light_size;
      references_.push_back(renderer.render(wall).front().color);
      scenes_.push_back(
          wall_scene(mesh, problem.directions[l], stage.resolution, params, problem.setup, true));
      scenes_.back().lights.front().size = stage.light_size;
    }
    shadows_.resize(problem.directions.size());
  }

  std::vector<glm::dvec3> operator()(const Mesh& mesh, FitProgress& p) {
    std::vector<glm::dvec3> grad(mesh.vertices.size(), glm::dvec3(0.0));
    for (size_t l = 0; l < scenes_.size(); ++l) {
      scenes_[l].meshes.front().vertices = mesh.vertices;
      const std::vector<RenderOutput> out = renderer_.render(scenes_[l]);
      shadows_[l] = shadow_image(out.front().color, references_[l]);
      Image g;
      p.loss += mse_loss(shadows_[l], targets_[l], &g);
      p.ious.push_back(binary_iou(shadows_[l], binarize(targets_[l])));
      OutputGrads og;
      og.color = shadow_image_backward(g, references_[l]);
      const SceneGrads sg = renderer_.backward(scenes_[l], {og});
      for (size_t i = 0; i < grad.size(); ++i) grad[i] += sg.vertices.front()[i];
    }
    p.images = &shadows_;
    return grad;
  }

 private:
  Renderer& renderer_;
  std::vector<Scene> scenes_;
  std::vector<Image> targets_, references_, shadows_;
};

}  // namespace

Mesh fit_shadows(Renderer& renderer, Mesh mesh, const ShadowProblem& problem,
                 const std::vector<ShadowStage>& stages, const FitObserver& observer,
                 const FitCheckpoints& checkpoints) {
  const int total = prepare_fit("fit_shadows", problem.targets, problem.directions.size(), "lights",
                                stages, mesh);
  return fit_stages(std::move(mesh), stages, total, observer, checkpoints,
                    [&](const ShadowStage& stage, const Mesh& m) {
                      return ShadowLoss(renderer, problem, stage, m);
                    });
}

}  // namespace penumbra::optim

namespace penumbra::optim {

bool orthogonal(const std::vector<glm::dvec3>& d) {
  for (size_t i = 0; i < d.size(); ++i)
    for (size_t j = 0; j < i; ++j)
      if (std::abs(glm::dot(glm::normalize(d[i]), glm::normalize(d[j]))) > 1e-6) return false;
  return true;
}

namespace {

// The room's wall across the light along `d` (unit, `up` its view_up): a grid of 8 × 8 quads,
// so that the perspective camera sees no long thin triangles.
Mesh room_wall(const glm::dvec3& d, const glm::dvec3& up, double W) {
  const glm::dvec3 right = glm::normalize(glm::cross(d, up)), wup = glm::cross(right, d);
  Mesh wall;
  wall.name = "wall";
  constexpr int kCells = 8;
  for (int j = 0; j <= kCells; ++j)
    for (int i = 0; i <= kCells; ++i)
      wall.vertices.push_back(W * d + W * (2.0 * i / kCells - 1) * right +
                              W * (2.0 * j / kCells - 1) * wup);
  for (int j = 0; j < kCells; ++j)
    for (int i = 0; i < kCells; ++i) {
      const int a = j * (kCells + 1) + i, b = a + 1, c = a + kCells + 1, e = c + 1;
      wall.faces.emplace_back(a, e, b);
      wall.faces.emplace_back(a, c, e);
    }
  wall.albedo.assign(wall.vertices.size(), glm::dvec3(0.8));
  return wall;
}

// The room's directional light along `d` (unit, `up` its view_up), its map covering the wall.
Light room_light(const glm::dvec3& d, const glm::dvec3& up, double intensity, const WallSetup& w) {
  const double W = w.wall_distance;
  Light light;
  light.type = LightType::Directional;
  light.direction = d;
  light.color = glm::dvec3(intensity);
  LightFrustum& f = light.frustum;
  f.fitted = true;
  f.target = glm::dvec3(0.0);
  f.up = up;
  f.half_size = W;
  f.distance = w.light_distance;
  f.near = 0.2 * w.light_distance;
  f.far = w.light_distance + W + 0.5;
  return light;
}

// Look into the corner from the open side (`open`, the sum of the directions' opposites); from a
// little above when there is no floor (with a floor, from higher up the object would hide its
// own shadow there).
Camera room_camera(const std::vector<glm::dvec3>& directions, const glm::dvec3& open, double W,
                   int width, int height) {
  bool floor = false;
  for (const glm::dvec3& d : directions) floor |= std::abs(glm::normalize(d).y) > 0.5;
  glm::dvec3 view = open + glm::dvec3(0, floor ? -0.3 : 0.35, 0);
  if (glm::length(view) < 1e-9) view = {0.3, 0.35, 1};
  view = glm::normalize(view);
  Camera cam;
  cam.projection = Projection::Perspective;
  cam.fov_deg = 40;
  cam.target = -0.45 * W * glm::normalize(open + glm::dvec3(1e-9));
  cam.eye = cam.target + 4.2 * W * view;
  cam.up = std::abs(view.y) > 0.99 ? glm::dvec3(0, 0, -1) : glm::dvec3(0, 1, 0);
  cam.near = 0.5;
  cam.far = 10 * W;
  cam.width = width;
  cam.height = height;
  return cam;
}

}  // namespace

Scene room_scene(const Mesh& shape, const std::vector<glm::dvec3>& directions, int width,
                 int height, const WallSetup& w, glm::dvec3 shape_albedo) {
  if (!orthogonal(directions))
    throw Error("room_scene: the light directions must be mutually orthogonal");
  Scene scene;
  Mesh s = shape;
  s.albedo.assign(s.vertices.size(), shape_albedo);
  s.albedo_mode = AlbedoMode::PerVertex;
  scene.meshes.push_back(s);
  glm::dvec3 open(0.0);
  // Walls of slightly different brightness, so that the corner reads.
  const double intensity[3] = {0.85, 0.7, 0.55};
  for (size_t k = 0; k < directions.size(); ++k) {
    const glm::dvec3 d = glm::normalize(directions[k]);
    open -= d;
    const glm::dvec3 up = view_up(d);
    scene.meshes.push_back(room_wall(d, up, w.wall_distance));
    scene.lights.push_back(room_light(d, up, intensity[k % 3], w));
  }
  scene.cameras.push_back(room_camera(directions, open, w.wall_distance, width, height));
  scene.ambient = {0.2, 0.2, 0.2};
  scene.background = {1, 1, 1};
  RenderParams& p = scene.params;
  p.shadows = Shadows::Hard;
  p.sampling = Sampling::Truncated;
  p.shadow_map_size = 512;
  p.sigma = 3e-6;
  p.light_sigma = 1e-7;
  p.gamma_s = 0.02;
  p.beta = 0.1;
  p.sigma_s = 1.0;
  return scene;
}

}  // namespace penumbra::optim
