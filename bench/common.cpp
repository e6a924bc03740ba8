// Shared pieces of the benchmark suite (see common.hpp).
#include "common.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>

#include <sys/resource.h>

#include "penumbra/error.hpp"
#include "penumbra/io.hpp"

namespace penumbra::bench {

// ---- icosphere -------------------------------------------------------------------------------

Mesh icosphere(int n, glm::dvec3 center, double radius, glm::dvec3 albedo) {
  if (n < 1) throw Error("icosphere frequency must be ≥ 1");
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  const std::array<glm::dvec3, 12> base = {{{-1, t, 0},
                                            {1, t, 0},
                                            {-1, -t, 0},
                                            {1, -t, 0},
                                            {0, -1, t},
                                            {0, 1, t},
                                            {0, -1, -t},
                                            {0, 1, -t},
                                            {t, 0, -1},
                                            {t, 0, 1},
                                            {-t, 0, -1},
                                            {-t, 0, 1}}};
  const int ico[20][3] = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                          {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                          {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                          {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  Mesh m;
  m.name = "sphere";
  // A grid point is identified by its weights on the icosahedron's corners: (corner, weight)
  // pairs with non-zero weight, sorted by corner, so points on shared edges and corners are
  // created once and with identical coordinates from every face that holds them.
  std::map<std::array<int, 6>, int> index;
  auto point = [&](const int f[3], int i, int j) {
    std::array<std::pair<int, int>, 3> w = {{{f[0], n - i - j}, {f[1], i}, {f[2], j}}};
    std::sort(w.begin(), w.end());
    std::array<int, 6> key = {-1, 0, -1, 0, -1, 0};
    glm::dvec3 p(0.0);
    int k = 0;
    for (auto [corner, weight] : w)
      if (weight > 0) {
        key[2 * k] = corner;
        key[2 * k + 1] = weight;
        ++k;
        p += double(weight) * base[corner];
      }
    auto it = index.find(key);
    if (it != index.end()) return it->second;
    const int id = int(m.vertices.size());
    m.vertices.push_back(center + radius * glm::normalize(p));
    index.emplace(key, id);
    return id;
  };
  for (const auto& f : ico)
    for (int i = 0; i < n; ++i)
      for (int j = 0; i + j < n; ++j) {
        const int a = point(f, i, j), b = point(f, i + 1, j), c = point(f, i, j + 1);
        m.faces.push_back({a, b, c});
        if (i + j + 1 < n) m.faces.push_back({b, point(f, i + 1, j + 1), c});
      }
  m.albedo.assign(m.vertices.size(), albedo);
  m.albedo_mode = AlbedoMode::PerVertex;
  return m;
}

int icosphere_frequency_for(int faces) {
  int n = 1;
  while (20 * n * n < faces) ++n;
  return n;
}

bool parse_int(const std::string& text, int lo, int hi, int* out) {
  std::size_t used = 0;
  int n = 0;
  try {
    n = std::stoi(text, &used);
  } catch (const std::exception&) {
    return false;
  }
  if (used == 0 || used != text.size() || n < lo || n > hi) return false;
  *out = n;
  return true;
}

// ---- scenes ----------------------------------------------------------------------------------

const char* word(Shadows s) {
  return s == Shadows::None ? "none" : s == Shadows::Hard ? "hard" : "soft";
}
const char* word(Sampling s, ExactBackend backend) {
  if (s == Sampling::Truncated) return "truncated";
  return backend == ExactBackend::CLBlast ? "gemm" : "exact";
}

Scene turnaround_scene() {
  std::string dir = PENUMBRA_DATA_DIR;
  if (const char* env = std::getenv("PENUMBRA_DATA_DIR"); env && *env) dir = env;
  return load_scene(dir + "/scenes/turnaround.json");
}

glm::dvec3 rotate_y(const glm::dvec3& v, double angle) {
  const double c = std::cos(angle), s = std::sin(angle);
  return {c * v.x + s * v.z, v.y, -s * v.x + c * v.z};
}

int total_faces(const Scene& s) {
  int n = 0;
  for (const Mesh& m : s.meshes) n += int(m.faces.size());
  return n;
}

Scene make_scene(const Case& c) {
  Scene s = turnaround_scene();
  if (c.frequency > 0) {
    // Same place, size and colour as the bundled sphere (the first mesh).
    Mesh& sphere = s.meshes.front();
    glm::dvec3 lo(1e300), hi(-1e300);
    for (auto& v : sphere.vertices) lo = glm::min(lo, v), hi = glm::max(hi, v);
    const glm::dvec3 albedo = sphere.albedo.empty() ? glm::dvec3(0.8) : sphere.albedo.front();
    sphere = icosphere(c.frequency, 0.5 * (lo + hi), 0.5 * (hi.y - lo.y), albedo);
  }
  for (auto& cam : s.cameras) cam.width = cam.height = c.image;
  if (c.lights < 1 || c.lights > 3) throw Error("bench: 1 to 3 lights");
  const Light first = s.lights.front();
  s.lights.resize(1);
  for (int k = 1; k < c.lights; ++k) {
    Light L = first;
    L.position = rotate_y(first.position, 2.0 * std::acos(-1.0) * k / 3.0);
    L.frustum = LightFrustum{};
    s.lights.push_back(L);
  }
  s.params.shadows = c.shadows;
  s.params.shadow_model = c.model;
  s.params.sampling = c.sampling;
  s.params.exact_backend = c.sampling == Sampling::Exact ? c.exact_backend : ExactBackend::Auto;
  s.params.shadow_map_size = c.map;
  s.params.sigma_s = c.sigma_s;
  // The frusta of the scene file were fitted to the bundled sphere: refit to this geometry.
  for (auto& L : s.lights) L.frustum = LightFrustum{};
  fit_light_frusta(s);
  validate(s);
  return s;
}

// ---- device ----------------------------------------------------------------------------------

namespace {
std::unique_ptr<Context> g_context;
std::unique_ptr<Renderer> g_renderer;
}  // namespace

Context& context() {
  if (!g_context) g_context = std::make_unique<Context>();
  return *g_context;
}

Renderer& renderer(const Scene&) {
  if (!g_renderer) g_renderer = std::make_unique<Renderer>(context(), Precision::Float);
  return *g_renderer;
}

Renderer& fresh_renderer(const Scene& scene) {
  g_renderer.reset();
  return renderer(scene);
}

void release_device() {
  g_renderer.reset();
  g_context.reset();
}

std::vector<OutputGrads> unit_grads(const Scene& s) {
  std::vector<OutputGrads> g;
  for (const Camera& c : s.cameras) {
    OutputGrads o;
    o.color = Image(c.width, c.height, 3, 1.0);
    o.silhouette = Image(c.width, c.height, 1, 1.0);
    o.depth = Image(c.width, c.height, 1, 1.0 / c.far);
    g.push_back(std::move(o));
  }
  return g;
}

// ---- measuring -------------------------------------------------------------------------------

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const size_t h = v.size() / 2;
  return v.size() % 2 ? v[h] : 0.5 * (v[h - 1] + v[h]);
}

double load_average() {
  std::ifstream f("/proc/loadavg");
  double one = 0;
  f >> one;
  return one;
}

namespace {
bool g_resettable = true;
double g_rss_at_reset = 0;

double status_mib(const char* key) {  // a "kB" line of /proc/self/status, in MiB
  std::ifstream f("/proc/self/status");
  std::string line;
  const size_t n = std::strlen(key);
  while (std::getline(f, line))
    if (line.compare(0, n, key) == 0) return std::atof(line.c_str() + n) / 1024.0;
  return -1;
}
}  // namespace

void reset_peak_rss() {
  std::ofstream f("/proc/self/clear_refs");
  if (f) f << "5";
  f.flush();
  if (!f) g_resettable = false;
  g_rss_at_reset = status_mib("VmRSS:");
}

bool peak_rss_resettable() { return g_resettable; }

double peak_rss_mib() {
  if (const double hwm = status_mib("VmHWM:"); hwm >= 0) return hwm;
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_maxrss / 1024.0;  // kB on Linux
}

double kept_fragments(const Renderer& r) {
  double n = 0;
  for (size_t count : r.fragment_counts()) n += double(count);
  return n;
}

void throughput_counters(benchmark::State& state, const Scene& s, double fragments, double seconds,
                         bool backward) {
  const RenderParams& p = s.params;
  const double faces = total_faces(s), lights = double(s.lights.size());
  const double map_texels = double(shadow_map_side(p)) * shadow_map_side(p);
  double pixels = 0;
  for (const Camera& c : s.cameras) pixels += double(c.width) * c.height;
  const bool shadows = p.shadows != Shadows::None;
  const double pairs = (pixels + (shadows ? lights * map_texels : 0.0)) * faces;
  auto& C = state.counters;
  C["image"] = s.cameras.front().width;
  C["map"] = shadow_map_side(p);
  C["faces"] = faces;
  C["sigma_s"] = shadow_sigma_s(p);
  C["lights"] = lights;
  C["fragments"] = fragments;
  if (seconds <= 0) return;
  C["pixel_face_pairs_per_s"] = pairs / seconds;
  if (!shadows) return;
  const bool truncated = p.sampling == Sampling::Truncated;
  const double radius = std::sqrt(2.0 * shadow_sigma_s(p) * std::log(1.0 / p.lambda_eps));
  const double per_fragment = truncated ? 4.0 * radius * radius : map_texels;
  C["samples_per_s"] = fragments * lights * per_fragment / seconds;
  if (p.shadows == Shadows::Hard && !truncated) {
    const double products = backward ? 3.0 : 1.0;
    C["gflops"] = products * 2.0 * fragments * map_texels * lights / seconds / 1e9;
  }
}

void memory_counter(benchmark::State& state) {
  state.counters["peak_rss_MiB"] = peak_rss_mib();
  state.counters["rss_at_start_MiB"] = g_rss_at_reset;
}

std::string case_name(const std::string& group, bool backward, const Case& c) {
  std::ostringstream o;
  // Faces of the scene: the sphere (bundled or generated) plus the rest of the bundled scene.
  static const int bundled_sphere = int(turnaround_scene().meshes.front().faces.size());
  static const int others = total_faces(turnaround_scene()) - bundled_sphere;
  const int faces = (c.frequency > 0 ? 20 * c.frequency * c.frequency : bundled_sphere) + others;
  o << group << '/' << (backward ? "bwd" : "fwd") << '/' << word(c.shadows) << '/'
    << word(c.sampling, c.exact_backend) << "/img:" << c.image << "/map:" << c.map
    << "/faces:" << faces << "/sigma_s:" << c.sigma_s << "/lights:" << c.lights;
  if (c.model != ShadowModel::Paper) o << "/model:" << word(c.model);  // the paper's: no suffix
  return o.str();
}

}  // namespace penumbra::bench
