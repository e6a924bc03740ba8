// The animated GIF writer (penumbra/image_io.hpp: save_gif, GifWriter), its files read back by
// the tests' own decoder (gif_decoder.hpp).
//
//   Gif.PaletteColoursRoundTrip   frames made of palette colours decode to exactly those colours
//   Gif.NearestColour             any colour decodes to a nearest entry of the file's palette
//   Gif.LongDataWidthsAndClears   noise (table fills, clear codes, 12-bit codes) and flat frames
//   Gif.GreyAndAlphaFrames        1- and 4-channel frames
//   Gif.Errors                    empty list, mismatched sizes, bad channels, unwritable path
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "gif_decoder.hpp"
#include "penumbra/error.hpp"
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
  return ::testing::TempDir() + "penumbra_gif_" + name;
}

// The documented palette: a 6×6×6 cube (index 36·r + 6·g + b, levels 0, 51, ..., 255), then
// 40 greys round((k + 1/2)·255/40).
std::vector<std::array<int, 3>> documented_palette() {
  std::vector<std::array<int, 3>> p;
  for (int r = 0; r < 6; ++r)
    for (int g = 0; g < 6; ++g)
      for (int b = 0; b < 6; ++b) p.push_back({51 * r, 51 * g, 51 * b});
  for (int k = 0; k < 40; ++k) {
    const int y = int(std::lround((k + 0.5) * 255.0 / 40));
    p.push_back({y, y, y});
  }
  return p;
}
TEST(Gif, PaletteColoursRoundTrip) {
  const auto pal = documented_palette();
  ASSERT_EQ(pal.size(), 256u);
  for (size_t i = 0; i < pal.size(); ++i)
    for (size_t j = 0; j < i; ++j) ASSERT_NE(pal[i], pal[j]) << i << " " << j;
  std::mt19937 rng(3);
  std::vector<penumbra::Image> frames;
  std::vector<std::vector<int>> expected;
  for (int f = 0; f < 3; ++f) {
    penumbra::Image im(37, 23, 3);
    std::vector<int> idx;
    for (int y = 0; y < im.height; ++y)
      for (int x = 0; x < im.width; ++x) {
        // Random entries, with runs so that longer strings enter the table.
        const int i = (x / 3 + f) % 2 ? int(rng() % 256) : (x + 7 * y) % 256;
        for (int c = 0; c < 3; ++c) im.at(x, y, c) = pal[size_t(i)][size_t(c)] / 255.0;
        idx.push_back(i);
      }
    frames.push_back(im);
    expected.push_back(idx);
  }
  const std::string path = temp_path("palette.gif");
  penumbra::save_gif(frames, path, 7);
  const DecodedGif g = decode_gif(path);
  EXPECT_EQ(g.width, 37);
  EXPECT_EQ(g.height, 23);
  EXPECT_TRUE(g.loops_forever);
  EXPECT_TRUE(g.trailer);
  ASSERT_EQ(g.palette, pal);
  ASSERT_EQ(g.frames.size(), 3u);
  for (size_t f = 0; f < 3; ++f) {
    EXPECT_EQ(g.delays[f], 7);
    for (size_t i = 0; i < expected[f].size(); ++i) {
      // The same colour (the palette holds no duplicates, so the same index).
      ASSERT_EQ(g.palette[g.frames[f][i]], pal[size_t(expected[f][i])])
          << "frame " << f << " pixel " << i;
    }
  }
}

TEST(Gif, NearestColour) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-0.1, 1.1);  // clamped to [0, 1]
  penumbra::Image im(64, 40, 3);
  for (double& v : im.data) v = u(rng);
  // Greys and the midpoints between cube levels too.
  for (int x = 0; x < 64; ++x)
    for (int c = 0; c < 3; ++c) im.at(x, 0, c) = x / 63.0;
  const std::string path = temp_path("nearest.gif");
  penumbra::save_gif({im}, path);
  const DecodedGif g = decode_gif(path);
  ASSERT_EQ(g.frames.size(), 1u);
  EXPECT_EQ(g.delays[0], 10);  // the default: 10 frames per second
  int worst = 0;               // largest squared distance to the chosen colour
  for (int y = 0; y < im.height; ++y)
    for (int x = 0; x < im.width; ++x) {
      const int r = to_byte(im.at(x, y, 0)), gg = to_byte(im.at(x, y, 1)),
                b = to_byte(im.at(x, y, 2));
      int best = 1 << 30;
      for (const auto& c : g.palette) best = std::min(best, distance2(c, r, gg, b));
      const auto& got = g.palette[g.frames[0][size_t(y) * im.width + x]];
      ASSERT_EQ(distance2(got, r, gg, b), best) << "pixel (" << x << ", " << y << ")";
      worst = std::max(worst, best);
    }
  EXPECT_LE(worst, 3 * 26 * 26);  // within half a cube step on every axis

  // Every grey level maps to a grey within 4 levels: no tint on grey ground and shadows.
  penumbra::Image greys(256, 1, 3);
  for (int v = 0; v < 256; ++v)
    for (int c = 0; c < 3; ++c) greys.at(v, 0, c) = v / 255.0;
  const std::string grey_path = temp_path("grey_levels.gif");
  penumbra::save_gif({greys}, grey_path);
  const DecodedGif d = decode_gif(grey_path);
  for (int v = 0; v < 256; ++v) {
    const auto& c = d.palette[d.frames[0][size_t(v)]];
    ASSERT_TRUE(c[0] == c[1] && c[1] == c[2]) << v;
    ASSERT_LE(std::abs(c[0] - v), 4) << v;
  }
}

TEST(Gif, LongDataWidthsAndClears) {
  // 300×300 random indices: the code table fills many times (clear codes) and codes reach 12
  // bits; a flat frame makes long strings quickly.
  const auto pal = documented_palette();
  std::mt19937 rng(5);
  penumbra::Image noise(300, 300, 3), flat(300, 300, 3, 0.4);
  std::vector<int> idx(size_t(300) * 300);
  for (size_t i = 0; i < idx.size(); ++i) {
    idx[i] = int(rng() % 256);
    for (int c = 0; c < 3; ++c) noise.data[i * 3 + c] = pal[size_t(idx[i])][size_t(c)] / 255.0;
  }
  const std::string path = temp_path("long.gif");
  penumbra::save_gif({noise, flat, noise}, path, 5);
  const DecodedGif g = decode_gif(path);
  ASSERT_EQ(g.frames.size(), 3u);
  for (size_t f : {size_t(0), size_t(2)})
    for (size_t i = 0; i < idx.size(); ++i)
      ASSERT_EQ(g.frames[f][i], idx[i]) << "frame " << f << " pixel " << i;
  const uint8_t grey = g.frames[1][0];
  for (uint8_t v : g.frames[1]) ASSERT_EQ(v, grey);
  EXPECT_EQ(g.palette[grey], (std::array<int, 3>{102, 102, 102}));  // 0.4 → 102: in the cube
  // Far smaller than the raw pixels for the flat frame: compression works.
  EXPECT_LT(fs::file_size(path), size_t(3) * 300 * 300);
}

TEST(Gif, GreyAndAlphaFrames) {
  penumbra::Image grey(5, 4, 1, 163 / 255.0), rgba(5, 4, 4, 0.0);
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 5; ++x) {
      rgba.at(x, y, 0) = 1.0;  // red, alpha ignored
      rgba.at(x, y, 3) = 0.3;
    }
  const std::string path = temp_path("grey.gif");
  penumbra::save_gif({grey, rgba}, path);
  const DecodedGif g = decode_gif(path);
  ASSERT_EQ(g.frames.size(), 2u);
  for (uint8_t v : g.frames[0]) EXPECT_EQ(g.palette[v], (std::array<int, 3>{163, 163, 163}));
  for (uint8_t v : g.frames[1]) EXPECT_EQ(g.palette[v], (std::array<int, 3>{255, 0, 0}));

  // The streaming writer gives the same file.
  const std::string streamed = temp_path("grey_streamed.gif");
  penumbra::GifWriter writer(streamed, 5, 4);
  writer.add_frame(grey);
  writer.add_frame(rgba);
  EXPECT_EQ(writer.frames(), 2);
  writer.close();
  EXPECT_EQ(read_text(streamed), read_text(path));
}

TEST(Gif, Errors) {
  const std::string path = temp_path("errors.gif");
  EXPECT_THROW(penumbra::save_gif({}, path), penumbra::Error);
  EXPECT_THROW(penumbra::save_gif({penumbra::Image(4, 4, 3), penumbra::Image(4, 5, 3)}, path),
               penumbra::Error);
  EXPECT_THROW(penumbra::save_gif({penumbra::Image(4, 4, 2)}, path), penumbra::Error);
  EXPECT_THROW(penumbra::save_gif({penumbra::Image()}, path), penumbra::Error);
  EXPECT_THROW(penumbra::save_gif({penumbra::Image(4, 4, 3)}, path, -1), penumbra::Error);
  EXPECT_THROW(penumbra::save_gif({penumbra::Image(4, 4, 3)}, temp_path("no/such/dir/x.gif")),
               penumbra::Error);
  try {
    penumbra::save_gif({penumbra::Image(4, 4, 3), penumbra::Image(4, 5, 3)}, path);
  } catch (const penumbra::Error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("frame 1"), std::string::npos) << m;
    EXPECT_EQ(m.find('\n'), std::string::npos) << m;
  }
  penumbra::GifWriter empty(temp_path("empty.gif"), 4, 4);
  EXPECT_THROW(empty.close(), penumbra::Error);
  EXPECT_THROW(empty.add_frame(penumbra::Image(3, 4, 3)), penumbra::Error);
}

// ---------------------------------------------------------------------------------------------
// The command.

}  // namespace
