// penumbra_bench --host-stages [N]: the host's work per call as the face count grows. For the
// bundled scene with icospheres of about 1k, 100k and 1M faces (no shadows, 256²), a renderer
// renders the scene twice (the first call packs and uploads the faces, the second only the
// vertices), then N more times (default 10), each call passing the same scene as an
// optimisation passes its moved vertices and taking its outputs into float buffers
// (render_into, as penumbra.torch does); then N steps, each a render and the backward of float
// gradients (dL/d(colour) and dL/d(silhouette) 1). Prints two Markdown tables, renders and
// steps, of the wall ms per call of each stage (PENUMBRA_PROFILE's stage timing, which it turns
// on): the host's stages, their sum, and the device's for scale.
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <functional>
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

// ms per call of `stage` ("call: stage") between two snapshots of the stage rows.
double per_call(const Stages& before, const Stages& after, const std::string& stage, int calls) {
  const auto a = after.find(stage);
  if (a == after.end()) return 0;
  const auto b = before.find(stage);
  return (a->second.first - (b == before.end() ? 0 : b->second.first)) / calls;
}

// The stages of a table: the host's, summed in a column after them, then the device's.
struct Columns {
  std::vector<std::string> host, device;
};

void print_header(const Columns& c) {
  std::string head = "| faces | vertices |", rule = "|---|---|";
  const auto add = [&](const std::string& name) { head += " " + name + " |", rule += "---|"; };
  for (const std::string& stage : c.host) add(stage.substr(stage.find(": ") + 2));
  add("host");
  for (const std::string& stage : c.device) add(stage.substr(stage.find(": ") + 2));
  std::printf("%s\n%s\n", head.c_str(), rule.c_str());
}

void print_row(const Scene& s, const Columns& c, const Stages& before, const Stages& after,
               int calls) {
  size_t nv = 0;
  for (const Mesh& m : s.meshes) nv += m.vertices.size();
  std::printf("| %d | %zu |", total_faces(s), nv);
  double sum = 0;
  for (const std::string& stage : c.host) {
    sum += per_call(before, after, stage, calls);
    std::printf(" %.2f |", per_call(before, after, stage, calls));
  }
  std::printf(" %.2f |", sum);
  for (const std::string& stage : c.device)
    std::printf(" %.2f |", per_call(before, after, stage, calls));
  std::printf("\n");
}

// The table of `columns` over N calls of `call` (after its warm-up calls) at each face count.
void print_table(const Columns& columns, int calls,
                 const std::function<void(Renderer&, const Scene&, bool warm_up)>& call) {
  print_header(columns);
  for (int faces : {1280, 100000, 1000000}) {
    Case c;
    c.frequency = icosphere_frequency_for(faces);
    const Scene s = make_scene(c);
    Renderer& r = fresh_renderer(s);
    call(r, s, true);
    const Stages before = detail::profile_stages();
    for (int i = 0; i < calls; ++i) call(r, s, false);
    print_row(s, columns, before, detail::profile_stages(), calls);
  }
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
    std::vector<std::vector<float>> store;
    std::vector<OutputBuffers<float>> out;
    std::vector<float> ones;  // dL/d(colour) and dL/d(silhouette) of every camera
    const auto render = [&](Renderer& r, const Scene& s, bool warm_up) {
      if (warm_up) out = float_buffers(s, store);
      for (int i = 0; i < (warm_up ? 2 : 1); ++i) r.render_into(s, out);
    };
    print_table({{"render: prepare", "render: upload", "render: outputs"},
                 {"render: raster", "render: resolve"}},
                calls, render);
    std::printf("\n");
    const auto step = [&](Renderer& r, const Scene& s, bool warm_up) {
      render(r, s, warm_up);
      if (warm_up) {
        ones.clear();
        for (const std::vector<float>& o : store) ones.resize(std::max(ones.size(), o.size()), 1);
      }
      r.backward(s, std::vector<GradBuffers<float>>(s.cameras.size(),
                                                    {ones.data(), ones.data(), nullptr}));
    };
    print_table({{"backward: check", "backward: sums", "backward: gradients"},
                 {"backward: resolve", "backward: faces"}},
                calls, step);
    if (std::fflush(stdout) != 0 || std::ferror(stdout))
      throw std::runtime_error("cannot write to standard output");
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "penumbra_bench: %s\n", e.what());
    return 1;
  }
}

}  // namespace penumbra::bench
