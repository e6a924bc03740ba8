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

constexpr double kHalfHeight = 1.0;  // every view shows the square [−1, 1]² across it

struct ShadowArtArgs {
  std::vector<std::string> targets, light_dirs;
  std::string output = "out/shadow-art";
  std::string device;
  int iterations = 250;
  int gif_every = 2;
  CheckpointOptions checkpoints;
};

// The target files and the direction of the light whose shadow shows each.
struct TargetLights {
  std::vector<std::string> files;
  std::vector<glm::dvec3> directions;
};

TargetLights target_lights(const ShadowArtArgs& a) {
  TargetLights t{a.targets, {}};
  std::vector<std::string>& files = t.files;
  if (files.empty())
    for (const char* letter : {"g", "e", "b"})
      files.push_back(data_dir() + "/targets/letter_" + letter + ".png");
  if (files.size() < 2 || files.size() > 3)
    throw Error("shadow-art takes two or three targets (got " + std::to_string(files.size()) + ")");
  t.directions = light_directions(a.light_dirs, files.size());
  const std::vector<glm::dvec3>& directions = t.directions;
  for (size_t i = 0; i < directions.size(); ++i)
    for (size_t j = 0; j < i; ++j)
      if (std::abs(glm::dot(directions[i], directions[j])) > 0.999)
        throw Error("lights " + std::to_string(j) + " and " + std::to_string(i) +
                    " are (anti)parallel: their shadows would be the same silhouette");
  return t;
}

// The starting object: the visual hull of the targets on a grid of about 32³ voxels over the
// cube the views share, meshed by surface nets and smoothed a little. A coarse pixel counts as
// covered from a third of its area on: the meshing and smoothing pull the surface inwards.
Mesh visual_hull_start(const optim::SilhouetteProblem& problem, int size) {
  using namespace optim;
  const int grid = stage_resolution(size, 32);
  std::vector<Image> coarse;
  for (const Image& t : problem.targets)
    coarse.push_back(binarize(downsample(t, size / grid), 0.35));
  const std::vector<unsigned char> hull =
      visual_hull(coarse, problem.directions, kHalfHeight, grid, 1.0);
  if (std::count(hull.begin(), hull.end(), 1) == 0)
    throw Error("the targets have no object in common: no voxel of the " + std::to_string(grid) +
                "^3 grid projects onto every target (are the targets consistent with the "
                "light directions?)");
  Mesh start = surface_nets(hull, grid, 1.0, 2);
  start.name = "shadow_art";
  return start;
}

// Coarse to fine: about 64 pixels, then the targets' size with σ narrowing to a tenth of a
// pixel (√σ in pixels 0.32, 0.2, 0.09), as in fit-silhouette.
std::vector<optim::SilhouetteStage> shadow_art_stages(int n, int size) {
  using namespace optim;
  const int r1 = stage_resolution(size, 64);
  const auto sigma = sigma_for_pixels;
  const RegulariserWeights reg{0.2, 0.0, 5e-4, EdgeLoss::Variance};
  std::vector<SilhouetteStage> stages(3);
  stages[0] = {r1, n * 2 / 5, sigma(0.32, r1), 0.003, 0, reg};
  stages[1] = {size, n * 2 / 5, sigma(0.2, size), 0.002, 0, reg};
  stages[2] = {size, n - 2 * (n * 2 / 5), sigma(0.09, size), 0.001, 0, reg};
  return stages;
}

int run_shadow_art(const ShadowArtArgs& a) {
  using namespace optim;
  check_fit_counts(a.iterations, 3, a.gif_every);
  const TargetLights t = target_lights(a);
  const std::vector<glm::dvec3>& directions = t.directions;

  SilhouetteProblem problem;
  problem.directions = directions;
  problem.half_height = kHalfHeight;
  const int size = load_fit_targets(t.files, 1024, problem.targets);

  const Stopwatch clock;
  const Mesh start = visual_hull_start(problem, size);
  const int n = a.iterations;
  const std::vector<SilhouetteStage> stages = shadow_art_stages(n, size);

  const FitCheckpointFile checkpoints(a.checkpoints, a.output, "shadow-art",
                                      "shadow-art iterations=" + std::to_string(n) + " targets=" +
                                          joined(t.files) + " light-dirs=" + joined(a.light_dirs));
  Context context(a.device);
  Renderer renderer(context, Precision::Float);
  FitRecorder recorder("shadow-art", a.output, problem.targets, n, a.gif_every, clock);
  const Mesh result =
      fit_silhouettes(renderer, start, problem, stages, recorder.observer(), checkpoints.hooks());
  const WallSetup walls;
  WallSetup room = walls;
  room.wall_distance = 2.0;  // closer walls: a tighter picture (the shadows are the same)
  recorder.finish_on_walls(renderer, result, directions, walls, room, 512);
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
  add_light_dir_option(*c.app, args->light_dirs);
  add_iterations_option(*c.app, args->iterations);
  add_output_option(*c.app, args->output, "mesh.obj, result.png, scene.png and fit.gif");
  add_gif_every_option(*c.app, args->gif_every);
  add_checkpoint_options(*c.app, args->checkpoints);
  add_fit_device_option(*c.app, args->device);
  c.run = [args] { return run_shadow_art(*args); };
  return c;
}

}  // namespace penumbra::cli
