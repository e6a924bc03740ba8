#include "common.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <utility>
#include <vector>

#include <unistd.h>

#include "penumbra/error.hpp"
#include "penumbra/io.hpp"

namespace fs = std::filesystem;

namespace penumbra::cli {

void add_scene_options(CLI::App& cmd, SceneSource& source, bool with_mesh) {
  CLI::Option* scene =
      cmd.add_option("scene", source.scene_path,
                     "scene file (JSON, see docs/scene-format.md); default: the bundled "
                     "data/scenes/turnaround.json");
  if (with_mesh) {
    cmd.add_option("--mesh", source.mesh_path,
                   "render one OBJ mesh in a framed scene instead of a scene file")
        ->excludes(scene);
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
  std::string help = "shadow-map size W_s = H_s in texels (1 to 8192; default: the model's";
  for (const ShadowModelTraits& m : shadow_models())
    help += ", " + std::to_string(m.map_side) + " " + m.word;
  return help + ")";
}
}  // namespace

void add_render_options(CLI::App& cmd, RenderOptions& o) {
  const std::string group = "Render parameters (override the values of the scene)";
  const std::string shadow_group = "Shadows (override the values of the scene)";
  o.o_shadows = cmd.add_option("--shadows", o.shadows,
                               "shadow mode: none, hard (a point light's sharp shadow) or soft "
                               "(a sphere light of diameter D_L: penumbrae)")
                    ->check(one_of<Shadows>())
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
  o.o_shadow_model = cmd.add_option("--shadow-model", o.shadow_model, shadow_model_help())
                         ->check(one_of<ShadowModel>())
                         ->group(shadow_group);
  o.o_map_size = cmd.add_option("--map-size", o.map_size, map_size_help())->group(shadow_group);
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

}  // namespace

void apply_render_options(const RenderOptions& o, Scene& scene) {
  RenderParams& p = scene.params;
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
  set_if_given(o.o_map_size, o.map_size, o.map_size >= 1 && o.map_size <= 8192,
               "a positive number of texels (at most 8192)", p.shadow_map_size);
  if (given(o.o_light_size)) {
    require(std::isfinite(o.light_size) && o.light_size >= 0, "--light-size",
            "a non-negative diameter", o.light_size);
    for (Light& light : scene.lights) light.size = o.light_size;
  }
  set_if_given(o.o_light_sigma, o.light_sigma,
               std::isfinite(o.light_sigma) && o.light_sigma >= 0 && o.light_sigma < 1,
               "in [0, 1) (0: a tenth of --sigma)", p.light_sigma);
  set_if_given(o.o_light_gamma, o.light_gamma,
               std::isfinite(o.light_gamma) && o.light_gamma >= 0 && o.light_gamma < 1,
               "in [0, 1) (0: the same as --gamma)", p.light_gamma);
  set_if_given(o.o_weight_eps, o.weight_eps, positive(o.weight_eps) && o.weight_eps < 1,
               "in (0, 1)", p.weight_eps);
  constexpr int kMaxSize = 16384;
  if (given(o.o_width)) {
    require(o.width > 0 && o.width <= kMaxSize, "--width",
            "a positive number of pixels (at most " + std::to_string(kMaxSize) + ")", o.width);
    for (Camera& cam : scene.cameras) cam.width = o.width;
  }
  if (given(o.o_height)) {
    require(o.height > 0 && o.height <= kMaxSize, "--height",
            "a positive number of pixels (at most " + std::to_string(kMaxSize) + ")", o.height);
    for (Camera& cam : scene.cameras) cam.height = o.height;
  }
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

std::string data_dir() {
  if (const char* env = std::getenv("PENUMBRA_DATA_DIR"); env != nullptr && *env != '\0')
    return env;
#ifdef PENUMBRA_BIN_TO_DATA_DIR
  {  // an installed tool: <prefix>/bin/penumbra and <prefix>/share/penumbra
    std::error_code ec;
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    const fs::path installed = exe.parent_path() / PENUMBRA_BIN_TO_DATA_DIR;
    if (!ec && fs::is_directory(installed / "scenes", ec)) return installed.lexically_normal();
  }
#endif
#ifdef PENUMBRA_SOURCE_DIR
  {
    std::string compiled = std::string(PENUMBRA_SOURCE_DIR) + "/data";
    std::error_code ec;
    if (fs::is_directory(compiled, ec)) return compiled;
  }
#endif
  return "data";
}

std::string default_scene_path() { return data_dir() + "/scenes/turnaround.json"; }

Scene load_scene_source(const SceneSource& source) {
  if (!source.mesh_path.empty()) return framed_scene(load_obj(source.mesh_path));
  std::string path = source.scene_path;
  if (path.empty()) {
    path = default_scene_path();
    std::error_code ec;
    if (!fs::exists(path, ec)) {
      throw Error("the bundled scene " + path +
                  " was not found; set PENUMBRA_DATA_DIR to the data folder or name a scene");
    }
  }
  return load_scene(path);
}

std::string view_path(const std::string& path, size_t view) {
  if (view == 0) return path;
  const fs::path p(path);
  return (p.parent_path() /
          (p.stem().string() + "_" + std::to_string(view) + p.extension().string()))
      .string();
}

std::string view_file(const std::string& dir, const std::string& stem, size_t view) {
  const std::string name = view == 0 ? stem + ".npy" : stem + "_" + std::to_string(view) + ".npy";
  return (fs::path(dir) / name).string();
}

void make_dirs(const std::string& dir) {
  if (dir.empty()) return;
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir)) {
    throw Error("cannot create the folder " + dir + (ec ? ": " + ec.message() : std::string()));
  }
}

void make_parent_dirs(const std::string& file) { make_dirs(fs::path(file).parent_path().string()); }

std::string cl_error_name(int code) {
#define PENUMBRA_CL_CODE(name) \
  case name:                   \
    return #name;
  switch (code) {
    PENUMBRA_CL_CODE(CL_SUCCESS)
    PENUMBRA_CL_CODE(CL_DEVICE_NOT_FOUND)
    PENUMBRA_CL_CODE(CL_DEVICE_NOT_AVAILABLE)
    PENUMBRA_CL_CODE(CL_COMPILER_NOT_AVAILABLE)
    PENUMBRA_CL_CODE(CL_MEM_OBJECT_ALLOCATION_FAILURE)
    PENUMBRA_CL_CODE(CL_OUT_OF_RESOURCES)
    PENUMBRA_CL_CODE(CL_OUT_OF_HOST_MEMORY)
    PENUMBRA_CL_CODE(CL_PROFILING_INFO_NOT_AVAILABLE)
    PENUMBRA_CL_CODE(CL_MEM_COPY_OVERLAP)
    PENUMBRA_CL_CODE(CL_IMAGE_FORMAT_MISMATCH)
    PENUMBRA_CL_CODE(CL_IMAGE_FORMAT_NOT_SUPPORTED)
    PENUMBRA_CL_CODE(CL_BUILD_PROGRAM_FAILURE)
    PENUMBRA_CL_CODE(CL_MAP_FAILURE)
    PENUMBRA_CL_CODE(CL_MISALIGNED_SUB_BUFFER_OFFSET)
    PENUMBRA_CL_CODE(CL_EXEC_STATUS_ERROR_FOR_EVENTS_IN_WAIT_LIST)
    PENUMBRA_CL_CODE(CL_COMPILE_PROGRAM_FAILURE)
    PENUMBRA_CL_CODE(CL_LINKER_NOT_AVAILABLE)
    PENUMBRA_CL_CODE(CL_LINK_PROGRAM_FAILURE)
    PENUMBRA_CL_CODE(CL_DEVICE_PARTITION_FAILED)
    PENUMBRA_CL_CODE(CL_KERNEL_ARG_INFO_NOT_AVAILABLE)
    PENUMBRA_CL_CODE(CL_INVALID_VALUE)
    PENUMBRA_CL_CODE(CL_INVALID_DEVICE_TYPE)
    PENUMBRA_CL_CODE(CL_INVALID_PLATFORM)
    PENUMBRA_CL_CODE(CL_INVALID_DEVICE)
    PENUMBRA_CL_CODE(CL_INVALID_CONTEXT)
    PENUMBRA_CL_CODE(CL_INVALID_QUEUE_PROPERTIES)
    PENUMBRA_CL_CODE(CL_INVALID_COMMAND_QUEUE)
    PENUMBRA_CL_CODE(CL_INVALID_HOST_PTR)
    PENUMBRA_CL_CODE(CL_INVALID_MEM_OBJECT)
    PENUMBRA_CL_CODE(CL_INVALID_IMAGE_FORMAT_DESCRIPTOR)
    PENUMBRA_CL_CODE(CL_INVALID_IMAGE_SIZE)
    PENUMBRA_CL_CODE(CL_INVALID_SAMPLER)
    PENUMBRA_CL_CODE(CL_INVALID_BINARY)
    PENUMBRA_CL_CODE(CL_INVALID_BUILD_OPTIONS)
    PENUMBRA_CL_CODE(CL_INVALID_PROGRAM)
    PENUMBRA_CL_CODE(CL_INVALID_PROGRAM_EXECUTABLE)
    PENUMBRA_CL_CODE(CL_INVALID_KERNEL_NAME)
    PENUMBRA_CL_CODE(CL_INVALID_KERNEL_DEFINITION)
    PENUMBRA_CL_CODE(CL_INVALID_KERNEL)
    PENUMBRA_CL_CODE(CL_INVALID_ARG_INDEX)
    PENUMBRA_CL_CODE(CL_INVALID_ARG_VALUE)
    PENUMBRA_CL_CODE(CL_INVALID_ARG_SIZE)
    PENUMBRA_CL_CODE(CL_INVALID_KERNEL_ARGS)
    PENUMBRA_CL_CODE(CL_INVALID_WORK_DIMENSION)
    PENUMBRA_CL_CODE(CL_INVALID_WORK_GROUP_SIZE)
    PENUMBRA_CL_CODE(CL_INVALID_WORK_ITEM_SIZE)
    PENUMBRA_CL_CODE(CL_INVALID_GLOBAL_OFFSET)
    PENUMBRA_CL_CODE(CL_INVALID_EVENT_WAIT_LIST)
    PENUMBRA_CL_CODE(CL_INVALID_EVENT)
    PENUMBRA_CL_CODE(CL_INVALID_OPERATION)
    PENUMBRA_CL_CODE(CL_INVALID_GL_OBJECT)
    PENUMBRA_CL_CODE(CL_INVALID_BUFFER_SIZE)
    PENUMBRA_CL_CODE(CL_INVALID_MIP_LEVEL)
    PENUMBRA_CL_CODE(CL_INVALID_GLOBAL_WORK_SIZE)
    PENUMBRA_CL_CODE(CL_INVALID_PROPERTY)
    PENUMBRA_CL_CODE(CL_INVALID_IMAGE_DESCRIPTOR)
    PENUMBRA_CL_CODE(CL_INVALID_COMPILER_OPTIONS)
    PENUMBRA_CL_CODE(CL_INVALID_LINKER_OPTIONS)
    PENUMBRA_CL_CODE(CL_INVALID_DEVICE_PARTITION_COUNT)
    // OpenCL 2.x codes, by value: the headers define them only for newer target versions.
    case -69:
      return "CL_INVALID_PIPE_SIZE";
    case -70:
      return "CL_INVALID_DEVICE_QUEUE";
    case -71:
      return "CL_INVALID_SPEC_ID";
    case -72:
      return "CL_MAX_SIZE_RESTRICTION_EXCEEDED";
    case -1001:
      return "CL_PLATFORM_NOT_FOUND_KHR";
    default:
      break;
  }
#undef PENUMBRA_CL_CODE
  return "CL_ERROR(" + std::to_string(code) + ")";
}

std::string joined(const std::vector<std::string>& words) {
  std::string out;
  for (const std::string& w : words) out += (out.empty() ? "" : ",") + w;
  return out;
}

std::string one_line(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (char c : text) {
    if (c == '\r') continue;
    if (c == '\n') {
      if (!out.empty() && out.back() != ' ') out += "; ";
      continue;
    }
    out += c;
  }
  while (!out.empty() && (out.back() == ' ' || out.back() == ';')) out.pop_back();
  return out;
}

Camera orbit(const Camera& camera, double angle) {
  const double c = std::cos(angle), s = std::sin(angle);
  auto turn = [&](const glm::dvec3& v) {
    return glm::dvec3(c * v.x + s * v.z, v.y, -s * v.x + c * v.z);
  };
  Camera out = camera;
  out.eye = camera.target + turn(camera.eye - camera.target);
  out.up = turn(camera.up);
  return out;
}

}  // namespace penumbra::cli
