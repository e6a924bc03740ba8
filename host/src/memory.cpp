// The device memory a render (and its backward) needs, estimated before anything is allocated
// (renderer.hpp: estimate_device_memory). It follows the buffers of ops/: per view the
// transformed vertices and face boxes, per pixel the counts, offsets, colour, depth and
// auxiliary sums, and per fragment the records of raster.cpp — for 1.25 fragments per pixel (1.5
// per texel of a map): how many there are is known only once they are counted, and then checked
// again —; per light with shadows its map view, the penumbra maps of soft shadows, the batches of
// the paper model's exact hard-shadow lookups (at most ~96 MiB each, fewer for fewer fragments).
#include <algorithm>
#include <cstddef>

#include "ops/ops.hpp"
#include "penumbra/renderer.hpp"
#include "shadow_models.hpp"

namespace penumbra {
namespace {

struct Sizes {
  size_t rs;                      // bytes of a real
  size_t nv = 0, nf = 0, na = 0;  // na: albedo entries
};

// Fragments per pixel of a camera's view and per texel of a light's map that the estimate
// assumes. Measured on the bundled scene (FaultsMemory.EstimateCoversWhatIsAllocated): 1.1–1.2
// per pixel of the camera's view; more per texel of the paper model's map, which the ground
// covers almost whole, faces near an edge each keeping a fragment on the texels within their
// coverage cut-off; fewer in the accurate model's, which holds only the casters (the ground
// casts no shadow) in a frustum fitted to them.
constexpr double kFragmentsPerPixel = 1.25, kFragmentsPerTexel = 1.5, kCasterFragmentsPerTexel = 1;

size_t fragments(size_t pixels, double per_pixel) { return size_t(double(pixels) * per_pixel); }

// One view of W×H pixels with `lights` lights in its shading, of which `shadowed` have shadow
// records (all with shadows on, none without: View::shadow_lights) (raster.cpp's buffers).
// `per_pixel`: fragments per pixel (kFragmentsPerPixel or a map's per texel).
size_t view_bytes(const Sizes& z, size_t pixels, size_t lights, size_t shadowed, bool backward,
                  double per_pixel) {
  // counts, offsets, kept; a fourth int for raster_count's list bits, which follow the tile
  // lists and are checked against the device when allocated (raster.cpp); aux, image, depth,
  // cover
  const size_t per_pixel_bytes = 4 * sizeof(int) + z.rs * (4 + 4 + 1 + 1);
  // face, weight and depth (2 reals), shading (shade_terms real4s), two light records (shadowed)
  const size_t shade_terms = size_t(detail::shade_terms(shadowed > 0, int(lights)));
  size_t per_fragment = sizeof(int) + z.rs * (2 + 4 * shade_terms + 8 * shadowed);
  size_t per_face = 5 * sizeof(int) + 4 * z.rs;  // box, normal, kept mark
  if (backward) {
    per_fragment += z.rs * (2 + 8 * shadowed);  // weight gradients, two light gradients
    per_face += z.rs * (36 + (6 * lights + 1) * 4);
  }
  return z.nv * 4 * z.rs + z.nf * per_face + pixels * per_pixel_bytes +
         fragments(pixels, per_pixel) * per_fragment;
}

// The exact lookups of hard shadows with the paper's model (paper_lookups.cpp, exact_forward and
// exact_backward) of one camera and light: batches of at most ~96 MiB of weights and products,
// or fewer fragments. `kept`: the weights, Gx, Gy and their supports (int4), the backward's
// also Gxd, Gyd, which stay with the camera's fragments from call to call (ExactWeights), the
// forward's through the backward. `call`: what a call holds besides, dots and norm (the
// backward's also dsum) and with CLBlast the products Gy·S (and Gyd·S) (the direct kernels
// store none, and matmul_tn's int4 box per 16 fragments instead).
struct ExactBytes {
  size_t kept = 0, call = 0;
};
ExactBytes exact_lookup_bytes(const Sizes& z, size_t texels_side, size_t fragments, bool backward,
                              bool clblast) {
  const size_t cap = std::max<size_t>(1, (size_t(96) << 20) / (texels_side * 6 * z.rs));
  const size_t support = 4 * sizeof(int);
  const size_t fwd_batch = std::min(cap, fragments);
  ExactBytes b;
  b.kept = fwd_batch * (2 * texels_side * z.rs + support);
  b.call = fwd_batch * ((clblast ? texels_side : 0) + 8) * z.rs;
  if (!backward) return b;
  const size_t bwd_batch = std::min(std::max<size_t>(cap / 2, 1), fragments);
  b.kept += bwd_batch * (4 * texels_side * z.rs + support);
  b.call = std::max(b.call, bwd_batch * ((clblast ? 2 * texels_side : 0) + 10) * z.rs +
                                (clblast ? 0 : (bwd_batch / 16 + 1) * support));
  return b;
}

}  // namespace

size_t estimate_device_memory(const Scene& scene, Precision precision, bool backward,
                              const Tuning* tuning) {
  Sizes z;
  z.rs = precision == Precision::Double ? 8 : 4;
  for (const Mesh& m : scene.meshes)
    z.nv += m.vertices.size(), z.nf += m.faces.size(), z.na += m.albedo.size();
  size_t bytes = z.nv * 3 * 4 * z.rs + z.nf * (16 * z.rs + 48);  // geometry (packing.cpp)
  // vertex, frame and albedo gradients; the corners grouped by albedo entry (backward.cpp)
  if (backward) bytes += z.nv * 20 * z.rs + z.na * (4 * z.rs + 4) + 4 + z.nf * 3 * 4;
  const RenderParams& p = scene.params;
  const size_t lights = scene.lights.size();
  const size_t shadowed = p.shadows == Shadows::None ? 0 : lights;
  for (const Camera& c : scene.cameras)
    bytes += view_bytes(z, size_t(c.width) * size_t(c.height), lights, shadowed, backward,
                        kFragmentsPerPixel) +
             (backward ? size_t(c.width) * size_t(c.height) * 6 * z.rs : 0);  // dL/d(image, depth)
  if (p.shadows == Shadows::None) return bytes;
  const size_t texels = size_t(shadow_map_side(p)) * size_t(shadow_map_side(p));
  size_t exact_kept = 0, exact_call = 0;  // exact_lookup_bytes, over the cameras and lights
  size_t call = 0;                        // the largest of one lookup call's own buffers
  size_t camera_fragments = 0;
  for (const Camera& c : scene.cameras)
    camera_fragments = std::max(camera_fragments,
                                fragments(size_t(c.width) * size_t(c.height), kFragmentsPerPixel));
  const auto model_bytes = detail::shadow_model_passes(p.shadow_model).memory;
  const double per_texel = shadow_model_traits(p.shadow_model).casters_only
                               ? kCasterFragmentsPerTexel
                               : kFragmentsPerTexel;
  for (size_t l = 0; l < lights; ++l) {
    bytes += view_bytes(z, texels, 0, 0, backward, per_texel);
    const detail::ModelBytes own =
        model_bytes({z.rs, z.nf, texels, camera_fragments, backward, p.shadows});
    bytes += own.kept;  // the model's own maps (shadow_models.cpp)
    call = std::max(call, own.call);
    if (backward) bytes += texels * 7 * z.rs;               // gradients of S (P or A), image, depth
    if (backward && !sampling_method(p.sampling).windowed)  // the exact gathers' chunk boxes
      for (const Camera& c : scene.cameras)
        bytes += (fragments(size_t(c.width) * size_t(c.height), kFragmentsPerPixel) /
                      detail::kGatherChunk +
                  1) *
                 4 * sizeof(int);
    if (detail::exact_lookups(p)) {
      const bool clblast = tuning ? exact_backend_in_force(p, *tuning) == ExactBackend::CLBlast
                                  : p.exact_backend != ExactBackend::Kernels;
      for (const Camera& c : scene.cameras) {  // a call's own buffers live one at a time
        const ExactBytes e = exact_lookup_bytes(
            z, size_t(shadow_map_side(p)),
            fragments(size_t(c.width) * size_t(c.height), kFragmentsPerPixel), backward, clblast);
        exact_kept += e.kept;
        exact_call = std::max(exact_call, e.call);
      }
    }
  }
  return bytes + exact_kept + std::max(exact_call, call);
}

}  // namespace penumbra
