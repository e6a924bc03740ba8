// The options the subcommands share (common.hpp): the scene's source, the render parameters
// and shadow settings that override the scene's, the device's memory limit and precision.
#include <cmath>
#include <cstdlib>
#include <optional>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "common.hpp"
#include "penumbra/error.hpp"

namespace penumbra::cli {

void add_scene_options(CLI::App& cmd, SceneSource& source, bool with_mesh) {
  CLI::Option* scene =
      cmd.add_option("scene", source.scene_path,
                     "scene file (JSON, see docs/scene-format.md); default: the bundled "
                     "data/scenes/turnaround.json");
  if (with_mesh) {
    CLI::Option* mesh =
        cmd.add_option("--mesh", source.mesh_path,
                       "render one mesh file (.obj, .ply, .stl, .gltf, .glb, .off) in a framed "
                       "scene instead of a scene file")
            ->excludes(scene);
    cmd.add_flag("--refuse-degenerate", source.refuse_degenerate,
                 "refuse a --mesh file holding zero-area faces (default: drop them, with a "
                 "warning)")
        ->needs(mesh);
  }
}

namespace {

bool given(const CLI::Option* option) { return option != nullptr && option->count() > 0; }

}  // namespace

CLI::Validator one_of(const std::vector<std::string>& words) {
  std::string list;
  for (size_t i = 0; i < words.size(); ++i)
    list += (i == 0 ? "" : i + 1 == words.size() ? " or " : ", ") + words[i];
  std::string names;
  for (size_t i = 0; i < words.size(); ++i) names += (i ? "|" : "") + words[i];
  return CLI::Validator(
      [words, list](std::string& value) {
        for (const std::string& w : words)
          if (value == w) return std::string();
        return "must be " + list + " (got '" + value + "')";
      },
      names);
}

namespace {
// "shadow model: accurate (what it does) or paper (...)", and the models' map sides, from the
// table of shadow models.
std::string shadow_model_help() {
  std::string help = "shadow model: ";
  const std::vector<ShadowModelTraits>& models = shadow_models();
  for (size_t i = 0; i < models.size(); ++i)
    help += std::string(i == 0                   ? ""
                        : i + 1 == models.size() ? " or "
                                                 : ", ") +
            models[i].word + " (" + models[i].does + ")";
  return help;
}
std::string map_size_help() {
  std::string help = "shadow-map size W_s = H_s in texels (1 to " +
                     std::to_string(kMaxShadowMapSize) + "; default: the model's";
  for (const ShadowModelTraits& m : shadow_models())
    help += ", " + std::to_string(m.map_side) + " " + m.word;
  return help + ")";
}
}  // namespace

CLI::Option* add_shadows_option(CLI::App& cmd, std::string& value, const std::string& help,
                                const std::vector<std::string>& words) {
  return cmd.add_option("--shadows", value, help)
      ->check(words.empty() ? one_of<Shadows>() : one_of(words));
}

CLI::Option* add_shadow_model_option(CLI::App& cmd, std::string& value, const std::string& help) {
  return cmd.add_option("--shadow-model", value, help)->check(one_of<ShadowModel>());
}

void add_render_options(CLI::App& cmd, RenderOptions& o) {
  const std::string group = "Render parameters (override the values of the scene)";
  const std::string shadow_group = "Shadows (override the values of the scene)";
  o.o_shadows = add_shadows_option(cmd, o.shadows,
                                   "shadow mode: none, hard (a point light's sharp shadow) or "
                                   "soft (a sphere light of diameter D_L: penumbrae)")
                    ->group(shadow_group);
  std::vector<std::string> sampling_words;
  std::string sampling_help = "shadow-filter sampling: ";
  for (const SamplingMethod& m : sampling_methods()) {
    sampling_words.push_back(m.word);
    sampling_help +=
        std::string(sampling_words.size() > 1 ? ", " : "") + m.word + " (" + m.sums + ")";
  }
  sampling_words.push_back(gemm_shorthand());
  o.o_sampling =
      cmd.add_option("--sampling", o.sampling,
                     sampling_help + "; gemm: short for --sampling exact --exact-backend clblast")
          ->check(one_of(sampling_words))
          ->group(shadow_group);
  o.o_exact_backend =
      cmd.add_option("--exact-backend", o.exact_backend,
                     "who computes the exact sum of the paper model's hard shadows: auto (the "
                     "tuning's choice for the device), kernels (penumbra's) or clblast "
                     "(CLBlast's GEMM)")
          ->check(one_of<ExactBackend>())
          ->group(shadow_group);
  o.o_shadow_model =
      add_shadow_model_option(cmd, o.shadow_model, shadow_model_help())->group(shadow_group);
  o.o_map_size = cmd.add_option("--map-size", o.map_size, map_size_help())->group(shadow_group);
  o.o_shadow_map = cmd.add_option("--shadow-map", o.shadow_map,
                                  "how every point light's shadows are mapped: auto (a cube where "
                                  "one frustum cannot hold its casters), frustum or cube")
                       ->check(one_of<ShadowMapShape>())
                       ->group(shadow_group);
  o.o_light_size = cmd.add_option("--light-size", o.light_size,
                                  "diameter D_L of every light (world units, >= 0; soft shadows)")
                       ->group(shadow_group);
  o.o_light_sigma = cmd.add_option("--light-sigma", o.light_sigma,
                                   "coverage sharpness σ_L of the light pass, in [0, 1) (0: σ/10)")
                        ->group(shadow_group);
  o.o_light_gamma = cmd.add_option("--light-gamma", o.light_gamma,
                                   "aggregation sharpness γ_L of the light pass, in [0, 1) "
                                   "(0: the same as γ)")
                        ->group(shadow_group);
  o.o_weight_eps = cmd.add_option("--weight-eps", o.weight_eps,
                                  "fragments weighing less than ε_w times the largest are left "
                                  "out of colour and depth (no shadow lookup), in (0, 1)")
                       ->group(shadow_group);
  o.o_sigma =
      cmd.add_option("--sigma", o.sigma, "coverage sharpness σ (screen units², > 0)")->group(group);
  o.o_gamma = cmd.add_option("--gamma", o.gamma, "aggregation sharpness γ (> 0)")->group(group);
  o.o_eps = cmd.add_option("--eps", o.eps, "background depth ε of the aggregation")->group(group);
  o.o_dist_eps =
      cmd.add_option("--dist-eps,--dist_eps", o.dist_eps, "coverage cut-off ε_D, in (0, 1)")
          ->group(group);
  o.o_sigma_s =
      cmd.add_option("--sigma-s", o.sigma_s, "shadow-map Gaussian variance σ_s (texel², > 0)")
          ->group(group);
  o.o_lambda_eps = cmd.add_option("--lambda-eps", o.lambda_eps,
                                  "truncation threshold ε_λ of the shadow filter, in (0, 1)")
                       ->group(group);
  o.o_gamma_s =
      cmd.add_option("--gamma-s", o.gamma_s, "depth-compare softness γ_s (> 0)")->group(group);
  o.o_beta = cmd.add_option("--beta", o.beta, "shadow depth bias β (depth units)")->group(group);
  o.o_gamma_p = cmd.add_option("--gamma-p", o.gamma_p, "penumbra soft-minimum sharpness γ_P (> 0)")
                    ->group(group);
  o.o_width =
      cmd.add_option("--width", o.width, "image width of every camera (pixels)")->group(group);
  o.o_height =
      cmd.add_option("--height", o.height, "image height of every camera (pixels)")->group(group);
  cmd.add_option("--device", o.device,
                 "OpenCL device: index from `penumbra devices` or part of its name "
                 "(default: $PENUMBRA_DEVICE, else the first GPU, else the first device)");
  o.o_max_memory = cmd.add_option("--max-memory", o.max_memory,
                                  "refuse, before allocating, a call estimated to need more "
                                  "device memory than this (e.g. 1GiB, 512MiB; default: all "
                                  "the device has)");
}

size_t parse_bytes(const std::string& text, const std::string& option) {
  static const std::pair<const char*, double> units[] = {{"", 1},
                                                         {"B", 1},
                                                         {"KiB", 1024.0},
                                                         {"MiB", 1048576.0},
                                                         {"GiB", 1073741824.0},
                                                         {"TiB", 1099511627776.0},
                                                         {"kB", 1e3},
                                                         {"KB", 1e3},
                                                         {"MB", 1e6},
                                                         {"GB", 1e9},
                                                         {"TB", 1e12}};
  const char* begin = text.c_str();
  char* end = nullptr;
  const double value = std::strtod(begin, &end);
  std::string unit(end == begin ? "?" : end);
  while (!unit.empty() && unit.front() == ' ') unit.erase(0, 1);
  for (const auto& [name, scale] : units)
    if (unit == name && std::isfinite(value) && value * scale >= 1 && value * scale < 1.8e19)
      return size_t(value * scale);
  throw Error(option + " must be a positive size such as 512MiB, 2GiB or 1e9 (got '" + text + "')");
}

void limit_memory(const RenderOptions& o, Context& context) {
  if (given(o.o_max_memory))
    context.set_memory_limit(parse_bytes(o.max_memory, "--max-memory"), "--max-memory");
}

namespace {

std::string number(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

void require(bool ok, const std::string& option, const std::string& what, double value) {
  if (!ok) throw Error(option + " must be " + what + " (got " + number(value) + ")");
}

// target = value where the command line gave the option, once `ok` (the value's check) holds;
// the error names the option by its first long name.
template <class T, class Target>
void set_if_given(const CLI::Option* option, T value, bool ok, const std::string& what,
                  Target& target) {
  if (!given(option)) return;
  require(ok, "--" + option->get_lnames().at(0), what, value);
  target = value;
}

// The model's scalar parameters: σ, γ, ε, the shadow terms and the light's blur.
void apply_model_numbers(const RenderOptions& o, RenderParams& p) {
  auto positive = [](double v) { return std::isfinite(v) && v > 0; };
  const char* const kPositive = "a positive finite number";
  set_if_given(o.o_sigma, o.sigma, positive(o.sigma), kPositive, p.sigma);
  set_if_given(o.o_gamma, o.gamma, positive(o.gamma), kPositive, p.gamma);
  set_if_given(o.o_eps, o.eps, std::isfinite(o.eps), "a finite number", p.eps);
  set_if_given(o.o_dist_eps, o.dist_eps, positive(o.dist_eps) && o.dist_eps < 1, "in (0, 1)",
               p.dist_eps);
  set_if_given(o.o_sigma_s, o.sigma_s, positive(o.sigma_s), kPositive, p.sigma_s);
  set_if_given(o.o_lambda_eps, o.lambda_eps, positive(o.lambda_eps) && o.lambda_eps < 1,
               "in (0, 1)", p.lambda_eps);
  set_if_given(o.o_gamma_s, o.gamma_s, positive(o.gamma_s), kPositive, p.gamma_s);
  set_if_given(o.o_beta, o.beta, std::isfinite(o.beta), "a finite number", p.beta);
  set_if_given(o.o_gamma_p, o.gamma_p, positive(o.gamma_p), kPositive, p.gamma_p);
  set_if_given(o.o_light_sigma, o.light_sigma,
               std::isfinite(o.light_sigma) && o.light_sigma >= 0 && o.light_sigma < 1,
               "in [0, 1) (0: a tenth of --sigma)", p.light_sigma);
  set_if_given(o.o_light_gamma, o.light_gamma,
               std::isfinite(o.light_gamma) && o.light_gamma >= 0 && o.light_gamma < 1,
               "in [0, 1) (0: the same as --gamma)", p.light_gamma);
  set_if_given(o.o_weight_eps, o.weight_eps, positive(o.weight_eps) && o.weight_eps < 1,
               "in (0, 1)", p.weight_eps);
}

// The words that pick a method: shadows, sampling and its backend, the shadow model.
void apply_method_words(const RenderOptions& o, RenderParams& p) {
  if (given(o.o_shadows)) p.shadows = parse_shadows(o.shadows);
  if (given(o.o_sampling)) {
    std::optional<ExactBackend> implied;  // --sampling gemm
    if (!sampling_from_word(o.sampling, &p.sampling, &implied))
      throw Error("--sampling must be " + sampling_word_choices() + " (got '" + o.sampling + "')");
    if (implied) p.exact_backend = *implied;
  }
  if (given(o.o_exact_backend)) {
    const ExactBackend backend = parse_word<ExactBackend>("--exact-backend", o.exact_backend);
    if (given(o.o_sampling) && o.sampling == gemm_shorthand() && backend != p.exact_backend)
      throw Error("--sampling gemm is exact sampling with --exact-backend clblast, not '" +
                  o.exact_backend + "'");
    p.exact_backend = backend;
  }
  if (given(o.o_shadow_model))
    p.shadow_model = parse_word<ShadowModel>("--shadow-model", o.shadow_model);
}

// Settings each light or camera carries: its shadow map and size, the image size.
void apply_scene_overrides(const RenderOptions& o, Scene& scene) {
  if (given(o.o_shadow_map)) {
    const ShadowMapShape shape = parse_word<ShadowMapShape>("--shadow-map", o.shadow_map);
    for (Light& light : scene.lights)
      if (light.type == LightType::Point) light.shadow_map = shape, light.frustum.fitted = false;
  }
  if (given(o.o_light_size)) {
    require(std::isfinite(o.light_size) && o.light_size >= 0, "--light-size",
            "a non-negative diameter", o.light_size);
    for (Light& light : scene.lights) light.size = o.light_size;
  }
  const std::string pixels =
      "a positive number of pixels (at most " + std::to_string(kMaxImageSize) + ")";
  if (given(o.o_width)) {
    require(o.width > 0 && o.width <= kMaxImageSize, "--width", pixels, o.width);
    for (Camera& cam : scene.cameras) cam.width = o.width;
  }
  if (given(o.o_height)) {
    require(o.height > 0 && o.height <= kMaxImageSize, "--height", pixels, o.height);
    for (Camera& cam : scene.cameras) cam.height = o.height;
  }
}

}  // namespace

void apply_render_options(const RenderOptions& o, Scene& scene) {
  RenderParams& p = scene.params;
  apply_model_numbers(o, p);
  apply_method_words(o, p);
  set_if_given(o.o_map_size, o.map_size, o.map_size >= 1 && o.map_size <= kMaxShadowMapSize,
               "a positive number of texels (at most " + std::to_string(kMaxShadowMapSize) + ")",
               p.shadow_map_size);
  apply_scene_overrides(o, scene);
  validate(scene);
  refit_light_frusta(scene);  // the fit depends on the shadow settings
}

Shadows parse_shadows(const std::string& w) { return parse_word<Shadows>("--shadows", w); }

void add_precision_option(CLI::App& cmd, std::string& precision, const std::string& default_value) {
  precision = default_value;
  cmd.add_option("--precision", precision, "arithmetic of the kernels: float or double")
      ->check(CLI::IsMember({"float", "double"}))
      ->capture_default_str();
}

Precision parse_precision(const std::string& name) {
  if (name == "float") return Precision::Float;
  if (name == "double") return Precision::Double;
  throw Error("--precision must be float or double (got '" + name + "')");
}

}  // namespace penumbra::cli
