// Scenes far from unit size or far from the origin (renderer.hpp: scale_scene, translate_scene;
// the renderer's normalisation).
#include <cmath>

#include "ops/ops.hpp"
#include "penumbra/renderer.hpp"

namespace penumbra {
namespace detail {

// The scale is the power of two the renderer multiplies a scene's lengths by: 1 while the
// bounding radius is within [2^-kNormalisedExponent, 2^kNormalisedExponent] (the scene is
// packed exactly as given), else 2^-e for the radius's exponent e, which brings the radius into
// [1, 2). Scenes at 1e±20 would otherwise overflow or underflow float (squared distances,
// areas) on the device. A power of two scales every length exactly. The origin is the centre
// of the bounds when that lies more than 2^kFarExponent radii from the world's origin: float
// keeps ~2^-23 of a coordinate's size, so far from the origin a scene loses precision by the
// ratio of its distance to its size.
constexpr int kNormalisedExponent = 12;
constexpr int kFarExponent = 6;
Normalisation normalisation(const Bounds& b) {
  Normalisation n;
  const double r = b.radius();
  if (!(r > 0) || !std::isfinite(r)) return n;
  const int e = std::ilogb(r);
  if (std::abs(e) > kNormalisedExponent) n.scale = std::ldexp(1.0, -e);
  if (glm::length(b.center()) > std::ldexp(r, kFarExponent)) n.origin = b.center();
  return n;
}

Scene normalised(const Scene& s, const Normalisation& n) {
  if (n.identity()) return s;
  return scale_scene(n.origin == glm::dvec3(0.0) ? s : translate_scene(s, -n.origin), n.scale);
}

}  // namespace detail

Scene scale_scene(const Scene& scene, double k) {
  Scene s = scene;
  for (Mesh& m : s.meshes)
    for (glm::dvec3& v : m.vertices) v *= k;
  for (Camera& c : s.cameras) {
    c.eye *= k;
    c.target *= k;
    c.half_height *= k;
    c.near *= k;
    c.far *= k;
  }
  for (Light& l : s.lights) {
    l.position *= k;
    l.size *= k;
    LightFrustum& f = l.frustum;
    f.target *= k;
    f.half_size *= k;
    f.distance *= k;
    f.near *= k;
    f.far *= k;
  }
  RenderParams& r = s.params;
  if (r.gamma_s) *r.gamma_s *= k;
  if (r.beta) *r.beta *= k;
  r.depth_unit *= k;
  return s;
}

Scene translate_scene(const Scene& scene, glm::dvec3 offset) {
  Scene s = scene;
  for (Mesh& m : s.meshes)
    for (glm::dvec3& v : m.vertices) v += offset;
  for (Camera& c : s.cameras) {
    c.eye += offset;
    c.target += offset;
  }
  for (Light& l : s.lights) {
    l.position += offset;
    l.frustum.target += offset;
  }
  return s;
}

}  // namespace penumbra
