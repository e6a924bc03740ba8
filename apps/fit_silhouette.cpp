// `penumbra fit-silhouette`: the paper's Figure 6. Orthographic cameras look at a sphere from
// the front and the side (and optionally from the top); its vertices move by Adam on the soft
// IoU between the rendered silhouettes and the target images, with Laplacian, edge-length and
// normal-consistency regularisers, coarse to fine (the sphere is subdivided between stages).
// Writes DIR/mesh.obj, DIR/result.png (each target next to the final hard silhouette) and
// DIR/fit.gif (the optimisation). The last line of its output is always
//   fit-silhouette: iterations=N seconds=T iou=[v1,v2,...]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "common.hpp"
#include "penumbra/context.hpp"
#include "penumbra/error.hpp"
#include "penumbra/io.hpp"
#include "penumbra/optim.hpp"
#include "penumbra/renderer.hpp"

namespace fs = std::filesystem;

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
};

int run_fit_silhouette(const FitSilhouetteArgs& a) {
  using namespace optim;
  if (a.iterations < 4 || a.iterations > 100000)
    throw Error("--iterations must be in 4 to 100000 (got " + std::to_string(a.iterations) + ")");
  if (a.gif_every < 1) throw Error("--gif-every must be positive");
  if (!(a.radius > 0 && a.radius < kHalfHeight))
    throw Error("--radius must be in (0, 1) (got " + std::to_string(a.radius) + ")");

  // Targets and views: bundled targets for the named views (default front and side), or the
  // user's own, paired with --view in order.
  std::vector<std::string> views = a.views;
  std::vector<std::string> files = a.targets;
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
  std::vector<glm::dvec3> directions;
  for (const std::string& v : views) directions.push_back(named_view(v));
  if (files.size() < views.size())
    throw Error("fewer targets (" + std::to_string(files.size()) + ") than views (" +
                std::to_string(views.size()) + "): give one --target per --view");
  if (files.size() > views.size())
    throw Error("more targets (" + std::to_string(files.size()) + ") than views (" +
                std::to_string(views.size()) + "): give one --view per --target");
  for (size_t i = 0; i < views.size(); ++i)
    for (size_t j = 0; j < i; ++j)
      if (views[i] == views[j]) throw Error("view '" + views[i] + "' is given twice");

  SilhouetteProblem problem;
  problem.directions = directions;
  problem.half_height = kHalfHeight;
  for (const std::string& f : files) problem.targets.push_back(load_target(f));
  check_targets(problem.targets, files);
  const int size = problem.targets.front().width;
  if (size < 16 || size > 1024)
    throw Error("target " + files.front() + " is " + std::to_string(size) + "x" +
                std::to_string(size) + "; targets must be 16 to 1024 pixels on a side");

  // Coarse to fine (docs/applications.md): the icosphere at about 32 pixels with a wide σ
  // (√σ half a pixel), then subdivided at about 64 pixels, then at the targets' size with σ
  // narrowing to a tenth of a pixel so that the soft silhouette's edge sits where the hard one
  // does. Regularisers: strong while the sphere moves far, weak for the fine fit.
  const int n = a.iterations;
  const int r0 = stage_resolution(size, 32), r1 = std::max(r0, stage_resolution(size, 64));
  auto sigma = [](double pixels, int resolution) {  // σ whose square root is `pixels` pixels
    const double s = pixels * 2.0 / resolution;
    return s * s;
  };
  std::vector<SilhouetteStage> stages(4);
  stages[0] = {r0, n / 2, sigma(0.5, r0), 0.01, 0, {1.0, 0.0, 0.01, EdgeLoss::Variance}};
  stages[1] = {r1, n / 4, sigma(0.32, r1), 0.005, 1, {0.2, 0.0, 5e-4, EdgeLoss::Variance}};
  stages[2] = {size, n / 6, sigma(0.2, size), 0.002, 0, {0.2, 0.0, 5e-4, EdgeLoss::Variance}};
  stages[3] = {size, n - n / 2 - n / 4 - n / 6, sigma(0.09, size), 0.001, 0,
               {0.2, 0.0, 5e-4, EdgeLoss::Variance}};

  Mesh sphere = load_obj(data_dir() + "/meshes/icosphere.obj");
  for (glm::dvec3& v : sphere.vertices) v *= a.radius;
  sphere.name = "shape";

  Context context(a.device);
  Renderer renderer(context, Precision::Float);
  make_dirs(a.output);
  const fs::path dir(a.output);

  // The animation: each target next to the current silhouette, at the target's size.
  std::vector<Image> target_pictures;
  for (const Image& t : problem.targets) target_pictures.push_back(mask_picture(t));
  auto frame_of = [&](const std::vector<Image>& silhouettes) {
    std::vector<Image> panels;
    for (size_t v = 0; v < silhouettes.size(); ++v) {
      panels.push_back(target_pictures[v]);
      panels.push_back(upscale(mask_picture(silhouettes[v]), size / silhouettes[v].width));
    }
    return side_by_side(panels);
  };
  std::unique_ptr<GifWriter> gif;
  ProgressPrinter progress("fit-silhouette", n);
  const auto t0 = std::chrono::steady_clock::now();
  auto seconds = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  };
  int done = 0;
  Mesh result = fit_silhouettes(renderer, sphere, problem, stages, [&](const FitProgress& p) {
    done = p.iteration;
    progress.update(p.iteration, p.loss, p.ious, seconds());
    if ((p.iteration - 1) % a.gif_every == 0 || p.iteration == p.total) {
      const Image frame = frame_of(*p.images);
      if (!gif)
        gif = std::make_unique<GifWriter>((dir / "fit.gif").string(), frame.width, frame.height, 8);
      gif->add_frame(frame);
    }
  });
  // Final: hard silhouettes at the targets' size.
  const std::vector<Image> hard = hard_silhouettes(renderer, result, directions, kHalfHeight, size);
  const double total_seconds = seconds();
  std::vector<double> ious;
  for (size_t v = 0; v < hard.size(); ++v) ious.push_back(binary_iou(hard[v], problem.targets[v]));
  const Image final_frame = frame_of(hard);
  if (gif) {
    for (int k = 0; k < 10; ++k) gif->add_frame(final_frame);  // hold the result a moment
    gif->close();
  }
  save_png(final_frame, (dir / "result.png").string());
  save_obj(result, (dir / "mesh.obj").string());
  std::printf("wrote %s, %s and %s\n", (dir / "mesh.obj").string().c_str(),
              (dir / "result.png").string().c_str(), (dir / "fit.gif").string().c_str());
  std::printf("fit-silhouette: iterations=%d seconds=%.1f iou=%s\n", done, total_seconds,
              iou_list(ious).c_str());
  std::fflush(stdout);
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
  c.app->add_option("--view", args->views,
                    "view of the target at the same position: front, side or top (repeatable; "
                    "default: front side)")
      ->check(CLI::IsMember({"front", "side", "top"}));
  c.app->add_option("--iterations", args->iterations, "Adam iterations over all stages")
      ->capture_default_str();
  c.app->add_option("-o,--output", args->output,
                    "folder for mesh.obj, result.png and fit.gif")
      ->capture_default_str();
  c.app->add_option("--gif-every", args->gif_every, "one animation frame every N iterations")
      ->capture_default_str();
  c.app->add_option("--radius", args->radius, "radius of the starting sphere (world units)")
      ->capture_default_str();
  c.app->add_option("--device", args->device,
                    "OpenCL device: index from `penumbra devices` or part of its name");
  c.run = [args] { return run_fit_silhouette(*args); };
  return c;
}

}  // namespace penumbra::cli
