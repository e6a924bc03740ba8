// The kernel cache (host/src/cl/program_cache.hpp): compiled programs kept on disk between
// processes. A damaged entry must be rebuilt, never trusted; a cache that cannot be written
// must never fail a render; a program loaded from a binary must compute exactly what the one
// built from source computes.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>
#include <regex>
#include <string>
#include <vector>

#include "cl/program_cache.hpp"
#include "cli_run.hpp"
#include "penumbra/context.hpp"

namespace fs = std::filesystem;
using namespace penumbra_tests;

namespace {

fs::path fresh_dir(const std::string& name) {
  fs::path dir = fs::path(::testing::TempDir()) / ("penumbra_cache_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

std::vector<fs::path> entries(const fs::path& dir) {
  std::vector<fs::path> out;
  if (fs::is_directory(dir))
    for (auto& e : fs::recursive_directory_iterator(dir))
      if (e.path().extension() == ".clbin") out.push_back(e.path());
  return out;
}

ino_t inode(const fs::path& p) {
  struct stat st {};
  ::stat(p.c_str(), &st);
  return st.st_ino;
}

RunResult run(const std::string& args, const fs::path& dir, const std::string& tag) {
  return run_cli_to(args, (dir / (tag + ".stdout")).string(), (dir / (tag + ".stderr")).string());
}

// A small render with soft shadows, its raw arrays written to `raw`; `model` picks the programs
// (accurate: accurate_lookups.cl; paper with exact sampling: paper_soft_map.cl and
// paper_lookups.cl).
std::string render_args(const fs::path& raw, const std::string& model = "accurate") {
  return "render -o " + quote((raw / "image.png").string()) +
         " --width 48 --height 32 --shadows soft --map-size 32 --shadow-model " + model +
         (model == "paper" ? " --sampling exact" : "") + " --raw " + quote(raw.string());
}

int count(const std::string& text, const std::string& what) {
  int n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

}  // namespace

TEST(ProgramCache, EntryRoundTripsAndDamageIsDetected) {
  using penumbra::detail::decode_program_entry;
  using penumbra::detail::encode_program_entry;
  const char bytes[] = "a program binary \x01\x02\x00 with bytes";  // the NUL included
  const std::string key(32, 'a'), binary(bytes, sizeof bytes - 1);
  const std::string entry = encode_program_entry(key, binary);
  ASSERT_TRUE(decode_program_entry(key, entry).has_value());
  EXPECT_EQ(*decode_program_entry(key, entry), binary);
  EXPECT_FALSE(decode_program_entry(key, ""));
  EXPECT_FALSE(decode_program_entry(key, entry.substr(0, entry.size() - 1)));  // truncated
  EXPECT_FALSE(decode_program_entry(key, entry.substr(0, 20)));                // header cut
  EXPECT_FALSE(decode_program_entry(key, entry + "x"));                        // too long
  EXPECT_FALSE(decode_program_entry(std::string(32, 'b'), entry));             // another key
  std::string flipped = entry;
  flipped.back() ^= 0x10;
  EXPECT_FALSE(decode_program_entry(key, flipped));                            // checksum
  EXPECT_FALSE(decode_program_entry(key, std::string(entry.size(), '\x5a')));  // noise
  EXPECT_FALSE(decode_program_entry(key, encode_program_entry(key, "")));      // no binary
}

TEST(ProgramCache, LocationFollowsTheEnvironment) {
  using penumbra::detail::program_cache_dir;
  ScopedEnv xdg("XDG_CACHE_HOME", "/x/cache"), home("HOME", "/h");
  {
    ScopedEnv dir("PENUMBRA_CACHE_DIR", "/somewhere");
    EXPECT_EQ(program_cache_dir(), "/somewhere");
  }
  {
    ScopedEnv dir("PENUMBRA_CACHE_DIR", "off");
    EXPECT_EQ(program_cache_dir(), "");
  }
  ScopedEnv dir("PENUMBRA_CACHE_DIR", nullptr);
  EXPECT_EQ(program_cache_dir(), "/x/cache/penumbra");
  ScopedEnv no_xdg("XDG_CACHE_HOME", nullptr);
  EXPECT_EQ(program_cache_dir(), "/h/.cache/penumbra");
}

// Each kind of damage in turn: the next process (here a fresh Context) must notice it, build
// from source and put a good entry in its place.
TEST(ProgramCache, DamagedEntryIsRebuiltAndReplaced) {
  const fs::path dir = fresh_dir("damaged");
  ScopedEnv env("PENUMBRA_CACHE_DIR", dir.c_str());
  { penumbra::Context().program("bin.cl", ""); }
  const std::vector<fs::path> files = entries(dir);
  ASSERT_EQ(files.size(), 1u);
  const std::string key = files[0].stem().string(), good = read_text(files[0].string());
  ASSERT_TRUE(penumbra::detail::decode_program_entry(key, good));
  const std::map<std::string, std::string> damage = {
      {"empty", ""},
      {"truncated", good.substr(0, good.size() / 2)},
      {"random bytes", std::string(4096, '\x17')},
      {"a binary the driver rejects",
       penumbra::detail::encode_program_entry(key, "not a program binary at all")}};
  for (const auto& [what, bytes] : damage) {
    write_text(files[0].string(), bytes);
    penumbra::Context ctx;  // a new program table, as in a new process
    EXPECT_NO_THROW(ctx.program("bin.cl", "")) << what;
    const std::string now = read_text(files[0].string());
    EXPECT_NE(now, bytes) << what << ": the entry was not replaced";
    EXPECT_TRUE(penumbra::detail::decode_program_entry(key, now)) << what;
  }
}

// An edited kernel under PENUMBRA_KERNEL_DIR is a different source, hence a different entry:
// never the binary of the source before the edit.
TEST(ProgramCache, EditedKernelSourceGetsItsOwnEntry) {
  const fs::path dir = fresh_dir("edited"), kernels = dir / "kernels";
  fs::copy(fs::path(PENUMBRA_DATA_DIR).parent_path() / "kernels", kernels,
           fs::copy_options::recursive);
  ScopedEnv env("PENUMBRA_CACHE_DIR", (dir / "cache").c_str()),
      source("PENUMBRA_KERNEL_DIR", kernels.c_str());
  { penumbra::Context().program("bin.cl", ""); }
  ASSERT_EQ(entries(dir / "cache").size(), 1u);
  write_text((kernels / "bin.cl").string(),
             read_text((kernels / "bin.cl").string()) + "\n// edited\n");
  { penumbra::Context().program("bin.cl", ""); }
  EXPECT_EQ(entries(dir / "cache").size(), 2u);
  { penumbra::Context().program("bin.cl", "-DTILE=8"); }  // other options: another entry
  EXPECT_EQ(entries(dir / "cache").size(), 3u);
}

// The same render in two processes, the first building every program from source into an
// empty cache, the second loading them all (not rewriting them): the raw arrays must be
// identical byte for byte.
void expect_cold_and_warm_identical(const fs::path& dir, const std::string& model) {
  const fs::path cache = dir / "cache";
  ScopedEnv env("PENUMBRA_CACHE_DIR", cache.c_str()), profile("PENUMBRA_PROFILE", "1");
  const RunResult cold = run(render_args(dir / "cold", model), dir, "cold");
  ASSERT_EQ(cold.exit_code, 0) << show(cold);
  EXPECT_EQ(count(cold.err, "loaded from the cache"), 0) << cold.err;
  const std::vector<fs::path> files = entries(cache);
  ASSERT_GE(files.size(), 4u) << cold.err;
  EXPECT_EQ(count(cold.err, "built from source"), int(files.size())) << cold.err;
  std::map<fs::path, ino_t> before;
  for (const fs::path& f : files) before[f] = inode(f);

  const RunResult warm = run(render_args(dir / "warm", model), dir, "warm");
  ASSERT_EQ(warm.exit_code, 0) << show(warm);
  EXPECT_EQ(count(warm.err, "built from source"), 0) << warm.err;
  EXPECT_EQ(count(warm.err, "loaded from the cache"), int(files.size())) << warm.err;
  for (const fs::path& f : files) EXPECT_EQ(inode(f), before[f]) << f << " was rewritten";

  int compared = 0;
  for (auto& e : fs::directory_iterator(dir / "cold")) {
    const fs::path twin = dir / "warm" / e.path().filename();
    ASSERT_TRUE(fs::exists(twin)) << twin;
    EXPECT_TRUE(read_text(e.path().string()) == read_text(twin.string())) << e.path().filename();
    ++compared;
  }
  EXPECT_GE(compared, 5);  // the PNG, colour, silhouette, depth, the shadow map, ...
}

TEST(ProgramCache, ColdAndWarmRendersAreBitIdentical) {
  expect_cold_and_warm_identical(fresh_dir("bit_identical_accurate"), "accurate");
  expect_cold_and_warm_identical(fresh_dir("bit_identical_paper"), "paper");
}

TEST(ProgramCache, OffWritesNothing) {
  const fs::path dir = fresh_dir("off");
  // Compiling every kernel can take over 2 s on a loaded machine; the progress lines of such a
  // render are not what this test is about.
  ScopedEnv env("PENUMBRA_CACHE_DIR", "off"), xdg("XDG_CACHE_HOME", (dir / "xdg").c_str()),
      home("HOME", (dir / "home").c_str()), progress("PENUMBRA_PROGRESS_AFTER", "600");
  const RunResult r = run(render_args(dir / "raw"), dir, "off");
  ASSERT_EQ(r.exit_code, 0) << show(r);
  EXPECT_TRUE(entries(dir).empty());
  // PoCL's compiler, building from source with its own cache in the fresh HOME, prints a count
  // of its warnings on some CPUs ("11 warnings generated.": AVX-512 ABI notes on a CPU without
  // it); that line is the driver's, not penumbra's.
  EXPECT_EQ(std::regex_replace(r.err, std::regex("[0-9]+ warnings? generated\\.\n"), ""), "");
}

// A cache folder that cannot be created (its parent is a regular file): the render succeeds,
// with at most one warning line.
TEST(ProgramCache, UnwritableFolderStillRenders) {
  const fs::path dir = fresh_dir("unwritable");
  write_text((dir / "file").string(), "a file, not a folder");
  ScopedEnv env("PENUMBRA_CACHE_DIR", (dir / "file" / "cache").c_str());
  const RunResult r = run(render_args(dir / "raw"), dir, "unwritable");
  ASSERT_EQ(r.exit_code, 0) << show(r);
  EXPECT_TRUE(fs::exists(dir / "raw" / "color.npy"));
  const std::vector<std::string> err = lines(r.err);
  ASSERT_LE(err.size(), 1u) << r.err;
  if (!err.empty()) {
    EXPECT_EQ(err[0].rfind("penumbra: warning:", 0), 0u) << r.err;
  }
}

// On PoCL a process that loads the kernel cache compiles no kernel: launches run the code the
// cached binaries hold (POCL_WORK_GROUP_SPECIALIZATION=0, host/src/cl/context.cpp). PoCL keeps
// what it compiles for a launch's sizes in POCL_CACHE_DIR, one folder per size ("64-1-1-goffs0"
// ...), and the code unpacked from a binary in folders named "0-0-0"; with PoCL's default
// (specialization on) the same warm run compiles for the sizes it launches.
namespace {
int kernels_compiled_for_launch_sizes(const fs::path& pocl_cache) {
  int n = 0;
  if (fs::is_directory(pocl_cache))
    for (auto& e : fs::recursive_directory_iterator(pocl_cache))
      n += e.path().extension() == ".so" && e.path().parent_path().filename() != "0-0-0";
  return n;
}
}  // namespace

TEST(ProgramCache, WarmCacheLeavesPoclNothingToCompile) {
  if (penumbra::list_devices().front().platform.find("Portable Computing Language") ==
      std::string::npos)
    GTEST_SKIP() << "not PoCL";
  const fs::path dir = fresh_dir("pocl_compiles");
  // Unset, as in a user's shell: the tool sets it (this process's list_devices set it too).
  ScopedEnv cache("PENUMBRA_CACHE_DIR", (dir / "cache").c_str()),
      unset("POCL_WORK_GROUP_SPECIALIZATION", nullptr);
  auto render_with = [&](const std::string& pocl_cache) {
    ScopedEnv pocl("POCL_CACHE_DIR", (dir / pocl_cache).c_str());
    const RunResult r = run(render_args(dir / ("raw_" + pocl_cache)), dir, pocl_cache);
    EXPECT_EQ(r.exit_code, 0) << show(r);
    return kernels_compiled_for_launch_sizes(dir / pocl_cache);
  };
  render_with("fill");
  EXPECT_EQ(render_with("warm"), 0);
  ScopedEnv specialize("POCL_WORK_GROUP_SPECIALIZATION", "1");
  EXPECT_GT(render_with("specialized"), 0);
}

// `penumbra kernels --warm` (what the build runs) fills the cache with every program a
// renderer builds by itself: afterwards a new process's render and backward, in each
// precision, shadow model, shadow mode and sampling, build nothing from source. The cache is
// the suite's own (PENUMBRA_CACHE_DIR), which the other tests share, so that filling it costs
// the suite little.
TEST(ProgramCache, WarmFillsWhatEveryRenderAndBackwardBuilds) {
  const fs::path dir = fresh_dir("warm");
  RunResult warm;
  {
    ScopedEnv progress("PENUMBRA_PROGRESS_AFTER", "0");
    warm = run("kernels --warm", dir, "warm");
  }
  ASSERT_EQ(warm.exit_code, 0) << show(warm);
  EXPECT_TRUE(std::regex_search(warm.out, std::regex("^kernels: [1-9][0-9]* programs for ")))
      << warm.out;
  EXPECT_TRUE(std::regex_search(
      warm.err, std::regex("kernels: warm device 1/[0-9]+, programs ([0-9]+)/\\1, 100 %")))
      << warm.err;
  const RunResult grads =
      run("render --width 48 --height 32 --shadows none -o " + quote((dir / "grads.png").string()) +
              " --raw " + quote((dir / "grads").string()),
          dir, "grads");
  ASSERT_EQ(grads.exit_code, 0) << show(grads);
  ScopedEnv profile("PENUMBRA_PROFILE", "1");
  for (const char* precision : {"float", "double"})
    for (const char* model : {"accurate", "paper"})
      for (const char* shadows : {"none", "hard", "soft"})
        for (const char* sampling : {"truncated", "exact"}) {
          const std::string tag =
              std::string(precision) + "_" + model + "_" + shadows + "_" + sampling;
          const RunResult r =
              run(std::string("backward --width 48 --height 32 --map-size 32") + " --precision " +
                      precision + " --shadow-model " + model + " --shadows " + shadows +
                      " --sampling " + sampling + " --grad-in " + quote((dir / "grads").string()) +
                      " -o " + quote((dir / tag).string()),
                  dir, tag);
          ASSERT_EQ(r.exit_code, 0) << show(r);
          EXPECT_EQ(count(r.err, "built from source"), 0) << tag << "\n" << r.err;
          EXPECT_GE(count(r.err, "loaded from the cache"), 4) << tag << "\n" << r.err;
        }
}
