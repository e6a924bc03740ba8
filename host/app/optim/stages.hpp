#pragma once
// The stage loop shared by fit_silhouettes and fit_shadows (internal): their inputs, where a
// (possibly resumed) fit enters each stage, its checkpoints, and the loop itself (fit_stages).
#include <algorithm>
#include <string>
#include <vector>

#include "penumbra/error.hpp"
#include "penumbra/optim.hpp"

namespace penumbra::optim {

// Checks a fit's inputs (`fit` names it in messages): one target per view or light (`unit`),
// every stage's resolution dividing the target size. Gives `mesh` per-vertex albedo when it has
// none, and returns the iterations over all stages.
template <class Stage>
int prepare_fit(const char* fit, const std::vector<Image>& targets, size_t views, const char* unit,
                const std::vector<Stage>& stages, Mesh& mesh) {
  check_targets(targets, {});
  if (targets.size() != views)
    throw Error(std::string(fit) + ": " + std::to_string(targets.size()) + " targets for " +
                std::to_string(views) + " " + unit);
  const int full = targets.front().width;
  int total = 0;
  for (const Stage& s : stages) {
    if (s.resolution < 1 || full % s.resolution != 0)
      throw Error(std::string(fit) + ": stage resolution " + std::to_string(s.resolution) +
                  " must divide the target size " + std::to_string(full));
    total += std::max(s.iterations, 0);
  }
  if (mesh.albedo.size() != mesh.vertices.size()) {
    mesh.albedo.assign(mesh.vertices.size(), glm::dvec3(0.8));
    mesh.albedo_mode = AlbedoMode::PerVertex;
  }
  return total;
}

// Throws unless the resumed state (if any) lies within `stages` stages of `total` iterations.
void check_resume(const FitCheckpoints& checkpoints, size_t stages, int total);
// Whether stage `stage` was finished before the state being resumed (it is then skipped).
bool stage_done(const FitCheckpoints& checkpoints, size_t stage);
// Enters stage `stage`, which begins at iteration `iteration` and has `iterations`: subdivides
// `mesh` `subdivisions` times, or takes the resumed state's mesh when the fit resumes in this
// stage. Returns the iteration within the stage to start at (0 unless resuming).
int enter_stage(const FitCheckpoints& checkpoints, size_t stage, int iteration, int iterations,
                int subdivisions, Mesh& mesh);
// The stage's optimiser: fresh, or the resumed one when the fit resumes in this stage.
Adam stage_optimiser(const FitCheckpoints& checkpoints, size_t stage, size_t values, double lr);
// After the step of iteration `iteration` (1-based, of `total`): saves a checkpoint when due.
void after_step(const FitCheckpoints& checkpoints, int iteration, int total, size_t stage,
                const Mesh& mesh, const Adam& adam);

// The stage loop of a fit, resumable from `checkpoints`: each stage not finished before the
// resumed state is entered (enter_stage), then `stage_loss(stage, mesh)` makes the stage's
// loss, a callable `loss(mesh, p)` that renders `mesh`, adds to p.loss and p.ious, points
// p.images at what it compared and returns the gradient of its loss by the vertices. The
// regularisers, the observer, the Adam step and the checkpoints are the loop's. `total` is
// prepare_fit's.
template <class Stage, class StageLoss>
Mesh fit_stages(Mesh mesh, const std::vector<Stage>& stages, int total, const FitObserver& observer,
                const FitCheckpoints& checkpoints, const StageLoss& stage_loss) {
  check_resume(checkpoints, stages.size(), total);
  int iteration = 0;
  for (size_t si = 0; si < stages.size(); ++si) {
    const Stage& stage = stages[si];
    const int iterations = std::max(stage.iterations, 0);
    if (stage_done(checkpoints, si)) {
      iteration += iterations;
      continue;
    }
    const int first = enter_stage(checkpoints, si, iteration, iterations, stage.subdivisions, mesh);
    iteration += first;
    const Topology topo = topology(mesh.faces, mesh.vertices.size());
    auto loss = stage_loss(stage, mesh);
    Adam adam = stage_optimiser(checkpoints, si, 3 * mesh.vertices.size(), stage.lr);
    for (int it = first; it < stage.iterations; ++it) {
      FitProgress p;
      p.iteration = ++iteration;
      p.total = total;
      p.stage = int(si);
      std::vector<glm::dvec3> grad = loss(mesh, p);
      p.regulariser = regularise(mesh, topo, stage.weights, &grad);
      p.mesh = &mesh;
      if (observer) observer(p);
      adam.step(mesh.vertices, grad);
      after_step(checkpoints, iteration, total, si, mesh, adam);
    }
  }
  return mesh;
}

}  // namespace penumbra::optim
