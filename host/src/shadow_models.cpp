// The shadow models' rows on the device (shadow_models.hpp): each points at its stages in ops/.
#include "shadow_models.hpp"

#include <iterator>
#include <string>

#include "penumbra/error.hpp"

namespace penumbra::detail {
namespace {

// The accurate model (accurate_lookups.cpp): its lookups read the light's blocker-search variance.
void accurate_lookup(Kernels& k, const RenderParams& p, const Light& L, const View& v, Fragments& f,
                     int light, const LightMaps& m) {
  pcf_forward(k, p, blocker_search_sigma(p, L), v, f, light, m);
}
MapGrads accurate_lookup_backward(Kernels& k, const RenderParams& p, const Light& L, const View& v,
                                  Fragments& f, FragmentGrads& fgr, int light, const LightMaps& m,
                                  double* gsize) {
  return pcf_backward(k, p, blocker_search_sigma(p, L), v, f, fgr, light, m, gsize);
}
// Soft shadows' search map, S and A at a stride of 2 or more; the backward's bucket radii, and
// per call its gather entries' copies of the fragments (accurate_lookups.cpp).
ModelBytes accurate_memory(const ModelMemoryInput& in) {
  ModelBytes b;
  if (in.shadows == Shadows::Soft) b.kept += in.texels / 2 * in.real_bytes;
  if (!in.backward) return b;
  b.kept += in.texels * in.real_bytes;
  b.call = in.camera_fragments * (10 * in.real_bytes + sizeof(int));
  return b;
}

// The paper model (paper_lookups.cpp, paper_soft_map.cpp): its lookups need no light but its index.
void paper_lookup(Kernels& k, const RenderParams& p, const Light& /*L*/, const View& v,
                  Fragments& f, int light, const LightMaps& m) {
  shadow_forward(k, p, v, f, light, m);
}
MapGrads paper_lookup_backward(Kernels& k, const RenderParams& p, const Light& /*L*/, const View& v,
                               Fragments& f, FragmentGrads& fgr, int light, const LightMaps& m,
                               double* /*gsize: through P, not the lookups*/) {
  return shadow_backward(k, p, v, f, fgr, light, m);
}
// Soft shadows' penumbra map P, its faces' boxes and its per-texel sums (paper_soft_map.cpp). The
// exact hard shadows' weights are counted by memory.cpp (exact_lookups).
ModelBytes paper_memory(const ModelMemoryInput& in) {
  ModelBytes b;
  if (in.shadows == Shadows::Soft) b.kept = in.faces * 16 + in.texels * 3 * in.real_bytes;
  return b;
}

// In the enum's order, one row per model: the build stops where a model has none.
constexpr ShadowModelPasses kRows[] = {
    {ShadowModel::Accurate, "accurate_lookups.cl", false, 1, true, nullptr, nullptr, nullptr,
     nullptr, nullptr, accurate_lookup, accurate_lookup_backward, accurate_memory},
    {ShadowModel::Paper, "paper_lookups.cl", true, 0, false,
     [](const RenderParams& p) { return p.shadows == Shadows::Soft; }, "penumbra map",
     soft_map_forward, soft_map_backward_texels, soft_map_backward_faces, paper_lookup,
     paper_lookup_backward, paper_memory},
};
static_assert(std::size(kRows) == size_t(ShadowModel::Count), "a ShadowModel without its row");
constexpr bool in_enum_order() {
  for (size_t i = 0; i < std::size(kRows); ++i)
    if (kRows[i].value != ShadowModel(i)) return false;
  return true;
}
static_assert(in_enum_order(), "the rows of kRows are not in ShadowModel's order");

}  // namespace

const ShadowModelPasses& shadow_model_passes(ShadowModel m) {
  if (size_t(m) < std::size(kRows)) return kRows[size_t(m)];
  throw Error("shadow model " + std::to_string(int(m)) + " has no row in shadow_model_passes()");
}

const ShadowModelPasses* lookup_file_model(const std::string& file) {
  for (const ShadowModelPasses& row : kRows)
    if (file == row.lookup_file) return &row;
  return nullptr;
}

}  // namespace penumbra::detail
