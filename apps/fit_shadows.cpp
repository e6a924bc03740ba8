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

struct FitShadowsArgs {
  std::vector<std::string> targets, light_dirs;
  std::string shadows = "hard";
  std::string output = "out/fit-shadows";
  std::string device;
  int iterations = 400;
  int gif_every = 4;
  double radius = 0.75;
  double light_size = 0.05;
};

// A shadow-map size of about `texels_per_pixel` texels per camera pixel (the map spans
// map_half_size, the camera half_height), a multiple of 16.
int map_size_for(int resolution, double texels_per_pixel, const optim::WallSetup& w) {
  const double texels = texels_per_pixel * resolution * w.map_half_size / w.half_height;
  return std::max(16, int(std::ceil(texels / 16.0)) * 16);
}

int run_fit_shadows(const FitShadowsArgs& a) {
  using namespace optim;
  if (a.iterations < 2 || a.iterations > 100000)
    throw Error("--iterations must be in 2 to 100000 (got " + std::to_string(a.iterations) + ")");
  if (a.gif_every < 1) throw Error("--gif-every must be positive");
  if (!(a.radius > 0 && a.radius < 1))
    throw Error("--radius must be in (0, 1) (got " + std::to_string(a.radius) + ")");
  if (!(a.light_size >= 0 && a.light_size < 1))
    throw Error("--light-size must be in [0, 1) (got " + std::to_string(a.light_size) + ")");
  const Shadows mode = parse_shadows(a.shadows);
  if (mode == Shadows::None) throw Error("--shadows must be hard or soft (got 'none')");

  // Targets and lights: the bundled shadows for lights along −z and −x, or the user's own with
  // the lights along −z, −x, −y in order (or --light-dir, one per target).
  std::vector<std::string> files = a.targets;
  if (files.empty())
    files = {data_dir() + "/targets/shadow_back.png", data_dir() + "/targets/shadow_side.png"};
  std::vector<glm::dvec3> directions;
  for (const std::string& d : a.light_dirs) directions.push_back(parse_direction(d));
  if (directions.empty()) {
    const std::vector<glm::dvec3> order = {{0, 0, -1}, {-1, 0, 0}, {0, -1, 0}};
    if (files.size() > order.size())
      throw Error(std::to_string(files.size()) +
                  " targets but 3 default lights; give --light-dir for each target");
    directions.assign(order.begin(), order.begin() + long(files.size()));
  }
  if (files.size() != directions.size())
    throw Error(std::string(files.size() < directions.size() ? "fewer" : "more") + " targets (" +
                std::to_string(files.size()) + ") than lights (" +
                std::to_string(directions.size()) + "): give one --target per --light-dir");

  ShadowProblem problem;
  problem.directions = directions;
  problem.params.shadows = mode;
  for (const std::string& f : files) problem.targets.push_back(load_target(f));
  check_targets(problem.targets, files);
  const int size = problem.targets.front().width;
  if (size < 16 || size > 512)
    throw Error("target " + files.front() + " is " + std::to_string(size) + "x" +
                std::to_string(size) + "; targets must be 16 to 512 pixels on a side");
  const WallSetup& w = problem.setup;

  // Coarse to fine (docs/applications.md): the icosphere at about 48 pixels with a map of about
  // one texel per pixel, then subdivided at the targets' size with a map of two texels per
  // pixel. σ_L puts √σ_L at about half a texel: the shadow's edge is as soft as the map allows.
  const int n = a.iterations;
  const int r0 = stage_resolution(size, 48);
  std::vector<ShadowStage> stages(2);
  const RegulariserWeights reg{0.2, 0.0, 0.002, EdgeLoss::Variance};
  auto light_sigma = [](int map) { return (1.1 / map) * (1.1 / map); };
  const int m0 = map_size_for(r0, 1.0, w), m1 = map_size_for(size, 2.0, w);
  // Soft shadows: the light shrinks to a quarter of --light-size for the fine stage, so that
  // the fit ends close to the hard shadow it is judged by (a soft shadow's 50 % edge lies half
  // a penumbra outside the occluder's outline).
  // Soft shadows converge more slowly at the fine stage (compare-then-filter blurs the edge
  // over the filter's width): they get half the iterations there, hard shadows a quarter.
  const bool soft = mode == Shadows::Soft;
  const double size0 = soft ? a.light_size : 0.0;
  const int fine = soft ? n / 2 : n / 4;
  stages[0] = {r0, n - fine, m0, light_sigma(m0), 0.01, 0, reg, size0};
  stages[1] = {size, fine, m1, light_sigma(m1), 0.003, 1, reg, size0 / 4};

  Mesh sphere = load_obj(data_dir() + "/meshes/icosphere.obj");
  for (glm::dvec3& v : sphere.vertices) v *= a.radius;
  sphere.name = "shape";

  Context context(a.device);
  Renderer renderer(context, Precision::Float);
  make_dirs(a.output);
  const fs::path dir(a.output);

  std::vector<Image> target_pictures;
  for (const Image& t : problem.targets) target_pictures.push_back(mask_picture(t));
  auto frame_of = [&](const std::vector<Image>& shadows) {
    std::vector<Image> panels;
    for (size_t v = 0; v < shadows.size(); ++v) {
      panels.push_back(target_pictures[v]);
      panels.push_back(upscale(mask_picture(shadows[v]), size / shadows[v].width));
    }
    return side_by_side(panels);
  };
  std::unique_ptr<GifWriter> gif;
  ProgressPrinter progress("fit-shadows", n);
  const auto t0 = std::chrono::steady_clock::now();
  auto seconds = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  };
  int done = 0;
  Mesh result = fit_shadows(renderer, sphere, problem, stages, [&](const FitProgress& p) {
    done = p.iteration;
    progress.update(p.iteration, p.loss, p.ious, seconds());
    if ((p.iteration - 1) % a.gif_every == 0 || p.iteration == p.total) {
      const Image frame = frame_of(*p.images);
      if (!gif)
        gif = std::make_unique<GifWriter>((dir / "fit.gif").string(), frame.width, frame.height, 8);
      gif->add_frame(frame);
    }
  });
  // Final: the hard shadows at the targets' size.
  const std::vector<Image> hard = hard_shadows(renderer, result, directions, size, w);
  const double total_seconds = seconds();
  std::vector<double> ious;
  for (size_t v = 0; v < hard.size(); ++v) ious.push_back(binary_iou(hard[v], problem.targets[v]));
  const Image final_frame = frame_of(hard);
  if (gif) {
    for (int k = 0; k < 10; ++k) gif->add_frame(final_frame);
    gif->close();
  }
  save_png(final_frame, (dir / "result.png").string());
  save_obj(result, (dir / "mesh.obj").string());
  std::string scene_png;
  if (orthogonal(directions)) {
    scene_png = (dir / "scene.png").string();
    save_png(renderer.render(room_scene(result, directions, 400, 400, w)).front().color,
             scene_png);
  }
  std::printf("wrote %s, %s%s%s and %s\n", (dir / "mesh.obj").string().c_str(),
              (dir / "result.png").string().c_str(), scene_png.empty() ? "" : ", ",
              scene_png.c_str(), (dir / "fit.gif").string().c_str());
  std::printf("fit-shadows: iterations=%d seconds=%.1f iou=%s\n", done, total_seconds,
              iou_list(ious).c_str());
  std::fflush(stdout);
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
  c.app->add_option("--shadows", args->shadows, "shadows to optimise: hard or soft")
      ->check(CLI::IsMember({"hard", "soft"}))
      ->capture_default_str();
  c.app->add_option("--target", args->targets,
                    "target shadow image (repeatable, one per light): the shadow dark on a light "
                    "background, square, all the same size; default: the bundled "
                    "data/targets/shadow_back.png and shadow_side.png");
  c.app->add_option("--light-dir", args->light_dirs,
                    "direction x,y,z the light of the target at the same position travels "
                    "(repeatable; default: 0,0,-1 then -1,0,0 then 0,-1,0)");
  c.app->add_option("--iterations", args->iterations, "Adam iterations over all stages")
      ->capture_default_str();
  c.app->add_option("--light-size", args->light_size,
                    "diameter D_L of the lights with --shadows soft (world units)")
      ->capture_default_str();
  c.app->add_option("-o,--output", args->output,
                    "folder for mesh.obj, result.png, scene.png and fit.gif")
      ->capture_default_str();
  c.app->add_option("--gif-every", args->gif_every, "one animation frame every N iterations")
      ->capture_default_str();
  c.app->add_option("--radius", args->radius, "radius of the starting sphere (world units)")
      ->capture_default_str();
  c.app->add_option("--device", args->device,
                    "OpenCL device: index from `penumbra devices` or part of its name");
  c.run = [args] { return run_fit_shadows(*args); };
  return c;
}

}  // namespace penumbra::cli
