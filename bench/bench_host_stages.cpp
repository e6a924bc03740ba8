// penumbra_bench --host-stages [N]: the host's work per render as the face count grows. For the
// bundled scene with icospheres of about 1k, 100k and 1M faces (no shadows, 256²), a renderer
// renders the scene twice (the first call packs and uploads the faces, the second only the
// vertices), then N more times (default 10), each call passing the same scene as an
// optimisation passes its moved vertices and taking its outputs into float buffers
// (render_into, as penumbra.torch does); prints, as a Markdown table, the wall ms per call of
// each stage of those N calls (PENUMBRA_PROFILE's stage timing, which it turns on).
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <vector>

#include "cl/device.hpp"
#include "common.hpp"
#include "suite.hpp"

namespace penumbra::bench {
namespace {

using Stages = std::map<std::string, std::pair<double, int>>;

// Float buffers for every camera's outputs (`store` holds them).
std::vector<OutputBuffers<float>> float_buffers(const Scene& s,
                                                std::vector<std::vector<float>>& store) {
  store.clear();
  for (const Camera& c : s.cameras)
    for (int channels : {3, 1, 1}) store.emplace_back(size_t(c.width) * c.height * channels);
  std::vector<OutputBuffers<float>> out;
  for (size_t c = 0; c < s.cameras.size(); ++c)
    out.push_back({store[3 * c].data(), store[3 * c + 1].data(), store[3 * c + 2].data()});
  return out;
}

// ms per call of `stage` between two snapshots of the stage rows.
double per_call(const Stages& before, const Stages& after, const std::string& stage, int calls) {
  const auto a = after.find("render: " + stage);
  if (a == after.end()) return 0;
  const auto b = before.find("render: " + stage);
  return (a->second.first - (b == before.end() ? 0 : b->second.first)) / calls;
}

}  // namespace

int run_host_stages(const std::string& calls_text) {
  try {
    int calls = 10;
    if (!calls_text.empty() && !parse_int(calls_text, 1, 1000, &calls))
      throw std::invalid_argument("--host-stages wants a number of calls 1-1000: '" + calls_text +
                                  "'");
    if (!detail::profiling())
      throw std::runtime_error("the stage timing is off: run with PENUMBRA_PROFILE=1");
    const std::vector<std::string> host = {"prepare", "upload", "outputs"},
                                   device = {"raster", "resolve"};
    std::printf("| faces | vertices | %s | host | %s |\n|---|---|---|---|---|---|---|---|\n",
                "prepare | upload | outputs", "raster | resolve");
    for (int faces : {1280, 100000, 1000000}) {
      Case c;
      c.frequency = icosphere_frequency_for(faces);
      const Scene s = make_scene(c);
      Renderer& r = fresh_renderer(s);
      std::vector<std::vector<float>> store;
      const std::vector<OutputBuffers<float>> out = float_buffers(s, store);
      r.render_into(s, out);
      r.render_into(s, out);
      const Stages before = detail::profile_stages();
      for (int i = 0; i < calls; ++i) r.render_into(s, out);
      const Stages after = detail::profile_stages();
      size_t nv = 0;
      for (const Mesh& m : s.meshes) nv += m.vertices.size();
      std::printf("| %d | %zu |", total_faces(s), nv);
      double sum = 0;
      for (const std::string& stage : host) {
        sum += per_call(before, after, stage, calls);
        std::printf(" %.2f |", per_call(before, after, stage, calls));
      }
      std::printf(" %.2f |", sum);
      for (const std::string& stage : device)
        std::printf(" %.2f |", per_call(before, after, stage, calls));
      std::printf("\n");
    }
    if (std::fflush(stdout) != 0 || std::ferror(stdout))
      throw std::runtime_error("cannot write to standard output");
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "penumbra_bench: %s\n", e.what());
    return 1;
  }
}

}  // namespace penumbra::bench
