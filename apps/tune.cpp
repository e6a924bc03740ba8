// `penumbra tune [--quick]`: times the launch-parameter candidates of every stage on the current
// device, rejects those whose output differs from the default configuration's, and stores the
// winners in the user's tuning database. Last line:
//   tune: device=NAME entries=N path=PATH
#include <cstdio>
#include <filesystem>
#include <memory>

#include "common.hpp"
#include "penumbra/context.hpp"
#include "penumbra/tuning.hpp"

namespace penumbra::cli {

namespace {

struct TuneArgs {
  SceneSource source;
  std::string device, output;
  bool quick = false;
  int runs = 5;
};

int run_tune(const TuneArgs& a) {
  Scene scene = load_scene_source(a.source);
  Context context(a.device);
  TuneOptions options;
  options.quick = a.quick;
  options.runs = a.runs;
  std::fprintf(stderr, "tuning on %s (%s)...\n", context.info().name.c_str(),
               a.quick ? "quick" : "full");
  const TuneReport report = tune(context, scene, options);
  for (const auto& c : report.candidates)
    std::printf("%-9s %-28s %9.2f ms %s%s\n", c.stage.c_str(), c.name.c_str(), c.median_ms,
                c.accepted ? "" : "REJECTED: ", c.note.c_str());
  const std::string path = a.output.empty() ? TuningDatabase::user_path() : a.output;
  TuningDatabase db = TuningDatabase::load({});
  if (std::filesystem::exists(path)) db = TuningDatabase::load({path});
  db.set(TuningDatabase::device_key(context.info()), report.best);
  db.save(path);
  std::printf("tune: device=%s entries=%zu path=%s\n", context.info().name.c_str(), db.size(),
              path.c_str());
  return 0;
}

}  // namespace

Command add_tune_command(CLI::App& root) {
  auto args = std::make_shared<TuneArgs>();
  Command c;
  c.app = root.add_subcommand("tune",
                              "time the launch parameters on this device and store the fastest "
                              "in the tuning database");
  add_scene_options(*c.app, args->source, false);
  c.app->add_flag("--quick", args->quick, "fewer candidates, smaller images, fewer runs");
  c.app->add_option("--runs", args->runs, "timed runs per candidate (median)")->capture_default_str();
  c.app->add_option("-o,--output", args->output,
                    "database file to update (default: the user's cache, see README)");
  c.app->add_option("--device", args->device, "OpenCL device (index or part of its name)");
  c.run = [args] { return run_tune(*args); };
  return c;
}

}  // namespace penumbra::cli
