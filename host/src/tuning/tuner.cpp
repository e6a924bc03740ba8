// The tuner: times the legal candidates of every stage, rejects any whose output differs from
// the default configuration's, and keeps the fastest.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <sstream>

#include "ops/ops.hpp"
#include "penumbra/error.hpp"
#include "penumbra/renderer.hpp"
#include "penumbra/tuning.hpp"
#include "tuning/stages.hpp"

namespace penumbra {

namespace {

struct Trial {
  double median_ms = 0;
  std::vector<RenderOutput> outputs;
};

// A warm-up render and backward (kernel builds), then `runs` timed ones; the median.
Trial time_candidate(Context& context, const Scene& scene, const Tuning& tuning, int runs) {
  Renderer renderer(context, Precision::Float, tuning);
  Trial trial;
  trial.outputs = renderer.render(scene);
  std::vector<OutputGrads> grads(trial.outputs.size());
  for (size_t v = 0; v < grads.size(); ++v)
    grads[v].color = Image(trial.outputs[v].color.width, trial.outputs[v].color.height, 3, 1.0);
  renderer.backward(scene, grads);
  std::vector<double> ms;
  for (int r = 0; r < runs; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    renderer.render(scene);
    renderer.backward(scene, grads);
    ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  std::sort(ms.begin(), ms.end());
  trial.median_ms = ms[ms.size() / 2];
  return trial;
}

// Largest difference between two renders (colour, silhouette, depth relative to far).
double difference(const std::vector<RenderOutput>& a, const std::vector<RenderOutput>& b) {
  double worst = 0;
  for (size_t v = 0; v < a.size(); ++v)
    for (auto [x, y] :
         {std::pair{&a[v].color, &b[v].color}, std::pair{&a[v].silhouette, &b[v].silhouette}})
      for (size_t i = 0; i < x->data.size(); ++i)
        worst = std::max(worst, std::abs(x->data[i] - y->data[i]));
  return worst;
}

std::string describe(const Tuning& t, const std::string& stage) {
  std::ostringstream s;
  if (stage == "raster")
    s << "tile " << t.raster.tile << ", " << t.raster.pixels_per_item << " px/item";
  if (stage == "exact" && !t.exact.clblast)
    s << "matmul vw " << t.exact.vector_width << ", rb " << t.exact.row_block;
  if (stage == "exact" && t.exact.clblast)
    s << "CLBlast GEMM " << (t.exact.xgemm ? t.exact.xgemm->describe() : "(its defaults)");
  if (stage == "soft_map") s << "tile " << t.soft_map.tile;
  if (stage == "gather")
    s << "group " << t.gather.group << "x" << t.gather.group << ", block " << t.gather.width << "x"
      << t.gather.height;
  return s.str();
}

}  // namespace

std::vector<XgemmParameters> xgemm_candidates(bool quick) {
  // Each work-item accumulates a block of MWG/MDIMC × NWG/NDIMC outputs held in float16 (AVX-512)
  // or float8 vectors: PoCL does not vectorize the Xgemm loops across work-items, so the
  // explicit vector widths VWM and VWN carry the SIMD. MDIMA = MDIMC and NDIMB = NDIMC.
  auto make = [](int mwg, int nwg, int kwg, int mdimc, int ndimc, int vwm, int vwn, int cache) {
    XgemmParameters x;
    x.MWG = mwg, x.NWG = nwg, x.KWG = kwg, x.KWI = 2;
    x.MDIMC = x.MDIMA = mdimc, x.NDIMC = x.NDIMB = ndimc;
    x.VWM = vwm, x.VWN = vwn, x.SA = x.SB = cache;
    x.GEMMK = 0, x.KREG = 1, x.STRM = x.STRN = 0;
    return x;
  };
  // --quick tries the first two: the fastest of these in both of two runs on a 2-core AVX-512
  // EPYC (docs/tuning.md), and one with float16 vectors.
  std::vector<XgemmParameters> all = {
      make(64, 64, 32, 8, 8, 8, 8, 0),     // 8 × 8 outputs per item in float8, no local memory
      make(128, 64, 32, 8, 8, 16, 8, 0),   // 16 × 8 outputs per item in float16
      make(64, 64, 32, 4, 8, 16, 8, 0),    // the same per item, half the tile
      make(64, 64, 32, 4, 8, 16, 8, 1),    // as the last, A and B tiles in local memory
      make(64, 128, 32, 4, 8, 16, 16, 0),  // 16 × 16 outputs per item
      make(32, 32, 16, 2, 4, 16, 8, 0),    // small tiles: little padding
  };
  if (quick) all.resize(2);
  return all;
}

namespace detail {

// Adds candidate `t` to `stage` if it is legal on `device`.
void add_if_legal(TuneStage& stage, const Tuning& t, const DeviceInfo& device) {
  try {
    validate(t, device);
    stage.candidates.push_back(t);
  } catch (const Error&) {  // not legal on this device
  }
}

// The texel gathers' work-groups at the starting block of texels, then the blocks at the
// starting group: the same sums in the same order, so bit for bit.
TuneStage gather_stage(const DeviceInfo& device, const Tuning& start, bool quick) {
  TuneStage gather{"gather", Shadows::Soft, Sampling::Truncated, 0.0, {}};
  for (int group : quick ? std::vector<int>{1, 2} : std::vector<int>{1, 2, 4, 8, 16}) {
    Tuning t = start;
    t.gather.group = group;
    add_if_legal(gather, t, device);
  }
  for (int width : quick ? std::vector<int>{} : std::vector<int>{4, 8, 16})
    for (int height : {1, 4, 8}) {
      Tuning t = start;
      t.gather.width = width;
      t.gather.height = height;
      if (width != start.gather.width || height != start.gather.height)
        add_if_legal(gather, t, device);
    }
  return gather;
}

std::vector<TuneStage> tune_stages(const DeviceInfo& device, const Tuning& start, bool quick) {
  // One stage at a time, each on the workload it dominates. `tolerance` 0 means the
  // candidates must agree bit for bit (same summation order).
  using Stage = TuneStage;
  std::vector<Stage> stages;
  Stage raster{"raster", Shadows::None, Sampling::Truncated, 0.0, {}};
  const std::vector<int> tiles = quick ? std::vector<int>{8, 16} : kRasterTiles;
  const std::vector<int> ppws = quick ? std::vector<int>{1, 8} : std::vector<int>{1, 2, 4, 8, 16};
  for (int tile : tiles)
    for (int ppw : ppws) {
      Tuning t = start;
      t.raster.tile = tile;
      t.raster.pixels_per_item = ppw;
      add_if_legal(raster, t, device);
    }
  stages.push_back(raster);
  // Exact-sum products: their order of summation differs, so outputs agree to rounding. Timed
  // dense: at the scene's σ_s most weights are 0, the products skip them and take a small part
  // of the frame, where the candidates' differences drown in the rest.
  Stage exact{"exact", Shadows::Hard, Sampling::Exact, 1e-4, {}, true};
  std::vector<std::pair<int, int>> shapes =
      quick ? std::vector<std::pair<int, int>>{{8, 4}}
            : std::vector<std::pair<int, int>>{{4, 4},  {8, 2},  {8, 4}, {8, 8},
                                               {16, 2}, {16, 4}, {16, 8}};
  for (auto [vw, rb] : shapes) {
    Tuning t = start;
    t.exact.clblast = false;
    t.exact.vector_width = vw;
    t.exact.row_block = rb;
    exact.candidates.push_back(t);
  }
  // CLBlast with its own parameters, then with each Xgemm candidate, forced to its Xgemm
  // kernel (below m·n·k = 896³ it would run its direct kernel, where they do nothing).
  Tuning blas = start;
  blas.exact.clblast = true;
  blas.exact.xgemm.reset();
  blas.exact.min_indirect_size = 0;
  exact.candidates.push_back(blas);
  for (const XgemmParameters& x : xgemm_candidates(quick)) {
    blas.exact.xgemm = x;
    blas.exact.min_indirect_size = 1;
    add_if_legal(exact, blas, device);
  }
  stages.push_back(exact);
  Stage pen{"soft_map", Shadows::Soft, Sampling::Truncated, 0.0, {}};
  for (int tile : quick ? std::vector<int>{16} : kRasterTiles) {
    Tuning t = start;
    t.soft_map.tile = tile;
    pen.candidates.push_back(t);
  }
  stages.push_back(pen);
  stages.push_back(gather_stage(device, start, quick));
  return stages;
}

}  // namespace detail

namespace {

// The scene a stage times: the stage's shadows, at most 128² images and maps when quick.
Scene stage_scene(const Scene& base, const detail::TuneStage& stage, bool quick) {
  Scene scene = base;
  scene.params.shadows = stage.shadows;
  scene.params.sampling = stage.sampling;
  scene.params.shadow_model = ShadowModel::Paper;  // the products and the penumbra map are its
  if (quick) {
    for (Camera& c : scene.cameras)
      c.width = std::min(c.width, 128), c.height = std::min(c.height, 128);
    scene.params.shadow_map_size = std::min(shadow_map_side(scene.params), 128);
  }
  // e^(−d²/(2σ_s)) stays above the least normal float (e^−87) for every offset d < side.
  if (stage.dense) scene.params.sigma_s = std::pow(shadow_map_side(scene.params), 2) / 170.0;
  refit_light_frusta(scene);
  return scene;
}

// With options.clblast_fraction > 0, CLBlast's own tuner's set (on a side³ product, side the
// exact stage's map side) as one more candidate of the exact stage, starting from `start`; a
// rejected row of the report where the tuner failed or its set is not legal here.
std::optional<XgemmParameters> add_clblast_tuned(Context& context, const Scene& base,
                                                 const TuneOptions& options, const Tuning& start,
                                                 std::vector<detail::TuneStage>& stages,
                                                 TuneReport& report) {
  const auto exact = std::find_if(stages.begin(), stages.end(),
                                  [](const detail::TuneStage& s) { return s.name == "exact"; });
  if (!(options.clblast_fraction > 0) || exact == stages.end()) return std::nullopt;
  const size_t n = size_t(shadow_map_side(stage_scene(base, *exact, options.quick).params));
  std::string why;
  std::optional<XgemmParameters> x =
      detail::clblast_tuned_xgemm(context, n, n, n, options.clblast_fraction, &why);
  if (!x) {
    report.candidates.push_back({"exact", "CLBlast's Xgemm tuner", 0, false, why});
    return x;
  }
  Tuning t = start;
  t.exact.clblast = true;
  t.exact.xgemm = *x;
  t.exact.min_indirect_size = 1;  // as the other sets: its Xgemm kernel at every size
  try {
    validate(t, context.info());
  } catch (const Error& e) {
    report.candidates.push_back(
        {"exact", "CLBlast GEMM " + x->describe() + " (CLBlast's tuner)", 0, false, e.what()});
    return std::nullopt;
  }
  exact->candidates.push_back(t);
  return x;
}

}  // namespace

TuneReport tune(Context& context, const Scene& base, const TuneOptions& options) {
  const DeviceInfo& device = context.info();
  const int runs = std::max(1, options.quick ? std::min(options.runs, 3) : options.runs);
  TuneReport report;
  // Start from what the database would pick today for this scene.
  Tuning best = TuningDatabase::load_default().lookup(device, workload_stats(base));

  std::vector<detail::TuneStage> stages = detail::tune_stages(device, best, options.quick);
  const std::optional<XgemmParameters> clblast_tuned =
      add_clblast_tuned(context, base, options, best, stages, report);
  for (detail::TuneStage& stage : stages) {
    const Scene scene = stage_scene(base, stage, options.quick);
    // The reference output: the configuration the stage starts from.
    Tuning reference = best;
    const Trial ref = time_candidate(context, scene, reference, 1);
    double best_ms = INFINITY, best_blas_ms = INFINITY;
    Tuning winner = best;
    ExactSumTuning best_blas;  // the fastest CLBlast candidate: exact backend `clblast` uses it
    for (Tuning candidate : stage.candidates) {
      // Candidates of the later stages inherit the winners of the earlier ones.
      if (stage.name != "raster") candidate.raster = best.raster;
      if (stage.name != "exact") candidate.exact = best.exact;
      if (stage.name != "soft_map") candidate.soft_map = best.soft_map;
      TuneReport::Candidate row{stage.name, describe(candidate, stage.name), 0, true, ""};
      if (stage.name == "exact" && candidate.exact.clblast && candidate.exact.xgemm &&
          candidate.exact.xgemm == clblast_tuned)
        row.name += " (CLBlast's tuner)";
      try {
        const Trial trial = time_candidate(context, scene, candidate, runs);
        row.median_ms = trial.median_ms;
        const double diff = difference(trial.outputs, ref.outputs);
        if (diff > stage.tolerance) {
          row.accepted = false;
          row.note = "output differs from the default by " + std::to_string(diff);
        }
      } catch (const std::exception& e) {
        row.accepted = false;
        row.note = e.what();
      }
      if (row.accepted && row.median_ms < best_ms) best_ms = row.median_ms, winner = candidate;
      if (row.accepted && stage.name == "exact" && candidate.exact.clblast &&
          row.median_ms < best_blas_ms)
        best_blas_ms = row.median_ms, best_blas = candidate.exact;
      report.candidates.push_back(row);
    }
    if (best_blas_ms < INFINITY) {
      winner.exact.xgemm = best_blas.xgemm;
      winner.exact.min_indirect_size = best_blas.min_indirect_size;
    }
    best = winner;
  }
  best.source = "tuned:" + TuningDatabase::device_key(device);
  report.best = best;
  return report;
}

}  // namespace penumbra
