#pragma once
// Shared pieces of the `penumbra` command-line tool: the scene argument, the render-parameter
// and shadow options of math.md §10 (each defined once, here), device and precision options, file
// helpers.
#include <CLI/CLI.hpp>
#include <chrono>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "penumbra/context.hpp"
#include "penumbra/error.hpp"
#include "penumbra/image_io.hpp"
#include "penumbra/io.hpp"
#include "penumbra/optim.hpp"
#include "penumbra/renderer.hpp"
#include "penumbra/scene.hpp"

namespace penumbra::cli {

// A subcommand: its CLI11 parser and the function that runs it after parsing (exit code).
struct Command {
  CLI::App* app = nullptr;
  std::function<int()> run;
};

Command add_devices_command(CLI::App& root);
Command add_render_command(CLI::App& root);
Command add_backward_command(CLI::App& root);
Command add_gradcheck_command(CLI::App& root);
Command add_turnaround_command(CLI::App& root);
Command add_figures_command(CLI::App& root);
Command add_fit_silhouette_command(CLI::App& root);
Command add_fit_shadows_command(CLI::App& root);
Command add_shadow_art_command(CLI::App& root);
Command add_tune_command(CLI::App& root);
Command add_kernels_command(CLI::App& root);

// Where the scene comes from: a positional SCENE.json, or --mesh FILE (a mesh file, load_mesh);
// neither means the bundled data/scenes/turnaround.json.
struct SceneSource {
  std::string scene_path;
  std::string mesh_path;
  bool refuse_degenerate = false;  // --refuse-degenerate: a zero-area face fails the mesh
};
void add_scene_options(CLI::App& cmd, SceneSource& source, bool with_mesh = true);

// math.md §10 parameters, shadow options, image size and device. Only options given on the command
// line override the scene's values.
struct RenderOptions {
  double sigma = 0, gamma = 0, eps = 0, dist_eps = 0, sigma_s = 0, lambda_eps = 0, gamma_s = 0,
         beta = 0, gamma_p = 0;
  std::string shadows, sampling;  // none|hard|soft, truncated|exact|gemm
  std::string exact_backend;      // auto|kernels|clblast
  std::string shadow_model;       // accurate|paper
  std::string shadow_map;         // auto|frustum|cube
  int map_size = 0;               // shadow_map_size
  double light_size = 0, light_sigma = 0, light_gamma = 0, weight_eps = 0;
  int width = 0, height = 0;
  std::string device, max_memory;
  // The parsed options, to tell "given" from "left at the default".
  CLI::Option *o_sigma = nullptr, *o_gamma = nullptr, *o_eps = nullptr, *o_dist_eps = nullptr,
              *o_sigma_s = nullptr, *o_lambda_eps = nullptr, *o_gamma_s = nullptr,
              *o_beta = nullptr, *o_gamma_p = nullptr, *o_width = nullptr, *o_height = nullptr,
              *o_shadows = nullptr, *o_sampling = nullptr, *o_exact_backend = nullptr,
              *o_shadow_model = nullptr, *o_map_size = nullptr, *o_light_size = nullptr,
              *o_light_sigma = nullptr, *o_light_gamma = nullptr, *o_weight_eps = nullptr,
              *o_max_memory = nullptr, *o_shadow_map = nullptr;
};
void add_render_options(CLI::App& cmd, RenderOptions& options);
// Applies the given overrides to every camera / the scene parameters; throws penumbra::Error for
// values that make no sense (zero image size, non-positive σ, ...), then validates the scene.
void apply_render_options(const RenderOptions& options, Scene& scene);

// The device named by --device, with the memory limit of --max-memory when given.
void limit_memory(const RenderOptions& options, Context& context);
// A size in bytes: a number, optionally followed by B, KiB, MiB, GiB, TiB (powers of 1024) or
// kB, MB, GB, TB (powers of 1000); throws penumbra::Error naming `option` otherwise.
size_t parse_bytes(const std::string& text, const std::string& option);

// A CLI11 check that the value is one of `words`, with a message that lists them.
CLI::Validator one_of(const std::vector<std::string>& words);
// The same for the words of an enum (scene.hpp's enum_words).
template <class E>
CLI::Validator one_of() {
  std::vector<std::string> words;
  for (const auto& [value, w] : enum_words<E>()) words.push_back(w);
  return one_of(words);
}
// The value of `w`, a word of enum E; throws penumbra::Error naming `option` otherwise.
template <class E>
E parse_word(const std::string& option, const std::string& w) {
  E value{};
  if (!from_word(w, &value))
    throw Error(option + " must be " + word_choices<E>() + " (got '" + w + "')");
  return value;
}

// The shadow mode of a --shadows word (the words of every enum: penumbra::word, scene.hpp).
Shadows parse_shadows(const std::string& word);
// --shadows and --shadow-model, for every command that takes them: checked against the
// enum's words, or against `words` where a command takes fewer.
CLI::Option* add_shadows_option(CLI::App& cmd, std::string& value, const std::string& help,
                                const std::vector<std::string>& words = {});
CLI::Option* add_shadow_model_option(CLI::App& cmd, std::string& value, const std::string& help);

// --precision float|double.
void add_precision_option(CLI::App& cmd, std::string& precision, const std::string& default_value);
Precision parse_precision(const std::string& name);

// The data folder: $PENUMBRA_DATA_DIR, else share/penumbra next to an installed tool, else
// <source tree>/data when it exists, else ./data.
std::string data_dir();
std::string default_scene_path();
// Loads (and validates) the scene named by `source`.
Scene load_scene_source(const SceneSource& source);

// "out.png" for view 0, "out_1.png", "out_2.png", ... for the others.
std::string view_path(const std::string& path, size_t view);
// "color.npy" for view 0, "color_1.npy", ... inside `dir`.
std::string view_file(const std::string& dir, const std::string& stem, size_t view);
// Creates the folder (and its parents) if needed; throws penumbra::Error on failure.
void make_dirs(const std::string& dir);
void make_parent_dirs(const std::string& file);

// "a,b,c".
std::string joined(const std::vector<std::string>& words);
// Replaces line breaks so that an error message prints as one line.
std::string one_line(const std::string& text);

// ---------------------------------------------------------------------------------------------
// The fitting commands (fit-silhouette, fit-shadows, shadow-art): their common options, checks,
// inputs and outputs.

// --iterations, -o/--output ("folder for <files>"), --gif-every, --radius, --light-dir and
// --device, worded alike in every fitting command.
void add_iterations_option(CLI::App& cmd, int& iterations);
void add_output_option(CLI::App& cmd, std::string& output, const std::string& files);
void add_gif_every_option(CLI::App& cmd, int& gif_every);
void add_radius_option(CLI::App& cmd, double& radius);
void add_light_dir_option(CLI::App& cmd, std::vector<std::string>& light_dirs);
void add_fit_device_option(CLI::App& cmd, std::string& device);

// --checkpoint-every N and --resume.
struct CheckpointOptions {
  int every = 25;
  bool resume = false;
};
void add_checkpoint_options(CLI::App& cmd, CheckpointOptions& options);

// DIR/checkpoint.json of a fit, written (atomically) every N iterations and after the last, and
// with --resume read first: it must exist and belong to the same run, `run` naming the command
// and every option that decides the fit. hooks() is what the fit takes.
class FitCheckpointFile {
 public:
  FitCheckpointFile(const CheckpointOptions& options, const std::string& dir,
                    const std::string& command, std::string run);
  FitCheckpointFile(const FitCheckpointFile&) = delete;
  FitCheckpointFile& operator=(const FitCheckpointFile&) = delete;
  const optim::FitCheckpoints& hooks() const { return hooks_; }

 private:
  std::string path_, run_;
  optim::FitState resumed_;
  optim::FitCheckpoints hooks_;
};

// Throws unless min_iterations ≤ iterations ≤ 100000 and gif_every ≥ 1.
void check_fit_counts(int iterations, int min_iterations, int gif_every);
// Throws unless the starting sphere's radius is in (0, 1).
void check_radius(double radius);

// The lights of the targets: the --light-dir values, or the defaults −z, −x, −y in order, one
// per target; throws when there are not as many lights as targets.
std::vector<glm::dvec3> light_directions(const std::vector<std::string>& light_dirs,
                                         size_t targets);
// Loads and checks the target images (optim::load_target, check_targets) into `targets`; returns
// their size, which must be 16 to max_size pixels.
int load_fit_targets(const std::vector<std::string>& files, int max_size,
                     std::vector<Image>& targets);
// The bundled icosphere with the given radius, named "shape": the starting mesh of the fits.
Mesh start_sphere(double radius);
// The coverage sharpness σ whose square root spans `pixels` pixels of a view of `resolution`
// pixels across the screen's [−1, 1].
double sigma_for_pixels(double pixels, int resolution);

// Seconds since construction.
class Stopwatch {
 public:
  double seconds() const;

 private:
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
};

// What a fitting command shows and writes while and after it runs: the progress lines, DIR/fit.gif
// (each target next to the current mask, at the targets' size), DIR/result.png, DIR/mesh.obj and
// the last two lines of its output.
class FitRecorder {
 public:
  // Creates the folder `dir`.
  FitRecorder(std::string command, const std::string& dir, const std::vector<Image>& targets,
              int iterations, int gif_every, const Stopwatch& clock);
  // The fit's observer: a progress line, and an animation frame every gif_every iterations and
  // at the last.
  void update(const optim::FitProgress& p);
  // update() as the fit's observer.
  optim::FitObserver observer() {
    return [this](const optim::FitProgress& p) { update(p); };
  }
  // The IoU of each final mask with its target; holds the final frame in the animation, then
  // writes result.png and mesh.obj.
  std::vector<double> finish(const Mesh& result, const std::vector<Image>& masks);
  // "wrote ..." (naming `scene_png` too when given) and
  // "<command>: iterations=N seconds=T iou=[...]".
  void report(double seconds, const std::vector<double>& ious,
              const std::string& scene_png = "") const;
  // DIR/scene.png, the shape between its walls and lights (optim::room_scene, `size` pixels
  // square), written only for mutually orthogonal lights; its path, or "" when not written.
  std::string save_scene(Renderer& renderer, const Mesh& result,
                         const std::vector<glm::dvec3>& directions, int size,
                         const optim::WallSetup& setup) const;
  // The end of a fit judged by its hard shadows (fit-shadows, shadow-art): the shadows on
  // `walls` at the targets' size, then finish(), save_scene() in `room` (`scene_size` pixels)
  // and report(), the seconds taken before the files are written.
  void finish_on_walls(Renderer& renderer, const Mesh& result,
                       const std::vector<glm::dvec3>& directions, const optim::WallSetup& walls,
                       const optim::WallSetup& room, int scene_size);
  // DIR/name.
  std::string path(const std::string& name) const;

 private:
  Image frame(const std::vector<Image>& masks) const;

  std::string command_, dir_;
  std::vector<Image> targets_, target_pictures_;
  int size_, gif_every_, done_ = 0;
  const Stopwatch& clock_;
  optim::ProgressPrinter progress_;
  std::unique_ptr<GifWriter> gif_;
};

// Progress of long render() and backward() calls on stderr (Renderer::set_progress). A call
// prints nothing for its first 2 s (PENUMBRA_PROGRESS_AFTER=SECONDS sets another delay); then
// on a terminal one line redrawn in place, otherwise a line each time another tenth of the
// call is done. Lines read
//   render: render view 1/1, shadow lookups 3/8, 31 %, 2.4 s
// `name` is the command; `what` (optional, e.g. "frame 3/72") goes before the call.
class CallProgress {
 public:
  explicit CallProgress(std::string name);
  ~CallProgress();
  // Reports every call of `renderer` from now on.
  void watch(Renderer& renderer);
  // A new call starts now (its 2 s count from here); `what` names it in the lines.
  void start(std::string what = "");
  // Ends a line redrawn in place, if one was drawn.
  void finish();
  void update(const RenderProgress& p);

 private:
  std::string name_, what_;
  bool tty_;
  double after_s_ = 2.0;
  std::chrono::steady_clock::time_point start_;
  int decile_ = -1;
  bool drawn_ = false;
};

}  // namespace penumbra::cli
