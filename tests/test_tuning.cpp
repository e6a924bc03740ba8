// Tuning: every candidate of every stage gives the default configuration's result, a broken
// database falls back with a warning, the tuner runs (the database's lookups and files, and the
// heuristic: test_tuning_database.cpp).
#include <clblast.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <optional>
#include <set>

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
  s.params.shadow_model = ShadowModel::Paper;  // the exact products and the penumbra map are its
  refit_light_frusta(s);
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

// What `call` prints on stderr.
template <class Call>
std::string warnings_of(Call call) {
  ::testing::internal::CaptureStderr();
  call();
  return ::testing::internal::GetCapturedStderr();
}

}  // namespace

// kernel_variants (what scripts/spir_check.sh compiles offline) lists every program a renderer
// builds: both shadow models, every shadow mode and sampling, both precisions, brute force.
TEST(Tuning, KernelVariantsListEveryProgramTheRendererBuilds) {
  Context ctx;  // its own: only the programs of this test
  auto run = [](Renderer& r, const Scene& s) {
    const auto out = r.render(s);
    std::vector<OutputGrads> grads(out.size());
    for (size_t v = 0; v < out.size(); ++v)
      grads[v].color = Image(out[v].color.width, out[v].color.height, 3, 1.0);
    r.backward(s, grads);
  };
  for (Precision p : {Precision::Float, Precision::Double}) {
    if (p == Precision::Double && !ctx.info().fp64) continue;
    Renderer renderer(ctx, p);
    for (ShadowModel model : {ShadowModel::Paper, ShadowModel::Accurate})
      for (Shadows shadows : {Shadows::None, Shadows::Hard, Shadows::Soft})
        for (Sampling sampling : {Sampling::Truncated, Sampling::Exact})
          for (ExactBackend backend :
               {ExactBackend::Auto, ExactBackend::Kernels, ExactBackend::CLBlast}) {
            if (backend != ExactBackend::Auto && sampling != Sampling::Exact) continue;
            if (backend == ExactBackend::CLBlast &&
                (shadows != Shadows::Hard || model != ShadowModel::Paper))
              continue;
            Scene s = small_scene(shadows, sampling);
            s.params.exact_backend = backend;
            s.params.shadow_model = model;
            refit_light_frusta(s);
            run(renderer, s);
          }
  }
  Tuning brute;
  brute.raster.brute_force = true;
  Renderer renderer(ctx, Precision::Float, brute);
  run(renderer, small_scene(Shadows::Soft, Sampling::Truncated));

  std::set<std::pair<std::string, std::string>> listed;
  for (const KernelVariant& v : kernel_variants(ctx.info())) listed.insert({v.file, v.options});
  const auto built = ctx.programs();
  EXPECT_GE(built.size(), 7u);
  for (const auto& program : built)
    EXPECT_TRUE(listed.count(program))
        << program.first << " built with '" << program.second << "' is not in kernel_variants";
}

// Oclgrind alone builds every program with -DPENUMBRA_OCLGRIND (kernels/common/real.clh: no
// forced inlining there); any other device gets the options it had without it.
TEST(Tuning, OnlyOclgrindBuildsWithoutForcedInlining) {
  DeviceInfo oclgrind;
  oclgrind.platform = "Oclgrind", oclgrind.name = "Oclgrind Simulator";
  oclgrind.is_gpu = oclgrind.fp64 = true, oclgrind.max_work_group = 1024;
  DeviceInfo other = oclgrind;
  other.platform = "Portable Computing Language";
  const auto with = kernel_variants(oclgrind), without = kernel_variants(other);
  ASSERT_EQ(with.size(), without.size());
  for (size_t i = 0; i < with.size(); ++i) {
    EXPECT_EQ(with[i].file, without[i].file);
    EXPECT_EQ(without[i].options.find("PENUMBRA_OCLGRIND"), std::string::npos);
    std::string options = with[i].options;
    const size_t at = options.find(" -DPENUMBRA_OCLGRIND");
    ASSERT_NE(at, std::string::npos) << with[i].file << " " << options;
    EXPECT_EQ(options.erase(at, 20), without[i].options);
  }
  const std::string real = Context::kernel_source("raster.cl");
  EXPECT_NE(real.find("#ifdef PENUMBRA_OCLGRIND\n#define INLINE inline\n#else"), std::string::npos);
}

// A render builds only the forward part of each stage's file; the backward kernels are
// programs of their own, built by the first backward (KernelPart, ops.hpp).
TEST(Tuning, RenderBuildsNoBackwardKernel) {
  Context ctx;  // its own, so that its programs are this test's alone
  Renderer renderer(ctx, Precision::Float);
  auto backward_programs = [&] {
    int n = 0;
    for (const auto& program : ctx.programs())
      n += program.second.find("-DBACKWARD_KERNELS") != std::string::npos;
    return n;
  };
  for (ShadowModel model : {ShadowModel::Paper, ShadowModel::Accurate})
    for (Shadows shadows : {Shadows::Hard, Shadows::Soft}) {
      Scene s = small_scene(shadows, Sampling::Truncated);
      s.params.shadow_model = model;
      refit_light_frusta(s);
      renderer.render(s);
    }
  EXPECT_EQ(backward_programs(), 0);
  const Scene s = small_scene(Shadows::Soft, Sampling::Truncated);  // paper: every stage
  const auto out = renderer.render(s);
  std::vector<OutputGrads> g(out.size());
  for (size_t c = 0; c < out.size(); ++c)
    g[c].color = Image(out[c].color.width, out[c].color.height, 3, 1.0);
  renderer.backward(s, g);
  // transform, raster, penumbra, paper_lookups.cl for soft_sample_bwd and for shadow_boxes
  EXPECT_EQ(backward_programs(), 5);
}

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

// The automatic tuning, chosen for the faces, first camera and cut-off (the heuristic reads every
// face), is kept while only vertices move, with the bits of the tile a new renderer picks; a new
// camera size chooses again. This device's own entry, made illegal, warns at each choice.
TEST(Tuning, AutomaticTuningIsKeptWhileOnlyVerticesMove) {
  const std::string path = ::testing::TempDir() + "/illegal_entry.json";
  std::ofstream(path) << R"({"entries": {")" << context().info().name
                      << R"(": {"raster": {"pixels_per_item": 3}}}})";
  setenv("PENUMBRA_TUNING", path.c_str(), 1);
  Scene s = small_scene(Shadows::Hard, Sampling::Truncated);
  s.cameras[0].width = s.cameras[0].height = 256;
  Scene moved = scale_scene(s, 4);  // every length 4 times, the camera kept: larger faces
  moved.cameras = s.cameras;
  Renderer renderer(context()), fresh(context());
  std::vector<RenderOutput> out, fresh_out;
  const std::string first = warnings_of([&] { renderer.render(s); });
  const int tile = renderer.tuning().raster.tile;
  EXPECT_EQ(warnings_of([&] { out = renderer.render(moved); }), "");
  EXPECT_EQ(renderer.tuning().raster.tile, tile);
  warnings_of([&] { fresh_out = fresh.render(moved); });
  for (Camera& c : moved.cameras) c.width = c.height = 255;
  const std::string again = warnings_of([&] { renderer.render(moved); });
  unsetenv("PENUMBRA_TUNING");
  EXPECT_NE(first.find("ignoring tuned entry"), std::string::npos) << first;
  ASSERT_NE(fresh.tuning().raster.tile, tile) << "the moved scene should get another tile";
  EXPECT_EQ(renderer.tuning().raster.tile, fresh.tuning().raster.tile);
  expect_identical(out, fresh_out, "the moved scene, kept and chosen tile");
  EXPECT_NE(again.find("ignoring tuned entry"), std::string::npos) << again;
}

TEST(Tuning, EveryPenumbraTileIsBitIdentical) {
  const Scene s = small_scene(Shadows::Soft, Sampling::Truncated);
  Tuning base;
  const auto ref = render_with(s, base, Precision::Double);
  for (int tile : {4, 8, 32, 64}) {
    Tuning t = base;
    t.soft_map.tile = tile;
    expect_identical(render_with(s, t, Precision::Double), ref,
                     "penumbra tile " + std::to_string(tile));
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
        t.exact = ExactSumTuning{};  // penumbra's kernels (clblast false), the rest default
        t.exact.vector_width = vw;
        t.exact.row_block = rb;
        EXPECT_LE(max_difference(render_with(s, t, p), ref), tol) << "vw " << vw << " rb " << rb;
      }
    Tuning blas = base;
    blas.exact.clblast = true;
    EXPECT_LE(max_difference(render_with(s, blas, p), ref), tol) << "CLBlast";
  }
}

// CLBlast's parameters as it reports them for this device (what its next GEMM will use).
std::unordered_map<std::string, size_t> clblast_xgemm(Precision p) {
  std::unordered_map<std::string, size_t> out;
  EXPECT_EQ(
      clblast::RetrieveParameters(
          context().info().device(), "Xgemm",
          p == Precision::Double ? clblast::Precision::kDouble : clblast::Precision::kSingle, out),
      clblast::StatusCode::kSuccess);
  return out;
}

// Every Xgemm set the tuner can try, forced onto CLBlast's Xgemm kernel (these products are
// far below the size where CLBlast leaves its direct kernel), agrees with penumbra's kernels;
// CLBlast really runs with the set, and an unset tuning gives CLBlast back its own parameters.
TEST(Tuning, EveryClblastCandidateAgreesToRounding) {
  const Scene s = small_scene(Shadows::Hard, Sampling::Exact);
  Tuning own;  // CLBlast with its own parameters
  own.exact.clblast = true;
  render_with(s, own, Precision::Float);
  const auto clblast_own = clblast_xgemm(Precision::Float);
  for (Precision p : {Precision::Float, Precision::Double}) {
    const double tol = p == Precision::Double ? 1e-12 : 2e-5;
    const auto ref = render_with(s, Tuning{}, p);
    std::vector<XgemmParameters> sets = xgemm_candidates(false);
    if (p == Precision::Double) sets.resize(1);  // each set is a cold CLBlast compile (seconds)
    for (const XgemmParameters& x : sets) {
      Tuning t;
      t.exact.clblast = true;
      t.exact.xgemm = x;
      t.exact.min_indirect_size = 1;
      EXPECT_LE(max_difference(render_with(s, t, p), ref), tol) << x.describe();
      const auto used = clblast_xgemm(p);
      for (const auto& [name, field] : XgemmParameters::fields())
        EXPECT_EQ(used.at(name), size_t(x.*field)) << name << " of " << x.describe();
    }
  }
  EXPECT_NE(clblast_xgemm(Precision::Float), clblast_own);  // the last candidate's set
  render_with(s, own, Precision::Float);
  EXPECT_EQ(clblast_xgemm(Precision::Float), clblast_own);
}

// A legal set with which CLBlast 1.5's GEMM computes wrong products (what its own tuner chose on
// a Xeon through PoCL, docs/tuning.md): a render that would use it stops with one line naming
// it, and CLBlast gets its own parameters back; a right set then renders as before.
TEST(Tuning, AClblastSetThatMultipliesWrongIsRefusedAtItsFirstGemm) {
  XgemmParameters wrong;
  wrong.GEMMK = 1, wrong.KREG = 2, wrong.KWG = 1, wrong.KWI = 1, wrong.MDIMA = wrong.MDIMC = 16;
  wrong.NDIMB = wrong.NDIMC = 4, wrong.MWG = 128, wrong.NWG = 16, wrong.VWM = 8, wrong.VWN = 1;
  wrong.SA = wrong.SB = 0;
  ASSERT_NO_THROW(validate(wrong, context().info()));
  const Scene s = small_scene(Shadows::Hard, Sampling::Exact);
  Tuning t;
  t.exact.clblast = true;
  t.exact.xgemm = wrong;
  t.exact.min_indirect_size = 1;
  Renderer r(context(), Precision::Float, t);
  try {
    r.render(s);
    FAIL() << "rendered with a set that multiplies wrong";
  } catch (const Error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("CLBlast's GEMM computes wrong products with the tuning's Xgemm set (" +
                     wrong.describe() + "): an error of "),
              std::string::npos)
        << m;
    EXPECT_EQ(m.find('\n'), std::string::npos) << m;
  }
  const auto after_refusal = clblast_xgemm(Precision::Float);
  Tuning own;
  own.exact.clblast = true;
  const auto ref = render_with(s, Tuning{}, Precision::Float);
  EXPECT_LE(max_difference(render_with(s, own, Precision::Float), ref), 2e-5);
  EXPECT_EQ(after_refusal, clblast_xgemm(Precision::Float));  // CLBlast's own, back at once
  EXPECT_NE(after_refusal.at("KWG"), size_t(wrong.KWG));
}

TEST(Tuning, IllegalClblastParametersAreRejectedWithAClearMessage) {
  const DeviceInfo& dev = context().info();
  EXPECT_NO_THROW(validate(XgemmParameters{}, dev));  // CLBlast's own float set for PoCL
  for (const XgemmParameters& x : xgemm_candidates(false)) EXPECT_NO_THROW(validate(x, dev));
  auto message = [&](const XgemmParameters& x, const DeviceInfo& d) {
    try {
      validate(x, d);
    } catch (const Error& e) {
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  XgemmParameters x = xgemm_candidates(false).front();  // MDIMC 4, VWM 16
  x.MWG = 48;
  EXPECT_NE(message(x, dev).find("MWG 48 must be a multiple of MDIMC·VWM = 64"), std::string::npos)
      << message(x, dev);
  x = XgemmParameters{};
  x.KWG = 24;  // KDIMA = MDIMC·NDIMC/MDIMA = 16
  EXPECT_NE(message(x, dev).find("KWG 24 must be a multiple of MDIMC·NDIMC/MDIMA = 16"),
            std::string::npos)
      << message(x, dev);
  x = XgemmParameters{};
  x.SA = 2;
  EXPECT_NE(message(x, dev).find("SA is 2; expected 0 or 1"), std::string::npos) << message(x, dev);
  x = XgemmParameters{};
  x.VWN = 3;
  EXPECT_NE(message(x, dev).find("VWM and VWN must be"), std::string::npos) << message(x, dev);
  DeviceInfo small = dev;
  small.max_work_group = 64;
  x = XgemmParameters{};  // 8 × 16 threads
  EXPECT_NE(message(x, small).find("MDIMC·NDIMC = 128 work-items per group"), std::string::npos)
      << message(x, small);
  // A renderer refuses it before any CLBlast call.
  Tuning t;
  t.exact.clblast = true;
  t.exact.xgemm = XgemmParameters{};
  t.exact.xgemm->MWG = 48;
  EXPECT_THROW({ Renderer r(context(), Precision::Float, t); }, Error);
}

TEST(Tuning, IllegalValuesAreRejectedWithAClearMessage) {
  // `t` is refused on this device with a message that contains `names`.
  auto expect_refused = [](const Tuning& t, const std::string& names) {
    try {
      validate(t, context().info());
      FAIL() << names << " accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(names), std::string::npos) << e.what();
    }
  };
  Tuning t;
  t.raster = {6, 8, false};
  expect_refused(t, "tile (6) must be a positive multiple of the 4×2 block of 8 pixel(s)");
  t.raster = {8, 3, false};
  expect_refused(t, "pixels_per_item (3) must be a power of two up to 16");
  t.raster = {8, 16, false};  // four 4×4 blocks
  EXPECT_NO_THROW(validate(t, context().info()));
  t = Tuning{};
  t.raster.pixels_per_item = 1;
  t.exact.vector_width = 3;
  expect_refused(t, "vector_width 3");
  for (int lanes : {-1, 3, 512}) {
    t = Tuning{};
    t.raster.pixels_per_item = 1;
    t.raster.face_lanes = lanes;
    expect_refused(t, "face_lanes (" + std::to_string(lanes) + ")");
  }
  for (int group : {-1, 17}) {
    t = Tuning{};
    t.raster.pixels_per_item = 1;
    t.gather.group = group;
    expect_refused(t, "gather tuning: group " + std::to_string(group));
  }
  for (auto [width, height] : {std::pair{2, 8}, {32, 8}, {8, 3}, {8, 32}, {-8, 8}}) {
    t = Tuning{};
    t.raster.pixels_per_item = 1;
    t.gather.width = width, t.gather.height = height;
    expect_refused(t, "gather tuning: width " + std::to_string(width) + " must be 4, 8 or 16 " +
                          "and height " + std::to_string(height));
  }
  DeviceInfo small = context().info();
  small.max_work_group = 63;  // 8 × 8 work-items do not fit
  t = Tuning{};
  t.raster = {8, 8, false};
  t.gather.group = 8;
  EXPECT_THROW(validate(t, small), Error);
  t.gather.group = 7;
  EXPECT_NO_THROW(validate(t, small));
}

TEST(Tuning, CorruptOrMissingDatabaseFallsBackWithAWarning) {
  const std::string bad = ::testing::TempDir() + "/tuning_corrupt.json", none = bad + ".none";
  std::ofstream(bad) << "{ this is not json";
  TuningDatabase db;
  const std::string err = warnings_of([&] { db = TuningDatabase::load({bad, none}); });
  EXPECT_EQ(db.size(), 0u);
  EXPECT_NE(err.find("penumbra: warning: ignoring tuning database"), std::string::npos) << err;
  EXPECT_NE(err.find("not found"), std::string::npos) << err;
  EXPECT_NO_THROW(validate(db.lookup(context().info(), WorkloadStats{}), context().info()));

  // A renderer pointed at it by PENUMBRA_TUNING still renders, with what it would use without.
  const Scene scene = small_scene(Shadows::None, Sampling::Truncated);
  const std::string expected =
      TuningDatabase::load_default().lookup(context().info(), workload_stats(scene)).source;
  setenv("PENUMBRA_TUNING", bad.c_str(), 1);
  std::optional<Renderer> r;
  const std::string warned =
      warnings_of([&] { EXPECT_EQ(r.emplace(context()).render(scene).size(), 1u); });
  unsetenv("PENUMBRA_TUNING");
  EXPECT_EQ(r->tuning().source, expected);
  EXPECT_NE(warned.find("ignoring tuning database"), std::string::npos) << warned;
}

// The report's rows of CLBlast's own tuner: its set as an exact candidate, or its failure.
std::vector<TuneReport::Candidate> clblast_tuner_rows(const TuneReport& report) {
  std::vector<TuneReport::Candidate> rows;
  for (const auto& c : report.candidates)
    if (c.name.find("CLBlast's tuner") != std::string::npos || c.name == "CLBlast's Xgemm tuner")
      rows.push_back(c);
  return rows;
}

TEST(Tuning, ClblastTunersSetIsTimedAndCheckedLikeTheOtherCandidates) {
  Scene s = small_scene(Shadows::None, Sampling::Truncated);
  s.params.shadow_map_size = 128;  // the tuner's product: 128³, where its search finds sets
  TuneOptions o;
  o.quick = true;
  o.runs = 1;
  o.clblast_fraction = 1e-4;
  const TuneReport report = tune(context(), s, o);
  const auto rows = clblast_tuner_rows(report);
  ASSERT_EQ(rows.size(), 1u);
  EXPECT_EQ(rows[0].stage, "exact");
  EXPECT_EQ(rows[0].name.rfind("CLBlast GEMM ", 0), 0u) << rows[0].name << ": " << rows[0].note;
  if (rows[0].accepted)
    EXPECT_GT(rows[0].median_ms, 0.0);
  else  // by the check of its first GEMM, or by its output
    EXPECT_TRUE(rows[0].note.find("wrong products") != std::string::npos ||
                rows[0].note.find("differs") != std::string::npos)
        << rows[0].note;
  EXPECT_NO_THROW(validate(report.best, context().info()));
}

TEST(Tuning, AFailedClblastTunerIsAReportedRowAndTheTuneGoesOn) {
  Scene s = small_scene(Shadows::None, Sampling::Truncated);
  TuneOptions o;
  o.quick = true;
  o.runs = 1;
  o.clblast_fraction = 1e-9;  // no configuration at all: CLBlast's tuner fails
  const TuneReport report = tune(context(), s, o);
  const auto rows = clblast_tuner_rows(report);
  ASSERT_EQ(rows.size(), 1u);
  EXPECT_FALSE(rows[0].accepted);
  EXPECT_NE(rows[0].note.find("CLBlast's Xgemm tuner failed"), std::string::npos) << rows[0].note;
  EXPECT_NO_THROW(validate(report.best, context().info()));
  EXPECT_EQ(report.best.source.rfind("tuned:", 0), 0u);
}

TEST(Tuning, TunerTimesEveryStageAndReturnsALegalWinner) {
  Scene s = small_scene(Shadows::None, Sampling::Truncated);
  TuneOptions o;
  o.quick = true;
  o.runs = 1;
  const TuneReport report = tune(context(), s, o);
  bool raster = false, exact = false, pen = false, gather = false;
  for (const auto& c : report.candidates) {
    raster |= c.stage == "raster";
    exact |= c.stage == "exact";
    pen |= c.stage == "soft_map";
    gather |= c.stage == "gather" && c.name.rfind("group 2x2, block ", 0) == 0;  // any device
    EXPECT_TRUE(c.accepted) << c.stage << " " << c.name << ": " << c.note;
    EXPECT_GT(c.median_ms, 0.0);
  }
  EXPECT_TRUE(raster && exact && pen && gather);
  EXPECT_NO_THROW(validate(report.best, context().info()));
  EXPECT_EQ(report.best.source.rfind("tuned:", 0), 0u);
}
