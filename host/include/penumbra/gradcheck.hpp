#pragma once
// Gradient check: Renderer::backward against central finite differences of Renderer::render.
//
// The loss is a random linear functional of every output of every view,
//   L = Σ_views Σ_pixels r_c·colour + r_a·silhouette + (r_z / far)·depth,   r ~ N(0, 1),
// so dL/d(outputs) = r and the analytic gradient is backward(scene, r). A sample of scene
// parameters (vertex coordinates of every mesh, albedo entries, point-light positions,
// directional-light directions, light colours, ambient) is then perturbed by ±h, and
// (L+ − L−)/(2h) is compared with the analytic value.
//
// The check works on a copy of the scene whose light frusta are fitted first
// (fit_light_frusta), so that every perturbed copy renders its shadow maps through the same
// fixed frusta (math.md §4.1). With shadows on, the sampled entries always include one vertex of
// every mesh and the position (point light) or direction (directional light) of every light
// (as many of these as `samples` allows).
#include <cstdint>
#include <string>
#include <vector>

#include "penumbra/context.hpp"
#include "penumbra/image.hpp"
#include "penumbra/renderer.hpp"
#include "penumbra/scene.hpp"

namespace penumbra {

struct GradCheckOptions {
  // Arithmetic of the analytic gradient (the renderer whose backward is checked).
  Precision precision = Precision::Double;
  int samples = 40;   // number of scalar entries compared
  uint64_t seed = 1;  // seeds both the loss weights and the choice of entries
  // With precision = Float: take the finite differences with a double-precision renderer (when
  // the device has fp64) rather than the float one. A float forward pass is too noisy, and the
  // soft raster too sharp at the default σ, for float differences to resolve float gradients:
  // correct float gradients fail about half the entries of the bundled scene that way. With
  // this on, the float gradient is compared with accurate differences at a relative tolerance
  // that covers float rounding.
  bool double_differences = true;
  // Finite-difference step. 0 selects the default by the arithmetic of the differences: 1e-6 in
  // double, 1e-3 in float. Positions (vertices, point lights) are stepped by step·scale,
  // scale = radius of the scene's bounds; directions of directional lights by
  // step·|direction|; colours (albedo, light colour, ambient) by step,
  // one-sided over [x, x + 2·step] where x − step would be negative (the outputs are linear in
  // colours, so this is as exact as the central difference).
  double step = 0.0;
  // Relative tolerance. 0 selects the default by `precision`: 1e-3 in double, 5e-2 in float.
  double rtol = 0.0;
  // Absolute floor of the comparison, as a fraction of the largest |analytic| gradient among all
  // entries of the scene: atol = atol_fraction · max|analytic|.
  double atol_fraction = 1e-4;
  RasterTuning tuning;
  // Fraction of entries allowed to disagree. The rendered function has kinks of measure zero:
  // the coverage cut-off of math.md §2.1 (an outside face whose d² reaches σ·ln(1/ε_D − 1) drops
  // from D = ε_D to 0), faces leaving the [near, far] depth range or crossing the near plane,
  // the min over edges and the clamps of the barycentrics. A finite difference that straddles
  // one sees a jump or a corner the derivative does not, so a small fraction of entries may
  // disagree without the gradient being wrong.
  double max_failure_fraction = 0.05;
  // Called before each entry's finite difference: call "finite differences", pass "entry",
  // index/count of the entries, stage = the entry's name; `fraction` the entries done.
  ProgressObserver progress;
};

// One compared entry.
struct GradCheckEntry {
  std::string name;     // "mesh0.v17.y", "mesh1.albedo3.g", "light0.position.x",
                        // "light0.direction.x", "light1.color.b", "ambient.r"
  double analytic = 0;  // from Renderer::backward
  double numeric = 0;   // central finite difference
  double rel_err = 0;   // |a − n| / max(|a|, |n|, atol)
  bool ok = true;
};

struct GradCheckResult {
  int checked = 0;
  int failed = 0;
  double max_rel_err = 0;  // over all checked entries
  double atol = 0;         // absolute floor used
  double rtol = 0;         // relative tolerance used
  double max_failure_fraction = 0.05;
  std::vector<GradCheckEntry> entries;

  double failure_fraction() const { return checked > 0 ? double(failed) / checked : 0.0; }
  bool passed() const { return failed <= max_failure_fraction * checked; }
};

// The comparison of one entry: fails if |a − n| > atol + rtol·max(|a|, |n|) (or either is not
// finite).
bool gradients_agree(double analytic, double numeric, double atol, double rtol);
// |a − n| / max(|a|, |n|, atol); 0 when all three are 0.
double gradient_relative_error(double analytic, double numeric, double atol);

// dL/d(outputs) of the random linear loss: one OutputGrads per camera, sized like its render,
// r ~ N(0, 1) from std::mt19937_64(seed), depth weights divided by the camera's far plane.
std::vector<OutputGrads> random_loss_weights(const Scene& scene, uint64_t seed);
// L = Σ weights · outputs over every view (empty weight images count as zero).
double linear_loss(const std::vector<RenderOutput>& outputs,
                   const std::vector<OutputGrads>& weights);
// Largest |entry| of a gradient.
double max_abs_gradient(const SceneGrads& grads);

// Runs the check on `context`: backward of a renderer of options.precision / options.tuning,
// finite differences in double or in that same precision (see double_differences).
GradCheckResult gradcheck(Context& context, const Scene& scene,
                          const GradCheckOptions& options = {});
// Runs the check with the given renderer for both the gradient and the differences (its
// precision replaces options.precision; options.tuning and double_differences are ignored).
GradCheckResult gradcheck(Renderer& renderer, const Scene& scene,
                          const GradCheckOptions& options = {});
// Compares a given "analytic" gradient of the loss `weights` (computed in options.precision)
// with finite differences computed by `renderer` (whose precision sets the default step).
// gradcheck() is render + backward + this; tests use it to make sure a wrong gradient is caught.
GradCheckResult compare_with_finite_differences(Renderer& renderer, const Scene& scene,
                                                const std::vector<OutputGrads>& weights,
                                                const SceneGrads& analytic,
                                                const GradCheckOptions& options = {});

// A small random scene for gradient checks, built in code: a 48×40-ish image, σ ≈ 3e-4,
// γ ≈ 3e-3, a jittered icosphere occluder with random per-vertex albedo resting above a ground
// quad, a random perspective or orthographic camera that sees both, one or two random point or
// directional lights (frusta fitted), shadows off. The same seed gives the same scene.
Scene random_scene(uint64_t seed);

}  // namespace penumbra
