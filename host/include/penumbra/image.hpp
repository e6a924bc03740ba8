#pragma once
// Row-major images (row 0 at the top), interleaved channels, double on the host.
#include <string>
#include <vector>

namespace penumbra {

struct Image {
  int width = 0, height = 0, channels = 0;
  std::vector<double> data;  // height * width * channels

  Image() = default;
  Image(int w, int h, int c, double fill = 0.0)
      : width(w), height(h), channels(c), data(size_t(w) * h * c, fill) {}
  double& at(int x, int y, int c = 0) { return data[(size_t(y) * width + x) * channels + c]; }
  double at(int x, int y, int c = 0) const { return data[(size_t(y) * width + x) * channels + c]; }
  size_t size() const { return data.size(); }
};

// The differentiable outputs of one view (math.md §2.3).
struct RenderOutput {
  Image color;       // 3 channels, I
  Image silhouette;  // 1 channel, A
  Image depth;       // 1 channel, I_z (view depth)
};

// dL/d(outputs) of one view; an empty image means zero gradient for that output.
using OutputGrads = RenderOutput;

// The outputs of one view in the caller's memory, laid out as RenderOutput's images: W·H·3
// colour values, W·H silhouette and W·H depth values, row 0 at the top (Renderer::render_into).
template <class Real>
struct OutputBuffers {
  Real* color = nullptr;
  Real* silhouette = nullptr;
  Real* depth = nullptr;
};
// dL/d(outputs) of one view in the caller's memory, laid out as OutputBuffers; null: a zero
// gradient for that output (Renderer::backward).
template <class Real>
struct GradBuffers {
  const Real* color = nullptr;
  const Real* silhouette = nullptr;
  const Real* depth = nullptr;
};

}  // namespace penumbra
