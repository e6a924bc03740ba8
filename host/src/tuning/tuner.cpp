// The tuner: times the legal candidates of every stage, rejects any whose output differs from
// the default configuration's, and keeps the fastest.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>

#include "penumbra/error.hpp"
#include "penumbra/renderer.hpp"
#include "penumbra/tuning.hpp"

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
    ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
                     .count());
  }
  std::sort(ms.begin(), ms.end());
  trial.median_ms = ms[ms.size() / 2];
  return trial;
}

// Largest difference between two renders (colour, silhouette, depth relative to far).
double difference(const std::vector<RenderOutput>& a, const std::vector<RenderOutput>& b) {
  double worst = 0;
  for (size_t v = 0; v < a.size(); ++v)
    for (auto [x, y] : {std::pair{&a[v].color, &b[v].color},
                        std::pair{&a[v].silhouette, &b[v].silhouette}})
      for (size_t i = 0; i < x->data.size(); ++i)
        worst = std::max(worst, std::abs(x->data[i] - y->data[i]));
  return worst;
}

std::string describe(const Tuning& t, const std::string& stage) {
  std::ostringstream s;
  if (stage == "raster") s << "tile " << t.raster.tile << ", " << t.raster.pixels_per_item << " px/item";
  if (stage == "exact")
    s << (t.exact.clblast ? std::string("CLBlast GEMM")
                          : "matmul vw " + std::to_string(t.exact.vector_width) + ", rb " +
                                std::to_string(t.exact.row_block));
  if (stage == "penumbra") s << "tile " << t.penumbra.tile;
  return s.str();
}

}  // namespace

TuneReport tune(Context& context, const Scene& base, const TuneOptions& options) {
  const DeviceInfo& device = context.info();
  const int runs = std::max(1, options.quick ? std::min(options.runs, 3) : options.runs);
  TuneReport report;
  // Start from what the database would pick today for this scene.
  Tuning best = TuningDatabase::load_default().lookup(device, workload_stats(base));

  // One stage at a time, each on the workload it dominates. `tolerance` 0 means the
  // candidates must agree bit for bit (same summation order).
  struct Stage {
    std::string name;
    Shadows shadows;
    Sampling sampling;
    double tolerance;
    std::vector<Tuning> candidates;
  };
  std::vector<Stage> stages;
  {
    Stage raster{"raster", Shadows::None, Sampling::Truncated, 0.0, {}};
    const std::vector<int> tiles = options.quick ? std::vector<int>{8, 16} : std::vector<int>{8, 16, 32};
    const std::vector<int> ppws = options.quick ? std::vector<int>{1, 8} : std::vector<int>{1, 2, 4, 8, 16};
    for (int tile : tiles)
      for (int ppw : ppws) {
        Tuning t = best;
        t.raster.tile = tile;
        t.raster.pixels_per_item = ppw;
        try {
          validate(t, device);
          raster.candidates.push_back(t);
        } catch (const Error&) {  // not legal on this device
        }
      }
    stages.push_back(raster);
    // Exact-sum products: their order of summation differs, so outputs agree to rounding.
    Stage exact{"exact", Shadows::Hard, Sampling::Exact, 1e-4, {}};
    std::vector<std::pair<int, int>> shapes =
        options.quick ? std::vector<std::pair<int, int>>{{8, 4}}
                      : std::vector<std::pair<int, int>>{{4, 4}, {8, 2}, {8, 4}, {16, 2}, {16, 4}};
    for (auto [vw, rb] : shapes) {
      Tuning t = best;
      t.exact = {false, vw, rb};
      exact.candidates.push_back(t);
    }
    Tuning blas = best;
    blas.exact.clblast = true;
    exact.candidates.push_back(blas);
    stages.push_back(exact);
    Stage pen{"penumbra", Shadows::Soft, Sampling::Truncated, 0.0, {}};
    for (int tile : options.quick ? std::vector<int>{16} : std::vector<int>{8, 16, 32}) {
      Tuning t = best;
      t.penumbra.tile = tile;
      pen.candidates.push_back(t);
    }
    stages.push_back(pen);
  }

  for (Stage& stage : stages) {
    Scene scene = base;
    scene.params.shadows = stage.shadows;
    scene.params.sampling = stage.sampling;
    if (options.quick) {
      for (Camera& c : scene.cameras) c.width = std::min(c.width, 128), c.height = std::min(c.height, 128);
      scene.params.shadow_map_size = std::min(scene.params.shadow_map_size, 128);
    }
    fit_light_frusta(scene);
    // The reference output: the configuration the stage starts from.
    Tuning reference = best;
    const Trial ref = time_candidate(context, scene, reference, 1);
    double best_ms = INFINITY;
    Tuning winner = best;
    for (Tuning candidate : stage.candidates) {
      // Candidates of the later stages inherit the winners of the earlier ones.
      if (stage.name != "raster") candidate.raster = best.raster;
      if (stage.name == "penumbra") candidate.exact = best.exact;
      TuneReport::Candidate row{stage.name, describe(candidate, stage.name), 0, true, ""};
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
      report.candidates.push_back(row);
    }
    best = winner;
  }
  best.source = "tuned:" + TuningDatabase::device_key(device);
  report.best = best;
  return report;
}

}  // namespace penumbra
