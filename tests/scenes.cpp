#include "scenes.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>

#include "cli_run.hpp"
#include "penumbra/error.hpp"
#include "penumbra/reference.hpp"

namespace penumbra_tests {

using glm::dvec3;
using namespace penumbra;

Context* shared_context(std::string* error) {
  static std::unique_ptr<Context> context;
  static std::string message;
  static bool tried = false;
  if (!tried) {
    tried = true;
    try {
      context = std::make_unique<Context>();
    } catch (const std::exception& e) {
      message = e.what();
    }
  }
  *error = message;
  return context.get();
}

Renderer& shared_renderer(Context& ctx, Precision precision) {
  static std::map<int, std::unique_ptr<Renderer>> renderers;
  auto& r = renderers[int(precision)];
  if (!r) r = std::make_unique<Renderer>(ctx, precision);
  return *r;
}

const char* name_of(Sampling s) {
  switch (s) {
    case Sampling::Truncated:
      return "truncated";
    case Sampling::Exact:
      return "exact";
  }
  return "?";
}

const char* name_of(Method m) {
  return m == Method::Truncated ? "truncated" : m == Method::Exact ? "exact" : "gemm";
}

void set_method(RenderParams& p, Method m) {
  p.sampling = m == Method::Truncated ? Sampling::Truncated : Sampling::Exact;
  p.exact_backend =
      m == Method::Gemm ? penumbra::ExactBackend::CLBlast : penumbra::ExactBackend::Auto;
}

const char* name_of(Precision p) { return p == Precision::Double ? "double" : "float"; }

Mesh icosphere(dvec3 center, double radius, int levels, const std::string& name,
               const SphereAlbedo& albedo) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<dvec3> v = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0},
                          {0, -1, t}, {0, 1, t}, {0, -1, -t}, {0, 1, -t},
                          {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  for (dvec3& p : v) p = glm::normalize(p);
  std::vector<glm::ivec3> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                               {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                               {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                               {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (int level = 0; level < levels; ++level) {
    std::map<std::pair<int, int>, int> midpoint;
    auto mid = [&](int a, int b) {
      const auto key = std::make_pair(std::min(a, b), std::max(a, b));
      const auto it = midpoint.find(key);
      if (it != midpoint.end()) return it->second;
      v.push_back(glm::normalize(v[size_t(a)] + v[size_t(b)]));
      return midpoint[key] = int(v.size()) - 1;
    };
    std::vector<glm::ivec3> next;
    for (const glm::ivec3& tri : f) {
      const int a = mid(tri.x, tri.y), b = mid(tri.y, tri.z), c = mid(tri.z, tri.x);
      next.push_back({tri.x, a, c});
      next.push_back({tri.y, b, a});
      next.push_back({tri.z, c, b});
      next.push_back({a, b, c});
    }
    f = std::move(next);
  }
  Mesh mesh;
  mesh.name = name;
  const dvec3 g = albedo.gain;
  for (const dvec3& p : v) {
    mesh.vertices.push_back(center + radius * p);
    mesh.albedo.push_back(albedo.base + dvec3(g.x * p.x, g.y * p.y, -g.z * p.z));
  }
  mesh.faces = std::move(f);
  mesh.albedo_mode = AlbedoMode::PerVertex;
  return mesh;
}

Mesh ground(double half, int n, double variation) {
  Mesh mesh;
  mesh.name = "ground";
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      const double x = -half + 2 * half * i / n, z = -half + 2 * half * j / n;
      mesh.vertices.push_back({x, 0.0, z});
      mesh.albedo.push_back({0.7 + variation * x / half, 0.7, 0.7 - variation * z / half});
    }
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i, b = a + 1, c = a + (n + 1), d = c + 1;
      mesh.faces.push_back({a, c, b});  // (c−a)×(b−a) points along +y
      mesh.faces.push_back({b, c, d});
    }
  mesh.albedo_mode = AlbedoMode::PerVertex;
  return mesh;
}

Light point_light(dvec3 position, dvec3 color, double size) {
  Light l;
  l.type = LightType::Point;
  l.position = position;
  l.color = color;
  l.size = size;
  return l;
}

Light directional_light(dvec3 direction, dvec3 color, double size) {
  Light l;
  l.type = LightType::Directional;
  l.direction = direction;
  l.color = color;
  l.size = size;
  return l;
}

Camera front_camera(bool ortho, double scale) {
  Camera cam;
  cam.eye = dvec3(0.6, 3.2, 4.6) * scale;
  cam.target = dvec3(0.0, 0.3, 0.0) * scale;
  cam.up = {0, 1, 0};
  cam.projection = ortho ? Projection::Orthographic : Projection::Perspective;
  cam.fov_deg = 48.0;
  cam.half_height = 2.4 * scale;
  cam.near = 0.5 * scale;
  cam.far = 12.0 * scale;
  cam.width = 48;
  cam.height = 40;
  return cam;
}

void shadow_params(Scene& s, penumbra::Shadows shadows, Sampling sampling,
                   penumbra::ShadowModel model) {
  s.ambient = {0.2, 0.2, 0.2};
  s.background = {0.3, 0.35, 0.4};
  auto& p = s.params;
  p.sigma = 3e-4;
  p.gamma = 3e-3;
  p.shadows = shadows;
  p.sampling = sampling;
  p.shadow_model = model;
  p.shadow_map_size = 32;
  p.sigma_s = 2.0;
  p.lambda_eps = 1e-3;
  p.gamma_s = 0.04;
  p.beta = 0.2;
}

void shadow_params(Scene& s, penumbra::Shadows shadows, Method method,
                   penumbra::ShadowModel model) {
  shadow_params(s, shadows, Sampling::Truncated, model);
  set_method(s.params, method);
}

size_t count_non_finite(const Image& img) {
  size_t bad = 0;
  for (double v : img.data) bad += std::isfinite(v) ? 0 : 1;
  return bad;
}

std::pair<int, int> pixel_of(const Camera& cam, dvec3 X) {
  const dvec3 f = glm::normalize(cam.target - cam.eye);
  const dvec3 r = glm::normalize(glm::cross(f, cam.up));
  const dvec3 u = glm::cross(r, f);
  const dvec3 c = X - cam.eye;
  const double k = cam.projection == Projection::Perspective
                       ? 1.0 / (glm::dot(c, f) * std::tan(glm::radians(cam.fov_deg) / 2))
                       : 1.0 / cam.half_height;
  const double x = glm::dot(c, r) * k, y = glm::dot(c, u) * k;
  const double px = (x * cam.height + cam.width - 1) / 2;
  const double py = (cam.height - 1 - y * cam.height) / 2;
  return {int(std::lround(px)), int(std::lround(py))};
}

void expect_finite(const Image& img, const std::string& what) {
  const size_t bad = count_non_finite(img);
  EXPECT_EQ(bad, 0u) << what << ": " << bad << " non-finite values";
}

double max_error(const Image& got, const Image& want, bool relative, std::string* where) {
  double worst = 0.0;
  size_t worst_i = 0;
  for (size_t i = 0; i < got.data.size() && i < want.data.size(); ++i) {
    double err = std::abs(got.data[i] - want.data[i]);
    if (relative) err /= std::max(std::abs(want.data[i]), 1e-300);
    if (!(err <= worst)) {
      worst = err;
      worst_i = i;
    }
  }
  if (where && !got.data.empty()) {
    const size_t pixel = worst_i / size_t(got.channels);
    std::ostringstream s;
    s << "(x=" << pixel % size_t(got.width) << ", y=" << pixel / size_t(got.width)
      << ", c=" << worst_i % size_t(got.channels) << "): got " << got.data[worst_i] << ", want "
      << (worst_i < want.data.size() ? want.data[worst_i] : NAN);
    *where = s.str();
  }
  return worst;
}

double expect_close(const Image& got, const Image& want, double tol, bool relative,
                    const std::string& what) {
  EXPECT_EQ(got.width, want.width) << what;
  EXPECT_EQ(got.height, want.height) << what;
  EXPECT_EQ(got.channels, want.channels) << what;
  EXPECT_EQ(got.data.size(), want.data.size()) << what;
  expect_finite(got, what);
  std::string where;
  const double err = max_error(got, want, relative, &where);
  EXPECT_LE(err, tol) << what << ": worst at " << where;
  return err;
}

double expect_matches_reference(Renderer& renderer, const Scene& scene, Tolerance tol,
                                const std::string& name) {
  std::vector<RenderOutput> got;
  EXPECT_NO_THROW(got = renderer.render(scene)) << name;
  EXPECT_EQ(got.size(), scene.cameras.size()) << name;
  double worst = 0;
  for (size_t v = 0; v < got.size() && v < scene.cameras.size(); ++v) {
    const RenderOutput want = penumbra::reference::render(scene, v);
    const std::string tag = name + " view " + std::to_string(v);
    const Camera& cam = scene.cameras[v];
    EXPECT_EQ(got[v].color.width, cam.width) << tag;
    EXPECT_EQ(got[v].color.height, cam.height) << tag;
    EXPECT_EQ(got[v].color.channels, 3) << tag;
    EXPECT_EQ(got[v].silhouette.channels, 1) << tag;
    EXPECT_EQ(got[v].depth.channels, 1) << tag;
    expect_finite(want.color, tag + " reference colour");
    worst =
        std::max(worst, expect_close(got[v].color, want.color, tol.color, false, tag + " colour"));
    expect_close(got[v].silhouette, want.silhouette, tol.silhouette, false, tag + " silhouette");
    expect_close(got[v].depth, want.depth, tol.depth_rel, true, tag + " depth");
  }
  return worst;
}

std::string describe(const penumbra::GradCheckResult& r) {
  std::ostringstream s;
  s << "checked=" << r.checked << " failed=" << r.failed << " max_rel_err=" << r.max_rel_err
    << " atol=" << r.atol << " rtol=" << r.rtol << "\n";
  for (const auto& e : r.entries)
    s << "  " << e.name << " analytic=" << e.analytic << " numeric=" << e.numeric
      << " rel_err=" << e.rel_err << (e.ok ? "" : "  FAIL") << "\n";
  return s.str();
}

bool has_entry(const penumbra::GradCheckResult& r, const std::string& prefix) {
  for (const auto& e : r.entries)
    if (e.name.compare(0, prefix.size(), prefix) == 0) return true;
  return false;
}

namespace {

bool same_bits(const std::vector<dvec3>& a, const std::vector<dvec3>& b) {
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(dvec3)) == 0);
}

}  // namespace

void expect_identical(const penumbra::SceneGrads& a, const penumbra::SceneGrads& b,
                      const std::string& what, bool with_light_size) {
  ASSERT_EQ(a.vertices.size(), b.vertices.size()) << what;
  for (size_t m = 0; m < a.vertices.size(); ++m) {
    EXPECT_TRUE(same_bits(a.vertices[m], b.vertices[m])) << what << " mesh " << m << " vertices";
    EXPECT_TRUE(same_bits(a.albedo[m], b.albedo[m])) << what << " mesh " << m << " albedo";
  }
  EXPECT_TRUE(same_bits(a.light_position, b.light_position)) << what << " light positions";
  EXPECT_TRUE(same_bits(a.light_color, b.light_color)) << what << " light colours";
  EXPECT_TRUE(same_bits({a.ambient}, {b.ambient})) << what << " ambient";
  if (!with_light_size) return;
  ASSERT_EQ(a.light_size.size(), b.light_size.size()) << what;
  EXPECT_TRUE(a.light_size.empty() || std::memcmp(a.light_size.data(), b.light_size.data(),
                                                  a.light_size.size() * sizeof(double)) == 0)
      << what << " light sizes";
}

std::string fresh_temp_dir(const std::string& name) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::path(::testing::TempDir()) / ("penumbra_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir.string();
}

std::vector<std::string> names_in(const std::string& dir) {
  std::vector<std::string> names;
  for (const auto& entry : std::filesystem::directory_iterator(dir))
    names.push_back(entry.path().filename());
  std::sort(names.begin(), names.end());
  return names;
}

std::string error_of(const std::function<void()>& fn) {
  try {
    fn();
  } catch (const penumbra::Error& e) {
    return e.what();
  }
  return "";
}

std::string patched_kernels(const std::string& name, const std::string& file,
                            const std::string& from, const std::string& to) {
  return patched_kernels(name, {{file, from, to}});
}

std::string patched_kernels(const std::string& name, const std::vector<KernelEdit>& edits) {
  namespace fs = std::filesystem;
  fs::path dir = fs::path(::testing::TempDir()) / name;
  fs::remove_all(dir);
  fs::copy(fs::path(PENUMBRA_DATA_DIR).parent_path() / "kernels", dir, fs::copy_options::recursive);
  for (const auto& [file, from, to] : edits) {
    std::string text = read_text((dir / file).string());
    const size_t at = text.find(from);
    EXPECT_NE(at, std::string::npos) << file << " no longer holds: " << from;
    if (at != std::string::npos) text.replace(at, from.size(), to);
    std::ofstream out(dir / file, std::ios::trunc);
    out << text;
    EXPECT_TRUE(out.flush().good()) << "cannot write " << (dir / file).string();
  }
  return dir.string();
}

Results results_with(const std::string& kernel_dir, const Scene& scene, Precision p,
                     const std::vector<OutputGrads>& weights) {
  ScopedEnv env("PENUMBRA_KERNEL_DIR", kernel_dir.empty() ? nullptr : kernel_dir.c_str());
  Context ctx;
  Renderer r(ctx, p);
  Results out{r.render(scene), {}};
  out.grads = r.backward(scene, weights);
  return out;
}

SceneGrads grads_with(const std::string& kernel_dir, const Scene& scene, Precision p,
                      const std::vector<OutputGrads>& weights) {
  return results_with(kernel_dir, scene, p, weights).grads;
}

bool same_images(const std::vector<RenderOutput>& a, const std::vector<RenderOutput>& b) {
  if (a.size() != b.size()) return false;
  for (size_t v = 0; v < a.size(); ++v)
    if (a[v].color.data != b[v].color.data || a[v].silhouette.data != b[v].silhouette.data ||
        a[v].depth.data != b[v].depth.data)
      return false;
  return true;
}

bool finite_image(const Image& im) {
  return std::all_of(im.data.begin(), im.data.end(), [](double v) { return std::isfinite(v); });
}

void clear_left_half(Image& im) {
  for (int y = 0; y < im.height; ++y)
    for (int x = 0; x < im.width / 2; ++x)
      for (int c = 0; c < im.channels; ++c) im.at(x, y, c) = 0;
}

bool all_finite(const SceneGrads& g) {
  for (const auto& mesh : g.vertices)
    for (const auto& v : mesh)
      if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z)) return false;
  return true;
}

std::string kernels_looking_up_every_fragment(const std::string& name) {
  return patched_kernels(name, "common/window.clh", "rec_shade[r * (1 + nl) + 1 + light].w == 0",
                         "0");
}

void expect_skip_changes_no_bit(const std::string& looking_up, const Scene& scene, Precision p,
                                const std::string& what) {
  const auto weights = random_loss_weights(scene, 11);
  const Results a = results_with("", scene, p, weights),
                b = results_with(looking_up, scene, p, weights);
  EXPECT_TRUE(same_images(a.images, b.images)) << what;
  expect_identical(a.grads, b.grads, what + ": lookups skipped or not", true);
}

void expect_skip_taken(const std::string& poisoned, const Scene& scene, const std::string& what) {
  const auto weights = random_loss_weights(scene, 11);
  EXPECT_TRUE(finite_image(results_with("", scene, Precision::Float, weights).images[0].color))
      << what;
  EXPECT_FALSE(
      finite_image(results_with(poisoned, scene, Precision::Float, weights).images[0].color))
      << what << ": no lookup was skipped";
}

}  // namespace penumbra_tests
