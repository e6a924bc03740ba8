// The paper's turnaround (its Figure 4 timing): 90 frames of data/scenes/turnaround.json at
// 256² (256² shadow map) with camera 0 orbiting 360° about +y through its target, the light
// fixed, shadows none / hard / soft (truncated sampling), forward only. The paper reports
// 1 s, 33 s and 104 s for its 90 frames on a GPU: hard/none = 33 and soft/none = 104.
// Each case renders one warm-up frame (kernel builds), then times the 90-frame loop once.
#include <cmath>
#include <cstdio>
#include <map>

#include "common.hpp"
#include "suite.hpp"

namespace penumbra::bench {

namespace {

constexpr int kFrames = 90;

struct PaperFigure {
  double seconds, ratio;
};
const std::map<Shadows, PaperFigure> kPaper = {
    {Shadows::None, {1, 1}}, {Shadows::Hard, {33, 33}}, {Shadows::Soft, {104, 104}}};

std::map<Shadows, double>& measured() {
  static std::map<Shadows, double> m;  // seconds for the 90 frames
  return m;
}

void run_turnaround(benchmark::State& state, Shadows shadows) {
  reset_peak_rss();
  Case c;
  c.shadows = shadows;
  Scene s = make_scene(c);
  const Camera base = s.cameras.front();
  Renderer& r = renderer(s);
  std::vector<double> frame_s;
  double fragments = 0;
  try {
    r.render(s);  // warm-up
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
    return;
  }
  double total = 0;
  for (auto _ : state) {
    frame_s.clear();
    fragments = 0;
    double counting = 0;  // reading the fragment counts back, left out of the time
    const auto t0 = Clock::now();
    for (int k = 0; k < kFrames; ++k) {
      s.cameras.front() = orbit(base, 2.0 * std::acos(-1.0) * k / kFrames);
      const auto f0 = Clock::now();
      benchmark::DoNotOptimize(r.render(s));
      frame_s.push_back(seconds_since(f0));
      const auto c0 = Clock::now();
      fragments += kept_fragments(r);
      counting += seconds_since(c0);
    }
    total = seconds_since(t0) - counting;
    state.SetIterationTime(total);
  }
  measured()[shadows] = total;
  auto& C = state.counters;
  C["frames"] = kFrames;
  C["seconds"] = total;
  C["ms_median"] = median(frame_s) * 1e3;
  C["frames_per_s"] = kFrames / total;
  C["fragments"] = fragments / kFrames;
  C["paper_seconds"] = kPaper.at(shadows).seconds;
  C["paper_ratio"] = kPaper.at(shadows).ratio;
  if (measured().count(Shadows::None) && measured()[Shadows::None] > 0)
    C["ratio_vs_none"] = total / measured()[Shadows::None];
  C["loadavg_1min"] = load_average();
  memory_counter(state);
}

}  // namespace

void register_turnaround_benchmarks() {
  for (Shadows sh : {Shadows::None, Shadows::Hard, Shadows::Soft}) {
    const std::string name = std::string("turnaround/fwd/") + word(sh) +
                             "/truncated/img:256/map:256/frames:" + std::to_string(kFrames);
    benchmark::RegisterBenchmark(name.c_str(),
                                 [sh](benchmark::State& st) { run_turnaround(st, sh); })
        ->UseManualTime()
        ->Iterations(1)
        ->Unit(benchmark::kSecond);
  }
}

void print_turnaround_summary() {
  auto& m = measured();
  if (!m.count(Shadows::None)) return;
  const double none = m[Shadows::None];
  std::fprintf(stderr,
               "\nturnaround, %d frames at 256² (map 256², truncated sampling), this machine vs "
               "the paper (1 s / 33 s / 104 s on a GPU):\n",
               kFrames);
  for (Shadows sh : {Shadows::None, Shadows::Hard, Shadows::Soft}) {
    if (!m.count(sh)) continue;
    std::fprintf(stderr, "  %-5s %8.2f s   %s/none = %6.2f   paper %6.0f s, ratio %4.0f\n",
                 word(sh), m[sh], word(sh), none > 0 ? m[sh] / none : 0.0, kPaper.at(sh).seconds,
                 kPaper.at(sh).ratio);
  }
  std::fflush(stderr);
}

}  // namespace penumbra::bench
