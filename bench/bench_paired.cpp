// penumbra_bench --paired DIR_A DIR_B REGEX [N]: whether the kernels of DIR_B make a case faster
// than those of DIR_A, told apart from a shared machine's drift. For each forward, backward or
// step case of the suite (bench_render.cpp) whose name matches REGEX, two renderers in one
// process, each on a Context of its own whose programs were built while PENUMBRA_KERNEL_DIR named
// its directory, take N calls each (default 20) in turn: A before B in even pairs, B before A in
// odd ones, after one untimed pair. Two calls a few milliseconds apart meet the same machine, where
// separate runs on a 2-core VM differed by up to 25 %. Prints a Markdown table: per case the median
// ms a call of each side, the median of the pairs' quotients B/A with its 95 % distribution-free
// interval, and in how many pairs B was faster; with PENUMBRA_PROFILE set, a second table of each
// kernel's median device ms a call on both sides.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <memory>
#include <optional>
#include <regex>
#include <stdexcept>
#include <string>
#include <vector>

#include "cl/device.hpp"
#include "penumbra/renderer.hpp"
#include "suite.hpp"

namespace penumbra::bench {
namespace {

using Rows = std::map<std::string, std::pair<double, int>>;

// PENUMBRA_KERNEL_DIR set to `dir` while this lives, then as it was.
class KernelDirScope {
 public:
  explicit KernelDirScope(const std::string& dir) {
    if (const char* v = std::getenv("PENUMBRA_KERNEL_DIR")) old_ = v;
    setenv("PENUMBRA_KERNEL_DIR", dir.c_str(), 1);
  }
  ~KernelDirScope() {
    if (old_) {
      setenv("PENUMBRA_KERNEL_DIR", old_->c_str(), 1);
    } else {
      unsetenv("PENUMBRA_KERNEL_DIR");
    }
  }
  KernelDirScope(const KernelDirScope&) = delete;
  KernelDirScope& operator=(const KernelDirScope&) = delete;

 private:
  std::optional<std::string> old_;
};

// One side of a comparison: a renderer on a context of its own, and what its calls took.
struct Side {
  std::unique_ptr<Context> context;
  std::unique_ptr<Renderer> renderer;
  std::vector<double> ms;                              // wall ms of each call
  std::map<std::string, std::vector<double>> kernels;  // device ms of each call, per kernel
};

// One call of the case: a render, its backward (of the last render), or both in turn.
void call(Renderer& r, RenderCase::Kind kind, const Scene& s, const std::vector<OutputGrads>& g) {
  if (kind != RenderCase::Kind::Backward) r.render(s);
  if (kind != RenderCase::Kind::Forward) r.backward(s, g);
}

// A side whose programs come from `dir`, warmed up by one call of each kind the case makes:
// every program it needs is built then, while PENUMBRA_KERNEL_DIR names `dir`.
Side open_side(const std::string& dir, RenderCase::Kind kind, const Scene& s,
               const std::vector<OutputGrads>& g) {
  const KernelDirScope scope(dir);
  Side side;
  side.context = std::make_unique<Context>();
  side.renderer = std::make_unique<Renderer>(*side.context, Precision::Float);
  side.renderer->render(s);
  if (kind != RenderCase::Kind::Forward) side.renderer->backward(s, g);
  return side;
}

void timed_call(Side& side, RenderCase::Kind kind, const Scene& s,
                const std::vector<OutputGrads>& g) {
  const Rows before = detail::profiling() ? detail::profile_kernels() : Rows{};
  const auto start = std::chrono::steady_clock::now();
  call(*side.renderer, kind, s, g);
  side.ms.push_back(
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
  if (!detail::profiling()) return;
  for (const auto& [name, row] : detail::profile_kernels()) {
    const auto b = before.find(name);
    side.kernels[name].push_back(row.first - (b == before.end() ? 0 : b->second.first));
  }
}

// The order statistics that hold the median of the values' distribution with 95 % confidence,
// whatever that distribution (the count below the median is binomial(n, 1/2)).
std::pair<double, double> median_interval(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const int n = int(v.size());
  const int k = std::max(0, int(std::floor((n - 1.96 * std::sqrt(double(n))) / 2)));
  return {v[size_t(k)], v[size_t(n - 1 - k)]};
}

std::string fixed(double ms) {
  char text[32];
  std::snprintf(text, sizeof text, "%.2f", ms);
  return text;
}

// "median (low-high)" of the quotients b[i] / a[i] of the pairs.
std::string paired_quotient(const std::vector<double>& a, const std::vector<double>& b) {
  std::vector<double> q;
  for (size_t i = 0; i < a.size(); ++i) q.push_back(b[i] / a[i]);
  const auto [lo, hi] = median_interval(q);
  char text[64];
  std::snprintf(text, sizeof text, "%.3f (%.3f-%.3f)", median(q), lo, hi);
  return text;
}

// The case's row of the table, and with PENUMBRA_PROFILE set its kernels' table.
std::string compare(const RenderCase& rc, const std::string& dir_a, const std::string& dir_b,
                    int n) {
  const Scene s = make_scene(rc.c);
  const std::vector<OutputGrads> g = unit_grads(s);
  Side a = open_side(dir_a, rc.kind, s, g), b = open_side(dir_b, rc.kind, s, g);
  call(*a.renderer, rc.kind, s, g);  // an untimed pair: each side's first call after both opened
  call(*b.renderer, rc.kind, s, g);
  for (int i = 0; i < n; ++i) {
    Side& first = i % 2 ? b : a;
    timed_call(first, rc.kind, s, g);
    timed_call(&first == &a ? b : a, rc.kind, s, g);
  }
  int b_faster = 0;
  for (size_t i = 0; i < a.ms.size(); ++i) b_faster += b.ms[i] < a.ms[i] ? 1 : 0;
  std::string out = "| " + rc.name + " | " + fixed(median(a.ms)) + " | " + fixed(median(b.ms)) +
                    " | " + paired_quotient(a.ms, b.ms) + " | " + std::to_string(b_faster) +
                    " of " + std::to_string(n) + " |\n";
  if (!detail::profiling()) return out;
  std::vector<std::pair<double, std::string>> order;
  for (const auto& [name, ms] : a.kernels) order.emplace_back(median(ms), name);
  std::sort(order.rbegin(), order.rend());
  out += "\n| kernel | A ms a call | B ms a call | B/A (95 %) |\n|---|---|---|---|\n";
  for (const auto& [ms_a, name] : order) {
    const auto other = b.kernels.find(name);
    if (ms_a <= 0 || other == b.kernels.end() || other->second.size() != a.kernels[name].size())
      continue;
    out += "| " + name + " | " + fixed(ms_a) + " | " + fixed(median(other->second)) + " | " +
           paired_quotient(a.kernels[name], other->second) + " |\n";
  }
  return out + "\n";
}

}  // namespace

int run_paired(const std::vector<std::string>& args) {
  try {
    if (args.size() < 3 || args.size() > 4)
      throw std::invalid_argument("--paired wants DIR_A DIR_B REGEX [N]");
    int n = 20;
    if (args.size() == 4) {
      size_t used = 0;
      try {
        n = std::stoi(args[3], &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used != args[3].size() || n < 2 || n > 10000)
        throw std::invalid_argument("--paired wants a number of pairs 2-10000: '" + args[3] + "'");
    }
    const std::regex pattern(args[2]);
    std::vector<RenderCase> chosen;
    for (const RenderCase& rc : render_cases())
      if (std::regex_search(rc.name + "/manual_time", pattern)) chosen.push_back(rc);
    if (chosen.empty())
      throw std::invalid_argument("--paired: no forward, backward or step case matches '" +
                                  args[2] + "' (penumbra_bench --benchmark_list_tests)");
    for (const RenderCase& rc : chosen) {
      const std::string rows = compare(rc, args[0], args[1], n);
      if (&rc == &chosen.front())  // the header once the first case has run
        std::printf(
            "A: %s, B: %s, %d pairs a case\n\n| case | A ms | B ms | B/A (95 %%) | "
            "B faster |\n|---|---|---|---|---|\n",
            args[0].c_str(), args[1].c_str(), n);
      std::fputs(rows.c_str(), stdout);
      std::fflush(stdout);
    }
    if (std::fflush(stdout) != 0 || std::ferror(stdout))
      throw std::runtime_error("cannot write to standard output");
  } catch (const std::regex_error& e) {
    std::fprintf(stderr, "penumbra_bench: --paired: bad REGEX '%s': %s\n", args[2].c_str(),
                 e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "penumbra_bench: %s\n", e.what());
    return 1;
  }
  return 0;
}

}  // namespace penumbra::bench
