// `penumbra render`: renders every camera of a scene to PNG (and optionally .npy arrays).
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

#include "common.hpp"
#include "penumbra/context.hpp"
#include "penumbra/image_io.hpp"
#include "penumbra/io.hpp"
#include "penumbra/renderer.hpp"

namespace fs = std::filesystem;

namespace penumbra::cli {

namespace {

struct RenderArgs {
  SceneSource source;
  RenderOptions render;
  std::string output, raw_dir, precision;
};

// Every file of the render: the PNG of each view, and with --raw the arrays of each view and
// the shadow map S (penumbra map P for soft shadows) of each light. Creates the folders.
std::vector<FileContent> render_files(const RenderArgs& a, const std::vector<RenderOutput>& views,
                                      const Renderer& renderer) {
  std::vector<FileContent> files;
  auto png = [&](const Image& image, const std::string& path) {
    files.push_back({path, png_bytes(image, path), "PNG"});
  };
  auto npy = [&](const Image& image, const std::string& path) {
    files.push_back({path, npy_bytes(image, path), "NumPy file"});
  };
  for (size_t v = 0; v < views.size(); ++v) png(views[v].color, view_path(a.output, v));
  make_parent_dirs(a.output);
  if (a.raw_dir.empty()) return files;
  make_dirs(a.raw_dir);
  for (size_t v = 0; v < views.size(); ++v) {
    npy(views[v].color, view_file(a.raw_dir, "color", v));
    npy(views[v].silhouette, view_file(a.raw_dir, "silhouette", v));
    npy(views[v].depth, view_file(a.raw_dir, "depth", v));
  }
  auto maps = [&](const std::vector<Image>& images, const std::string& stem) {
    for (size_t l = 0; l < images.size(); ++l)
      npy(images[l], (fs::path(a.raw_dir) / (stem + std::to_string(l) + ".npy")).string());
  };
  maps(renderer.shadow_maps(), "shadow_map_");
  maps(renderer.penumbra_maps(), "penumbra_map_");
  return files;
}

// The sampling, and for the paper model's exact hard shadows the exact backend that ran
// ("exact on clblast"; "auto → clblast" when the tuning chose it).
std::string sampling_summary(const RenderParams& p, const Renderer& renderer) {
  std::string s = word(p.sampling);
  if (p.sampling != Sampling::Exact || p.shadows != Shadows::Hard ||
      !shadow_model_traits(p.shadow_model).exact_products)
    return s;
  const std::string used = word(exact_backend_in_force(p, renderer.tuning()));
  return s + " on " + (p.exact_backend == ExactBackend::Auto ? "auto → " + used : used);
}

int run_render(const RenderArgs& a) {
  Scene scene = load_scene_source(a.source);
  apply_render_options(a.render, scene);
  const Precision precision = parse_precision(a.precision);

  Context context(a.render.device);
  limit_memory(a.render, context);
  Renderer renderer(context, precision);
  CallProgress progress("render");
  progress.watch(renderer);
  const auto t0 = std::chrono::steady_clock::now();
  progress.start();
  const std::vector<RenderOutput> views = renderer.render(scene);
  progress.finish();
  const auto t1 = std::chrono::steady_clock::now();
  const double ms = std::chrono::duration<double, std::milli>(t1 - t0).count();

  write_files(render_files(a, views, renderer));
  size_t faces = 0;
  for (const Mesh& m : scene.meshes) faces += m.faces.size();
  const Camera& cam = scene.cameras.front();
  std::string shadows = word(scene.params.shadows);
  if (scene.params.shadows != Shadows::None) {
    const size_t maps = cube_faces(scene.lights, nullptr).size();  // six for a light's cube
    const std::string side = std::to_string(shadow_map_side(scene.params));
    shadows += " (" + word(scene.params.shadow_model) + ", " +
               sampling_summary(scene.params, renderer) + ", " +
               (maps == 1 ? "" : std::to_string(maps) + " ") + side + "x" + side +
               (maps == 1 ? " map)" : " maps)");
  }
  std::printf("rendered %zu view%s, %dx%d, %zu faces, shadows %s, %.1f ms (%s) -> %s%s\n",
              views.size(), views.size() == 1 ? "" : "s", cam.width, cam.height, faces,
              shadows.c_str(), ms, precision == Precision::Double ? "double" : "float",
              a.output.c_str(), views.size() > 1 ? " (+ _k for view k)" : "");
  return 0;
}

}  // namespace

Command add_render_command(CLI::App& root) {
  auto args = std::make_shared<RenderArgs>();
  Command c;
  c.app = root.add_subcommand("render", "render every camera of a scene to PNG");
  add_scene_options(*c.app, args->source);
  c.app->add_option("-o,--output", args->output, "PNG of camera 0; camera k >= 1 goes to OUT_k.png")
      ->required();
  c.app->add_option("--raw", args->raw_dir,
                    "also write DIR/color.npy (H,W,3), silhouette.npy (H,W), depth.npy (H,W) "
                    "as float32 (suffix _k for camera k >= 1), and with shadows on "
                    "shadow_map_<l>.npy (H_s,W_s), the light-view depth map S of shadow map l (six "
                    "for a light's cube), and "
                    "with soft shadows penumbra_map_<l>.npy, its penumbra map P");
  add_precision_option(*c.app, args->precision, "float");
  add_render_options(*c.app, args->render);
  c.run = [args] { return run_render(*args); };
  return c;
}

}  // namespace penumbra::cli
