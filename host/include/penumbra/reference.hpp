#pragma once
// Plain C++ double-precision reference of the forward pass (math.md §2–§3) with hard shadows
// (math.md §4.2, §6.1–§6.2: truncated or exact Gaussian sampling; the exact backend does not change
// the sum) and soft shadows (math.md §4.3 penumbra map, §6.3 eq. 11; truncated or exact sampling),
// written for clarity, not speed: every pixel visits every face. Tests compare the OpenCL
// kernels against it. Light frusta not given are fitted to a copy of the scene by
// fit_light_frusta, as the renderer does.
#include <cstddef>

#include "penumbra/image.hpp"
#include "penumbra/scene.hpp"

namespace penumbra::reference {

// Colour, silhouette and soft depth of camera `camera_index`, with the scene's shadows (none,
// hard, or soft; soft shadows with exact backend clblast (gemm) throw penumbra::Error, as the
// renderer does).
RenderOutput render(const Scene& scene, size_t camera_index);

// The shadow map S of light `light` (math.md §4.2): the soft depth of the light pass, W_s × H_s
// (shadow_map_size²), one channel, row 0 at the top. Independent of params.shadows.
Image shadow_map(const Scene& scene, size_t light);

// The penumbra map P of light `light` (math.md §4.3, with its membership offset),
// computed from its shadow map and the light's size D_L: W_s × H_s, one channel, row 0 at the
// top, 1 where no occluder is near (everywhere when D_L = 0). Independent of params.shadows.
Image penumbra_map(const Scene& scene, size_t light);

}  // namespace penumbra::reference
