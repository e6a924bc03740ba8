// The device memory a render (and its backward) needs, estimated before anything is allocated
// (renderer.hpp: estimate_device_memory). It follows the buffers of ops/: per view the
// transformed vertices and face boxes, per pixel the counts, offsets, colour, depth and
// auxiliary sums, and per fragment the records of raster.cpp — for a fragment on every fourth
// pixel: how many there are is known only once they are counted, and then checked again —; per light with shadows its map view, the
// penumbra maps of soft shadows, the batches of the exact filter (at most 96 MiB each).
#include <cstddef>

#include "penumbra/renderer.hpp"

namespace penumbra {
namespace {

struct Sizes {
  size_t rs;          // bytes of a real
  size_t nv = 0, nf = 0;
};

// One view of W×H pixels with `lights` lights in its shading.
size_t view_bytes(const Sizes& z, size_t pixels, size_t lights, bool backward) {
  const size_t per_pixel = 3 * sizeof(int) + 1 + z.rs * (4 + 4 + 1);  // counts, aux, image, depth
  size_t per_fragment = sizeof(int) + z.rs * 4 * (3 + 5 * lights);
  size_t per_face = 4 * sizeof(int) + 4 * z.rs;  // box, normal
  if (backward) {
    per_fragment += z.rs * 4 * (1 + 2 * lights);
    per_face += z.rs * (36 + (6 * lights + 1) * 4);
  }
  return z.nv * 4 * z.rs + z.nf * per_face + pixels * per_pixel + pixels / 4 * per_fragment;
}

}  // namespace

size_t estimate_device_memory(const Scene& scene, Precision precision, bool backward) {
  Sizes z;
  z.rs = precision == Precision::Double ? 8 : 4;
  for (const Mesh& m : scene.meshes) z.nv += m.vertices.size(), z.nf += m.faces.size();
  size_t bytes = z.nv * 3 * 4 * z.rs + z.nf * (16 * z.rs + 48);  // geometry (renderer.cpp)
  if (backward) bytes += z.nv * 20 * z.rs;                         // vertex and frame gradients
  const RenderParams& p = scene.params;
  const size_t lights = scene.lights.size();
  for (const Camera& c : scene.cameras)
    bytes += view_bytes(z, size_t(c.width) * size_t(c.height), lights, backward);
  if (p.shadows == Shadows::None) return bytes;
  const size_t texels = size_t(p.shadow_map_size) * size_t(p.shadow_map_size);
  for (size_t l = 0; l < lights; ++l) {
    bytes += view_bytes(z, texels, 0, backward);
    if (p.shadows == Shadows::Soft) bytes += z.nf * 16 + texels * 3 * z.rs;  // P and its sums
    if (backward) bytes += texels * 6 * z.rs;  // gradients of S (and P), image, depth
    if (p.sampling != Sampling::Truncated) bytes += (backward ? 2 : 1) * (size_t(96) << 20);
  }
  return bytes;
}

}  // namespace penumbra
