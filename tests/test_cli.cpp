// The `penumbra` command-line tool (PENUMBRA_CLI), run as a child process.
//
// Bad inputs must end with a non-zero exit code (not a signal) and exactly one line on stderr
// starting with "penumbra: error:"; good inputs must produce their files.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "cli_run.hpp"
#include "penumbra/context.hpp"
#include "penumbra/image.hpp"
#include "penumbra/image_io.hpp"
#include "penumbra/io.hpp"
#include "penumbra/renderer.hpp"

namespace fs = std::filesystem;

namespace {

// Running the tool (cli_run.hpp).
using namespace penumbra_tests;

std::string temp_path(const std::string& name) {
  return ::testing::TempDir() + "penumbra_cli_" + name;
}

// Runs `penumbra <args>` with stdout and stderr captured in files.
RunResult run_cli(const std::string& args, const std::string& tag) {
  return penumbra_tests::run_cli_to(args, temp_path(tag + ".stdout"), temp_path(tag + ".stderr"));
}

std::string obj_file(const std::string& name, const std::string& text) {
  std::string path = temp_path(name + ".obj");
  write_text(path, text);
  return path;
}

RunResult render_obj(const std::string& name, const std::string& text) {
  const std::string path = obj_file(name, text);
  return run_cli("render --mesh " + quote(path) + " -o " + quote(temp_path(name + ".png")),
                 "obj_" + name);
}

const std::string kBundled = std::string(PENUMBRA_DATA_DIR) + "/scenes/turnaround.json";

// ---------------------------------------------------------------------------------------------
// Bad inputs.

TEST(Cli, MalformedObj) {
  expect_clean_error(render_obj("malformed", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 zz\n"));
}

TEST(Cli, EmptyObj) { expect_clean_error(render_obj("empty", "# no geometry at all\n")); }

TEST(Cli, NanVertex) {
  expect_clean_error(render_obj("nan", "v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"));
}

TEST(Cli, OutOfRangeIndex) {
  expect_clean_error(render_obj("range", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n"));
}

TEST(Cli, DegenerateTriangle) {
  expect_clean_error(render_obj("degenerate", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n"));
}

TEST(Cli, MissingObj) {
  expect_clean_error(run_cli("render --mesh " + quote(temp_path("does_not_exist.obj")) + " -o " +
                                 quote(temp_path("missing.png")),
                             "missing_obj"));
}

TEST(Cli, ZeroSizeImage) {
  expect_clean_error(
      run_cli("render -o " + quote(temp_path("zero.png")) + " --width 0", "zero_width"), "--width");
}

TEST(Cli, NonPositiveSigma) {
  expect_clean_error(
      run_cli("render -o " + quote(temp_path("sigma.png")) + " --sigma 0", "sigma_zero"),
      "--sigma");
  expect_clean_error(
      run_cli("render -o " + quote(temp_path("sigma.png")) + " --sigma -1e-5", "sigma_neg"),
      "--sigma");
}

TEST(Cli, NonPositiveGamma) {
  expect_clean_error(
      run_cli("render -o " + quote(temp_path("gamma.png")) + " --gamma -1", "gamma_neg"),
      "--gamma");
  expect_clean_error(run_cli("gradcheck --samples 2 --gamma 0", "gamma_zero_gradcheck"), "--gamma");
}

TEST(Cli, UnknownDevice) {
  expect_clean_error(run_cli("render -o " + quote(temp_path("device.png")) +
                                 " --width 16 --height 16 --device no-such-device-xyz",
                             "device"));
}

TEST(Cli, UsageErrorsExitWithTwo) {
  RunResult r = run_cli("render --width 16", "usage_no_output");  // -o is required
  expect_clean_error(r);
  EXPECT_EQ(r.exit_code, 2);
  r = run_cli("no-such-command", "usage_command");
  expect_clean_error(r);
  EXPECT_EQ(r.exit_code, 2);
  r = run_cli("render -o x.png --precision quad", "usage_precision");
  expect_clean_error(r);
  EXPECT_EQ(r.exit_code, 2);
  r = run_cli("render -o x.png --sigma abc", "usage_number");
  expect_clean_error(r);
  EXPECT_EQ(r.exit_code, 2);
}

TEST(Cli, BadShadowOptions) {
  struct Case {
    std::string args, mentions;
  };
  const std::string png = quote(temp_path("shadow_opts.png"));
  const std::vector<Case> cases = {
      {"render -o " + png + " --shadows sometimes", "--shadows"},
      {"render -o " + png + " --shadows", "--shadows"},
      {"render -o " + png + " --sampling bogus", "--sampling"},
      {"render -o " + png + " --exact-backend blas", "--exact-backend"},
      {"render -o " + png +
           " --shadows hard --shadow-model paper --sampling gemm "
           "--exact-backend kernels",
       "--sampling gemm"},
      {"render -o " + png + " --shadows hard --sampling truncated --exact-backend clblast",
       "exact backend 'clblast'"},
      {"render -o " + png + " --map-size 0", "--map-size"},
      {"render -o " + png + " --map-size 9000", "--map-size"},
      {"render -o " + png + " --map-size abc", "--map-size"},
      {"render -o " + png + " --light-size -1", "--light-size"},
      {"render -o " + png + " --light-sigma 1", "--light-sigma"},
      {"render -o " + png + " --light-gamma -0.5", "--light-gamma"},
      {"render -o " + png + " --weight-eps 0", "--weight-eps"},
      {"gradcheck --samples 2 --shadows maybe", "--shadows"},
      {"backward --grad-in . -o " + quote(temp_path("shadow_opts_grads")) + " --sampling x",
       "--sampling"},
  };
  for (size_t i = 0; i < cases.size(); ++i) {
    const RunResult r = run_cli(cases[i].args, "shadow_opts_" + std::to_string(i));
    expect_clean_error(r, cases[i].mentions);
    EXPECT_TRUE(r.exit_code == 1 || r.exit_code == 2) << show(r);
  }
}

TEST(Cli, BackwardRejectsWrongGradientShape) {
  const std::string dir = temp_path("bad_grads");
  fs::create_directories(dir);
  penumbra::save_npy(penumbra::Image(8, 8, 3, 0.5), dir + "/color.npy");
  const RunResult r = run_cli("backward --width 16 --height 12 --grad-in " + quote(dir) + " -o " +
                                  quote(temp_path("bad_grads_out")),
                              "backward_shape");
  expect_clean_error(r, "color.npy");
  EXPECT_NE(r.err.find("(12, 16, 3)"), std::string::npos) << show(r);
  EXPECT_NE(r.err.find("(8, 8, 3)"), std::string::npos) << show(r);
}

// ---------------------------------------------------------------------------------------------
// Good inputs.

TEST(Cli, Help) {
  const RunResult r = run_cli("--help", "help");
  EXPECT_EQ(r.exit_code, 0) << show(r);
  for (const char* word : {"devices", "render", "backward", "gradcheck", "turnaround"})
    EXPECT_NE(r.out.find(word), std::string::npos) << word;
  const RunResult sub = run_cli("render --help", "help_render");
  EXPECT_EQ(sub.exit_code, 0) << show(sub);
  for (const char* option :
       {"--sigma",       "--gamma",       "--eps",           "--dist-eps",  "--sigma-s",
        "--lambda-eps",  "--gamma-s",     "--beta",          "--gamma-p",   "--width",
        "--height",      "--device",      "--raw",           "--precision", "--mesh",
        "--shadows",     "--sampling",    "--exact-backend", "--map-size",  "--light-size",
        "--light-sigma", "--light-gamma", "--weight-eps"})
    EXPECT_NE(sub.out.find(option), std::string::npos) << option;
  for (const char* command : {"gradcheck", "backward", "turnaround"}) {
    const RunResult help = run_cli(std::string(command) + " --help", "help_shadows");
    EXPECT_EQ(help.exit_code, 0) << show(help);
    for (const char* option : {"--shadows", "--sampling", "--map-size", "--light-size"})
      EXPECT_NE(help.out.find(option), std::string::npos) << command << " " << option;
  }
}

TEST(Cli, Devices) {
  const RunResult r = run_cli("devices", "devices");
  EXPECT_EQ(r.exit_code, 0) << show(r);
  const std::vector<std::string> rows = lines(r.out);
  ASSERT_GE(rows.size(), 2u) << show(r);  // header + at least one device
  EXPECT_NE(rows[0].find("transfers"), std::string::npos) << rows[0];
  const std::vector<penumbra::DeviceInfo> devices = penumbra::list_devices();
  ASSERT_EQ(rows.size(), devices.size() + 1) << show(r);
  for (const penumbra::DeviceInfo& d : devices) {
    const std::string& row = rows[size_t(d.index) + 1];
    EXPECT_NE(row.find(d.name), std::string::npos) << row;
    const std::string transfers = d.shares_host_memory ? "map" : "copy";
    EXPECT_EQ(row.substr(row.size() - transfers.size()), transfers) << row;
  }
}

TEST(Cli, RenderBundledSceneWritesPng) {
  const std::string png = temp_path("render/turnaround.png");
  const std::string raw = temp_path("render_raw");
  fs::remove_all(temp_path("render"));
  fs::remove_all(raw);
  const RunResult r = run_cli("render " + quote(kBundled) + " -o " + quote(png) +
                                  " --width 64 --height 48 --raw " + quote(raw),
                              "render");
  ASSERT_EQ(r.exit_code, 0) << show(r);
  EXPECT_EQ(lines(r.out).size(), 1u) << "one summary line\n" << show(r);
  const std::string bytes = read_text(png);
  ASSERT_GE(bytes.size(), 8u) << png;
  EXPECT_EQ(bytes.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  const penumbra::Image image = penumbra::load_image(png);
  EXPECT_EQ(image.width, 64);
  EXPECT_EQ(image.height, 48);

  const penumbra::Image color = penumbra::load_npy(raw + "/color.npy");
  EXPECT_EQ(color.width, 64);
  EXPECT_EQ(color.height, 48);
  EXPECT_EQ(color.channels, 3);
  for (const char* name : {"silhouette", "depth"}) {
    const penumbra::Image x = penumbra::load_npy(raw + "/" + name + ".npy");
    EXPECT_EQ(x.width, 64) << name;
    EXPECT_EQ(x.height, 48) << name;
    EXPECT_EQ(x.channels, 1) << name;
  }
}

TEST(Cli, RenderDefaultsToBundledScene) {
  const std::string png = temp_path("default.png");
  fs::remove(png);
  const RunResult r = run_cli("render -o " + quote(png) + " --width 32 --height 32", "default");
  ASSERT_EQ(r.exit_code, 0) << show(r);
  EXPECT_TRUE(fs::exists(png));
}

TEST(Cli, BackwardWritesGradients) {
  // Incoming gradients: ones on the colour (a sum-of-colour loss), silhouette and depth missing.
  const std::string in = temp_path("grads_in"), out = temp_path("grads_out");
  fs::remove_all(in);
  fs::remove_all(out);
  fs::create_directories(in);
  penumbra::save_npy(penumbra::Image(32, 24, 3, 1.0), in + "/color.npy");
  const RunResult r = run_cli("backward " + quote(kBundled) + " --width 32 --height 24 --grad-in " +
                                  quote(in) + " -o " + quote(out),
                              "backward");
  ASSERT_EQ(r.exit_code, 0) << show(r);
  for (const char* file : {"vertices_sphere.npy", "vertices_ground.npy", "albedo_sphere.npy",
                           "albedo_ground.npy", "lights.npy", "ambient.npy"}) {
    EXPECT_TRUE(fs::exists(out + "/" + file)) << file << "\n" << show(r);
  }
  // (N, 3), (L, 7), (1, 3); a 2-D array loads as height = rows, width = columns.
  const penumbra::Image v = penumbra::load_npy(out + "/vertices_sphere.npy");
  EXPECT_EQ(v.width, 3);
  EXPECT_EQ(v.height, 642);
  const penumbra::Image lights = penumbra::load_npy(out + "/lights.npy");
  EXPECT_EQ(lights.width, 7);
  EXPECT_EQ(lights.height, 1);
  EXPECT_EQ(lights.data[6], 0.0);  // hard shadows do not depend on the light's size
  const penumbra::Image ambient = penumbra::load_npy(out + "/ambient.npy");
  EXPECT_EQ(ambient.width, 3);
  EXPECT_EQ(ambient.height, 1);
  // d(Σ colour)/d(ambient) = Σ over pixels of the ambient albedo factor: positive.
  EXPECT_GT(ambient.data[0], 0.0);
  // float64 on disk: header says <f8.
  EXPECT_NE(read_text(out + "/ambient.npy").find("<f8"), std::string::npos);
  // Soft shadows: the seventh column is dL/dD_L.
  const RunResult soft =
      run_cli("backward " + quote(kBundled) + " --width 32 --height 24 " +
                  "--shadows soft --light-size 0.5 --grad-in " + quote(in) + " -o " + quote(out),
              "backward_soft");
  ASSERT_EQ(soft.exit_code, 0) << show(soft);
  EXPECT_NE(penumbra::load_npy(out + "/lights.npy").data[6], 0.0);
}

// PENUMBRA_PROFILE=1: besides the kernels' device time, each stage of render() and backward()
// gets one row of wall time, once per call.
TEST(Cli, ProfileTimesEveryStageOfRenderAndBackward) {
  const std::string in = temp_path("profile_in"), out = temp_path("profile_out");
  fs::remove_all(in);
  fs::create_directories(in);
  penumbra::save_npy(penumbra::Image(32, 24, 3, 1.0), in + "/color.npy");
  ScopedEnv profile("PENUMBRA_PROFILE", "1");
  const RunResult r = run_cli("backward " + quote(kBundled) + " --width 32 --height 24 --grad-in " +
                                  quote(in) + " -o " + quote(out),
                              "profile");
  ASSERT_EQ(r.exit_code, 0) << show(r);
  const size_t table = r.err.find("penumbra profile (wall ms, calls of each renderer stage):\n");
  ASSERT_NE(table, std::string::npos) << show(r);
  for (const char* stage :
       {"render: prepare", "render: upload", "render: shadow map", "render: raster",
        "render: shadow lookups", "render: resolve", "render: outputs", "backward: check",
        "backward: sums", "backward: resolve", "backward: shadow lookups", "backward: faces",
        "backward: shadow map", "backward: gradients"}) {
    const std::regex row("\n  " + std::string(stage) + " +[0-9]+\\.[0-9]{2} +1\n");
    EXPECT_TRUE(std::regex_search(r.err.substr(table), row)) << stage << "\n" << show(r);
  }
}

TEST(Cli, RenderHardShadowsWritesShadowMap) {
  const std::string raw = temp_path("render_shadow_raw");
  fs::remove_all(raw);
  const RunResult r =
      run_cli("render " + quote(kBundled) + " -o " + quote(temp_path("render_shadow.png")) +
                  " --width 32 --height 24 --shadows hard --map-size 20 --raw " + quote(raw),
              "render_shadow");
  ASSERT_EQ(r.exit_code, 0) << show(r);
  const std::string path = raw + "/shadow_map_0.npy";
  ASSERT_TRUE(fs::exists(path)) << show(r);
  EXPECT_NE(read_text(path).find("'shape': (20, 20)"), std::string::npos) << read_text(path);
  EXPECT_NE(read_text(path).find("<f4"), std::string::npos);
  const penumbra::Image map = penumbra::load_npy(path);
  EXPECT_EQ(map.width, 20);
  EXPECT_EQ(map.height, 20);
  EXPECT_EQ(map.channels, 1);
  // Light-view depth: positive, and the sphere (nearer the light) is nearer than the far plane.
  double lo = 1e300, hi = -1e300;
  for (double v : map.data) {
    ASSERT_TRUE(std::isfinite(v));
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  EXPECT_GT(lo, 0.0);
  EXPECT_LT(lo, hi);
  EXPECT_FALSE(fs::exists(raw + "/shadow_map_1.npy"));
  EXPECT_FALSE(fs::exists(raw + "/penumbra_map_0.npy"));  // hard shadows have none

  // Soft shadows also write the penumbra map P, in [0, 1].
  const std::string soft = temp_path("render_soft_raw");
  fs::remove_all(soft);
  const RunResult rs = run_cli(
      "render " + quote(kBundled) + " -o " + quote(temp_path("render_soft.png")) +
          " --width 32 --height 24 --shadows soft --shadow-model paper --map-size 20 --raw " +
          quote(soft),
      "render_soft");
  ASSERT_EQ(rs.exit_code, 0) << show(rs);
  const penumbra::Image pen = penumbra::load_npy(soft + "/penumbra_map_0.npy");
  EXPECT_EQ(pen.width, 20);
  EXPECT_EQ(pen.height, 20);
  for (double v : pen.data) {
    EXPECT_GE(v, 0.0);
    EXPECT_LE(v, 1.0 + 1e-6);
  }

  // With shadows off there is no shadow map.
  const std::string off = temp_path("render_noshadow_raw");
  fs::remove_all(off);
  const RunResult r2 =
      run_cli("render " + quote(kBundled) + " -o " + quote(temp_path("render_noshadow.png")) +
                  " --width 32 --height 24 --shadows none --raw " + quote(off),
              "render_noshadow");
  ASSERT_EQ(r2.exit_code, 0) << show(r2);
  EXPECT_TRUE(fs::exists(off + "/color.npy"));
  EXPECT_FALSE(fs::exists(off + "/shadow_map_0.npy"));
}

TEST(Cli, ShadowOptionsChangeTheImage) {
  // --shadows hard darkens the ground next to the sphere; --light-size and the sampling words
  // are accepted (and --shadows none matches a scene without shadows).
  const std::string dir = temp_path("shadow_images");
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string common = "render " + quote(kBundled) + " --width 40 --height 40 --map-size 32";
  std::vector<penumbra::Image> images;
  int i = 0;
  for (const std::string& extra :
       {std::string("--shadows none"), std::string("--shadows hard --sampling truncated"),
        std::string("--shadows hard --sampling exact --light-size 0.3"),
        std::string("--shadows hard --sampling gemm --shadow-model paper --light-sigma 2e-5 "
                    "--light-gamma 2e-4 "
                    "--weight-eps 1e-8")}) {
    const std::string png = dir + "/" + std::to_string(i) + ".png";
    const RunResult r =
        run_cli(common + " " + extra + " -o " + quote(png), "shadow_images_" + std::to_string(i++));
    ASSERT_EQ(r.exit_code, 0) << show(r);
    images.push_back(penumbra::load_image(png, 3));
  }
  double none = 0, hard = 0;
  for (size_t k = 0; k < images[0].data.size(); ++k) {
    none += images[0].data[k];
    hard += images[1].data[k];
  }
  EXPECT_LT(hard, none - 1.0) << "hard shadows should darken the image";
}

TEST(Cli, GradcheckHardShadows) {
  const RunResult r = run_cli("gradcheck " + quote(kBundled) +
                                  " --shadows hard --sampling truncated --samples 12 --width 40 "
                                  "--height 40 --map-size 32 --verbose",
                              "gradcheck_shadows");
  EXPECT_EQ(r.exit_code, 0) << show(r);
  const auto out = lines(r.out);
  ASSERT_FALSE(out.empty()) << show(r);
  const std::regex format(R"(^gradcheck: checked=12 failed=\d+ max_rel_err=\S+$)");
  EXPECT_TRUE(std::regex_match(out.back(), format)) << "last line: " << out.back();
  // The light's position and a vertex of both meshes are among the checked entries.
  for (const char* entry : {"light0.position.", "mesh0.v", "mesh1.v"})
    EXPECT_NE(r.out.find(entry), std::string::npos) << entry << "\n" << show(r);
}

TEST(Cli, GradcheckBundledScene) {
  const RunResult r =
      run_cli("gradcheck " + quote(kBundled) + " --samples 8 --width 48 --height 48", "gradcheck");
  EXPECT_EQ(r.exit_code, 0) << show(r);
  const auto out = lines(r.out);
  ASSERT_FALSE(out.empty()) << show(r);
  const std::regex format(R"(^gradcheck: checked=8 failed=\d+ max_rel_err=\S+$)");
  EXPECT_TRUE(std::regex_match(out.back(), format)) << "last line: " << out.back();
}

TEST(Cli, GradcheckRandomSceneVerbose) {
  const RunResult r =
      run_cli("gradcheck --random-scene --seed 4 --samples 6 --verbose", "gradcheck_random");
  EXPECT_EQ(r.exit_code, 0) << show(r);
  const auto out = lines(r.out);
  ASSERT_GE(out.size(), 7u) << show(r);  // per-entry lines, then the summary
  const std::regex format(R"(^gradcheck: checked=6 failed=\d+ max_rel_err=\S+$)");
  EXPECT_TRUE(std::regex_match(out.back(), format)) << "last line: " << out.back();
}

}  // namespace

TEST(Cli, FiguresWritesEveryPicture) {
  const std::string dir = temp_path("figures");
  const RunResult r = run_cli("figures -o " + quote(dir), "figures");
  ASSERT_EQ(r.exit_code, 0) << show(r);
  for (const char* name :
       {"fig1_a.png", "fig1_b.png", "fig1_c.png", "fig1_d.png", "fig2_depth_map.png",
        "fig4_soft_000.png", "fig4_soft_270.png", "fig5_penumbra_map.png", "soft_size_1.5.png",
        "model_paper_hard.png", "model_accurate_hard.png", "model_paper_soft.png",
        "model_accurate_soft.png"}) {
    const penumbra::Image img = penumbra::load_image(dir + "/" + name);
    EXPECT_GT(img.width, 0) << name;
  }
  const auto out = lines(r.out);
  ASSERT_FALSE(out.empty());
  EXPECT_EQ(out.back().rfind("figures: files=17 seconds=", 0), 0u) << show(r);
}

// The bundled scene at the largest image and map sizes, with as many cameras as it takes for the
// estimate to exceed the memory of the device the CLI opens (one on PoCL's few GiB, several on
// a GPU with 100+ GiB).
TEST(Cli, SceneTooLargeForTheDeviceFailsUpFront) {
  nlohmann::json scene = nlohmann::json::parse(std::ifstream(kBundled));
  for (auto& mesh : scene["meshes"])
    mesh["file"] = std::string(PENUMBRA_DATA_DIR) + "/scenes/" + mesh["file"].get<std::string>();
  scene["cameras"][0]["width"] = scene["cameras"][0]["height"] = 16384;
  scene["render"]["shadow_map_size"] = 8192;
  const size_t one = penumbra::estimate_device_memory(penumbra::parse_scene(scene.dump(), ""),
                                                      penumbra::Precision::Float);
  const size_t device = penumbra::Context().memory_limit();
  for (size_t i = 0; i < device / one; ++i) scene["cameras"].push_back(scene["cameras"][0]);
  const std::string path = temp_path("huge.json");
  std::ofstream(path) << scene.dump();
  const RunResult r =
      run_cli("render " + quote(path) + " -o " + quote(temp_path("huge.png")), "huge");
  expect_clean_error(r, "GiB of device memory, more than the ");
}

// ---------------------------------------------------------------------------------------------
// README.md against --help.

namespace {

// The subcommands `penumbra --help` lists.
std::vector<std::string> subcommands() {
  const RunResult r = run_cli("--help", "help_commands");
  std::vector<std::string> out;
  bool in_list = false;
  for (const std::string& line : lines(r.out)) {
    if (line.rfind("Subcommands:", 0) == 0) in_list = true;
    std::smatch m;
    if (in_list && std::regex_search(line, m, std::regex("^  ([a-z][-a-z]*)\\s")))
      out.push_back(m[1]);
  }
  return out;
}

// Every option name (`-o` and `--output` alike) that `penumbra <command> --help` lists.
std::set<std::string> help_options(const std::string& command) {
  const RunResult r = run_cli(command + " --help", "help_" + command);
  EXPECT_EQ(r.exit_code, 0) << show(r);
  std::set<std::string> out;
  for (const std::string& line : lines(r.out)) {
    std::smatch m;
    if (!std::regex_search(line, m, std::regex("^  (-[^ ]+)"))) continue;
    std::stringstream names(m[1].str());
    for (std::string name; std::getline(names, name, ',');) out.insert(name);
  }
  return out;
}

// The `...` spans of a piece of Markdown.
std::vector<std::string> code_spans(const std::string& text) {
  std::vector<std::string> out;
  const std::regex span("`([^`]*)`");
  for (auto it = std::sregex_iterator(text.begin(), text.end(), span); it != std::sregex_iterator();
       ++it)
    out.push_back((*it)[1]);
  return out;
}

// The cells of a Markdown table row (`\|` inside a cell is no separator).
std::vector<std::string> cells(const std::string& row) {
  std::vector<std::string> out;
  std::string cell;
  for (size_t i = 1; i < row.size(); ++i) {
    if (row[i] == '|' && row[i - 1] != '\\') {
      out.push_back(cell);
      cell.clear();
    } else {
      cell += row[i];
    }
  }
  return out;
}

// README.md's option tables, per subcommand. A table belongs to the commands of the `###
// `penumbra X`` heading it is under, or, when the paragraph before it says "shared by", to the
// commands named after those words; a "commands" column narrows a row to the commands it
// names ("all": every command of the table). The options of a row are the code spans of its
// first cell that start with "-" (their first word).
struct ReadmeOptions {
  std::map<std::string, std::set<std::string>> options;
  std::set<std::string> sections;  // commands with a `### `penumbra X`` heading
};

ReadmeOptions readme_options() {
  ReadmeOptions doc;
  const std::string text = read_text(std::string(PENUMBRA_DATA_DIR) + "/../README.md");
  EXPECT_FALSE(text.empty()) << "README.md not found";
  std::vector<std::string> section, table;
  std::string paragraph;
  int commands_column = -1;
  bool header = false, fenced = false, ended = false;
  for (const std::string& line : lines(text)) {
    if (line.rfind("```", 0) == 0) fenced = !fenced;
    if (fenced) continue;
    if (line.rfind('#', 0) == 0) {
      section.clear();
      if (line.rfind("### ", 0) == 0) {
        const std::regex name("`penumbra ([a-z][-a-z]*)`");
        for (auto it = std::sregex_iterator(line.begin(), line.end(), name);
             it != std::sregex_iterator(); ++it) {
          section.push_back((*it)[1]);
          doc.sections.insert((*it)[1]);
        }
      }
      paragraph.clear();
      continue;
    }
    if (line.rfind('|', 0) != 0) {  // text: the paragraph before the next table
      table.clear();
      if (line.empty())
        ended = true;
      else
        paragraph = (ended ? "" : paragraph + " ") + line, ended = false;
      continue;
    }
    if (table.empty() && !header) {  // the header row: whose table, which columns
      const size_t shared = paragraph.find("shared by");
      table = shared == std::string::npos ? section : code_spans(paragraph.substr(shared));
      const auto names = cells(line);
      commands_column = -1;
      for (size_t i = 0; i < names.size(); ++i)
        if (names[i].find("commands") != std::string::npos) commands_column = int(i);
      header = true;
      if (table.empty()) table.emplace_back();  // a table of no command (environment variables)
      continue;
    }
    header = false;
    if (line.rfind("|---", 0) == 0) continue;
    const auto row = cells(line);
    if (row.empty()) continue;
    std::vector<std::string> to = table;
    if (commands_column >= 0 && commands_column < int(row.size()) &&
        row[commands_column].find("all") == std::string::npos)
      to = code_spans(row[commands_column]);
    for (const std::string& span : code_spans(row[0])) {
      if (span.empty() || span[0] != '-') continue;
      const std::string option = span.substr(0, span.find(' '));
      for (const std::string& command : to)
        if (!command.empty()) doc.options[command].insert(option);
    }
  }
  return doc;
}

}  // namespace

// Every option of every subcommand's --help is in README's option tables, and every option
// README documents for a command is one its --help lists.
TEST(Cli, ReadmeAndHelpNameTheSameOptions) {
  const ReadmeOptions doc = readme_options();
  // -h/--help: CLI11 gives every command one; README says so once, above the sections.
  const std::set<std::string> exempt = {"-h", "--help"};
  const std::vector<std::string> commands = subcommands();
  EXPECT_GE(commands.size(), 11u);
  for (const std::string& command : commands) {
    EXPECT_TRUE(doc.sections.count(command))
        << "README has no section `penumbra " << command << "`";
    const std::set<std::string> help = help_options(command);
    EXPECT_TRUE(help.count("--help")) << command;
    const std::set<std::string>& documented =
        doc.options.count(command) ? doc.options.at(command) : std::set<std::string>{};
    for (const std::string& option : help)
      EXPECT_TRUE(exempt.count(option) || documented.count(option))
          << "`penumbra " << command << " " << option << "` is not in README's option tables";
    for (const std::string& option : documented)
      EXPECT_TRUE(help.count(option)) << "README documents " << option << " for `penumbra "
                                      << command << "`, which its --help does not list";
  }
  for (const std::string& section : doc.sections)
    EXPECT_NE(std::find(commands.begin(), commands.end(), section), commands.end())
        << "README has a section for `penumbra " << section << "`, which is no command";
}
