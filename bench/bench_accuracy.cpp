// Accuracy beside cost: each shadow model, mode and sampling against the ray-traced truth
// (bench/truth.hpp) on the scenes of bench/accuracy.hpp, next to its forward time.
//
// Case names: accuracy/fwd/<shadows>/<sampling>/img:W/map:M/faces:F/sigma_s:S/lights:1/
// model:<accurate|paper>/scene:<name>, and accuracy/ratio/<shadows>/truncated/img:256/map:256/
// lights:1/scene:<name> (both models at a 256² map) or .../img:256/maps:default/... (each at its
// own default map): the accurate model's forward time over the paper model's, a frame of
// each in turn so that what else runs on this shared machine weighs on both alike (counters
// ms_accurate and ms_paper, the medians, and time_ratio, their quotient; the separate fwd cases
// run minutes apart). Counters of the fwd cases (accuracy.hpp defines them): area_ratio,
// lit_error, rmse_shadow, leak (scenes with a contact), the pixel counts of each region, plus
// the timing counters of the render cases. With $PENUMBRA_BENCH_IMAGES set, every case at the
// reference settings (truncated, the model's default map size and σ_s) writes
// truth | penumbra | difference as
// compare_<scene>_<model>_<shadows>.png there, penumbra's colour as <scene>_<model>_<shadows>.npy,
// and, once per scene, what save_side_by_side writes (the scene, its truth and shadow region).
//
// Built only when CMake finds Embree 3 (Debian: libembree-dev); otherwise the group is absent
// and the suite says so once.
#include <cstdio>

#include "common.hpp"
#include "suite.hpp"

#ifdef PENUMBRA_HAVE_EMBREE

#include <cstdlib>
#include <optional>
#include <set>
#include <sstream>
#include <vector>

#include "accuracy.hpp"
#include "penumbra/io.hpp"

namespace penumbra::bench {

namespace {

// Exact sampling weighs every texel of the map whose weight is not 0 for every fragment; the
// default suite runs it at this map size, the large/ cases at 256².
constexpr int kExactMap = 128;

void metric_counters(benchmark::State& state, const AccuracyCase& c, const AccuracyMetrics& m) {
  auto& C = state.counters;
  C["default_sigma_s"] = c.sigma_s ? 0 : 1;  // σ_s left to the shadow model
  C["default_map"] = c.map ? 0 : 1;          // the map size too
  C["area_ratio"] = m.area_ratio;
  C["lit_error"] = m.lit_error;
  C["rmse_shadow"] = m.rmse_shadow;
  if (m.leak) C["leak"] = *m.leak;
  C["ground_pixels"] = m.ground_pixels;
  C["shadow_pixels"] = m.shadow_pixels;
  C["true_shadow_pixels"] = m.true_shadow_pixels;
  C["lit_pixels"] = m.lit_pixels;
  C["contact_pixels"] = m.contact_pixels;
  C["contact_shadow_pixels"] = m.contact_shadow_pixels;
}

bool reference_settings(const AccuracyCase& c) {
  return c.sampling == Sampling::Truncated && !c.map && !c.sigma_s;
}

void save_images(const AccuracyCase& c, const Image& color) {
  const char* dir = std::getenv("PENUMBRA_BENCH_IMAGES");
  if (!dir || !*dir || !reference_settings(c)) return;
  const std::string at = std::string(dir) + "/" + c.scene;
  static std::set<std::string> saved;  // the scene, its truth and region: once per scene
  if (saved.insert(c.scene).second) save_side_by_side(c.scene, dir);
  const std::string tail = "_" + word(c.model) + "_" + word(c.shadows);
  save_npy(color, at + tail + ".npy");
  save_comparison(truth(c.scene, truth_for(c.shadows)), color,
                  std::string(dir) + "/compare_" + c.scene + tail + ".png");
}

void run_accuracy(benchmark::State& state, const AccuracyCase& c) {
  reset_peak_rss();
  try {
    truth(c.scene, truth_for(c.shadows));
    truth(c.scene, TruthLight::Sphere);  // the shadow region
    const Scene s = accuracy_scene(c);
    Renderer& r = renderer(s);
    const Rendered out = render_visibility(r, s);  // also the warm-up
    save_images(c, out.color);
    r.render(s);
    const double fragments = kept_fragments(r);
    const double med = timed_frames(state, [&] { benchmark::DoNotOptimize(r.render(s)); });
    throughput_counters(state, s, fragments, med, false);
    memory_counter(state);
    metric_counters(state, c, measure(c, out));
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
  }
}

void run_ratio(benchmark::State& state, const AccuracyCase& accurate, const AccuracyCase& paper) {
  try {
    const Scene a = accuracy_scene(accurate), p = accuracy_scene(paper);
    Renderer ra(context(), Precision::Float), rp(context(), Precision::Float);
    ra.render(a);  // warm-up: programs and buffers
    rp.render(p);
    const InTurn t = timed_in_turn(
        state, [&] { benchmark::DoNotOptimize(ra.render(a)); },
        [&] { benchmark::DoNotOptimize(rp.render(p)); });
    state.counters["ms_accurate"] = t.first * 1e3;
    state.counters["ms_paper"] = t.second * 1e3;
    state.counters["time_ratio"] = t.first / t.second;
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
  }
}

std::string name_of(const AccuracyCase& c, bool large) {
  const Scene s = accuracy_scene(c);
  std::ostringstream o;
  o << (large ? "large/" : "") << "accuracy/fwd/" << word(c.shadows) << '/'
    << word(c.sampling, c.exact_backend) << "/img:" << s.cameras.front().width
    << "/map:" << shadow_map_side(s.params) << "/faces:" << total_faces(s)
    << "/sigma_s:" << shadow_sigma_s(s.params) << "/lights:1/model:" << word(c.model)
    << "/scene:" << c.scene;
  return o.str();
}

void add(const AccuracyCase& c, bool large = false) {
  benchmark::RegisterBenchmark(name_of(c, large).c_str(),
                               [c](benchmark::State& st) { run_accuracy(st, c); })
      ->UseManualTime()
      ->Unit(benchmark::kMillisecond);
}

AccuracyCase make(const std::string& scene, ShadowModel model, Shadows sh, Sampling sa,
                  std::optional<int> map = std::nullopt,
                  std::optional<double> sigma_s = std::nullopt) {
  AccuracyCase c;
  c.scene = scene;
  c.model = model;
  c.shadows = sh;
  c.sampling = sa;
  c.map = map;
  c.sigma_s = sigma_s;
  return c;
}

// The models at equal settings, both at the paper model's 256² map, or each at its own default
// map (the accurate model's is 384²).
void add_ratio(const std::string& scene, Shadows sh, bool equal_maps) {
  const std::optional<int> map = equal_maps ? std::optional<int>(256) : std::nullopt;
  const AccuracyCase a = make(scene, ShadowModel::Accurate, sh, Sampling::Truncated, map),
                     p = make(scene, ShadowModel::Paper, sh, Sampling::Truncated, map);
  const std::string name = std::string("accuracy/ratio/") + word(sh) + "/truncated/img:256/" +
                           (equal_maps ? "map:256" : "maps:default") + "/lights:1/scene:" + scene;
  benchmark::RegisterBenchmark(name.c_str(), [a, p](benchmark::State& st) { run_ratio(st, a, p); })
      ->UseManualTime()
      ->Unit(benchmark::kMillisecond);
}

}  // namespace

void register_accuracy_benchmarks() {
  for (const std::string& scene : accuracy_scene_names()) {
    add(make(scene, ShadowModel::Accurate, Shadows::None, Sampling::Truncated));
    for (Shadows sh : {Shadows::Hard, Shadows::Soft})
      for (bool equal_maps : {true, false}) add_ratio(scene, sh, equal_maps);
    for (ShadowModel model : {ShadowModel::Accurate, ShadowModel::Paper})
      for (Shadows sh : {Shadows::Hard, Shadows::Soft}) {
        add(make(scene, model, sh, Sampling::Truncated));
        add(make(scene, model, sh, Sampling::Exact, kExactMap));
        add(make(scene, model, sh, Sampling::Exact, 256), true);
      }
  }
  // The light among the objects held to one frustum, beside its cube.
  for (Shadows sh : {Shadows::Hard, Shadows::Soft})
    add(make("among_frustum", ShadowModel::Accurate, sh, Sampling::Truncated));
  // The bundled scene with a 100,820-face sphere, at 256² and 512²: penumbra at scale, beside a
  // ray tracer (bench/mitsuba_side_by_side.py).
  for (const char* scene : {"sphere_100k", "sphere_100k_512"})
    for (Shadows sh : {Shadows::Hard, Shadows::Soft})
      add(make(scene, ShadowModel::Accurate, sh, Sampling::Truncated));
  // The sphere scene: filter width (those of 0.5, 2 and 8 texel² that are not the model's
  // default) and map size (those of 128², 256² and 512² that are not), both models.
  for (ShadowModel model : {ShadowModel::Accurate, ShadowModel::Paper})
    for (Shadows sh : {Shadows::Hard, Shadows::Soft}) {
      const AccuracyCase base = make("sphere", model, sh, Sampling::Truncated);
      const RenderParams standard = accuracy_scene(base).params;
      for (double ss : {0.5, 2.0, 8.0})
        if (ss != shadow_sigma_s(standard))
          add(make("sphere", model, sh, Sampling::Truncated, std::nullopt, ss));
      for (int map : {128, 256, 512})
        if (map != shadow_map_side(standard))
          add(make("sphere", model, sh, Sampling::Truncated, map));
    }
  AccuracyCase gemm = make("sphere", ShadowModel::Paper, Shadows::Hard, Sampling::Exact);
  gemm.exact_backend = ExactBackend::CLBlast;
  add(gemm);
}

}  // namespace penumbra::bench

#else  // no Embree

namespace penumbra::bench {
void register_accuracy_benchmarks() {
  std::fprintf(stderr,
               "penumbra_bench: accuracy benchmarks skipped: built without Embree 3 (install "
               "the Debian package libembree-dev and reconfigure)\n");
}
}  // namespace penumbra::bench

#endif
