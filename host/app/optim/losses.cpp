// Image losses of the applications (math.md §9): soft IoU and mean squared error with their
// gradients with respect to the rendered image, and the binary IoU that reports results.
#include <string>

#include "penumbra/error.hpp"
#include "penumbra/optim.hpp"

namespace penumbra::optim {
namespace {

void check_pair(const Image& a, const Image& t, const char* what) {
  if (a.width != t.width || a.height != t.height || a.channels != 1 || t.channels != 1 ||
      a.data.size() != t.data.size())
    throw Error(std::string(what) + ": images must be one-channel and of the same size (got " +
                std::to_string(a.width) + "x" + std::to_string(a.height) + "x" +
                std::to_string(a.channels) + " and " + std::to_string(t.width) + "x" +
                std::to_string(t.height) + "x" + std::to_string(t.channels) + ")");
}

// Sizes an empty gradient image like `like` (zeros); checks a given one.
void prepare_grad(Image* grad, const Image& like, const char* what) {
  if (grad == nullptr) return;
  if (grad->data.empty()) {
    *grad = Image(like.width, like.height, 1, 0.0);
    return;
  }
  check_pair(*grad, like, what);
}

}  // namespace

double soft_iou_loss(const Image& a, const Image& t, Image* grad, double weight) {
  check_pair(a, t, "soft_iou_loss");
  prepare_grad(grad, a, "soft_iou_loss gradient");
  double inter = 0, uni = 0;
  for (size_t i = 0; i < a.data.size(); ++i) {
    inter += a.data[i] * t.data[i];
    uni += a.data[i] + t.data[i] - a.data[i] * t.data[i];
  }
  if (!(uni > 0)) return 0.0;  // both empty: nothing to match
  if (grad != nullptr) {
    // L = 1 − I/U: dL/dA = −(T·U − I·(1 − T)) / U².
    const double inv_u2 = 1.0 / (uni * uni);
    for (size_t i = 0; i < a.data.size(); ++i)
      grad->data[i] -= weight * (t.data[i] * uni - inter * (1.0 - t.data[i])) * inv_u2;
  }
  return weight * (1.0 - inter / uni);
}

double mse_loss(const Image& a, const Image& t, Image* grad, double weight) {
  check_pair(a, t, "mse_loss");
  prepare_grad(grad, a, "mse_loss gradient");
  if (a.data.empty()) return 0.0;
  const double inv_n = 1.0 / double(a.data.size());
  double sum = 0;
  for (size_t i = 0; i < a.data.size(); ++i) {
    const double d = a.data[i] - t.data[i];
    sum += d * d;
    if (grad != nullptr) grad->data[i] += weight * 2.0 * d * inv_n;
  }
  return weight * sum * inv_n;
}

double binary_iou(const Image& a, const Image& b, double threshold) {
  check_pair(a, b, "binary_iou");
  size_t inter = 0, uni = 0;
  for (size_t i = 0; i < a.data.size(); ++i) {
    const bool x = a.data[i] > threshold, y = b.data[i] > threshold;
    inter += (x && y) ? 1 : 0;
    uni += (x || y) ? 1 : 0;
  }
  return uni == 0 ? 1.0 : double(inter) / double(uni);
}

}  // namespace penumbra::optim
