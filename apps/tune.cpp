// `penumbra tune [--quick]`: times the launch-parameter candidates of every stage on the current
// device, rejects those whose output differs from the default configuration's, and stores the
// winners in the user's tuning database. Last line:
//   tune: device=NAME entries=N path=PATH
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>

#include "common.hpp"
#include "penumbra/context.hpp"
#include "penumbra/error.hpp"
#include "penumbra/io.hpp"
#include "penumbra/tuning.hpp"

namespace penumbra::cli {

namespace {

struct TuneArgs {
  SceneSource source;
  std::string device, output;
  bool quick = false;
  int runs = 5;
  double clblast_fraction = 0;  // TuneOptions::clblast_fraction
};

// The database file as it is now, "" when there is none.
std::string read_database(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return "";
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  if (!in || in.bad()) throw Error("cannot read the tuning database " + path);
  return text.str();
}

int run_tune(const TuneArgs& a) {
  Scene scene = load_scene_source(a.source);
  Context context(a.device);
  const std::string path = a.output.empty() ? TuningDatabase::user_path() : a.output;
  const std::string key = TuningDatabase::device_key(context.info());
  // Before the minutes of tuning: the database must be one, and its folder writable. Its
  // temporary file is created only once the tune is done, so that none is held meanwhile.
  const std::string existing = read_database(path);
  TuningDatabase::updated_text(existing, path, key, Tuning());
  make_parent_dirs(path);
  check_writable(path, "tuning database");

  TuneOptions options;
  options.quick = a.quick;
  options.runs = a.runs;
  options.clblast_fraction = a.clblast_fraction;
  std::fprintf(stderr, "tuning on %s (%s)...\n", context.info().name.c_str(),
               a.quick ? "quick" : "full");
  const TuneReport report = tune(context, scene, options);
  for (const auto& c : report.candidates)
    std::printf("%-9s %-28s %9.2f ms %s%s\n", c.stage.c_str(), c.name.c_str(), c.median_ms,
                c.accepted ? "" : "REJECTED: ", c.note.c_str());
  const std::string text = TuningDatabase::updated_text(existing, path, key, report.best);
  write_file(path, text, "tuning database");
  const size_t entries = nlohmann::json::parse(text).at("entries").size();
  std::printf("tune: device=%s entries=%zu path=%s\n", context.info().name.c_str(), entries,
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
  c.app->add_option("--runs", args->runs, "timed runs per candidate (median)")
      ->capture_default_str();
  c.app
      ->add_option("--clblast-fraction", args->clblast_fraction,
                   "share of CLBlast's Xgemm parameter space its own tuner searches first, its "
                   "fastest set then timed and checked as an exact-stage candidate (0: skip; "
                   "1e-4: about 20 s on a 2-core CPU)")
      ->check(CLI::Range(0.0, 1.0));
  c.app->add_option("-o,--output", args->output,
                    "database file to update (default: the user's cache, see README)");
  c.app->add_option("--device", args->device, "OpenCL device (index or part of its name)");
  c.run = [args] { return run_tune(*args); };
  return c;
}

}  // namespace penumbra::cli
