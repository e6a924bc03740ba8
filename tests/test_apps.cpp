// The applications of the `penumbra` tool (PENUMBRA_CLI), run as child processes:
// fit-silhouette, fit-shadows and shadow-art.
//
//   Apps.*Errors      bad targets and options: a non-zero exit status and exactly one line on
//                     stderr starting with "penumbra: error:" that names the problem
//   Apps.*Converges   short runs on small targets the tool has never seen (a disc and a square,
//                     made here, consistent: the front and side views of a cylinder cut to a
//                     square): the last line's format, the files written, the IoUs reached
//   Apps.*Bundled     a few iterations on the bundled targets: they are found and read
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "cli_run.hpp"
#include "penumbra/image.hpp"
#include "penumbra/image_io.hpp"
#include "penumbra/io.hpp"

namespace fs = std::filesystem;

namespace {

// Running the tool (cli_run.hpp).
using namespace penumbra_tests;

// Files of the running test: ctest runs tests in parallel processes, so no two tests share one.
std::string temp_path(const std::string& name) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  return ::testing::TempDir() + "penumbra_apps_" + (info ? std::string(info->name()) + "_" : "") +
         name;
}

RunResult run_cli(const std::string& args, const std::string& tag) {
  return penumbra_tests::run_cli_to(args, temp_path(tag + ".stdout"), temp_path(tag + ".stderr"));
}

// A target image: `inside(u, v)` (u, v in [−1, 1], v up) is the shape, drawn dark.
template <class F>
std::string target(const std::string& name, int size, F inside) {
  penumbra::Image im(size, size, 1, 1.0);
  for (int y = 0; y < size; ++y)
    for (int x = 0; x < size; ++x) {
      const double u = (2 * x + 1 - size) / double(size), v = (size - 2 * y - 1) / double(size);
      if (inside(u, v)) im.at(x, y) = 0.0;
    }
  std::string path = temp_path(name + ".png");
  penumbra::save_png(im, path);
  return path;
}

std::string disc(int size, const std::string& name = "disc") {
  return target(name + std::to_string(size), size,
                [](double u, double v) { return u * u + v * v <= 0.6 * 0.6; });
}
std::string square(int size, const std::string& name = "square") {
  return target(name + std::to_string(size), size,
                [](double u, double v) { return std::abs(u) <= 0.6 && std::abs(v) <= 0.6; });
}
std::string flat(int size, double value) {
  penumbra::Image im(size, size, 1, value);
  std::string path = temp_path("flat" + std::to_string(value) + ".png");
  penumbra::save_png(im, path);
  return path;
}
std::string wide() {
  penumbra::Image im(32, 24, 1, 1.0);
  for (int y = 8; y < 16; ++y)
    for (int x = 8; x < 24; ++x) im.at(x, y) = 0.0;
  std::string path = temp_path("wide.png");
  penumbra::save_png(im, path);
  return path;
}

// The last line of stdout: "<command>: iterations=N seconds=T iou=[v1,...]". Returns the IoUs.
std::vector<double> last_line_ious(const RunResult& r, const std::string& command, int iterations,
                                   size_t count) {
  const auto out = lines(r.out);
  EXPECT_FALSE(out.empty()) << show(r);
  if (out.empty()) return {};
  const std::regex re(command + R"(: iterations=(\d+) seconds=([0-9.]+) iou=\[([0-9.,]*)\])");
  std::smatch m;
  EXPECT_TRUE(std::regex_match(out.back(), m, re)) << out.back() << "\n" << show(r);
  if (m.empty()) return {};
  EXPECT_EQ(std::stoi(m[1].str()), iterations) << show(r);
  std::vector<double> ious;
  std::stringstream list(m[3].str());
  std::string item;
  while (std::getline(list, item, ',')) {
    EXPECT_TRUE(std::regex_match(item, std::regex(R"([01]\.\d{3})"))) << item;
    ious.push_back(std::stod(item));
  }
  EXPECT_EQ(ious.size(), count) << show(r);
  return ious;
}

void expect_outputs(const std::string& dir, bool scene) {
  for (const char* f : {"mesh.obj", "result.png", "fit.gif"})
    EXPECT_TRUE(fs::exists(fs::path(dir) / f)) << dir << "/" << f;
  EXPECT_EQ(fs::exists(fs::path(dir) / "scene.png"), scene) << dir << "/scene.png";
  EXPECT_NO_THROW(penumbra::load_obj((fs::path(dir) / "mesh.obj").string()));
  const penumbra::Image result = penumbra::load_image((fs::path(dir) / "result.png").string());
  EXPECT_GT(result.width, result.height);  // targets and results side by side
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Bad inputs.

TEST(Apps, FitSilhouetteErrors) {
  const std::string out = " -o " + quote(temp_path("err_sil"));
  expect_clean_error(
      run_cli("fit-silhouette --target " + quote(temp_path("missing.png")) + " --view front" + out,
              "sil_missing"),
      "missing.png");
  expect_clean_error(run_cli("fit-silhouette --target " + quote(flat(32, 1.0)) + out, "sil_white"),
                     "no shape");
  expect_clean_error(run_cli("fit-silhouette --target " + quote(flat(32, 0.0)) + out, "sil_black"),
                     "no background");
  expect_clean_error(run_cli("fit-silhouette --target " + quote(wide()) + out, "sil_wide"),
                     "square");
  expect_clean_error(
      run_cli("fit-silhouette --target " + quote(disc(32)) + " --target " + quote(square(48)) + out,
              "sil_sizes"),
      "same size");
  expect_clean_error(
      run_cli("fit-silhouette --target " + quote(disc(32)) + " --view front --view side" + out,
              "sil_fewer"),
      "fewer targets");
  expect_clean_error(run_cli("fit-silhouette --view back" + out, "sil_view"), "back");
  expect_clean_error(run_cli("fit-silhouette --view front --view front" + out, "sil_twice"),
                     "twice");
  expect_clean_error(run_cli("fit-silhouette --iterations 0" + out, "sil_iters"), "--iterations");
}

TEST(Apps, FitShadowsErrors) {
  const std::string out = " -o " + quote(temp_path("err_shd"));
  expect_clean_error(run_cli("fit-shadows --shadows none" + out, "shd_none"), "none");
  expect_clean_error(
      run_cli("fit-shadows --target " + quote(temp_path("missing.png")) + out, "shd_missing"),
      "missing.png");
  expect_clean_error(run_cli("fit-shadows --target " + quote(flat(32, 0.0)) + out, "shd_black"),
                     "no background");
  expect_clean_error(
      run_cli("fit-shadows --target " + quote(disc(32)) + " --light-dir 1,2" + out, "shd_dir"),
      "three numbers");
  expect_clean_error(
      run_cli("fit-shadows --target " + quote(disc(32)) + " --light-dir 0,0,0" + out, "shd_zero"),
      "zero");
  expect_clean_error(run_cli("fit-shadows --target " + quote(disc(32)) +
                                 " --light-dir 0,0,-1 --light-dir -1,0,0" + out,
                             "shd_fewer"),
                     "fewer targets");
}

TEST(Apps, ShadowArtErrors) {
  const std::string out = " -o " + quote(temp_path("err_art"));
  expect_clean_error(run_cli("shadow-art --target " + quote(disc(32)) + out, "art_one"),
                     "two or three");
  expect_clean_error(
      run_cli("shadow-art --target " + quote(disc(32)) + " --target " + quote(flat(32, 1.0)) + out,
              "art_white"),
      "no shape");
  expect_clean_error(
      run_cli("shadow-art --target " + quote(disc(32)) + " --target " + quote(square(64)) + out,
              "art_sizes"),
      "same size");
  // Inconsistent: the front view wants the top half, the side view the bottom half.
  const std::string top = target("top32", 32, [](double, double v) { return v > 0.1; });
  const std::string bottom = target("bottom32", 32, [](double, double v) { return v < -0.1; });
  expect_clean_error(
      run_cli("shadow-art --target " + quote(top) + " --target " + quote(bottom) + out,
              "art_inconsistent"),
      "no object in common");
  expect_clean_error(run_cli("shadow-art --target " + quote(disc(32)) + " --target " +
                                 quote(square(32)) + " --light-dir 0,0,-1 --light-dir 0,0,1" + out,
                             "art_parallel"),
                     "parallel");
}

// ---------------------------------------------------------------------------------------------
// Targets never seen before: a disc in front, a square at the side.

TEST(Apps, FitSilhouetteConverges) {
  const std::string dir = temp_path("fit_sil");
  const RunResult r =
      run_cli("fit-silhouette --target " + quote(disc(32)) + " --view front --target " +
                  quote(square(32)) + " --view side --iterations 160 -o " + quote(dir),
              "fit_sil");
  ASSERT_EQ(r.exit_code, 0) << show(r);
  const auto ious = last_line_ious(r, "fit-silhouette", 160, 2);
  for (double iou : ious) EXPECT_GE(iou, 0.9) << show(r);
  expect_outputs(dir, false);
}

TEST(Apps, FitShadowsConverges) {
  const std::string dir = temp_path("fit_shd");
  const RunResult r = run_cli("fit-shadows --target " + quote(disc(32)) + " --target " +
                                  quote(square(32)) + " --iterations 60 -o " + quote(dir),
                              "fit_shd");
  ASSERT_EQ(r.exit_code, 0) << show(r);
  const auto ious = last_line_ious(r, "fit-shadows", 60, 2);
  for (double iou : ious) EXPECT_GE(iou, 0.85) << show(r);
  expect_outputs(dir, true);
}

TEST(Apps, ShadowArtConverges) {
  const std::string dir = temp_path("art");
  const RunResult r = run_cli("shadow-art --target " + quote(disc(32)) + " --target " +
                                  quote(square(32)) + " --iterations 30 -o " + quote(dir),
                              "art");
  ASSERT_EQ(r.exit_code, 0) << show(r);
  const auto ious = last_line_ious(r, "shadow-art", 30, 2);
  for (double iou : ious) EXPECT_GE(iou, 0.9) << show(r);
  expect_outputs(dir, true);
}

TEST(Apps, ShadowArtObliqueLight) {
  // A light that is not along an axis: the walls of the two lights are not orthogonal, so no
  // scene picture, but the shadows are still fitted.
  const std::string dir = temp_path("art_oblique");
  const RunResult r =
      run_cli("shadow-art --target " + quote(disc(32)) + " --target " + quote(disc(32)) +
                  " --light-dir 0,0,-1 --light-dir -1,0,-1 " + "--iterations 12 -o " + quote(dir),
              "art_oblique");
  ASSERT_EQ(r.exit_code, 0) << show(r);
  const auto ious = last_line_ious(r, "shadow-art", 12, 2);
  for (double iou : ious) EXPECT_GE(iou, 0.8) << show(r);
  expect_outputs(dir, false);
}

// ---------------------------------------------------------------------------------------------
// The bundled targets: found, read, a few iterations.

TEST(Apps, Bundled) {
  struct Case {
    std::string command;
    int iterations;
    size_t views;
  };
  for (const Case& c :
       {Case{"fit-silhouette", 8, 2}, Case{"fit-shadows", 4, 2}, Case{"shadow-art", 3, 3}}) {
    const std::string dir = temp_path("bundled_" + c.command);
    const RunResult r =
        run_cli(c.command + " --iterations " + std::to_string(c.iterations) + " -o " + quote(dir),
                "bundled_" + c.command);
    ASSERT_EQ(r.exit_code, 0) << show(r);
    const auto ious = last_line_ious(r, c.command, c.iterations, c.views);
    for (double iou : ious) EXPECT_GT(iou, 0.3) << show(r);
    if (c.command == "shadow-art") {
      for (double iou : ious) EXPECT_GT(iou, 0.85) << show(r);  // the visual hull alone
    }
  }
}
