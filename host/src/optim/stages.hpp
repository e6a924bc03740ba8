#pragma once
// The stage loop shared by fit_silhouettes and fit_shadows (internal): where a (possibly
// resumed) fit enters each stage, and its checkpoints.
#include "penumbra/optim.hpp"

namespace penumbra::optim {

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
