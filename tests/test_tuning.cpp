// Tuning: every candidate of every stage gives the default configuration's result, the
// database falls back cleanly, the heuristic reacts to the workload, the tuner runs.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>

#include "penumbra/error.hpp"
#include "penumbra/io.hpp"
#include "penumbra/renderer.hpp"
#include "penumbra/tuning.hpp"

using namespace penumbra;

namespace {

Context& context() {
  static Context ctx;
  return ctx;
}

// The bundled scene, small: 48×40 image, 32² map.
Scene small_scene(Shadows shadows, Sampling sampling) {
  Scene s = load_scene(std::string(PENUMBRA_DATA_DIR) + "/scenes/turnaround.json");
  for (Camera& c : s.cameras) c.width = 48, c.height = 40;
  s.params.shadows = shadows;
  s.params.sampling = sampling;
  s.params.shadow_map_size = 32;
  return s;
}

std::vector<RenderOutput> render_with(const Scene& s, const Tuning& t, Precision p) {
  Renderer r(context(), p, t);
  return r.render(s);
}

double max_difference(const std::vector<RenderOutput>& a, const std::vector<RenderOutput>& b) {
  double worst = 0;
  for (size_t v = 0; v < a.size(); ++v)
    for (size_t i = 0; i < a[v].color.data.size(); ++i)
      worst = std::max(worst, std::abs(a[v].color.data[i] - b[v].color.data[i]));
  return worst;
}

void expect_identical(const std::vector<RenderOutput>& a, const std::vector<RenderOutput>& b,
                      const std::string& what) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t v = 0; v < a.size(); ++v) {
    EXPECT_EQ(a[v].color.data, b[v].color.data) << what;
    EXPECT_EQ(a[v].silhouette.data, b[v].silhouette.data) << what;
    EXPECT_EQ(a[v].depth.data, b[v].depth.data) << what;
  }
}

}  // namespace

TEST(Tuning, EveryRasterCandidateIsBitIdenticalWithShadows) {
  for (Shadows shadows : {Shadows::Hard, Shadows::Soft}) {
    const Scene s = small_scene(shadows, Sampling::Truncated);
    Tuning base;
    base.raster = {16, 1, false};
    const auto ref = render_with(s, base, Precision::Float);
    for (int tile : {8, 16, 32})
      for (int ppw : {1, 2, 4, 8, 16}) {
        if (tile % ppw) continue;
        Tuning t = base;
        t.raster = {tile, ppw, false};
        expect_identical(render_with(s, t, Precision::Float), ref,
                         "tile " + std::to_string(tile) + ", ppw " + std::to_string(ppw));
      }
  }
}

TEST(Tuning, EveryPenumbraTileIsBitIdentical) {
  const Scene s = small_scene(Shadows::Soft, Sampling::Truncated);
  Tuning base;
  const auto ref = render_with(s, base, Precision::Double);
  for (int tile : {4, 8, 32, 64}) {
    Tuning t = base;
    t.penumbra.tile = tile;
    expect_identical(render_with(s, t, Precision::Double), ref, "penumbra tile " + std::to_string(tile));
  }
}

// The exact-sum products change their summation order with the vector width and row block,
// and CLBlast orders them its own way: the results agree to rounding, not bit for bit.
TEST(Tuning, EveryExactSumCandidateAgreesToRounding) {
  const Scene s = small_scene(Shadows::Hard, Sampling::Exact);
  for (Precision p : {Precision::Float, Precision::Double}) {
    const double tol = p == Precision::Double ? 1e-12 : 2e-5;
    Tuning base;
    const auto ref = render_with(s, base, p);
    for (int vw : {1, 2, 4, 8, 16})
      for (int rb : {1, 2, 4, 8}) {
        Tuning t = base;
        t.exact = {false, vw, rb};
        EXPECT_LE(max_difference(render_with(s, t, p), ref), tol) << "vw " << vw << " rb " << rb;
      }
    Tuning blas = base;
    blas.exact.clblast = true;
    EXPECT_LE(max_difference(render_with(s, blas, p), ref), tol) << "CLBlast";
  }
}

TEST(Tuning, IllegalValuesAreRejectedWithAClearMessage) {
  Tuning t;
  t.raster = {12, 8, false};
  EXPECT_THROW(validate(t, context().info()), Error);
  t = Tuning{};
  t.raster.pixels_per_item = 1;
  t.exact.vector_width = 3;
  try {
    validate(t, context().info());
    FAIL() << "vector width 3 accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("vector_width 3"), std::string::npos) << e.what();
  }
}

TEST(Tuning, DatabaseFallsBackFromDeviceToClassToHeuristic) {
  const std::string path = ::testing::TempDir() + "/tuning_db.json";
  {
    std::ofstream out(path);
    out << R"({"version": 1, "entries": {
      "Exact Device 1": {"raster": {"tile": 32, "pixels_per_item": 4},
                         "exact": {"clblast": false, "vector_width": 16, "row_block": 2},
                         "penumbra": {"tile": 8}},
      "Acme/gpu": {"exact": {"clblast": true}, "penumbra": {"tile": 32}},
      "cpu": {"raster": {"pixels_per_item": 8}}}})";
  }
  const TuningDatabase db = TuningDatabase::load({path});
  EXPECT_EQ(db.size(), 3u);
  DeviceInfo dev;
  dev.max_work_group = 1024;
  WorkloadStats w;
  w.faces = 1000, w.mean_face_pixels = 20, w.cutoff_pixels = 1, w.width = w.height = 256;

  dev.name = "Exact Device 1", dev.vendor = "Acme", dev.is_gpu = true;
  Tuning t = db.lookup(dev, w);
  EXPECT_EQ(t.source, "tuned:Exact Device 1");
  EXPECT_EQ(t.raster.tile, 32);
  EXPECT_EQ(t.exact.vector_width, 16);
  EXPECT_EQ(t.penumbra.tile, 8);

  dev.name = "Unknown Device 7";  // same vendor and type: the class entry, heuristic tile
  t = db.lookup(dev, w);
  EXPECT_EQ(t.source, "heuristic+Acme/gpu");
  EXPECT_TRUE(t.exact.clblast);
  EXPECT_EQ(t.penumbra.tile, 32);
  EXPECT_EQ(t.raster.pixels_per_item, 1);  // the heuristic's choice for a GPU

  dev.vendor = "Nobody", dev.is_gpu = false;  // only the type matches
  t = db.lookup(dev, w);
  EXPECT_EQ(t.source, "heuristic+cpu");
  EXPECT_EQ(t.raster.pixels_per_item, 8);

  const TuningDatabase empty = TuningDatabase::load({});
  t = empty.lookup(dev, w);
  EXPECT_EQ(t.source, "heuristic");
  EXPECT_NO_THROW(validate(t, dev));
}

TEST(Tuning, CorruptOrMissingDatabaseFallsBackWithAWarning) {
  const std::string bad = ::testing::TempDir() + "/tuning_corrupt.json";
  {
    std::ofstream out(bad);
    out << "{ this is not json";
  }
  ::testing::internal::CaptureStderr();
  const TuningDatabase db = TuningDatabase::load({bad, ::testing::TempDir() + "/no_such_file.json"});
  const std::string err = ::testing::internal::GetCapturedStderr();
  EXPECT_EQ(db.size(), 0u);
  EXPECT_NE(err.find("penumbra: warning: ignoring tuning database"), std::string::npos) << err;
  EXPECT_NE(err.find("not found"), std::string::npos) << err;
  EXPECT_NO_THROW(validate(db.lookup(context().info(), WorkloadStats{}), context().info()));

  // A renderer pointed at it by PENUMBRA_TUNING still renders, with what it would use without.
  const Scene scene = small_scene(Shadows::None, Sampling::Truncated);
  const std::string expected =
      TuningDatabase::load_default().lookup(context().info(), workload_stats(scene)).source;
  setenv("PENUMBRA_TUNING", bad.c_str(), 1);
  ::testing::internal::CaptureStderr();
  Renderer r(context());
  const auto out = r.render(scene);
  const std::string warned = ::testing::internal::GetCapturedStderr();
  unsetenv("PENUMBRA_TUNING");
  EXPECT_EQ(out.size(), 1u);
  EXPECT_EQ(r.tuning().source, expected);
  EXPECT_NE(warned.find("ignoring tuning database"), std::string::npos) << warned;
}

TEST(Tuning, HeuristicPrefersSmallTilesForManySmallFaces) {
  DeviceInfo cpu;
  cpu.max_work_group = 4096;
  WorkloadStats many_small;
  many_small.faces = 200000, many_small.mean_face_pixels = 1, many_small.cutoff_pixels = 1;
  many_small.width = many_small.height = 1024;
  WorkloadStats few_large = many_small;
  few_large.faces = 50, few_large.mean_face_pixels = 20000;
  const Tuning a = heuristic_tuning(cpu, many_small), b = heuristic_tuning(cpu, few_large);
  EXPECT_LT(a.raster.tile, b.raster.tile);
  EXPECT_EQ(a.raster.pixels_per_item, 8);
  DeviceInfo gpu = cpu;
  gpu.is_gpu = true;
  gpu.max_work_group = 1024;
  EXPECT_EQ(heuristic_tuning(gpu, few_large).raster.pixels_per_item, 1);
}

TEST(Tuning, TunerTimesEveryStageAndReturnsALegalWinner) {
  Scene s = small_scene(Shadows::None, Sampling::Truncated);
  TuneOptions o;
  o.quick = true;
  o.runs = 1;
  const TuneReport report = tune(context(), s, o);
  bool raster = false, exact = false, pen = false;
  for (const auto& c : report.candidates) {
    raster |= c.stage == "raster";
    exact |= c.stage == "exact";
    pen |= c.stage == "penumbra";
    EXPECT_TRUE(c.accepted) << c.stage << " " << c.name << ": " << c.note;
    EXPECT_GT(c.median_ms, 0.0);
  }
  EXPECT_TRUE(raster && exact && pen);
  EXPECT_NO_THROW(validate(report.best, context().info()));
  EXPECT_EQ(report.best.source.rfind("tuned:", 0), 0u);
}
