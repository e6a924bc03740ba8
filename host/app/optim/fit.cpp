// Fitting a mesh to orthographic silhouettes with the differentiable renderer: the loop shared
// by `penumbra fit-silhouette` and `penumbra shadow-art`.
#include <algorithm>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

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

namespace {

// One stage's loss of fit_silhouettes: the soft IoU of each view's silhouette with its target,
// at the stage's resolution.
class SilhouetteLoss {
 public:
  SilhouetteLoss(Renderer& renderer, const SilhouetteProblem& problem, const SilhouetteStage& stage,
                 const Mesh& mesh)
      : renderer_(renderer),
        scene_(silhouette_scene(mesh, problem.directions, problem.half_height, stage.resolution,
                                stage.sigma)) {
    const int full = problem.targets.front().width;
    for (const Image& t : problem.targets)
      targets_.push_back(downsample(t, full / stage.resolution));
    grads_.resize(targets_.size());
    silhouettes_.resize(targets_.size());
  }

  std::vector<glm::dvec3> operator()(const Mesh& mesh, FitProgress& p) {
    scene_.meshes.front().vertices = mesh.vertices;
    const std::vector<RenderOutput> out = renderer_.render(scene_);
    for (size_t v = 0; v < targets_.size(); ++v) {
      grads_[v] = OutputGrads{};
      p.loss += soft_iou_loss(out[v].silhouette, targets_[v], &grads_[v].silhouette);
      silhouettes_[v] = out[v].silhouette;
      p.ious.push_back(binary_iou(out[v].silhouette, binarize(targets_[v])));
    }
    p.images = &silhouettes_;
    return renderer_.backward(scene_, grads_).vertices.front();
  }

 private:
  Renderer& renderer_;
  Scene scene_;
  std::vector<Image> targets_;
  std::vector<OutputGrads> grads_;
  std::vector<Image> silhouettes_;
};

}  // namespace

Mesh fit_silhouettes(Renderer& renderer, Mesh mesh, const SilhouetteProblem& problem,
                     const std::vector<SilhouetteStage>& stages, const FitObserver& observer,
                     const FitCheckpoints& checkpoints) {
  const int total = prepare_fit("fit_silhouettes", problem.targets, problem.directions.size(),
                                "views", stages, mesh);
  return fit_stages(std::move(mesh), stages, total, observer, checkpoints,
                    [&](const SilhouetteStage& stage, const Mesh& m) {
                      return SilhouetteLoss(renderer, problem, stage, m);
                    });
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
