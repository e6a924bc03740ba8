// The animated GIF writer (penumbra/io.hpp: save_gif, GifWriter) and `penumbra turnaround`.
//
// The GIF files are read back by a small independent decoder written here (blocks, the global
// colour table, the NETSCAPE2.0 loop, graphic control delays and a GIF LZW decoder with
// variable code widths and clear codes).
//
//   Gif.PaletteColoursRoundTrip   frames made of palette colours decode to exactly those colours
//   Gif.NearestColour             any colour decodes to a nearest entry of the file's palette
//   Gif.LongDataWidthsAndClears   noise (table fills, clear codes, 12-bit codes) and flat frames
//   Gif.GreyAndAlphaFrames        1- and 4-channel frames
//   Gif.Errors                    empty list, mismatched sizes, bad channels, unwritable path
//   Turnaround.Cli                `penumbra turnaround` writes the frames and a valid GIF
//   Turnaround.CliErrors          bad --frames / --shadows / --map-size, no -o: one-line errors
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <regex>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli_run.hpp"
#include "penumbra/error.hpp"
#include "penumbra/image.hpp"
#include "penumbra/image_io.hpp"
#include "penumbra/io.hpp"

namespace fs = std::filesystem;

namespace {

// ---------------------------------------------------------------------------------------------
// A GIF decoder for the tests.

struct DecodedGif {
  int width = 0, height = 0;
  std::vector<std::array<int, 3>> palette;   // global colour table
  bool loops_forever = false;                // NETSCAPE2.0 with loop count 0
  std::vector<int> delays;                   // centiseconds, one per frame
  std::vector<std::vector<uint8_t>> frames;  // palette indices, row-major
  bool trailer = false;
};

struct Reader {
  const std::string& bytes;
  size_t pos = 0;
  uint8_t u8() {
    if (pos >= bytes.size()) throw std::runtime_error("unexpected end of file");
    return uint8_t(bytes[pos++]);
  }
  int u16() {
    const int lo = u8();
    return lo | (u8() << 8);
  }
  std::string sub_blocks() {
    std::string data;
    for (int n = u8(); n != 0; n = u8())
      for (int i = 0; i < n; ++i) data += char(u8());
    return data;
  }
};

// GIF LZW: codes least significant bit first, starting at min_code_size + 1 bits.
std::vector<uint8_t> lzw_decode(const std::string& data, int min_code_size, size_t expected) {
  const int clear = 1 << min_code_size, end = clear + 1;
  std::vector<std::vector<uint8_t>> table;
  int width = 0;
  auto reset = [&] {
    table.assign(size_t(clear) + 2, {});
    for (int i = 0; i < clear; ++i) table[size_t(i)] = {uint8_t(i)};
    width = min_code_size + 1;
  };
  reset();
  std::vector<uint8_t> out;
  size_t bitpos = 0;
  int prev = -1;
  bool ended = false;
  while (true) {
    if (bitpos + size_t(width) > data.size() * 8) break;
    int code = 0;
    for (int b = 0; b < width; ++b, ++bitpos)
      code |= ((uint8_t(data[bitpos / 8]) >> (bitpos % 8)) & 1) << b;
    if (code == clear) {
      reset();
      prev = -1;
      continue;
    }
    if (code == end) {
      ended = true;
      break;
    }
    std::vector<uint8_t> entry;
    if (code < int(table.size())) {
      entry = table[size_t(code)];
    } else if (code == int(table.size()) && prev >= 0) {
      entry = table[size_t(prev)];
      entry.push_back(table[size_t(prev)][0]);
    } else {
      throw std::runtime_error("LZW code " + std::to_string(code) + " out of range (table " +
                               std::to_string(table.size()) + ")");
    }
    if (prev >= 0 && table.size() < 4096) {
      std::vector<uint8_t> added = table[size_t(prev)];
      added.push_back(entry[0]);
      table.push_back(added);
      if (table.size() == (size_t(1) << width) && width < 12) ++width;
    }
    out.insert(out.end(), entry.begin(), entry.end());
    prev = code;
  }
  if (!ended) throw std::runtime_error("LZW data has no end code");
  if (out.size() != expected)
    throw std::runtime_error("LZW data holds " + std::to_string(out.size()) + " pixels, expected " +
                             std::to_string(expected));
  return out;
}

using penumbra_tests::read_text;

DecodedGif decode_gif(const std::string& path) {
  const std::string bytes = read_text(path);
  Reader r{bytes};
  DecodedGif g;
  if (bytes.substr(0, 6) != "GIF89a") throw std::runtime_error("not a GIF89a file");
  r.pos = 6;
  g.width = r.u16();
  g.height = r.u16();
  const uint8_t packed = r.u8();
  r.u8();  // background
  r.u8();  // aspect
  if (packed & 0x80) {
    const int n = 1 << ((packed & 7) + 1);
    for (int i = 0; i < n; ++i) {
      const int cr = r.u8(), cg = r.u8(), cb = r.u8();
      g.palette.push_back({cr, cg, cb});
    }
  }
  int pending_delay = -1;
  while (true) {
    const uint8_t block = r.u8();
    if (block == 0x3B) {
      g.trailer = true;
      break;
    }
    if (block == 0x21) {
      const uint8_t label = r.u8();
      if (label == 0xFF) {
        const std::string app = r.sub_blocks();
        if (app.substr(0, 11) == "NETSCAPE2.0" && app.size() >= 14 && app[11] == 1)
          g.loops_forever = (uint8_t(app[12]) | (uint8_t(app[13]) << 8)) == 0;
      } else if (label == 0xF9) {
        const std::string gce = r.sub_blocks();
        if (gce.size() != 4) throw std::runtime_error("graphic control extension size");
        pending_delay = uint8_t(gce[1]) | (uint8_t(gce[2]) << 8);
      } else {
        r.sub_blocks();
      }
      continue;
    }
    if (block != 0x2C) throw std::runtime_error("unexpected block " + std::to_string(block));
    const int left = r.u16(), top = r.u16(), w = r.u16(), h = r.u16();
    const uint8_t flags = r.u8();
    if (left != 0 || top != 0 || w != g.width || h != g.height)
      throw std::runtime_error("frame does not cover the screen");
    if (flags & 0x80) throw std::runtime_error("unexpected local colour table");
    if (flags & 0x40) throw std::runtime_error("unexpected interlacing");
    const int min_code_size = r.u8();
    const std::string data = r.sub_blocks();
    g.frames.push_back(lzw_decode(data, min_code_size, size_t(w) * h));
    g.delays.push_back(pending_delay);
    pending_delay = -1;
  }
  return g;
}

// ---------------------------------------------------------------------------------------------

std::string temp_path(const std::string& name) {
  return ::testing::TempDir() + "penumbra_gif_" + name;
}

int to_byte(double v) { return int(std::lround(std::min(1.0, std::max(0.0, v)) * 255.0)); }

int distance2(const std::array<int, 3>& c, int r, int g, int b) {
  return (c[0] - r) * (c[0] - r) + (c[1] - g) * (c[1] - g) + (c[2] - b) * (c[2] - b);
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
