// `penumbra figures [SCENE.json] [-o docs/images]`: the pictures of the documentation,
// reproducing the paper's figures on the bundled scene:
//   fig1_a.png … fig1_d.png  hard-shadow parameter sweep (paper Figure 1, math.md §10 units)
//   fig2_depth_map.png       the shadow map S of the Figure 1 (a) settings (paper Figure 2)
//   fig4_soft_*.png          soft-shadow turnaround frames (paper Figure 4)
//   fig5_penumbra_map.png    a penumbra map P (paper Figure 5)
//   soft_size_*.png          soft shadows as the light grows
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <string>
#include <utility>

#include "common.hpp"
#include "penumbra/context.hpp"
#include "penumbra/image_io.hpp"
#include "penumbra/io.hpp"
#include "penumbra/renderer.hpp"

namespace fs = std::filesystem;

namespace penumbra::cli {

namespace {

struct FiguresArgs {
  SceneSource source;
  std::string output = "docs/images", device;
};

// Depth maps as pictures: near is bright, far is dark, texels that see no surface are black.
Image depth_picture(const Image& S, double background) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (double v : S.data)
    if (v < 0.999 * background) lo = std::min(lo, v), hi = std::max(hi, v);
  Image out(S.width, S.height, 1);
  for (size_t i = 0; i < S.data.size(); ++i)
    out.data[i] =
        S.data[i] < 0.999 * background && hi > lo ? 1 - 0.8 * (S.data[i] - lo) / (hi - lo) : 0;
  return out;
}

// Writes the pictures into one folder, each with a line "wrote PATH", and counts them.
class FigureWriter {
 public:
  explicit FigureWriter(std::string dir) : dir_(std::move(dir)) {}
  void save(const Image& image, const std::string& name) {
    const std::string path = (fs::path(dir_) / name).string();
    save_png(image, path);
    std::printf("wrote %s\n", path.c_str());
    ++files_;
  }
  int files() const { return files_; }

 private:
  std::string dir_;
  int files_ = 0;
};

// Figure 1: (a) γ_s = 0.01, β = 0.5, σ_s = 0.5 at σ = 1e-5, γ = 1e-4; (b–d) γ_s = 2/3, β = 2,
// σ_s = 2·10⁴·σ with (σ, γ) = (1e-5, 1e-4), (1e-4, 1e-3), (10^-3.2, 10^-2.2); Figure 2: the
// shadow map of (a).
void save_hard_sweep(Renderer& renderer, const Scene& base, FigureWriter& out) {
  struct Setting {
    const char* name;
    double gamma_s, beta, sigma, gamma, sigma_s;
  };
  const Setting sweep[] = {{"fig1_a.png", 0.01, 0.5, 1e-5, 1e-4, 0.5},
                           {"fig1_b.png", 2.0 / 3, 2.0, 1e-5, 1e-4, 2e4 * 1e-5},
                           {"fig1_c.png", 2.0 / 3, 2.0, 1e-4, 1e-3, 2e4 * 1e-4},
                           {"fig1_d.png", 2.0 / 3, 2.0, std::pow(10.0, -3.2), std::pow(10.0, -2.2),
                            2e4 * std::pow(10.0, -3.2)}};
  for (const Setting& s : sweep) {
    Scene scene = base;
    RenderParams& p = scene.params;
    p.shadows = Shadows::Hard;
    p.sampling = Sampling::Truncated;
    p.gamma_s = s.gamma_s, p.beta = s.beta, p.sigma = s.sigma, p.gamma = s.gamma;
    p.sigma_s = s.sigma_s;
    out.save(renderer.render(scene).front().color, s.name);
    if (&s == &sweep[0])
      out.save(depth_picture(renderer.shadow_maps().front(), scene.lights.front().frustum.far),
               "fig2_depth_map.png");
  }
}

// Figure 4 and 5: soft shadows, the camera at four points of its orbit; then the light growing.
void save_soft_shadows(Renderer& renderer, const Scene& base, FigureWriter& out) {
  Scene soft = base;
  soft.params.shadows = Shadows::Soft;
  soft.params.sampling = Sampling::Truncated;
  for (int k = 0; k < 4; ++k) {
    Scene frame = soft;
    frame.cameras.front() = orbit(base.cameras.front(), std::acos(-1.0) / 2 * k);
    char name[32];
    std::snprintf(name, sizeof name, "fig4_soft_%03d.png", 90 * k);
    out.save(renderer.render(frame).front().color, name);
    if (k == 0) out.save(renderer.penumbra_maps().front(), "fig5_penumbra_map.png");
  }
  for (double size : {0.0, 0.5, 1.5}) {
    Scene scene = soft;
    for (Light& l : scene.lights) l.size = size;
    char name[32];
    std::snprintf(name, sizeof name, "soft_size_%.1f.png", size);
    out.save(renderer.render(scene).front().color, name);
  }
}

// The two shadow models side by side (docs/shadows.md, "The accurate model").
void save_shadow_models(Renderer& renderer, const Scene& base, FigureWriter& out) {
  for (Shadows mode : {Shadows::Hard, Shadows::Soft})
    for (ShadowModel model : {ShadowModel::Paper, ShadowModel::Accurate}) {
      Scene scene = base;
      scene.params.shadows = mode;
      scene.params.shadow_model = model;
      for (Light& l : scene.lights) l.size = mode == Shadows::Soft ? 0.5 : 0.0;
      refit_light_frusta(scene);
      out.save(renderer.render(scene).front().color,
               "model_" + word(model) + "_" + word(mode) + ".png");
    }
}

int run_figures(const FiguresArgs& a) {
  const auto t0 = std::chrono::steady_clock::now();
  Scene base = load_scene_source(a.source);
  base.cameras.resize(1);
  const Scene accurate_base = base;               // for the comparison of the two models at the end
  base.params.shadow_model = ShadowModel::Paper;  // the paper's figures
  refit_light_frusta(base);
  make_dirs(a.output);
  Context context(a.device);
  Renderer renderer(context, Precision::Float);
  FigureWriter out(a.output);
  save_hard_sweep(renderer, base, out);
  save_soft_shadows(renderer, base, out);
  save_shadow_models(renderer, accurate_base, out);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("figures: files=%d seconds=%.2f dir=%s\n", out.files(), seconds, a.output.c_str());
  return 0;
}

}  // namespace

Command add_figures_command(CLI::App& root) {
  auto args = std::make_shared<FiguresArgs>();
  Command c;
  c.app = root.add_subcommand(
      "figures", "render the documentation's pictures (the paper's Figures 1, 2, 4 and 5)");
  add_scene_options(*c.app, args->source, false);
  c.app->add_option("-o,--output", args->output, "folder for the PNG files")->capture_default_str();
  c.app->add_option("--device", args->device, "OpenCL device (index or part of its name)");
  c.run = [args] { return run_figures(*args); };
  return c;
}

}  // namespace penumbra::cli
