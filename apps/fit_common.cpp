// The fitting commands' shared options, checks, progress and output (fit-silhouette,
// fit-shadows, shadow-art); declared in common.hpp.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "common.hpp"
#include "penumbra/error.hpp"
#include "penumbra/image_io.hpp"
#include "penumbra/interrupt.hpp"
#include "penumbra/io.hpp"

namespace fs = std::filesystem;

namespace penumbra::cli {
void add_iterations_option(CLI::App& cmd, int& iterations) {
  cmd.add_option("--iterations", iterations, "Adam iterations over all stages")
      ->capture_default_str();
}

void add_output_option(CLI::App& cmd, std::string& output, const std::string& files) {
  cmd.add_option("-o,--output", output, "folder for " + files)->capture_default_str();
}

void add_gif_every_option(CLI::App& cmd, int& gif_every) {
  cmd.add_option("--gif-every", gif_every, "one animation frame every N iterations")
      ->capture_default_str();
}

void add_radius_option(CLI::App& cmd, double& radius) {
  cmd.add_option("--radius", radius, "radius of the starting sphere (world units)")
      ->capture_default_str();
}

void add_light_dir_option(CLI::App& cmd, std::vector<std::string>& light_dirs) {
  cmd.add_option("--light-dir", light_dirs,
                 "direction x,y,z the light of the target at the same position travels "
                 "(repeatable; default: 0,0,-1 then -1,0,0 then 0,-1,0)");
}

void add_fit_device_option(CLI::App& cmd, std::string& device) {
  cmd.add_option("--device", device,
                 "OpenCL device: index from `penumbra devices` or part of its name");
}

void add_checkpoint_options(CLI::App& cmd, CheckpointOptions& options) {
  cmd.add_option("--checkpoint-every", options.every,
                 "write DIR/checkpoint.json every N iterations and after the last (0: never)")
      ->capture_default_str();
  cmd.add_flag("--resume", options.resume,
               "go on from DIR/checkpoint.json, left by an interrupted run with the same options");
}

FitCheckpointFile::FitCheckpointFile(const CheckpointOptions& options, const std::string& dir,
                                     const std::string& command, std::string run)
    : path_((fs::path(dir) / "checkpoint.json").string()), run_(std::move(run)) {
  if (options.every < 0)
    throw Error("--checkpoint-every must be 0 (never) or a positive number of iterations (got " +
                std::to_string(options.every) + ")");
  hooks_.every = options.every;
  hooks_.save = [this](const optim::FitState& state) {
    write_file(path_, optim::checkpoint_text(state, run_), "checkpoint");
  };
  // An interruption's line says so once there is a checkpoint to go on from.
  if (options.every > 0)
    set_interrupted_note("--resume goes on from " + path_, options.resume ? "" : path_);
  if (!options.resume) return;
  std::ifstream in(path_, std::ios::binary);
  if (!in)
    throw Error("--resume: cannot read the checkpoint " + path_ + ": " + std::strerror(errno));
  std::ostringstream text;
  text << in.rdbuf();
  resumed_ = optim::parse_checkpoint(text.str(), path_, run_);
  hooks_.resume = &resumed_;
  std::fprintf(stderr, "%s: resuming from %s at iteration %d\n", command.c_str(), path_.c_str(),
               resumed_.iteration);
}

void check_fit_counts(int iterations, int min_iterations, int gif_every) {
  if (iterations < min_iterations || iterations > 100000)
    throw Error("--iterations must be in " + std::to_string(min_iterations) + " to 100000 (got " +
                std::to_string(iterations) + ")");
  if (gif_every < 1) throw Error("--gif-every must be positive");
}

void check_radius(double radius) {
  if (!(radius > 0 && radius < 1))
    throw Error("--radius must be in (0, 1) (got " + std::to_string(radius) + ")");
}

std::vector<glm::dvec3> light_directions(const std::vector<std::string>& light_dirs,
                                         size_t targets) {
  std::vector<glm::dvec3> directions;
  directions.reserve(light_dirs.size());
  for (const std::string& d : light_dirs) directions.push_back(optim::parse_direction(d));
  if (directions.empty()) {
    const std::vector<glm::dvec3> order = {{0, 0, -1}, {-1, 0, 0}, {0, -1, 0}};
    if (targets > order.size())
      throw Error(std::to_string(targets) +
                  " targets but 3 default lights; give --light-dir for each target");
    directions.assign(order.begin(), order.begin() + long(targets));
  }
  if (targets != directions.size())
    throw Error(std::string(targets < directions.size() ? "fewer" : "more") + " targets (" +
                std::to_string(targets) + ") than lights (" + std::to_string(directions.size()) +
                "): give one --target per --light-dir");
  return directions;
}

int load_fit_targets(const std::vector<std::string>& files, int max_size,
                     std::vector<Image>& targets) {
  for (const std::string& f : files) targets.push_back(optim::load_target(f));
  optim::check_targets(targets, files);
  const int size = targets.front().width;
  if (size < 16 || size > max_size)
    throw Error("target " + files.front() + " is " + std::to_string(size) + "x" +
                std::to_string(size) + "; targets must be 16 to " + std::to_string(max_size) +
                " pixels on a side");
  return size;
}

Mesh start_sphere(double radius) {
  Mesh sphere = load_obj(data_dir() + "/meshes/icosphere.obj");
  for (glm::dvec3& v : sphere.vertices) v *= radius;
  sphere.name = "shape";
  return sphere;
}

double sigma_for_pixels(double pixels, int resolution) {
  const double s = pixels * 2.0 / resolution;
  return s * s;
}

double Stopwatch::seconds() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

FitRecorder::FitRecorder(std::string command, const std::string& dir,
                         const std::vector<Image>& targets, int iterations, int gif_every,
                         const Stopwatch& clock)
    : command_(std::move(command)),
      dir_(dir),
      targets_(targets),
      size_(targets.front().width),
      gif_every_(gif_every),
      clock_(clock),
      progress_(command_, iterations) {
  make_dirs(dir_);
  for (const Image& t : targets_) target_pictures_.push_back(optim::mask_picture(t));
}

std::string FitRecorder::path(const std::string& name) const {
  return (fs::path(dir_) / name).string();
}

Image FitRecorder::frame(const std::vector<Image>& masks) const {
  std::vector<Image> panels;
  for (size_t v = 0; v < masks.size(); ++v) {
    panels.push_back(target_pictures_[v]);
    panels.push_back(optim::upscale(optim::mask_picture(masks[v]), size_ / masks[v].width));
  }
  return optim::side_by_side(panels);
}

void FitRecorder::update(const optim::FitProgress& p) {
  done_ = p.iteration;
  progress_.update(p.iteration, p.loss, p.ious, clock_.seconds());
  if ((p.iteration - 1) % gif_every_ == 0 || p.iteration == p.total) {
    const Image f = frame(*p.images);
    if (!gif_) gif_ = std::make_unique<GifWriter>(path("fit.gif"), f.width, f.height, 8);
    gif_->add_frame(f);
  }
}

std::vector<double> FitRecorder::finish(const Mesh& result, const std::vector<Image>& masks) {
  std::vector<double> ious;
  for (size_t v = 0; v < masks.size(); ++v)
    ious.push_back(optim::binary_iou(masks[v], targets_[v]));
  const Image final_frame = frame(masks);
  if (gif_) {
    for (int k = 0; k < 10; ++k) gif_->add_frame(final_frame);  // hold the result a moment
    gif_->close();
  }
  write_files({{path("result.png"), png_bytes(final_frame, path("result.png")), "PNG"},
               {path("mesh.obj"), obj_text(result), "OBJ file"}});
  return ious;
}

std::string FitRecorder::save_scene(Renderer& renderer, const Mesh& result,
                                    const std::vector<glm::dvec3>& directions, int size,
                                    const optim::WallSetup& setup) const {
  if (!optim::orthogonal(directions)) return "";
  std::string scene_png = path("scene.png");
  save_png(renderer.render(optim::room_scene(result, directions, size, size, setup)).front().color,
           scene_png);
  return scene_png;
}

void FitRecorder::finish_on_walls(Renderer& renderer, const Mesh& result,
                                  const std::vector<glm::dvec3>& directions,
                                  const optim::WallSetup& walls, const optim::WallSetup& room,
                                  int scene_size) {
  const std::vector<Image> shadows =
      optim::hard_shadows(renderer, result, directions, size_, walls);
  const double total_seconds = clock_.seconds();
  const std::vector<double> ious = finish(result, shadows);
  const std::string scene_png = save_scene(renderer, result, directions, scene_size, room);
  report(total_seconds, ious, scene_png);
}

void FitRecorder::report(double seconds, const std::vector<double>& ious,
                         const std::string& scene_png) const {
  std::printf("wrote %s, %s%s%s and %s\n", path("mesh.obj").c_str(), path("result.png").c_str(),
              scene_png.empty() ? "" : ", ", scene_png.c_str(), path("fit.gif").c_str());
  std::printf("%s: iterations=%d seconds=%.1f iou=%s\n", command_.c_str(), done_, seconds,
              optim::iou_list(ious).c_str());
  std::fflush(stdout);
}

}  // namespace penumbra::cli
