// Fitting a mesh to orthographic silhouettes with the differentiable renderer: the loop shared
// by `penumbra fit-silhouette` and `penumbra shadow-art`.
#include <algorithm>
#include <cmath>
#include <string>

#include "optim/stages.hpp"
#include "penumbra/error.hpp"
#include "penumbra/optim.hpp"

namespace penumbra::optim {

double regularise(const Mesh& mesh, const Topology& topo, const RegulariserWeights& w,
                  std::vector<glm::dvec3>* grad) {
  if (grad != nullptr && grad->empty()) grad->assign(mesh.vertices.size(), glm::dvec3(0.0));
  double value = 0;
  if (w.laplacian != 0) value += laplacian_loss(mesh.vertices, topo, grad, w.laplacian);
  if (w.edge != 0) value += edge_loss(mesh.vertices, topo, w.edge_kind, grad, w.edge);
  if (w.normal != 0)
    value += normal_consistency_loss(mesh.vertices, mesh.faces, topo, grad, w.normal);
  return value;
}

Scene silhouette_scene(const Mesh& mesh, const std::vector<glm::dvec3>& directions,
                       double half_height, int size, double sigma) {
  Scene scene;
  scene.meshes.push_back(mesh);
  for (const glm::dvec3& d : directions)
    scene.cameras.push_back(ortho_camera(d, half_height, size, {0, 0, 0}, 10.0, 0.1, 20.0));
  scene.ambient = {1, 1, 1};
  scene.background = {1, 1, 1};
  scene.params.sigma = sigma;
  scene.params.shadows = Shadows::None;
  return scene;
}

Mesh fit_silhouettes(Renderer& renderer, Mesh mesh, const SilhouetteProblem& problem,
                     const std::vector<SilhouetteStage>& stages, const FitObserver& observer,
                     const FitCheckpoints& checkpoints) {
  const int total = prepare_fit("fit_silhouettes", problem.targets, problem.directions.size(),
                                "views", stages, mesh);
  const int full = problem.targets.front().width;
  check_resume(checkpoints, stages.size(), total);
  int iteration = 0;
  for (size_t si = 0; si < stages.size(); ++si) {
    const SilhouetteStage& stage = stages[si];
    const int iterations = std::max(stage.iterations, 0);
    if (stage_done(checkpoints, si)) {
      iteration += iterations;
      continue;
    }
    const int first = enter_stage(checkpoints, si, iteration, iterations, stage.subdivisions, mesh);
    iteration += first;
    const Topology topo = topology(mesh.faces, mesh.vertices.size());
    std::vector<Image> targets;
    for (const Image& t : problem.targets)
      targets.push_back(downsample(t, full / stage.resolution));
    Scene scene = silhouette_scene(mesh, problem.directions, problem.half_height, stage.resolution,
                                   stage.sigma);
    Adam adam = stage_optimiser(checkpoints, si, 3 * mesh.vertices.size(), stage.lr);
    std::vector<OutputGrads> grads(targets.size());
    std::vector<Image> silhouettes(targets.size());
    for (int it = first; it < stage.iterations; ++it) {
      scene.meshes.front().vertices = mesh.vertices;
      const std::vector<RenderOutput> out = renderer.render(scene);
      FitProgress p;
      p.iteration = ++iteration;
      p.total = total;
      p.stage = int(si);
      for (size_t v = 0; v < targets.size(); ++v) {
        grads[v] = OutputGrads{};
        p.loss += soft_iou_loss(out[v].silhouette, targets[v], &grads[v].silhouette);
        silhouettes[v] = out[v].silhouette;
        p.ious.push_back(binary_iou(out[v].silhouette, binarize(targets[v])));
      }
      const SceneGrads g = renderer.backward(scene, grads);
      std::vector<glm::dvec3> grad = g.vertices.front();
      p.regulariser = regularise(mesh, topo, stage.weights, &grad);
      p.mesh = &mesh;
      p.images = &silhouettes;
      if (observer) observer(p);
      adam.step(mesh.vertices, grad);
      after_step(checkpoints, iteration, total, si, mesh, adam);
    }
  }
  return mesh;
}

std::vector<Image> hard_silhouettes(Renderer& renderer, const Mesh& mesh,
                                    const std::vector<glm::dvec3>& directions, double half_height,
                                    int size) {
  const Scene scene = silhouette_scene(mesh, directions, half_height, size, 1e-9);
  std::vector<Image> masks;
  for (const RenderOutput& o : renderer.render(scene)) masks.push_back(binarize(o.silhouette));
  return masks;
}

}  // namespace penumbra::optim
