// Whole-frame cost of Renderer::render (forward) and Renderer::backward, each timed alone
// (both calls are synchronous: they return host images / gradients), over shadows
// none / hard / soft × sampling truncated / exact / gemm (exact on CLBlast), image size, shadow-map
// size, face count, σ_s and the number of lights. Every case is the bundled turnaround scene
// (data/scenes/turnaround.json) with one setting changed from the reference point
//   image 256², map 256², 1312 faces (1280-face sphere + 32-face ground), σ_s = 2, 1 light,
// the paper's shadow model (Case::model).
//
// Names: [large/]<fwd|bwd>/<shadows>/<sampling>/img:W/map:M/faces:F/sigma_s:S/lights:L, then
// /model:accurate for the cases of the accurate model (at the reference point only).
// Cases step/<shadows>/<sampling>/... time a render and its backward in turn (run_step).
// Counter device_MiB: the most device memory the renderer's buffers held at once during one
// render() (with backward(): the render and the backward after it), penumbra::device_memory_use.
// Cases under large/ (1024² and 2048² images, 1024² maps, 200k and 1M faces, soft exact at 256²
// maps, ...) take far longer; they run only when the filter names them (see main.cpp).
#include <set>
#include <tuple>

#include "common.hpp"
#include "penumbra/error.hpp"
#include "penumbra/renderer.hpp"
#include "suite.hpp"

namespace penumbra::bench {

namespace {

void run_case(benchmark::State& state, const Case& c, bool backward) {
  reset_peak_rss();
  Scene s;
  std::vector<RenderOutput> out;
  std::vector<OutputGrads> grads;
  try {
    s = make_scene(c);
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
    return;
  }
  Renderer& r = fresh_renderer(s);
  reset_device_memory_peak();  // the warm-up call's own buffers, not those of earlier cases
  try {
    out = r.render(s);  // warm-up: builds every program this case needs
    if (backward) {
      grads = unit_grads(s);
      r.backward(s, grads);
    }
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
    return;
  }
  state.counters["device_MiB"] = double(device_memory_use().peak) / (1 << 20);
  const double fragments = kept_fragments(r);
  const double med = timed_frames(state, [&] {
    if (backward)
      benchmark::DoNotOptimize(r.backward(s, grads));
    else
      benchmark::DoNotOptimize(r.render(s));
  });
  throughput_counters(state, s, fragments, med, backward);
  memory_counter(state);
}

// A render then the backward of it, in turn, as each step of an optimisation takes them: the
// backward/forward quotient and the step's time with both calls meeting the same machine.
// Counters ms_fwd, ms_bwd (medians), ms_median (of the steps) and bwd_ratio = ms_bwd / ms_fwd.
void run_step(benchmark::State& state, const Case& c) {
  try {
    const Scene s = make_scene(c);
    Renderer& r = renderer(s);
    const std::vector<OutputGrads> grads = unit_grads(s);
    r.render(s);  // warm-up: every program of both calls
    r.backward(s, grads);
    const InTurn t = timed_in_turn(
        state, [&] { benchmark::DoNotOptimize(r.render(s)); },
        [&] { benchmark::DoNotOptimize(r.backward(s, grads)); });
    state.counters["ms_fwd"] = t.first * 1e3;
    state.counters["ms_bwd"] = t.second * 1e3;
    state.counters["ms_median"] = t.both * 1e3;
    state.counters["bwd_ratio"] = t.second / t.first;
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
  }
}

std::vector<RenderCase>& cases() {
  static std::vector<RenderCase> all;
  return all;
}

void add_step(const Case& c) {
  const std::string name = "step" + case_name("", false, c).substr(4);  // less "/fwd"
  cases().push_back({name, c, RenderCase::Kind::Step});
  benchmark::RegisterBenchmark(name.c_str(), [c](benchmark::State& st) { run_step(st, c); })
      ->UseManualTime()
      ->Unit(benchmark::kMillisecond);
}

using Key = std::tuple<bool, int, int, int, int, int, int, double, int, int>;

void add(bool backward, const Case& c, bool large = false) {
  static std::set<Key> seen;  // a case shared by several sweeps runs once
  const Key key{backward,    int(c.shadows), int(c.sampling), int(c.exact_backend), c.image, c.map,
                c.frequency, c.sigma_s,      c.lights,        int(c.model)};
  if (!seen.insert(key).second) return;
  const std::string name = (large ? "large/" : "") + case_name("", backward, c).substr(1);
  cases().push_back({name, c, backward ? RenderCase::Kind::Backward : RenderCase::Kind::Forward});
  benchmark::RegisterBenchmark(name.c_str(),
                               [c, backward](benchmark::State& st) { run_case(st, c, backward); })
      ->UseManualTime()
      ->Unit(benchmark::kMillisecond);
}

Case with(Shadows sh, Sampling sa, ExactBackend backend = ExactBackend::Kernels) {
  Case c;
  c.shadows = sh;
  c.sampling = sa;
  c.exact_backend = backend;
  return c;
}

// `c` with one setting changed.
template <class T, class V>
Case set(Case c, T Case::*member, V value) {
  c.*member = value;
  return c;
}

// Steps (render, then backward) of the targets' quotients and of the 100k-face sum, the latter
// also through the accurate model (the renderer's default), hard and soft.
void add_steps() {
  for (Shadows sh : {Shadows::None, Shadows::Hard, Shadows::Soft})
    add_step(with(sh, Sampling::Truncated));
  add_step(with(Shadows::Hard, Sampling::Exact));
  add_step(with(Shadows::Hard, Sampling::Exact, ExactBackend::CLBlast));
  const Case large = set(with(Shadows::Hard, Sampling::Truncated), &Case::frequency, 71);
  add_step(large);
  for (Shadows sh : {Shadows::Hard, Shadows::Soft})
    add_step(set(set(large, &Case::shadows, sh), &Case::model, ShadowModel::Accurate));
}

// σ_s (texel²): the truncated window grows as sqrt(σ_s), and so does the part of the map whose
// exact weights are not 0. At σ_s = 400 none of a 256² map's is (float): the exact products run
// dense, and their GFLOP/s are flops executed.
void add_sigma_s_sweep(const Case& hard, const Case& soft, const Case& hard_exact) {
  for (double ss : {0.5, 1.0, 4.0, 8.0, 400.0}) {
    if (ss < 400)
      for (const Case& c : {hard, soft}) add(false, set(c, &Case::sigma_s, ss));
    if (ss == 0.5 || ss == 8.0)
      for (const Case& c : {hard, soft}) add(true, set(c, &Case::sigma_s, ss));
    if (ss == 0.5 || ss == 8.0 || ss == 400)
      for (bool bwd : {false, true}) add(bwd, set(hard_exact, &Case::sigma_s, ss));
  }
}

}  // namespace

void register_render_benchmarks() {
  const Case none = with(Shadows::None, Sampling::Truncated),
             hard = with(Shadows::Hard, Sampling::Truncated),
             hard_exact = with(Shadows::Hard, Sampling::Exact),
             hard_gemm = with(Shadows::Hard, Sampling::Exact, ExactBackend::CLBlast),
             soft = with(Shadows::Soft, Sampling::Truncated),
             soft_exact = with(Shadows::Soft, Sampling::Exact);
  // The shadows × sampling matrix at the reference point (soft shadows have no gemm).
  for (bool bwd : {false, true}) {
    for (const Case& c : {none, hard, hard_exact, hard_gemm, soft}) add(bwd, c);
    add(bwd, set(soft_exact, &Case::map, 64));  // exact soft: a sigmoid per nonzero weight
    add(bwd, soft_exact, true);
    // The accurate model (the renderer's default) at the same point.
    for (const Case& c : {hard, soft}) add(bwd, set(c, &Case::model, ShadowModel::Accurate));
  }

  // Image size (map 256²).
  for (int img : {128, 512, 1024, 2048}) {
    const bool large = img > 512;
    for (const Case& c : {none, hard, soft}) add(false, set(c, &Case::image, img), large);
    for (const Case& c : {none, hard}) add(true, set(c, &Case::image, img), large);
    if (img <= 1024) add(false, set(hard_exact, &Case::image, img), img > 256);  // N ∝ W·H
  }

  // Shadow-map size (image 256²).
  for (int map : {64, 128, 512, 1024}) {
    const bool large = map > 512;
    for (const Case& c : {hard, soft, hard_exact}) add(false, set(c, &Case::map, map), large);
    add(false, set(hard_gemm, &Case::map, map), map > 128);
    add(true, set(hard, &Case::map, map), large);
    add(true, set(hard_exact, &Case::map, map), map > 128);
  }

  // Face count: icospheres of 1280 to 1 000 000 faces (frequency 8 to 224) on the ground plane.
  for (int freq : {0, 16, 32, 50, 71, 100, 224}) {  // 0: the bundled 1280-face sphere
    const bool large = freq > 71;
    for (const Case& c : {none, hard, soft}) add(false, set(c, &Case::frequency, freq), large);
    if (freq == 16 || freq >= 71)
      for (const Case& c : {none, hard}) add(true, set(c, &Case::frequency, freq), large);
  }
  // 512² with a 100k-face mesh.
  add(false, set(set(none, &Case::frequency, 71), &Case::image, 512));
  add(false, set(set(hard, &Case::frequency, 71), &Case::image, 512), true);

  add_sigma_s_sweep(hard, soft, hard_exact);

  // Lights: one shadow map (and penumbra map) per light.
  for (int nl : {2, 3})
    for (bool bwd : {false, true})
      for (const Case& c : {none, hard, soft}) add(bwd, set(c, &Case::lights, nl));

  add_steps();
}

const std::vector<RenderCase>& render_cases() { return cases(); }

}  // namespace penumbra::bench
