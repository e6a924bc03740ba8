#pragma once
// The per-view parameter block P (kernels/common/layout.h) of a camera or of a light's
// shadow-map view, with the views' frames, and the chain rule from a light's frame back to the
// light (internal to the renderer).
#include <cstddef>
#include <vector>

#include "penumbra/scene.hpp"

namespace penumbra::detail {

// P of camera `c` of scene `s`.
std::vector<double> view_params(const Scene& s, const Camera& c);
// P of light `i`'s shadow-map view.
std::vector<double> light_view_params(const Scene& s, size_t i);
// dL/d(light position or direction) from dL/d(its frame's eye, forward, right and up).
glm::dvec3 light_frame_backward(const Light& L, glm::dvec3 g_eye, glm::dvec3 g_fwd,
                                glm::dvec3 g_right, glm::dvec3 g_up);

}  // namespace penumbra::detail
