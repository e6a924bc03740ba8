// `penumbra shadow-art`: one object whose shadows on two or three walls show the given images
// (by default the letters G, E and B on three orthogonal walls, as on the cover of Gödel,
// Escher, Bach). The object starts as the visual hull of the targets carved on a coarse voxel
// grid (surface nets); its vertices then move by Adam on the soft IoU of its silhouettes seen
// along the lights (a directional light's hard shadow on a wall across it is the orthographic
// silhouette seen from the light) with Laplacian and normal-consistency regularisers, coarse to
// fine. The IoU it reports compares each target with the final object's hard shadow, rendered
// with shadows on by a camera looking at the wall. Writes DIR/mesh.obj, DIR/result.png (each
// target next to the final shadow), DIR/scene.png (the object and its shadows, for mutually
// orthogonal lights) and DIR/fit.gif. The last line of its output is always
//   shadow-art: iterations=N seconds=T iou=[v1,v2,...]
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

struct ShadowArtArgs {
  std::vector<std::string> targets, light_dirs;
  std::string output = "out/shadow-art";
  std::string device;
  int iterations = 250;
  int gif_every = 2;
};

int run_shadow_art(const ShadowArtArgs& a) {
  using namespace optim;
  if (a.iterations < 3 || a.iterations > 100000)
    throw Error("--iterations must be in 3 to 100000 (got " + std::to_string(a.iterations) + ")");
  if (a.gif_every < 1) throw Error("--gif-every must be positive");

  std::vector<std::string> files = a.targets;
  if (files.empty())
    for (const char* letter : {"g", "e", "b"})
      files.push_back(data_dir() + "/targets/letter_" + letter + ".png");
  if (files.size() < 2 || files.size() > 3)
    throw Error("shadow-art takes two or three targets (got " + std::to_string(files.size()) +
                ")");
  std::vector<glm::dvec3> directions;
  for (const std::string& d : a.light_dirs) directions.push_back(parse_direction(d));
  if (directions.empty()) {
    const std::vector<glm::dvec3> order = {{0, 0, -1}, {-1, 0, 0}, {0, -1, 0}};
    directions.assign(order.begin(), order.begin() + long(files.size()));
  }
  if (files.size() != directions.size())
    throw Error(std::string(files.size() < directions.size() ? "fewer" : "more") + " targets (" +
                std::to_string(files.size()) + ") than lights (" +
                std::to_string(directions.size()) + "): give one --target per --light-dir");
  for (size_t i = 0; i < directions.size(); ++i)
    for (size_t j = 0; j < i; ++j)
      if (std::abs(glm::dot(directions[i], directions[j])) > 0.999)
        throw Error("lights " + std::to_string(j) + " and " + std::to_string(i) +
                    " are (anti)parallel: their shadows would be the same silhouette");

  SilhouetteProblem problem;
  problem.directions = directions;
  problem.half_height = kHalfHeight;
  for (const std::string& f : files) problem.targets.push_back(load_target(f));
  check_targets(problem.targets, files);
  const int size = problem.targets.front().width;
  if (size < 16 || size > 1024)
    throw Error("target " + files.front() + " is " + std::to_string(size) + "x" +
                std::to_string(size) + "; targets must be 16 to 1024 pixels on a side");

  const auto t0 = std::chrono::steady_clock::now();
  auto seconds = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  };

  // The starting object: the visual hull of the targets on a grid of about 32³ voxels over the
  // cube the views share, meshed by surface nets and smoothed a little.
  const int grid = stage_resolution(size, 32);
  std::vector<Image> coarse;
  for (const Image& t : problem.targets) coarse.push_back(binarize(downsample(t, size / grid)));
  const std::vector<unsigned char> hull = visual_hull(coarse, directions, kHalfHeight, grid, 1.0);
  if (std::count(hull.begin(), hull.end(), 1) == 0)
    throw Error("the targets have no object in common: no voxel of the " + std::to_string(grid) +
                "^3 grid projects onto every target (are the targets consistent with the "
                "light directions?)");
  Mesh start = surface_nets(hull, grid, 1.0, 2);
  start.name = "shadow_art";

  // Coarse to fine: about 64 pixels, then the targets' size with σ narrowing to a tenth of a
  // pixel (√σ in pixels 0.32, 0.2, 0.09), as in fit-silhouette.
  const int n = a.iterations;
  const int r1 = stage_resolution(size, 64);
  auto sigma = [](double pixels, int resolution) {
    const double s = pixels * 2.0 / resolution;
    return s * s;
  };
  const RegulariserWeights reg{0.2, 0.0, 5e-4, EdgeLoss::Variance};
  std::vector<SilhouetteStage> stages(3);
  stages[0] = {r1, n * 2 / 5, sigma(0.32, r1), 0.003, 0, reg};
  stages[1] = {size, n * 2 / 5, sigma(0.2, size), 0.002, 0, reg};
  stages[2] = {size, n - 2 * (n * 2 / 5), sigma(0.09, size), 0.001, 0, reg};

  Context context(a.device);
  Renderer renderer(context, Precision::Float);
  make_dirs(a.output);
  const fs::path dir(a.output);

  std::vector<Image> target_pictures;
  for (const Image& t : problem.targets) target_pictures.push_back(mask_picture(t));
  auto frame_of = [&](const std::vector<Image>& masks) {
    std::vector<Image> panels;
    for (size_t v = 0; v < masks.size(); ++v) {
      panels.push_back(target_pictures[v]);
      panels.push_back(upscale(mask_picture(masks[v]), size / masks[v].width));
    }
    return side_by_side(panels);
  };
  std::unique_ptr<GifWriter> gif;
  ProgressPrinter progress("shadow-art", n);
  int done = 0;
  Mesh result = fit_silhouettes(renderer, start, problem, stages, [&](const FitProgress& p) {
    done = p.iteration;
    progress.update(p.iteration, p.loss, p.ious, seconds());
    if ((p.iteration - 1) % a.gif_every == 0 || p.iteration == p.total) {
      const Image frame = frame_of(*p.images);
      if (!gif)
        gif = std::make_unique<GifWriter>((dir / "fit.gif").string(), frame.width, frame.height, 8);
      gif->add_frame(frame);
    }
  });
  // Final: the hard shadow on each wall, at the targets' size.
  const WallSetup walls;
  const std::vector<Image> shadows = hard_shadows(renderer, result, directions, size, walls);
  const double total_seconds = seconds();
  std::vector<double> ious;
  for (size_t v = 0; v < shadows.size(); ++v)
    ious.push_back(binary_iou(shadows[v], problem.targets[v]));
  const Image final_frame = frame_of(shadows);
  if (gif) {
    for (int k = 0; k < 10; ++k) gif->add_frame(final_frame);
    gif->close();
  }
  save_png(final_frame, (dir / "result.png").string());
  save_obj(result, (dir / "mesh.obj").string());
  std::string scene_png;
  if (orthogonal(directions)) {
    scene_png = (dir / "scene.png").string();
    WallSetup room = walls;
    room.wall_distance = 2.0;  // closer walls: a tighter picture (the shadows are the same)
    save_png(renderer.render(room_scene(result, directions, 512, 512, room)).front().color,
             scene_png);
  }
  std::printf("wrote %s, %s%s%s and %s\n", (dir / "mesh.obj").string().c_str(),
              (dir / "result.png").string().c_str(), scene_png.empty() ? "" : ", ",
              scene_png.c_str(), (dir / "fit.gif").string().c_str());
  std::printf("shadow-art: iterations=%d seconds=%.1f iou=%s\n", done, total_seconds,
              iou_list(ious).c_str());
  std::fflush(stdout);
  return 0;
}

}  // namespace

Command add_shadow_art_command(CLI::App& root) {
  auto args = std::make_shared<ShadowArtArgs>();
  Command c;
  c.app = root.add_subcommand(
      "shadow-art",
      "make one object whose shadows on two or three walls show the given images (default: "
      "G, E and B, as on the cover of Goedel, Escher, Bach)");
  c.app->add_option("--target", args->targets,
                    "target shadow image (repeatable, two or three, one per light): the shape "
                    "dark on a light background, square, all the same size; default: the "
                    "bundled data/targets/letter_g.png, letter_e.png, letter_b.png");
  c.app->add_option("--light-dir", args->light_dirs,
                    "direction x,y,z the light of the target at the same position travels "
                    "(repeatable; default: 0,0,-1 then -1,0,0 then 0,-1,0)");
  c.app->add_option("--iterations", args->iterations, "Adam iterations over all stages")
      ->capture_default_str();
  c.app->add_option("-o,--output", args->output,
                    "folder for mesh.obj, result.png, scene.png and fit.gif")
      ->capture_default_str();
  c.app->add_option("--gif-every", args->gif_every, "one animation frame every N iterations")
      ->capture_default_str();
  c.app->add_option("--device", args->device,
                    "OpenCL device: index from `penumbra devices` or part of its name");
  c.run = [args] { return run_shadow_art(*args); };
  return c;
}

}  // namespace penumbra::cli
