// The words of the scene's enums (as scene files and the tool spell them) and the tables of
// sampling methods and shadow models with their traits (penumbra/scene.hpp).
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "penumbra/error.hpp"
#include "penumbra/scene.hpp"

namespace penumbra {

template <>
const std::vector<std::pair<Projection, std::string>>& enum_words<Projection>() {
  static const std::vector<std::pair<Projection, std::string>> words{
      {Projection::Perspective, "perspective"}, {Projection::Orthographic, "orthographic"}};
  return words;
}
template <>
const std::vector<std::pair<LightType, std::string>>& enum_words<LightType>() {
  static const std::vector<std::pair<LightType, std::string>> words{
      {LightType::Point, "point"}, {LightType::Directional, "directional"}};
  return words;
}
template <>
const std::vector<std::pair<ShadowMapShape, std::string>>& enum_words<ShadowMapShape>() {
  static const std::vector<std::pair<ShadowMapShape, std::string>> words{
      {ShadowMapShape::Auto, "auto"},
      {ShadowMapShape::Frustum, "frustum"},
      {ShadowMapShape::Cube, "cube"}};
  return words;
}
template <>
const std::vector<std::pair<Shadows, std::string>>& enum_words<Shadows>() {
  static const std::vector<std::pair<Shadows, std::string>> words{
      {Shadows::None, "none"}, {Shadows::Hard, "hard"}, {Shadows::Soft, "soft"}};
  return words;
}
const std::vector<SamplingMethod>& sampling_methods() {
  static const std::vector<SamplingMethod> methods{
      {Sampling::Truncated, "truncated", "Gaussian cut at ε_λ", true},
      {Sampling::Exact, "exact", "every texel", false}};
  return methods;
}
const SamplingMethod& sampling_method(Sampling s) {
  for (const SamplingMethod& m : sampling_methods())
    if (m.value == s) return m;
  throw Error("sampling method " + std::to_string(int(s)) + " is not in sampling_methods()");
}
template <>
const std::vector<std::pair<Sampling, std::string>>& enum_words<Sampling>() {
  static const std::vector<std::pair<Sampling, std::string>> words = [] {
    std::vector<std::pair<Sampling, std::string>> w;
    for (const SamplingMethod& m : sampling_methods()) w.emplace_back(m.value, m.word);
    return w;
  }();
  return words;
}
template <>
const std::vector<std::pair<ExactBackend, std::string>>& enum_words<ExactBackend>() {
  static const std::vector<std::pair<ExactBackend, std::string>> words{
      {ExactBackend::Auto, "auto"},
      {ExactBackend::Kernels, "kernels"},
      {ExactBackend::CLBlast, "clblast"}};
  return words;
}

bool sampling_from_word(const std::string& w, Sampling* sampling,
                        std::optional<ExactBackend>* backend) {
  if (w == gemm_shorthand()) {
    *sampling = Sampling::Exact;
    *backend = ExactBackend::CLBlast;
    return true;
  }
  backend->reset();
  return from_word(w, sampling);
}

std::string sampling_word_choices() {
  std::string out;
  for (const auto& [value, w] : enum_words<Sampling>()) out += w + ", ";
  return out.substr(0, out.size() - 2) + " or " + gemm_shorthand();
}
// The defaults and their reasons: docs/shadows.md (paper: math.md §10). The accurate model's
// compare needs no slack for a tilted receiver, so a small β keeps contact shadows closed; its
// hard shadow's edge falls within a fraction of a texel of the true edge, so the map sets how
// far it can stray (against the ray tracer a 256² map left one contact pixel lit on a knot
// touching the ground, bench/accuracy.hpp).
const std::vector<ShadowModelTraits>& shadow_models() {
  static const std::vector<ShadowModelTraits> models{
      {ShadowModel::Accurate, "accurate",
       "percentage-closer filtering; soft shadows by a blocker search, PCSS", 0.35, 0.004, 0.01,
       384, true, false, "compares, then filters"},
      {ShadowModel::Paper, "paper", "filter then compare; the penumbra map", 2.0, 0.02, 0.05, 256,
       false, true, ""}};
  return models;
}
const ShadowModelTraits& shadow_model_traits(ShadowModel m) {
  for (const ShadowModelTraits& t : shadow_models())
    if (t.value == m) return t;
  throw Error("shadow model " + std::to_string(int(m)) + " is not in shadow_models()");
}
template <>
const std::vector<std::pair<ShadowModel, std::string>>& enum_words<ShadowModel>() {
  static const std::vector<std::pair<ShadowModel, std::string>> words = [] {
    std::vector<std::pair<ShadowModel, std::string>> w;
    for (const ShadowModelTraits& m : shadow_models()) w.emplace_back(m.value, m.word);
    return w;
  }();
  return words;
}

}  // namespace penumbra
