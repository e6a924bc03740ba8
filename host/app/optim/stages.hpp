#pragma once
// The stage loop shared by fit_silhouettes and fit_shadows (internal): their inputs, where a
// (possibly resumed) fit enters each stage, and its checkpoints.
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

}  // namespace penumbra::optim
