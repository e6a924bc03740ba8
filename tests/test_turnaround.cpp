// `penumbra turnaround`: the frames and the GIF it writes (read back by gif_decoder.hpp).
//
//   Turnaround.Cli                `penumbra turnaround` writes the frames and a valid GIF
//   Turnaround.CliErrors          bad --frames / --shadows / --map-size, no -o: one-line errors
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <regex>
#include <string>
#include <vector>

#include "cli_run.hpp"
#include "gif_decoder.hpp"
#include "penumbra/image.hpp"
#include "penumbra/image_io.hpp"

namespace fs = std::filesystem;
using penumbra_tests::decode_gif;
using penumbra_tests::DecodedGif;
using penumbra_tests::distance2;
using penumbra_tests::read_text;
using penumbra_tests::to_byte;

namespace {

std::string temp_path(const std::string& name) {
  return ::testing::TempDir() + "penumbra_turnaround_" + name;
}

// Running the tool (cli_run.hpp).
using penumbra_tests::lines;
using penumbra_tests::quote;
using penumbra_tests::RunResult;
using penumbra_tests::show;

RunResult run_cli(const std::string& args, const std::string& tag) {
  return penumbra_tests::run_cli_to(args, temp_path(tag + ".stdout"), temp_path(tag + ".stderr"));
}

TEST(Turnaround, Cli) {
  const std::string dir = temp_path("turnaround");
  fs::remove_all(dir);
  const RunResult r = run_cli(
      "turnaround --frames 4 --width 32 --height 32 --map-size 32 --shadows hard -o " + quote(dir),
      "turnaround");
  ASSERT_EQ(r.exit_code, 0) << show(r);
  const auto out = lines(r.out);
  ASSERT_FALSE(out.empty()) << show(r);
  const std::regex format(R"(^turnaround: frames=4 shadows=hard sampling=truncated )"
                          R"(seconds=\d+\.\d\d ms_per_frame=\d+\.\d$)");
  EXPECT_TRUE(std::regex_match(out.back(), format)) << "last line: " << out.back();

  std::vector<penumbra::Image> pngs;
  for (const char* name : {"frame_000.png", "frame_001.png", "frame_002.png", "frame_003.png"}) {
    ASSERT_TRUE(fs::exists(dir + "/" + name)) << name << "\n" << show(r);
    pngs.push_back(penumbra::load_image(dir + "/" + name, 3));
    EXPECT_EQ(pngs.back().width, 32);
    EXPECT_EQ(pngs.back().height, 32);
  }
  EXPECT_FALSE(fs::exists(dir + "/frame_004.png"));
  // The camera moves: consecutive frames differ.
  EXPECT_NE(pngs[0].data, pngs[1].data);

  const std::string gif = dir + "/turnaround.gif";
  ASSERT_TRUE(fs::exists(gif)) << show(r);
  EXPECT_EQ(read_text(gif).substr(0, 6), "GIF89a");
  const DecodedGif g = decode_gif(gif);
  EXPECT_EQ(g.width, 32);
  EXPECT_EQ(g.height, 32);
  EXPECT_TRUE(g.loops_forever);
  ASSERT_EQ(g.frames.size(), 4u);
  for (size_t f = 0; f < 4; ++f) {
    EXPECT_EQ(g.delays[f], 10) << "about 10 frames per second";
    // Each GIF frame is its PNG frame mapped to a nearest palette colour.
    for (int y = 0; y < 32; ++y)
      for (int x = 0; x < 32; ++x) {
        const int cr = to_byte(pngs[f].at(x, y, 0)), cg = to_byte(pngs[f].at(x, y, 1)),
                  cb = to_byte(pngs[f].at(x, y, 2));
        int best = 1 << 30;
        for (const auto& c : g.palette) best = std::min(best, distance2(c, cr, cg, cb));
        ASSERT_EQ(distance2(g.palette[g.frames[f][size_t(y) * 32 + x]], cr, cg, cb), best)
            << "frame " << f << " pixel (" << x << ", " << y << ")";
      }
  }
}

TEST(Turnaround, CliErrors) {
  for (const std::string& args :
       {std::string("turnaround --frames 0 -o ") + quote(temp_path("bad_frames")),
        std::string("turnaround --shadows sometimes -o ") + quote(temp_path("bad_shadows")),
        std::string("turnaround --map-size 0 -o ") + quote(temp_path("bad_map")),
        std::string("turnaround --frames 2")}) {
    const RunResult r = run_cli(args, "turnaround_error");
    EXPECT_FALSE(r.signaled) << show(r);
    EXPECT_TRUE(r.exit_code == 1 || r.exit_code == 2) << show(r);
    const auto err = lines(r.err);
    ASSERT_EQ(err.size(), 1u) << show(r);
    EXPECT_EQ(err[0].rfind("penumbra: error:", 0), 0u) << show(r);
  }
}

}  // namespace
