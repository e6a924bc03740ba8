#pragma once
// Plain C++ double-precision reference of the forward pass (SPEC §1–§2), written for clarity,
// not speed: every pixel visits every face. Tests compare the OpenCL kernels against it.
#include "penumbra/image.hpp"
#include "penumbra/scene.hpp"

namespace penumbra::reference {

RenderOutput render(const Scene& scene, size_t camera_index);

}  // namespace penumbra::reference
