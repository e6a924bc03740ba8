#pragma once
// The tuner's stages and their candidates, shared by the tuner (tuner.cpp) and by
// kernel_variants (ops/kernels.cpp), which builds every program a candidate can ask for.
#include <string>
#include <vector>

#include "penumbra/scene.hpp"
#include "penumbra/tuning.hpp"

namespace penumbra::detail {

// The raster tiles the heuristic chooses from and the tuner tries.
inline const std::vector<int> kRasterTiles = {8, 16, 32};

// One stage of the tuner: the workload it times (shadow mode and sampling; `dense`: at a σ_s
// where no Gaussian weight of the map is 0, so that the exact sum's products skip nothing), how
// far a candidate's output may differ from the starting configuration's (0: bit for bit), and
// the candidates, each `start` with this stage's parameters changed.
struct TuneStage {
  std::string name;  // raster, exact, soft_map, gather
  Shadows shadows;
  Sampling sampling;
  double tolerance;
  std::vector<Tuning> candidates;
  bool dense = false;
};

// The stages in the order the tuner runs them, with the candidates legal on `device`
// (`quick`: fewer).
std::vector<TuneStage> tune_stages(const DeviceInfo& device, const Tuning& start, bool quick);

}  // namespace penumbra::detail
