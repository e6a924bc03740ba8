#pragma once
// Shared pieces of the benchmark suite: the device, one renderer, scene builders (the bundled
// turnaround scene, a subdivided icosphere of any size on its ground plane, extra lights),
// whole-frame timing with per-frame medians, throughput counters and peak memory.
#include <benchmark/benchmark.h>

#include <chrono>
#include <string>
#include <vector>

#include "penumbra/context.hpp"
#include "penumbra/renderer.hpp"
#include "penumbra/scene.hpp"

namespace penumbra::bench {

// ---- scene geometry ------------------------------------------------------------------------

// A unit icosphere of geodesic frequency n: every icosahedron face is split into n² triangles
// (edges cut into n equal steps, points pushed onto the sphere). 20·n² faces, 10·n² + 2
// vertices, outward counter-clockwise winding. n = 8 gives 1280 faces, n = 71 gives 100 820.
Mesh icosphere(int frequency, glm::dvec3 center = {0, 0, 0}, double radius = 1.0,
               glm::dvec3 albedo = {0.85, 0.35, 0.3});
// The smallest frequency whose icosphere has at least `faces` faces.
int icosphere_frequency_for(int faces);
// Whether `text` is a whole decimal integer in [lo, hi]; if so it is written to `out`.
bool parse_int(const std::string& text, int lo, int hi, int* out);

// ---- scenes --------------------------------------------------------------------------------

// What a benchmark case renders.
struct Case {
  Shadows shadows = Shadows::None;
  Sampling sampling = Sampling::Truncated;
  // Exact sampling of hard shadows: penumbra's kernels (`exact`) or CLBlast (`gemm`).
  ExactBackend exact_backend = ExactBackend::Kernels;
  int image = 256;       // W = H
  int map = 256;         // W_s = H_s
  int frequency = 0;     // 0: the bundled 1280-face sphere; else an icosphere of this frequency
  double sigma_s = 2.0;  // texel²
  int lights = 1;        // 1 to 3
  // The paper's model: the reference point of the suite's targets (σ_s = 2 is its default), and
  // the only model whose exact sum runs on CLBlast (gemm). The accuracy group times both.
  ShadowModel model = ShadowModel::Paper;
};

// data/scenes/turnaround.json (a unit sphere resting on an 8×8 ground plane, one point light of
// diameter 0.5, camera 0 at 256²) with the case's settings applied and every light frustum
// fitted. Extra lights are copies of light 0 turned about +y by 120° and 240°.
Scene make_scene(const Case& c);
// Loads data/scenes/turnaround.json (PENUMBRA_DATA_DIR, overridable by $PENUMBRA_DATA_DIR).
Scene turnaround_scene();
int total_faces(const Scene& s);

// v rotated by `angle` radians about +y.
glm::dvec3 rotate_y(const glm::dvec3& v, double angle);

const char* word(Shadows s);
// The sampling of a case name: truncated, exact (penumbra's kernels) or gemm (exact on CLBlast).
const char* word(Sampling s, ExactBackend backend);

// ---- device and renderer -------------------------------------------------------------------

Context& context();
// The process's float renderer, made on first use with the tuning the library picks for the
// device and workload, so that the cases that share it build their programs once. The cases
// name their exact backend (kernels for `exact`, clblast for `gemm`), so that the two exact-sum
// paths stay apart whatever the tuning picks for `auto`.
Renderer& renderer(const Scene& scene);
// That renderer made anew (its programs from the kernel cache): a renderer rasters into its last
// render's fragment buffers where they fit, so the first render of a fresh one makes every
// buffer a render holds, and the device memory it counts is all of it, not what it added to an
// earlier case's buffers.
Renderer& fresh_renderer(const Scene& scene);
// Releases the renderer and the device before exit (PoCL's own exit handlers then find no live
// objects).
void release_device();

// dL/d(colour) = 1, dL/d(silhouette) = 1, dL/d(depth) = 1/far for every camera: a loss that
// reaches every stage of the backward pass.
std::vector<OutputGrads> unit_grads(const Scene& s);

// ---- measuring -----------------------------------------------------------------------------

using Clock = std::chrono::steady_clock;
inline double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

double median(std::vector<double> v);

// The 1-minute load average of the machine (/proc/loadavg), recorded with every case: on a
// shared machine it says how much else was running.
double load_average();

// Peak resident memory of the process, MiB. On PoCL's CPU device, device buffers live in host
// memory, so this also bounds the device memory in use. reset_peak_rss() restarts the peak
// (Linux /proc/self/clear_refs) at the current resident size, which still holds what earlier
// cases left allocated (allocator and PoCL pools); where it cannot, the peak is that of the
// whole process.
void reset_peak_rss();
double peak_rss_mib();
bool peak_rss_resettable();

// The fragments every camera's view kept in r's most recent render (Renderer::fragment_counts):
// the number N of fragments whose shadow terms the lookups sample.
double kept_fragments(const Renderer& r);

// Runs `frame` once per benchmark iteration, timing each call (wall clock, manual time), and
// sets ms_median, ms_min, ms_mean, frames_per_s (1 / median) and loadavg_1min counters.
template <class F>
double timed_frames(benchmark::State& state, F&& frame) {
  std::vector<double> t;
  for (auto _ : state) {
    const auto t0 = Clock::now();
    frame();
    const double s = seconds_since(t0);
    state.SetIterationTime(s);
    t.push_back(s);
  }
  double sum = 0, lo = t.empty() ? 0 : t[0];
  for (double s : t) sum += s, lo = std::min(lo, s);
  const double med = median(t);
  state.counters["ms_median"] = med * 1e3;
  state.counters["ms_min"] = lo * 1e3;
  state.counters["ms_mean"] = t.empty() ? 0 : sum / t.size() * 1e3;
  state.counters["frames_per_s"] = med > 0 ? 1.0 / med : 0;
  state.counters["loadavg_1min"] = load_average();
  return med;
}

// Runs `first` then `second` once per benchmark iteration, timing each (the iteration's manual
// time is their sum), so that both meet the same machine: a quotient of their times is then not
// at the mercy of what the machine did in between, as it is between separate cases run minutes
// apart. Sets loadavg_1min; returns the medians of first, of second and of their sums, seconds.
struct InTurn {
  double first, second, both;
};
template <class F, class G>
InTurn timed_in_turn(benchmark::State& state, F&& first, G&& second) {
  std::vector<double> ta, tb, both;
  for (auto _ : state) {
    auto t0 = Clock::now();
    first();
    ta.push_back(seconds_since(t0));
    t0 = Clock::now();
    second();
    tb.push_back(seconds_since(t0));
    both.push_back(ta.back() + tb.back());
    state.SetIterationTime(both.back());
  }
  state.counters["loadavg_1min"] = load_average();
  return {median(ta), median(tb), median(both)};
}

// Throughput counters of one render or backward frame of `s` taking `seconds` (the median):
//   pixel_face_pairs_per_s  (W·H + lights·W_s·H_s when shadows are on) · faces / s — the
//                           brute-force pair count, a size-normalised speed (tiling visits far
//                           fewer pairs)
//   samples_per_s           shadow-map texels weighed per second: N·lights·(2R)² truncated
//                           (R = sqrt(2σ_s ln(1/ε_λ))), N·lights·W_s·H_s exact and gemm
//   gflops                  exact and gemm hard shadows: products·2·N·W_s·H_s / s, with one
//                           product per light forward and three backward (math.md §6.2, §8.3): the
//                           dense products' flops, which CLBlast executes; penumbra's kernels skip
//                           the weights that are exactly 0, so for them a dense-equivalent rate
//                           (flops executed only where no weight is 0: bench/report.py)
// plus the case's parameters (image, map, faces, sigma_s, lights, fragments).
void throughput_counters(benchmark::State& state, const Scene& s, double fragments, double seconds,
                         bool backward);

// Adds peak_rss_MiB (see peak_rss_mib) and rss_at_start_MiB (resident size when the case began).
void memory_counter(benchmark::State& state);

// Name of a render case: <group>/<fwd|bwd>/<shadows>/<sampling>/img:W/map:M/faces:F/
// sigma_s:S/lights:L, every key:value segment parsed by bench/report.py.
std::string case_name(const std::string& group, bool backward, const Case& c);

}  // namespace penumbra::bench
