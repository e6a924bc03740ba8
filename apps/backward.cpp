// `penumbra backward`: renders a scene, reads dL/d(outputs) from .npy files and writes the
// gradients with respect to vertices, albedo, lights and ambient as float64 .npy files.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <set>

#include "common.hpp"
#include "penumbra/context.hpp"
#include "penumbra/error.hpp"
#include "penumbra/io.hpp"
#include "penumbra/renderer.hpp"

namespace fs = std::filesystem;

namespace penumbra::cli {

namespace {

struct BackwardArgs {
  SceneSource source;
  RenderOptions render;
  std::string grad_in, output, precision;
};

std::string shape_of(int height, int width, int channels) {
  std::string s = "(" + std::to_string(height) + ", " + std::to_string(width);
  if (channels != 1) s += ", " + std::to_string(channels);
  return s + ")";
}

const char* const kGradStems[] = {"color", "silhouette", "depth"};

// Every file --grad-in may hold for a scene of `views` cameras: color.npy, silhouette.npy,
// depth.npy, then the same with _k for camera k >= 1.
std::vector<std::string> expected_grad_names(size_t views) {
  std::vector<std::string> names;
  for (size_t v = 0; v < views; ++v)
    for (const char* stem : kGradStems) names.push_back(fs::path(view_file("", stem, v)).string());
  return names;
}

// Throws when the folder holds anything that is not the gradient of an output of the scene (a
// misspelt name, a camera the scene does not have), which would otherwise be read as zero.
void check_grad_names(const std::string& dir, size_t views) {
  const std::vector<std::string> expected = expected_grad_names(views);
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (std::find(expected.begin(), expected.end(), name) != expected.end()) continue;
    std::string list;
    for (const std::string& e : expected) list += (list.empty() ? "" : ", ") + e;
    throw Error("--grad-in: " + it->path().string() + " matches no output of the scene (" +
                std::to_string(views) + " camera" + (views == 1 ? "" : "s") + "; expected " + list +
                ")");
  }
  if (ec) throw Error("--grad-in: cannot list " + dir + ": " + ec.message());
}

// "[i, j]" or "[i, j, c]": the position of flat index `i` in an (H, W, C) array.
std::string index_of(const Image& image, size_t i) {
  const size_t c = size_t(image.channels), w = size_t(image.width);
  std::string s = "[" + std::to_string(i / c / w) + ", " + std::to_string(i / c % w);
  if (c != 1) s += ", " + std::to_string(i % c);
  return s + "]";
}

// The gradient image of one output, or an empty image (zero gradient) if the file is missing.
Image read_grad(const std::string& dir, const std::string& stem, size_t view, const Camera& cam,
                int channels) {
  const std::string path = view_file(dir, stem, view);
  std::error_code ec;
  if (!fs::exists(path, ec)) return Image();
  Image image = load_npy(path);
  if (image.width != cam.width || image.height != cam.height || image.channels != channels) {
    throw Error(path + ": expected shape " + shape_of(cam.height, cam.width, channels) +
                " to match the render of camera " + std::to_string(view) + ", got " +
                shape_of(image.height, image.width, image.channels));
  }
  for (size_t i = 0; i < image.data.size(); ++i)
    if (!std::isfinite(image.data[i]))
      throw Error(path + ": value " +
                  (std::isnan(image.data[i]) ? "NaN"
                   : image.data[i] > 0       ? "inf"
                                             : "-inf") +
                  " at index " + index_of(image, i) + " is not finite; gradients must be finite");
  return image;
}

// File-name-safe, unique names for the meshes ("mesh<i>" when a mesh has no name).
std::vector<std::string> mesh_file_names(const Scene& scene) {
  std::vector<std::string> names;
  std::set<std::string> used;
  for (size_t i = 0; i < scene.meshes.size(); ++i) {
    std::string name;
    for (char c : scene.meshes[i].name) {
      const bool ok =
          std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == '.';
      name += ok ? c : '_';
    }
    if (name.empty() || name.front() == '.') name = "mesh" + std::to_string(i);
    if (used.count(name)) name += "_" + std::to_string(i);
    used.insert(name);
    names.push_back(name);
  }
  return names;
}

std::vector<double> flatten(const std::vector<glm::dvec3>& values) {
  std::vector<double> out;
  out.reserve(values.size() * 3);
  for (const auto& v : values) out.insert(out.end(), {v.x, v.y, v.z});
  return out;
}

// The gradient files: vertices_<mesh>.npy and albedo_<mesh>.npy per mesh, lights.npy (L, 7),
// ambient.npy, all float64.
std::vector<FileContent> gradient_files(const std::string& dir, const Scene& scene,
                                        const SceneGrads& g) {
  std::vector<FileContent> files;
  auto npy = [&](const std::vector<double>& values, size_t rows, size_t cols,
                 const std::string& name) {
    const std::string path = (fs::path(dir) / name).string();
    files.push_back({path, npy_bytes(values, rows, cols, path, true), "NumPy file"});
  };
  const std::vector<std::string> names = mesh_file_names(scene);
  for (size_t m = 0; m < scene.meshes.size(); ++m) {
    const std::vector<glm::dvec3> none;
    const auto& gv = m < g.vertices.size() ? g.vertices[m] : none;
    const auto& ga = m < g.albedo.size() ? g.albedo[m] : none;
    npy(flatten(gv), gv.size(), 3, "vertices_" + names[m] + ".npy");
    npy(flatten(ga), ga.size(), 3, "albedo_" + names[m] + ".npy");
  }
  std::vector<double> lights;
  for (size_t l = 0; l < scene.lights.size(); ++l) {
    const glm::dvec3 p = l < g.light_position.size() ? g.light_position[l] : glm::dvec3(0.0);
    const glm::dvec3 c = l < g.light_color.size() ? g.light_color[l] : glm::dvec3(0.0);
    const double size = l < g.light_size.size() ? g.light_size[l] : 0.0;
    lights.insert(lights.end(), {p.x, p.y, p.z, c.x, c.y, c.z, size});
  }
  npy(lights, scene.lights.size(), 7, "lights.npy");
  npy({g.ambient.x, g.ambient.y, g.ambient.z}, 1, 3, "ambient.npy");
  return files;
}

int run_backward(const BackwardArgs& a) {
  Scene scene = load_scene_source(a.source);
  apply_render_options(a.render, scene);
  const Precision precision = parse_precision(a.precision);
  std::error_code ec;
  if (!fs::is_directory(a.grad_in, ec)) throw Error("--grad-in: " + a.grad_in + " is not a folder");

  // Read (and check) the incoming gradients before any device work.
  check_grad_names(a.grad_in, scene.cameras.size());
  std::vector<OutputGrads> grads(scene.cameras.size());
  for (size_t v = 0; v < scene.cameras.size(); ++v) {
    const Camera& cam = scene.cameras[v];
    grads[v].color = read_grad(a.grad_in, "color", v, cam, 3);
    grads[v].silhouette = read_grad(a.grad_in, "silhouette", v, cam, 1);
    grads[v].depth = read_grad(a.grad_in, "depth", v, cam, 1);
  }

  Context context(a.render.device);
  limit_memory(a.render, context);
  Renderer renderer(context, precision);
  CallProgress progress("backward");
  progress.watch(renderer);
  renderer.render(scene);
  progress.start();
  const SceneGrads g = renderer.backward(scene, grads);
  progress.finish();

  make_dirs(a.output);
  write_files(gradient_files(a.output, scene, g));

  std::printf("wrote gradients of %zu mesh%s, %zu light%s and ambient to %s\n", scene.meshes.size(),
              scene.meshes.size() == 1 ? "" : "es", scene.lights.size(),
              scene.lights.size() == 1 ? "" : "s", a.output.c_str());
  return 0;
}

}  // namespace

Command add_backward_command(CLI::App& root) {
  auto args = std::make_shared<BackwardArgs>();
  Command c;
  c.app = root.add_subcommand(
      "backward",
      "render, then back-propagate dL/d(outputs) read from --grad-in to the scene parameters");
  add_scene_options(*c.app, args->source);
  c.app
      ->add_option("--grad-in", args->grad_in,
                   "folder with color.npy (H,W,3), silhouette.npy (H,W), depth.npy (H,W) "
                   "(suffix _k for camera k >= 1); a missing file means zero gradient; other "
                   "files and non-finite values are errors")
      ->required();
  c.app
      ->add_option("-o,--output", args->output,
                   "folder for vertices_<mesh>.npy (N,3), albedo_<mesh>.npy, lights.npy (L,7: "
                   "position or direction, colour, size D_L), ambient.npy (1,3), float64")
      ->required();
  add_precision_option(*c.app, args->precision, "float");
  add_render_options(*c.app, args->render);
  c.run = [args] { return run_backward(*args); };
  return c;
}

}  // namespace penumbra::cli
