// Accuracy beside cost: each shadow method's rendered colour (float) against a ground truth
// ray-traced on the CPU with Embree, next to its forward time.
//
// The ground truth renders the same scene (camera 0 of data/scenes/turnaround.json, 256²)
// with one primary ray through every pixel centre (SPEC §0 screen units), the same shading
// (SPEC §2: flat face normal turned to the camera, albedo interpolated with the hit's
// barycentrics, C = a ⊙ I_a + Σ_L v_L · a ⊙ I_L · max(0, n·l), l towards the light's centre,
// the ambient term unshadowed) and visibility v_L from shadow rays:
//   point     one shadow ray to the light's position (the hard-shadow reference);
//   sphere    a sphere light of radius D_L/2 centred at the light's position: v is the
//             fraction of 256 stratified points on the light's disc facing the receiver that
//             the receiver sees (the soft-shadow reference).
// Errors are RMSEs of the colour (all three channels, values in [0, 1]) over
//   image     every pixel;
//   ground    pixels whose primary ray hits the ground and whose four neighbours do too
//             (silhouette pixels, where the soft rasterizer blends, are left out);
//   shadow    ground pixels within 8 pixels of a pixel the sphere-light reference shadows
//             (penumbra included): the same region for every method and both references, wide
//             enough that a shadow drawn too large counts as well as one drawn too small.
// Counters: rmse_{image,ground,shadow}_{point,sphere} (the error against each reference),
// ground_pixels, shadow_pixels, plus the timing counters of the render cases.
//
// Built only when CMake finds Embree 3 (Debian: libembree-dev); otherwise the group is absent
// and the suite says so once.
#include <cstdio>

#include "common.hpp"
#include "suite.hpp"

#ifdef PENUMBRA_HAVE_EMBREE

#include <embree3/rtcore.h>

#include <cmath>
#include <cstdlib>
#include <map>
#include <memory>
#include <thread>

#include "penumbra/error.hpp"
#include "penumbra/io.hpp"

namespace penumbra::bench {

namespace {

constexpr int kImage = 256;
constexpr int kSphereSamplesSqrt = 16;  // 256 samples of the sphere light per pixel

struct GroundTruth {
  int W = 0, H = 0;
  std::vector<double> color;  // H·W·3
  std::vector<int> mesh;      // mesh hit by the primary ray, −1 for the background
  std::vector<double> vis;    // visibility of the lights (min over lights), 1 where nothing hit
};

struct EmbreeScene {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  explicit EmbreeScene(const Scene& s) {
    device = rtcNewDevice(nullptr);
    if (!device) throw Error("Embree: rtcNewDevice failed");
    scene = rtcNewScene(device);
    for (size_t mi = 0; mi < s.meshes.size(); ++mi) {
      const Mesh& m = s.meshes[mi];
      RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
      auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(
          g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), m.vertices.size()));
      for (size_t i = 0; i < m.vertices.size(); ++i)
        for (int k = 0; k < 3; ++k) v[3 * i + k] = float(m.vertices[i][k]);
      auto* f = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
          g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), m.faces.size()));
      for (size_t i = 0; i < m.faces.size(); ++i)
        for (int k = 0; k < 3; ++k) f[3 * i + k] = unsigned(m.faces[i][k]);
      rtcCommitGeometry(g);
      rtcAttachGeometryByID(scene, g, unsigned(mi));
      rtcReleaseGeometry(g);
    }
    rtcCommitScene(scene);
  }
  ~EmbreeScene() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }
  EmbreeScene(const EmbreeScene&) = delete;
  EmbreeScene& operator=(const EmbreeScene&) = delete;

  bool occluded(glm::dvec3 from, glm::dvec3 dir, double tfar) const {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    RTCRay r{};
    r.org_x = float(from.x), r.org_y = float(from.y), r.org_z = float(from.z);
    r.dir_x = float(dir.x), r.dir_y = float(dir.y), r.dir_z = float(dir.z);
    r.tnear = 0.0f;
    r.tfar = float(tfar);
    r.mask = 0xFFFFFFFFu;
    rtcOccluded1(scene, &ctx, &r);
    return r.tfar < 0;
  }
};

// Small integer hash → [0, 1), for per-pixel rotations of the stratified light samples.
double hash01(uint32_t x) {
  x ^= x >> 16;
  x *= 0x7feb352dU;
  x ^= x >> 15;
  x *= 0x846ca68bU;
  x ^= x >> 16;
  return (x >> 8) * (1.0 / 16777216.0);
}

// Shirley's concentric map of the unit square onto the unit disc.
glm::dvec2 concentric(double u, double v) {
  const double a = 2 * u - 1, b = 2 * v - 1;
  if (a == 0 && b == 0) return {0, 0};
  const double q = std::acos(-1.0) / 4;
  if (std::abs(a) > std::abs(b)) return a * glm::dvec2(std::cos(q * b / a), std::sin(q * b / a));
  return b * glm::dvec2(std::cos(2 * q - q * a / b), std::sin(2 * q - q * a / b));
}

GroundTruth ray_trace(const Scene& s, bool sphere_light) {
  const EmbreeScene es(s);
  const Camera& cam = s.cameras.front();
  const int W = cam.width, H = cam.height;
  GroundTruth gt;
  gt.W = W;
  gt.H = H;
  gt.color.assign(size_t(W) * H * 3, 0.0);
  gt.mesh.assign(size_t(W) * H, -1);
  gt.vis.assign(size_t(W) * H, 1.0);
  const bool ortho = cam.projection == Projection::Orthographic;
  const glm::dvec3 fwd = glm::normalize(cam.target - cam.eye);
  const glm::dvec3 right = glm::normalize(glm::cross(fwd, cam.up)), up = glm::cross(right, fwd);
  const double scale =
      ortho ? cam.half_height : std::tan(0.5 * cam.fov_deg * std::acos(-1.0) / 180.0);
  const Bounds b = bounds(s);
  const double offset = 1e-4 * std::max(b.radius(), 1e-6);

  auto shade_row = [&](int py) {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    for (int px = 0; px < W; ++px) {
      const size_t pix = size_t(py) * W + px;
      const double x = (2.0 * px + 1 - W) / H, y = (H - 2.0 * py - 1) / H;
      glm::dvec3 org = cam.eye, dir = fwd + scale * (x * right + y * up);
      if (ortho) org = cam.eye + scale * (x * right + y * up), dir = fwd;
      RTCRayHit rh{};
      rh.ray.org_x = float(org.x), rh.ray.org_y = float(org.y), rh.ray.org_z = float(org.z);
      rh.ray.dir_x = float(dir.x), rh.ray.dir_y = float(dir.y), rh.ray.dir_z = float(dir.z);
      rh.ray.tnear = 0.0f;
      rh.ray.tfar = INFINITY;
      rh.ray.mask = 0xFFFFFFFFu;
      rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
      rtcIntersect1(es.scene, &ctx, &rh);
      double* C = &gt.color[pix * 3];
      if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) {
        for (int k = 0; k < 3; ++k) C[k] = s.background[k];
        continue;
      }
      const Mesh& m = s.meshes[rh.hit.geomID];
      const glm::ivec3 F = m.faces[rh.hit.primID];
      const double u = rh.hit.u, v = rh.hit.v, w0 = 1 - u - v;
      const glm::dvec3 V0 = m.vertices[F.x], V1 = m.vertices[F.y], V2 = m.vertices[F.z];
      const glm::dvec3 X = w0 * V0 + u * V1 + v * V2;
      glm::dvec3 a = m.albedo_mode == AlbedoMode::PerFace
                         ? m.albedo[rh.hit.primID]
                         : w0 * m.albedo[F.x] + u * m.albedo[F.y] + v * m.albedo[F.z];
      glm::dvec3 n = glm::normalize(glm::cross(V1 - V0, V2 - V0));
      const glm::dvec3 to_cam = ortho ? -fwd : cam.eye - X;
      if (glm::dot(n, to_cam) < 0) n = -n;
      gt.mesh[pix] = int(rh.hit.geomID);
      glm::dvec3 c = a * s.ambient;
      double vmin = 1.0;
      for (const Light& L : s.lights) {
        const bool point = L.type == LightType::Point;
        glm::dvec3 l = point ? L.position - X : -L.direction;
        const double dist = glm::length(l);
        l /= dist;
        const double ndotl = glm::dot(n, l);
        double vis = 1.0;
        // A receiver facing away from the light gets no direct light whatever its visibility,
        // so its shadow rays are skipped; its visibility counts as 0.
        if (ndotl <= 0) {
          vis = 0.0;
        } else {
          const glm::dvec3 o = X + offset * n;
          if (!point) {
            vis = es.occluded(o, l, INFINITY) ? 0.0 : 1.0;
          } else if (!sphere_light || L.size <= 0) {
            const glm::dvec3 to = L.position - o;
            vis = es.occluded(o, to, 1.0 - 1e-6) ? 0.0 : 1.0;
          } else {
            const glm::dvec3 t1 = glm::normalize(
                glm::cross(l, std::abs(l.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0)));
            const glm::dvec3 t2 = glm::cross(l, t1);
            const double r = 0.5 * L.size;
            const double ju = hash01(uint32_t(pix * 2 + 1)), jv = hash01(uint32_t(pix * 2 + 2));
            int seen = 0;
            const int K = kSphereSamplesSqrt;
            for (int i = 0; i < K; ++i)
              for (int j = 0; j < K; ++j) {
                const double su = std::fmod((i + 0.5) / K + ju, 1.0),
                             sv = std::fmod((j + 0.5) / K + jv, 1.0);
                const glm::dvec2 d = r * concentric(su, sv);
                const glm::dvec3 target = L.position + d.x * t1 + d.y * t2;
                seen += !es.occluded(o, target - o, 1.0 - 1e-6);
              }
            vis = double(seen) / (K * K);
          }
        }
        vmin = std::min(vmin, vis);
        c += vis * a * L.color * std::max(0.0, ndotl);
      }
      gt.vis[pix] = vmin;
      for (int k = 0; k < 3; ++k) C[k] = c[k];
    }
  };
  const unsigned threads = std::max(1u, std::thread::hardware_concurrency());
  std::vector<std::thread> pool;
  for (unsigned t = 0; t < threads; ++t)
    pool.emplace_back([&, t] {
      for (int py = int(t); py < H; py += int(threads)) shade_row(py);
    });
  for (auto& th : pool) th.join();
  return gt;
}

// The accuracy scene: camera 0 of the turnaround scene at 256², the bundled sphere.
Scene accuracy_scene(const Case& c) {
  Case k = c;
  k.image = kImage;
  return make_scene(k);
}

const GroundTruth& ground_truth(bool sphere_light) {
  static std::map<bool, std::unique_ptr<GroundTruth>> cache;
  auto& slot = cache[sphere_light];
  if (!slot) {
    Case c;
    c.shadows = Shadows::Hard;
    const auto t0 = Clock::now();
    slot = std::make_unique<GroundTruth>(ray_trace(accuracy_scene(c), sphere_light));
    std::fprintf(stderr, "accuracy: %s-light ground truth ray-traced in %.2f s\n",
                 sphere_light ? "sphere" : "point", seconds_since(t0));
    if (const char* dir = std::getenv("PENUMBRA_BENCH_IMAGES"); dir && *dir) {
      Image img(slot->W, slot->H, 3);
      img.data = slot->color;
      save_png(img, std::string(dir) + (sphere_light ? "/truth_sphere.png" : "/truth_point.png"));
    }
  }
  return *slot;
}

int ground_mesh(const Scene& s) {
  for (size_t i = 0; i < s.meshes.size(); ++i)
    if (s.meshes[i].name == "ground") return int(i);
  return int(s.meshes.size()) - 1;
}

// Ground pixels (primary ray on the ground, four neighbours too: silhouette pixels, where the
// soft rasterizer blends, are left out) and the shadow region: ground pixels within
// kShadowMargin pixels of a pixel the sphere-light reference shadows (visibility < 0.999,
// penumbra included), so that a shadow drawn too large counts as well as one drawn too small.
constexpr int kShadowMargin = 8;

struct Regions {
  std::vector<char> ground, shadow;
};

const Regions& regions(int ground_index) {
  static std::unique_ptr<Regions> r;
  if (r) return *r;
  const GroundTruth& gt = ground_truth(true);
  const int W = gt.W, H = gt.H;
  auto is_ground = [&](int x, int y) {
    return x >= 0 && y >= 0 && x < W && y < H && gt.mesh[size_t(y) * W + x] == ground_index;
  };
  r = std::make_unique<Regions>();
  r->ground.assign(size_t(W) * H, 0);
  r->shadow.assign(size_t(W) * H, 0);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x)
      r->ground[size_t(y) * W + x] = is_ground(x, y) && is_ground(x - 1, y) &&
                                     is_ground(x + 1, y) && is_ground(x, y - 1) &&
                                     is_ground(x, y + 1);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const size_t p = size_t(y) * W + x;
      if (!is_ground(x, y) || gt.vis[p] >= 0.999) continue;
      for (int dy = -kShadowMargin; dy <= kShadowMargin; ++dy)
        for (int dx = -kShadowMargin; dx <= kShadowMargin; ++dx) {
          const int u = x + dx, v = y + dy;
          if (u >= 0 && v >= 0 && u < W && v < H) r->shadow[size_t(v) * W + u] = 1;
        }
    }
  for (size_t p = 0; p < r->shadow.size(); ++p) r->shadow[p] &= r->ground[p];
  return *r;
}

void error_counters(benchmark::State& state, const Image& color, const GroundTruth& gt,
                    const Regions& reg, const char* suffix) {
  double se_all = 0, se_ground = 0, se_shadow = 0;
  size_t n_all = 0, n_ground = 0, n_shadow = 0;
  for (size_t p = 0; p < size_t(gt.W) * gt.H; ++p) {
    double se = 0;
    for (int k = 0; k < 3; ++k) {
      const double d = color.data[p * 3 + k] - gt.color[p * 3 + k];
      se += d * d;
    }
    se_all += se, n_all += 3;
    if (reg.ground[p]) se_ground += se, n_ground += 3;
    if (reg.shadow[p]) se_shadow += se, n_shadow += 3;
  }
  auto rmse = [](double se, size_t n) { return n ? std::sqrt(se / n) : 0.0; };
  auto& C = state.counters;
  C[std::string("rmse_image_") + suffix] = rmse(se_all, n_all);
  C[std::string("rmse_ground_") + suffix] = rmse(se_ground, n_ground);
  C[std::string("rmse_shadow_") + suffix] = rmse(se_shadow, n_shadow);
  C["ground_pixels"] = double(n_ground / 3);
  C["shadow_pixels"] = double(n_shadow / 3);
}

void run_accuracy(benchmark::State& state, const Case& c, const std::string& tag) {
  reset_peak_rss();
  Scene s;
  std::vector<RenderOutput> out;
  try {
    ground_truth(false);
    ground_truth(true);
    s = accuracy_scene(c);
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
    return;
  }
  Renderer& r = renderer(s);
  try {
    out = r.render(s);  // warm-up; also the image that is compared
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
    return;
  }
  if (const char* dir = std::getenv("PENUMBRA_BENCH_IMAGES"); dir && *dir)
    save_png(out.front().color, std::string(dir) + "/" + tag + ".png");
  const double fragments = covered_pixels(out);
  const double med = timed_frames(state, [&] { benchmark::DoNotOptimize(r.render(s)); });
  throughput_counters(state, s, fragments, med, false);
  memory_counter(state);
  const Regions& reg = regions(ground_mesh(s));
  error_counters(state, out.front().color, ground_truth(false), reg, "point");
  error_counters(state, out.front().color, ground_truth(true), reg, "sphere");
}

void add(const Case& c, bool large = false) {
  std::string name = (large ? "large/" : "") + case_name("accuracy", false, c);
  std::string tag = case_name("", false, c).substr(5);  // <shadows>/<sampling>/img:...
  for (char& ch : tag)
    if (ch == '/' || ch == ':') ch = '_';
  benchmark::RegisterBenchmark(name.c_str(),
                               [c, tag](benchmark::State& st) { run_accuracy(st, c, tag); })
      ->UseManualTime()
      ->Unit(benchmark::kMillisecond);
}

}  // namespace

void register_accuracy_benchmarks() {
  auto make = [](Shadows sh, Sampling sa, int map = 256, double sigma_s = 2.0) {
    Case c;
    c.shadows = sh;
    c.sampling = sa;
    c.image = kImage;
    c.map = map;
    c.sigma_s = sigma_s;
    return c;
  };
  add(make(Shadows::None, Sampling::Truncated));
  for (Shadows sh : {Shadows::Hard, Shadows::Soft}) {
    for (double ss : {0.5, 2.0, 8.0}) add(make(sh, Sampling::Truncated, 256, ss));
    for (int map : {128, 512}) add(make(sh, Sampling::Truncated, map));
  }
  add(make(Shadows::Hard, Sampling::Exact));
  add(make(Shadows::Hard, Sampling::Exact, 128));
  add(make(Shadows::Hard, Sampling::Gemm));
  add(make(Shadows::Soft, Sampling::Exact, 64));
  add(make(Shadows::Soft, Sampling::Exact, 128));
  add(make(Shadows::Soft, Sampling::Exact, 256), true);
}

}  // namespace penumbra::bench

#else  // no Embree

namespace penumbra::bench {
void register_accuracy_benchmarks() {
  std::fprintf(stderr,
               "penumbra_bench: accuracy benchmarks skipped: built without Embree 3 (install "
               "the Debian package libembree-dev and reconfigure)\n");
}
}  // namespace penumbra::bench

#endif
