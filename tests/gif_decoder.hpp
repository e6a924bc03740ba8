#pragma once
// A small GIF decoder of the tests, independent of the writer (penumbra/image_io.hpp): blocks,
// the global colour table, the NETSCAPE2.0 loop, graphic control delays and a GIF LZW decoder
// with variable code widths and clear codes. Header-only, as cli_run.hpp.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli_run.hpp"  // read_text

namespace penumbra_tests {

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
inline std::vector<uint8_t> lzw_decode(const std::string& data, int min_code_size,
                                       size_t expected) {
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

inline DecodedGif decode_gif(const std::string& path) {
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

// A colour channel in [0, 1] as the byte the writer stores.
inline int to_byte(double v) { return int(std::lround(std::min(1.0, std::max(0.0, v)) * 255.0)); }

inline int distance2(const std::array<int, 3>& c, int r, int g, int b) {
  return (c[0] - r) * (c[0] - r) + (c[1] - g) * (c[1] - g) + (c[2] - b) * (c[2] - b);
}

}  // namespace penumbra_tests
