// Scenes far from unit size (renderer.hpp: scale_scene; the renderer's normalisation).
#include <cmath>

#include "ops/ops.hpp"
#include "penumbra/renderer.hpp"

namespace penumbra {
namespace detail {

// The power of two the renderer multiplies a scene's lengths by before packing it for the
// device: 1 while the bounding radius is within [2^-kNormalisedExponent, 2^kNormalisedExponent]
// (the scene is packed exactly as given), else 2^-e for the radius's exponent e, which brings
// the radius into [1, 2). Scenes at 1e±20 would otherwise overflow or underflow float (squared
// distances, areas) on the device. A power of two scales every length exactly.
constexpr int kNormalisedExponent = 12;
double normalisation(const Scene& s) {
  const double r = bounds(s).radius();
  if (!(r > 0) || !std::isfinite(r)) return 1;
  const int e = std::ilogb(r);
  return std::abs(e) <= kNormalisedExponent ? 1 : std::ldexp(1.0, -e);
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

}  // namespace penumbra
