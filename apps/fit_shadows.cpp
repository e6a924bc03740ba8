// `penumbra fit-shadows`: the paper's Figure 7. A shape that starts as a sphere sits between
// directional lights on perpendicular sides and a wall behind it for each light; a camera
// between the shape and each wall looks at the wall, so it sees the shadow and never the shape.
// The vertices move by Adam on the mean squared error between the shadow images and the
// targets (plus Laplacian and normal-consistency regularisers), coarse to fine: every gradient
// reaches the shape through the shadows (hard, or soft with --shadows soft).
// Writes DIR/mesh.obj, DIR/result.png (each target next to the final hard shadow),
// DIR/scene.png (the setup with the final shape) and DIR/fit.gif. The last line of its output
// is always
//   fit-shadows: iterations=N seconds=T iou=[v1,v2,...]
#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "common.hpp"
#include "penumbra/context.hpp"
#include "penumbra/error.hpp"
#include "penumbra/io.hpp"
#include "penumbra/optim.hpp"
#include "penumbra/renderer.hpp"

namespace penumbra::cli {

namespace {

struct FitShadowsArgs {
  std::vector<std::string> targets, light_dirs;
  std::string shadows = "hard";
  std::string shadow_model = "accurate";
  std::string output = "out/fit-shadows";
  std::string device;
  int iterations = 400;
  int gif_every = 4;
  double radius = 0.75;
  double light_size = 0.05;
  CheckpointOptions checkpoints;
};

// A shadow-map size of about `texels_per_pixel` texels per camera pixel (the map spans
// map_half_size, the camera half_height), a multiple of 16.
int map_size_for(int resolution, double texels_per_pixel, const optim::WallSetup& w) {
  const double texels = texels_per_pixel * resolution * w.map_half_size / w.half_height;
  return std::max(16, int(std::ceil(texels / 16.0)) * 16);
}

// The shadow mode to fit, after checking the options that need no input files.
Shadows checked_shadows(const FitShadowsArgs& a) {
  check_fit_counts(a.iterations, 2, a.gif_every);
  check_radius(a.radius);
  if (!(a.light_size >= 0 && a.light_size < 1))
    throw Error("--light-size must be in [0, 1) (got " + std::to_string(a.light_size) + ")");
  const Shadows mode = parse_shadows(a.shadows);
  if (mode == Shadows::None) throw Error("--shadows must be hard or soft (got 'none')");
  return mode;
}

// Coarse to fine (docs/applications.md): the icosphere at about 48 pixels with a map of about
// one texel per pixel, then subdivided at the targets' size with a map of two texels per
// pixel. σ_L puts √σ_L at about half a texel: the shadow's edge is as soft as the map allows.
std::vector<optim::ShadowStage> shadow_stages(const FitShadowsArgs& a, Shadows mode, int size,
                                              const optim::WallSetup& w) {
  using namespace optim;
  const int n = a.iterations;
  const int r0 = stage_resolution(size, 48);
  std::vector<ShadowStage> stages(2);
  const RegulariserWeights reg{0.2, 0.0, 0.002, EdgeLoss::Variance};
  auto light_sigma = [](int map) { return (1.1 / map) * (1.1 / map); };
  const int m0 = map_size_for(r0, 1.0, w), m1 = map_size_for(size, 2.0, w);
  // Soft shadows: the light shrinks to a quarter of --light-size for the fine stage, so that
  // the fit ends close to the hard shadow it is judged by (a soft shadow's 50 % edge lies half
  // a penumbra outside the occluder's outline).
  // Half the iterations at the fine stage: the thin parts of a shape (the bundled loft's bottom
  // edge) form only there (hard shadows, bundled targets: N/4 fine gave IoU [0.936, 0.952],
  // N/2 [0.955, 0.970]).
  const bool soft = mode == Shadows::Soft;
  const double size0 = soft ? a.light_size : 0.0;
  const int fine = n / 2;
  stages[0] = {r0, n - fine, m0, light_sigma(m0), 0.01, 0, reg, size0};
  stages[1] = {size, fine, m1, light_sigma(m1), 0.003, 1, reg, size0 / 4};
  return stages;
}

int run_fit_shadows(const FitShadowsArgs& a) {
  using namespace optim;
  const Shadows mode = checked_shadows(a);

  // Targets and lights: the bundled shadows for lights along −z and −x, or the user's own with
  // the lights along −z, −x, −y in order (or --light-dir, one per target).
  std::vector<std::string> files = a.targets;
  if (files.empty())
    files = {data_dir() + "/targets/shadow_back.png", data_dir() + "/targets/shadow_side.png"};
  const std::vector<glm::dvec3> directions = light_directions(a.light_dirs, files.size());

  ShadowProblem problem;
  problem.directions = directions;
  problem.params = ShadowProblem::default_shadow_fit_params(
      parse_word<ShadowModel>("--shadow-model", a.shadow_model));
  problem.params.shadows = mode;
  const int size = load_fit_targets(files, 512, problem.targets);
  const WallSetup& w = problem.setup;
  const std::vector<ShadowStage> stages = shadow_stages(a, mode, size, w);

  const Mesh sphere = start_sphere(a.radius);
  const FitCheckpointFile checkpoints(
      a.checkpoints, a.output, "fit-shadows",
      "fit-shadows iterations=" + std::to_string(a.iterations) +
          " radius=" + std::to_string(a.radius) + " shadows=" + a.shadows +
          " shadow-model=" + a.shadow_model + " light-size=" + std::to_string(a.light_size) +
          " targets=" + joined(files) + " light-dirs=" + joined(a.light_dirs));
  Context context(a.device);
  Renderer renderer(context, Precision::Float);
  const Stopwatch clock;
  FitRecorder recorder("fit-shadows", a.output, problem.targets, a.iterations, a.gif_every, clock);
  const Mesh result =
      fit_shadows(renderer, sphere, problem, stages, recorder.observer(), checkpoints.hooks());
  recorder.finish_on_walls(renderer, result, directions, w, w, 400);
  return 0;
}

}  // namespace

Command add_fit_shadows_command(CLI::App& root) {
  auto args = std::make_shared<FitShadowsArgs>();
  Command c;
  c.app = root.add_subcommand(
      "fit-shadows",
      "deform a sphere until the shadows it casts on walls match target images; the cameras "
      "see only the walls (the paper's Figure 7)");
  add_shadows_option(*c.app, args->shadows, "shadows to optimise: hard or soft", {"hard", "soft"})
      ->capture_default_str();
  add_shadow_model_option(*c.app, args->shadow_model,
                          "shadow model the fit renders through: " + word_choices<ShadowModel>() +
                              " (the result is judged by the accurate model's hard shadows "
                              "either way)")
      ->capture_default_str();
  c.app->add_option("--target", args->targets,
                    "target shadow image (repeatable, one per light): the shadow dark on a light "
                    "background, square, all the same size; default: the bundled "
                    "data/targets/shadow_back.png and shadow_side.png");
  add_light_dir_option(*c.app, args->light_dirs);
  add_iterations_option(*c.app, args->iterations);
  c.app
      ->add_option("--light-size", args->light_size,
                   "diameter D_L of the lights with --shadows soft (world units)")
      ->capture_default_str();
  add_output_option(*c.app, args->output, "mesh.obj, result.png, scene.png and fit.gif");
  add_gif_every_option(*c.app, args->gif_every);
  add_radius_option(*c.app, args->radius);
  add_checkpoint_options(*c.app, args->checkpoints);
  add_fit_device_option(*c.app, args->device);
  c.run = [args] { return run_fit_shadows(*args); };
  return c;
}

}  // namespace penumbra::cli
