// The Embree ground truth (see truth.hpp).
#include "truth.hpp"

#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>
#include <thread>

#include "penumbra/error.hpp"

namespace penumbra::bench {

namespace {

constexpr int kSphereSamplesSqrt = 16;  // 256 samples of the sphere light per pixel

struct EmbreeScene {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  explicit EmbreeScene(const Scene& s) {
    device = rtcNewDevice(nullptr);
    if (!device) throw Error("Embree: rtcNewDevice failed");
    scene = rtcNewScene(device);
    for (size_t mi = 0; mi < s.meshes.size(); ++mi) attach(s.meshes[mi], unsigned(mi));
    rtcCommitScene(scene);
  }
  ~EmbreeScene() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }
  EmbreeScene(const EmbreeScene&) = delete;
  EmbreeScene& operator=(const EmbreeScene&) = delete;

  void attach(const Mesh& m, unsigned id) {
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
    rtcAttachGeometryByID(scene, g, id);
    rtcReleaseGeometry(g);
  }

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

  // The primary hit along org + t·dir: its mesh, face and barycentrics (mesh −1: none).
  RTCHit intersect(glm::dvec3 org, glm::dvec3 dir) const {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    RTCRayHit rh{};
    rh.ray.org_x = float(org.x), rh.ray.org_y = float(org.y), rh.ray.org_z = float(org.z);
    rh.ray.dir_x = float(dir.x), rh.ray.dir_y = float(dir.y), rh.ray.dir_z = float(dir.z);
    rh.ray.tnear = 0.0f;
    rh.ray.tfar = INFINITY;
    rh.ray.mask = 0xFFFFFFFFu;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene, &ctx, &rh);
    return rh.hit;
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

// Fraction of the disc of radius r (facing the receiver, centred at the light) that `o` sees,
// over kSphereSamplesSqrt² stratified points rotated per pixel.
double disc_visibility(const EmbreeScene& es, glm::dvec3 o, glm::dvec3 l, const Light& L,
                       size_t pix) {
  const glm::dvec3 t1 = glm::normalize(
      glm::cross(l, std::abs(l.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0)));
  const glm::dvec3 t2 = glm::cross(l, t1);
  const double r = 0.5 * L.size;
  const double ju = hash01(uint32_t(pix * 2 + 1)), jv = hash01(uint32_t(pix * 2 + 2));
  int seen = 0;
  const int K = kSphereSamplesSqrt;
  for (int i = 0; i < K; ++i)
    for (int j = 0; j < K; ++j) {
      const double su = std::fmod((i + 0.5) / K + ju, 1.0), sv = std::fmod((j + 0.5) / K + jv, 1.0);
      const glm::dvec2 d = r * concentric(su, sv);
      const glm::dvec3 target = L.position + d.x * t1 + d.y * t2;
      seen += !es.occluded(o, target - o, 1.0 - 1e-6);
    }
  return double(seen) / (K * K);
}

// Visibility of light L from the receiver X (normal n, towards the camera; unit l towards the
// light): 0 facing away, else from shadow rays leaving X offset along n.
double visibility(const EmbreeScene& es, const Light& L, glm::dvec3 X, glm::dvec3 n, glm::dvec3 l,
                  double offset, TruthLight light, size_t pix) {
  if (glm::dot(n, l) <= 0) return 0.0;
  const glm::dvec3 o = X + offset * n;
  if (L.type != LightType::Point) return es.occluded(o, l, INFINITY) ? 0.0 : 1.0;
  if (light == TruthLight::Point || L.size <= 0)
    return es.occluded(o, L.position - o, 1.0 - 1e-6) ? 0.0 : 1.0;
  return disc_visibility(es, o, l, L, pix);
}

struct View {
  glm::dvec3 eye, fwd, right, up;
  double scale;
  bool ortho;
  explicit View(const Camera& cam)
      : eye(cam.eye),
        fwd(glm::normalize(cam.target - cam.eye)),
        right(glm::normalize(glm::cross(fwd, cam.up))),
        up(glm::cross(right, fwd)),
        scale(cam.projection == Projection::Orthographic
                  ? cam.half_height
                  : std::tan(0.5 * cam.fov_deg * std::acos(-1.0) / 180.0)),
        ortho(cam.projection == Projection::Orthographic) {}
};

void shade_pixel(const Scene& s, const EmbreeScene& es, const View& v, TruthLight light,
                 double offset, int px, int py, GroundTruth& gt) {
  const int W = gt.W, H = gt.H;
  const size_t pix = size_t(py) * W + px;
  const double x = (2.0 * px + 1 - W) / H, y = (H - 2.0 * py - 1) / H;
  const glm::dvec3 across = v.scale * (x * v.right + y * v.up);
  const RTCHit hit =
      v.ortho ? es.intersect(v.eye + across, v.fwd) : es.intersect(v.eye, v.fwd + across);
  double* C = &gt.color[pix * 3];
  if (hit.geomID == RTC_INVALID_GEOMETRY_ID) {
    for (int k = 0; k < 3; ++k) C[k] = s.background[k];
    return;
  }
  const Mesh& m = s.meshes[hit.geomID];
  const glm::ivec3 F = m.faces[hit.primID];
  const double u = hit.u, w = hit.v, w0 = 1 - u - w;
  const glm::dvec3 V0 = m.vertices[F.x], V1 = m.vertices[F.y], V2 = m.vertices[F.z];
  const glm::dvec3 X = w0 * V0 + u * V1 + w * V2;
  const glm::dvec3 a = m.albedo_mode == AlbedoMode::PerFace
                           ? m.albedo[hit.primID]
                           : w0 * m.albedo[F.x] + u * m.albedo[F.y] + w * m.albedo[F.z];
  glm::dvec3 n = glm::normalize(glm::cross(V1 - V0, V2 - V0));
  if (glm::dot(n, v.ortho ? -v.fwd : v.eye - X) < 0) n = -n;
  gt.mesh[pix] = int(hit.geomID);
  gt.point[pix] = X;
  glm::dvec3 c = a * s.ambient;
  double vmin = 1.0;
  for (const Light& L : s.lights) {
    const glm::dvec3 l = glm::normalize(L.type == LightType::Point ? L.position - X : -L.direction);
    const double vis = visibility(es, L, X, n, l, offset, light, pix);
    vmin = std::min(vmin, vis);
    c += vis * a * L.color * std::max(0.0, glm::dot(n, l));
  }
  gt.vis[pix] = vmin;
  for (int k = 0; k < 3; ++k) C[k] = c[k];
}

}  // namespace

GroundTruth ray_trace(const Scene& s, TruthLight light) {
  const EmbreeScene es(s);
  const Camera& cam = s.cameras.front();
  GroundTruth gt;
  gt.W = cam.width;
  gt.H = cam.height;
  const size_t pixels = size_t(gt.W) * gt.H;
  gt.color.assign(pixels * 3, 0.0);
  gt.mesh.assign(pixels, -1);
  gt.point.assign(pixels, glm::dvec3(0.0));
  gt.vis.assign(pixels, 1.0);
  const View view(cam);
  const double offset = 1e-4 * std::max(bounds(s).radius(), 1e-6);
  const unsigned threads = std::max(1u, std::thread::hardware_concurrency());
  std::vector<std::thread> pool;
  for (unsigned t = 0; t < threads; ++t)
    pool.emplace_back([&, t] {
      for (int py = int(t); py < gt.H; py += int(threads))
        for (int px = 0; px < gt.W; ++px) shade_pixel(s, es, view, light, offset, px, py, gt);
    });
  for (auto& th : pool) th.join();
  return gt;
}

}  // namespace penumbra::bench
