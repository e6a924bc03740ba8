// `penumbra gradcheck`: Renderer::backward against central finite differences.
// The last line of its output is always `gradcheck: checked=N failed=K max_rel_err=E`.
#include "penumbra/gradcheck.hpp"

#include <cstdio>
#include <iostream>
#include <memory>

#include "common.hpp"
#include "penumbra/context.hpp"
#include "penumbra/error.hpp"

namespace penumbra::cli {

namespace {

struct GradcheckArgs {
  SceneSource source;
  RenderOptions render;
  std::string precision;
  int samples = 40;
  uint64_t seed = 1;
  double step = 0, rtol = 0;
  bool random = false, verbose = false, float_differences = false;
};

int run_gradcheck(const GradcheckArgs& a) {
  if (a.samples < 1)
    throw Error("--samples must be at least 1 (got " + std::to_string(a.samples) + ")");
  if (a.random && !(a.source.scene_path.empty() && a.source.mesh_path.empty()))
    throw Error("--random-scene builds its own scene; give no scene file or --mesh with it");
  Scene scene = a.random ? random_scene(a.seed) : load_scene_source(a.source);
  apply_render_options(a.render, scene);

  GradCheckOptions options;
  options.precision = parse_precision(a.precision);
  options.samples = a.samples;
  options.seed = a.seed;
  options.double_differences = !a.float_differences;
  options.step = a.step;
  options.rtol = a.rtol;

  Context context(a.render.device);
  limit_memory(a.render, context);
  CallProgress progress("gradcheck");
  options.progress = [&progress](const RenderProgress& p) { progress.update(p); };
  const GradCheckResult r = gradcheck(context, scene, options);
  progress.finish();
  if (a.verbose) {
    std::printf("%-24s %15s %15s %10s\n", "entry", "analytic", "numeric", "rel_err");
    for (const GradCheckEntry& e : r.entries) {
      std::printf("%-24s %15.8g %15.8g %10.3g%s\n", e.name.c_str(), e.analytic, e.numeric,
                  e.rel_err, e.ok ? "" : "  FAIL");
    }
    std::printf("atol=%.3g rtol=%.3g allowed failures=%.0f%%\n", r.atol, r.rtol,
                100.0 * r.max_failure_fraction);
  }
  std::printf("gradcheck: checked=%d failed=%d max_rel_err=%.3g\n", r.checked, r.failed,
              r.max_rel_err);
  std::fflush(stdout);
  if (!r.passed()) {
    std::cerr << "penumbra: error: gradient check failed: " << r.failed << " of " << r.checked
              << " entries disagree with finite differences" << std::endl;
    return 1;
  }
  return 0;
}

}  // namespace

Command add_gradcheck_command(CLI::App& root) {
  auto args = std::make_shared<GradcheckArgs>();
  Command c;
  c.app = root.add_subcommand(
      "gradcheck", "check the gradients of backward against finite differences of render");
  add_scene_options(*c.app, args->source);
  add_precision_option(*c.app, args->precision, "double");
  c.app->add_option("--samples", args->samples, "number of scalar entries to check")
      ->capture_default_str();
  c.app
      ->add_option("--seed", args->seed,
                   "seed of the loss weights, the entries and "
                   "--random-scene")
      ->capture_default_str();
  c.app
      ->add_option("--step", args->step,
                   "finite-difference step (positions: times the scene radius); default 1e-6 "
                   "for differences in double, 1e-3 in float")
      ->check(CLI::NonNegativeNumber);
  c.app
      ->add_option("--rtol", args->rtol,
                   "relative tolerance; default 1e-3 in double, 5e-2 in "
                   "float")
      ->check(CLI::NonNegativeNumber);
  c.app->add_flag("--float-differences", args->float_differences,
                  "with --precision float: take the finite differences in float too (noisy) "
                  "instead of in double");
  c.app->add_flag("--random-scene", args->random,
                  "check a small random scene built from --seed instead of a scene file");
  c.app->add_flag("-v,--verbose", args->verbose, "print every checked entry");
  add_render_options(*c.app, args->render);
  c.run = [args] { return run_gradcheck(*args); };
  return c;
}

}  // namespace penumbra::cli
