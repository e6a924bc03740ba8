// `penumbra turnaround`: the animation of the paper's Figure 4. The first camera orbits 360°
// around the vertical (+y) axis through its target, keeping its distance and elevation; the
// lights stay where they are and their shadow-map frusta are fitted once. One Renderer renders
// every frame. Writes DIR/frame_000.png, ... and the looping animation DIR/turnaround.gif.
// The last line of its output is always
//   turnaround: frames=N shadows=S sampling=M seconds=T ms_per_frame=X
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

#include "common.hpp"
#include "penumbra/context.hpp"
#include "penumbra/error.hpp"
#include "penumbra/image_io.hpp"
#include "penumbra/io.hpp"
#include "penumbra/renderer.hpp"

namespace fs = std::filesystem;

namespace penumbra::cli {

namespace {

constexpr int kGifDelayCentiseconds = 10;  // 10 frames per second
constexpr int kMaxFrames = 100000;

struct TurnaroundArgs {
  SceneSource source;
  RenderOptions render;
  std::string output, precision;
  int frames = 90;
};

// Progress on stderr: a bar redrawn in place on a terminal, otherwise about ten plain lines.
class Progress {
 public:
  explicit Progress(int total) : total_(total), tty_(isatty(STDERR_FILENO) == 1) {}

  void update(int done, double seconds) {
    if (tty_) {
      constexpr int kWidth = 30;
      const int filled = int(double(kWidth) * done / total_);
      const double eta = done > 0 ? seconds / done * (total_ - done) : 0.0;
      std::fprintf(stderr, "\rturnaround [%s%s] %d/%d  %.1f s  eta %.1f s ",
                   std::string(size_t(filled), '#').c_str(),
                   std::string(size_t(kWidth - filled), '.').c_str(), done, total_, seconds, eta);
      if (done == total_) std::fputc('\n', stderr);
      std::fflush(stderr);
      return;
    }
    const int every = std::max(1, (total_ + 9) / 10);
    if (done % every == 0 || done == total_) {
      std::fprintf(stderr, "turnaround: %d/%d frames, %.1f s\n", done, total_, seconds);
      std::fflush(stderr);
    }
  }

 private:
  int total_;
  bool tty_;
};

std::string frame_name(int frame, int frames) {
  int digits = 3;
  for (int n = frames - 1; n >= 1000; n /= 10) ++digits;
  std::string number = std::to_string(frame);  // frame >= 0, zero-padded to `digits`
  if (number.size() < size_t(digits)) number.insert(0, size_t(digits) - number.size(), '0');
  return "frame_" + number + ".png";
}

int run_turnaround(const TurnaroundArgs& a) {
  if (a.frames < 1 || a.frames > kMaxFrames)
    throw Error("--frames must be in 1 to " + std::to_string(kMaxFrames) + " (got " +
                std::to_string(a.frames) + ")");
  Scene scene = load_scene_source(a.source);
  apply_render_options(a.render, scene);
  const Precision precision = parse_precision(a.precision);
  scene.cameras.resize(1);  // the first camera orbits; the others are not rendered
  fit_light_frusta(scene);  // once: the lights and their frusta stay fixed while the camera moves
  const Camera base = scene.cameras.front();

  Context context(a.render.device);
  limit_memory(a.render, context);
  Renderer renderer(context, precision);
  make_dirs(a.output);
  const std::string gif_path = (fs::path(a.output) / "turnaround.gif").string();
  std::unique_ptr<GifWriter> gif;  // opened once the first frame has rendered

  Progress progress(a.frames);
  CallProgress call_progress("turnaround");  // within a frame that takes long
  call_progress.watch(renderer);
  const double two_pi = 2.0 * std::acos(-1.0);
  const auto t0 = std::chrono::steady_clock::now();
  for (int k = 0; k < a.frames; ++k) {
    scene.cameras.front() = orbit(base, two_pi * k / a.frames);
    call_progress.start("frame " + std::to_string(k + 1) + "/" + std::to_string(a.frames));
    const std::vector<RenderOutput> views = renderer.render(scene);
    call_progress.finish();
    save_png(views.front().color, (fs::path(a.output) / frame_name(k, a.frames)).string());
    if (!gif)
      gif = std::make_unique<GifWriter>(gif_path, base.width, base.height, kGifDelayCentiseconds);
    gif->add_frame(views.front().color);
    progress.update(k + 1,
                    std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  gif->close();

  std::printf("wrote %s ... %s and %s\n",
              (fs::path(a.output) / frame_name(0, a.frames)).string().c_str(),
              frame_name(a.frames - 1, a.frames).c_str(), gif_path.c_str());
  std::printf("turnaround: frames=%d shadows=%s sampling=%s seconds=%.2f ms_per_frame=%.1f\n",
              a.frames, word(scene.params.shadows).c_str(), word(scene.params.sampling).c_str(),
              seconds, 1000.0 * seconds / a.frames);
  std::fflush(stdout);
  return 0;
}

}  // namespace

Command add_turnaround_command(CLI::App& root) {
  auto args = std::make_shared<TurnaroundArgs>();
  Command c;
  c.app = root.add_subcommand(
      "turnaround",
      "orbit the first camera 360° around the scene (lights fixed) and write the frames as PNG "
      "and one looping GIF");
  add_scene_options(*c.app, args->source);
  c.app
      ->add_option("-o,--output", args->output,
                   "folder for frame_000.png, frame_001.png, ... and turnaround.gif")
      ->required();
  c.app->add_option("--frames", args->frames, "number of frames of the full orbit")
      ->capture_default_str();
  add_precision_option(*c.app, args->precision, "float");
  add_render_options(*c.app, args->render);
  c.run = [args] { return run_turnaround(*args); };
  return c;
}

}  // namespace penumbra::cli
