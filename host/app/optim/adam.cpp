// Adam (Kingma & Ba 2015) with bias-corrected moments.
#include <cmath>
#include <string>

#include "penumbra/error.hpp"
#include "penumbra/optim.hpp"

namespace penumbra::optim {

Adam::Adam(size_t size, AdamOptions options) : options_(options) { reset(size); }

void Adam::reset(size_t size) {
  m_.assign(size, 0.0);
  v_.assign(size, 0.0);
  t_ = 0;
}

void Adam::restore(const State& state) {
  if (state.m.size() != state.v.size() || state.t < 0)
    throw Error("Adam::restore: " + std::to_string(state.m.size()) + " first and " +
                std::to_string(state.v.size()) + " second moments, step " +
                std::to_string(state.t));
  m_ = state.m;
  v_ = state.v;
  t_ = state.t;
}

void Adam::step(double* x, const double* g) {
  ++t_;
  if (m_.empty()) return;
  const double b1 = options_.beta1, b2 = options_.beta2;
  const double c1 = 1.0 - std::pow(b1, double(t_)), c2 = 1.0 - std::pow(b2, double(t_));
  for (size_t i = 0; i < m_.size(); ++i) {
    m_[i] = b1 * m_[i] + (1.0 - b1) * g[i];
    v_[i] = b2 * v_[i] + (1.0 - b2) * g[i] * g[i];
    const double mhat = m_[i] / c1, vhat = v_[i] / c2;
    x[i] -= options_.lr * mhat / (std::sqrt(vhat) + options_.eps);
  }
}

void Adam::step(std::vector<double>& x, const std::vector<double>& g) {
  if (x.size() != m_.size() || g.size() != m_.size())
    throw Error("Adam::step: " + std::to_string(x.size()) + " parameters and " +
                std::to_string(g.size()) + " gradients for an optimiser of size " +
                std::to_string(m_.size()));
  step(x.data(), g.data());
}

void Adam::step(std::vector<glm::dvec3>& x, const std::vector<glm::dvec3>& g) {
  if (3 * x.size() != m_.size() || 3 * g.size() != m_.size())
    throw Error("Adam::step: " + std::to_string(x.size()) + " vectors and " +
                std::to_string(g.size()) + " gradients for an optimiser of size " +
                std::to_string(m_.size()));
  // glm::dvec3 is three packed doubles.
  static_assert(sizeof(glm::dvec3) == 3 * sizeof(double), "dvec3 must be three packed doubles");
  if (!x.empty()) step(&x[0].x, &g[0].x);
}

}  // namespace penumbra::optim
