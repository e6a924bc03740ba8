// `penumbra fit-silhouette`: the paper's Figure 6. Orthographic cameras look at a sphere from
// the front and the side (and optionally from the top); its vertices move by Adam on the soft
// IoU between the rendered silhouettes and the target images, with Laplacian, edge-length and
// normal-consistency regularisers, coarse to fine (the sphere is subdivided between stages).
// Writes DIR/mesh.obj, DIR/result.png (each target next to the final hard silhouette) and
// DIR/fit.gif (the optimisation). The last line of its output is always
//   fit-silhouette: iterations=N seconds=T iou=[v1,v2,...]
#include <algorithm>
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

constexpr double kHalfHeight = 1.0;  // every view shows the square [−1, 1]² across it

struct FitSilhouetteArgs {
  std::vector<std::string> targets, views;
  std::string output = "out/fit-silhouette";
  std::string device;
  int iterations = 600;
  int gif_every = 5;
  double radius = 0.75;
  CheckpointOptions checkpoints;
};

// The target files and the view of each (files[i] is seen from views[i]).
struct TargetViews {
  std::vector<std::string> files, views;
  std::vector<glm::dvec3> directions;
};

// Targets and views: bundled targets for the named views (default front and side), or the
// user's own, paired with --view in order.
TargetViews target_views(const FitSilhouetteArgs& a) {
  TargetViews t{a.targets, a.views, {}};
  std::vector<std::string>& views = t.views;
  std::vector<std::string>& files = t.files;
  if (files.empty()) {
    if (views.empty()) views = {"front", "side"};
    for (const std::string& v : views)
      files.push_back(data_dir() + "/targets/silhouette_" + v + ".png");
  } else if (views.empty()) {
    const std::vector<std::string> order = {"front", "side", "top"};
    if (files.size() > order.size())
      throw Error(std::to_string(files.size()) +
                  " targets but at most 3 views (front, side, top); give --view for each");
    views.assign(order.begin(), order.begin() + long(files.size()));
  }
  t.directions.reserve(views.size());
  for (const std::string& v : views) t.directions.push_back(optim::named_view(v));
  if (files.size() < views.size())
    throw Error("fewer targets (" + std::to_string(files.size()) + ") than views (" +
                std::to_string(views.size()) + "): give one --target per --view");
  if (files.size() > views.size())
    throw Error("more targets (" + std::to_string(files.size()) + ") than views (" +
                std::to_string(views.size()) + "): give one --view per --target");
  for (size_t i = 0; i < views.size(); ++i)
    for (size_t j = 0; j < i; ++j)
      if (views[i] == views[j]) throw Error("view '" + views[i] + "' is given twice");
  return t;
}

// Coarse to fine (docs/applications.md): the icosphere at about 32 pixels with a wide σ
// (√σ half a pixel), then subdivided at about 64 pixels, then at the targets' size with σ
// narrowing to a tenth of a pixel so that the soft silhouette's edge sits where the hard one
// does. Regularisers: strong while the sphere moves far, weak for the fine fit.
std::vector<optim::SilhouetteStage> silhouette_stages(int n, int size) {
  using optim::EdgeLoss;
  const int r0 = optim::stage_resolution(size, 32);
  const int r1 = std::max(r0, optim::stage_resolution(size, 64));
  const auto sigma = sigma_for_pixels;
  std::vector<optim::SilhouetteStage> stages(4);
  stages[0] = {r0, n / 2, sigma(0.5, r0), 0.01, 0, {1.0, 0.0, 0.01, EdgeLoss::Variance}};
  stages[1] = {r1, n / 4, sigma(0.32, r1), 0.005, 1, {0.2, 0.0, 5e-4, EdgeLoss::Variance}};
  stages[2] = {size, n / 6, sigma(0.2, size), 0.002, 0, {0.2, 0.0, 5e-4, EdgeLoss::Variance}};
  stages[3] = {size, n - n / 2 - n / 4 - n / 6,           sigma(0.09, size), 0.001,
               0,    {0.2, 0.0, 5e-4, EdgeLoss::Variance}};
  return stages;
}

int run_fit_silhouette(const FitSilhouetteArgs& a) {
  using namespace optim;
  check_fit_counts(a.iterations, 4, a.gif_every);
  check_radius(a.radius);
  const TargetViews t = target_views(a);

  SilhouetteProblem problem;
  problem.directions = t.directions;
  problem.half_height = kHalfHeight;
  const int size = load_fit_targets(t.files, 1024, problem.targets);
  const int n = a.iterations;
  const std::vector<SilhouetteStage> stages = silhouette_stages(n, size);

  const Mesh sphere = start_sphere(a.radius);
  const FitCheckpointFile checkpoints(
      a.checkpoints, a.output, "fit-silhouette",
      "fit-silhouette iterations=" + std::to_string(n) + " radius=" + std::to_string(a.radius) +
          " targets=" + joined(t.files) + " views=" + joined(t.views));
  Context context(a.device);
  Renderer renderer(context, Precision::Float);
  const Stopwatch clock;
  FitRecorder recorder("fit-silhouette", a.output, problem.targets, n, a.gif_every, clock);
  const Mesh result =
      fit_silhouettes(renderer, sphere, problem, stages, recorder.observer(), checkpoints.hooks());
  // Final: hard silhouettes at the targets' size.
  const std::vector<Image> hard =
      hard_silhouettes(renderer, result, t.directions, kHalfHeight, size);
  const double total_seconds = clock.seconds();
  recorder.report(total_seconds, recorder.finish(result, hard));
  return 0;
}

}  // namespace

Command add_fit_silhouette_command(CLI::App& root) {
  auto args = std::make_shared<FitSilhouetteArgs>();
  Command c;
  c.app = root.add_subcommand(
      "fit-silhouette",
      "deform a sphere until its orthographic silhouettes (front, side, top) match target "
      "images (the paper's Figure 6)");
  c.app->add_option("--target", args->targets,
                    "target image (repeatable, one per --view): the shape dark on a light "
                    "background, square, all the same size; default: the bundled "
                    "data/targets/silhouette_<view>.png");
  c.app
      ->add_option("--view", args->views,
                   "view of the target at the same position: front, side or top (repeatable; "
                   "default: front side)")
      ->check(CLI::IsMember({"front", "side", "top"}));
  add_iterations_option(*c.app, args->iterations);
  add_output_option(*c.app, args->output, "mesh.obj, result.png and fit.gif");
  add_gif_every_option(*c.app, args->gif_every);
  add_radius_option(*c.app, args->radius);
  add_checkpoint_options(*c.app, args->checkpoints);
  add_fit_device_option(*c.app, args->device);
  c.run = [args] { return run_fit_silhouette(*args); };
  return c;
}

}  // namespace penumbra::cli
