// Animated GIF writer (io.hpp): GIF89a with one fixed global palette, LZW-compressed frames
// and the NETSCAPE2.0 looping extension.
//
// File layout: header "GIF89a"; logical screen descriptor with a 256-entry global colour
// table; application extension NETSCAPE2.0 (loop forever); per frame a graphic control
// extension (delay) and an image descriptor followed by LZW data in sub-blocks of at most 255
// bytes; trailer 0x3B.
//
// LZW (GIF flavour): minimum code size 8, so codes start 9 bits wide; code 256 clears the
// table, 257 ends the data. A code is emitted at the current width; after a new table entry is
// assigned the code 2^width, the width grows by one (at most 12 bits). When the table is full
// (4096 codes), a clear code is emitted and the table and width start over.
#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <vector>

#include "penumbra/error.hpp"
#include "penumbra/io.hpp"

namespace penumbra {

namespace {

// A 6×6×6 colour cube and 40 greys between its 6 greys: rendered scenes are mostly grey
// (ground, background, shadow), and greys taken from the cube alone would band and tint them.
constexpr int kRedLevels = 6, kGreenLevels = 6, kBlueLevels = 6;
constexpr int kCubeSize = kRedLevels * kGreenLevels * kBlueLevels;  // 216
constexpr int kGreyCount = 40;
static_assert(kCubeSize + kGreyCount == 256, "the palette has 256 entries");

std::string quoted(const std::string& path) { return "'" + path + "'"; }

// The fixed palette: index 36·r + 6·g + b for the cube (levels 0, 51, ..., 255), then the
// greys round((k + 1/2)·255/40), k = 0..39.
struct Palette {
  std::array<std::array<uint8_t, 3>, 256> rgb{};
  // Nearest cube level of each 8-bit value, per channel (ties to the lower level).
  std::array<uint8_t, 256> nearest_r{}, nearest_g{}, nearest_b{};
  std::array<int, kRedLevels> r_level{};
  std::array<int, kGreenLevels> g_level{};
  std::array<int, kBlueLevels> b_level{};
  std::array<int, kGreyCount> grey{};

  Palette() {
    for (int i = 0; i < kRedLevels; ++i)
      r_level[i] = int(std::lround(i * 255.0 / (kRedLevels - 1)));
    for (int i = 0; i < kGreenLevels; ++i)
      g_level[i] = int(std::lround(i * 255.0 / (kGreenLevels - 1)));
    for (int i = 0; i < kBlueLevels; ++i)
      b_level[i] = int(std::lround(i * 255.0 / (kBlueLevels - 1)));
    for (int r = 0; r < kRedLevels; ++r)
      for (int g = 0; g < kGreenLevels; ++g)
        for (int b = 0; b < kBlueLevels; ++b)
          rgb[index(r, g, b)] = {uint8_t(r_level[r]), uint8_t(g_level[g]), uint8_t(b_level[b])};
    for (int k = 0; k < kGreyCount; ++k) {
      grey[k] = int(std::lround((k + 0.5) * 255.0 / kGreyCount));
      const uint8_t v = uint8_t(grey[k]);
      rgb[size_t(kCubeSize) + size_t(k)] = {v, v, v};
    }
    fill_nearest(r_level.data(), kRedLevels, nearest_r);
    fill_nearest(g_level.data(), kGreenLevels, nearest_g);
    fill_nearest(b_level.data(), kBlueLevels, nearest_b);
  }

  static int index(int r, int g, int b) { return (r * kGreenLevels + g) * kBlueLevels + b; }

  static void fill_nearest(const int* levels, int n, std::array<uint8_t, 256>& out) {
    for (int v = 0; v < 256; ++v) {
      int best = 0;
      for (int i = 1; i < n; ++i)
        if (std::abs(levels[i] - v) < std::abs(levels[best] - v)) best = i;
      out[v] = uint8_t(best);
    }
  }

  // Nearest palette entry in 8-bit RGB (Euclidean; ties go to the lower index). The cube is a
  // product grid, so its nearest entry is the nearest level per channel.
  uint8_t nearest(int r, int g, int b) const {
    const int ri = nearest_r[r], gi = nearest_g[g], bi = nearest_b[b];
    const int dr = r - r_level[ri], dg = g - g_level[gi], db = b - b_level[bi];
    int best = index(ri, gi, bi), best_d = dr * dr + dg * dg + db * db;
    for (int k = 0; k < kGreyCount; ++k) {
      const int y = grey[k];
      const int d = (r - y) * (r - y) + (g - y) * (g - y) + (b - y) * (b - y);
      if (d < best_d) best = kCubeSize + k, best_d = d;
    }
    return uint8_t(best);
  }
};

const Palette& palette() {
  static const Palette p;
  return p;
}

uint8_t to_byte(double v) {
  v = std::isnan(v) ? 0.0 : std::min(1.0, std::max(0.0, v));
  return static_cast<uint8_t>(std::lround(v * 255.0));
}

// Palette indices of a frame, row by row from the top.
std::vector<uint8_t> quantize(const Image& frame) {
  const Palette& pal = palette();
  const size_t n = size_t(frame.width) * frame.height;
  std::vector<uint8_t> out(n);
  const int c = frame.channels;
  for (size_t i = 0; i < n; ++i) {
    const double* p = frame.data.data() + i * c;
    const int r = to_byte(p[0]);
    const int g = c >= 3 ? to_byte(p[1]) : r;
    const int b = c >= 3 ? to_byte(p[2]) : r;
    out[i] = pal.nearest(r, g, b);
  }
  return out;
}

// Packs variable-width codes least significant bit first into bytes.
class BitWriter {
 public:
  void put(int code, int width) {
    acc_ |= uint32_t(code) << bits_;
    bits_ += width;
    while (bits_ >= 8) {
      bytes_.push_back(uint8_t(acc_ & 0xFF));
      acc_ >>= 8;
      bits_ -= 8;
    }
  }
  std::vector<uint8_t> finish() {
    if (bits_ > 0) bytes_.push_back(uint8_t(acc_ & 0xFF));
    acc_ = 0;
    bits_ = 0;
    return std::move(bytes_);
  }

 private:
  std::vector<uint8_t> bytes_;
  uint32_t acc_ = 0;
  int bits_ = 0;
};

constexpr int kMinCodeSize = 8;
constexpr int kClear = 1 << kMinCodeSize;  // 256
constexpr int kEnd = kClear + 1;           // 257
constexpr int kMaxCodes = 4096;            // 12-bit codes

// The LZW string table: child(code, byte) = the code of string(code) + byte. Entries carry the
// generation they were written in, so that clearing the table is O(1) rather than a pass over
// all 4096 × 256 slots.
class LzwTable {
 public:
  LzwTable() : code_(size_t(kMaxCodes) * 256, 0), stamp_(size_t(kMaxCodes) * 256, 0) {}
  void clear() { ++generation_; }
  int find(int prefix, uint8_t byte) const {
    const size_t slot = size_t(prefix) * 256 + byte;
    return stamp_[slot] == generation_ ? code_[slot] : -1;
  }
  void add(int prefix, uint8_t byte, int code) {
    const size_t slot = size_t(prefix) * 256 + byte;
    code_[slot] = uint16_t(code);
    stamp_[slot] = generation_;
  }

 private:
  std::vector<uint16_t> code_;
  std::vector<uint32_t> stamp_;
  uint32_t generation_ = 1;
};

// LZW-compresses palette indices; returns the code stream as bytes (not yet in sub-blocks).
std::vector<uint8_t> lzw_encode(const std::vector<uint8_t>& indices, LzwTable& table) {
  table.clear();
  BitWriter out;
  int width = kMinCodeSize + 1;
  int next = kEnd + 1;
  out.put(kClear, width);
  if (indices.empty()) {
    out.put(kEnd, width);
    return out.finish();
  }
  int prefix = indices[0];
  for (size_t i = 1; i < indices.size(); ++i) {
    const uint8_t k = indices[i];
    const int found = table.find(prefix, k);
    if (found >= 0) {
      prefix = found;
      continue;
    }
    out.put(prefix, width);
    if (next < kMaxCodes) {
      table.add(prefix, k, next);
      if (next == (1 << width) && width < 12) ++width;
      ++next;
    } else {
      out.put(kClear, width);
      table.clear();
      width = kMinCodeSize + 1;
      next = kEnd + 1;
    }
    prefix = k;
  }
  out.put(prefix, width);
  out.put(kEnd, width);
  return out.finish();
}

void put16(std::vector<uint8_t>& out, int v) {
  out.push_back(uint8_t(v & 0xFF));
  out.push_back(uint8_t((v >> 8) & 0xFF));
}

std::string frame_shape(const Image& f) {
  return std::to_string(f.width) + "x" + std::to_string(f.height) + "x" +
         std::to_string(f.channels);
}

}  // namespace

struct GifWriter::Impl {
  std::string path;
  std::unique_ptr<OutputFile> file;
  int width = 0, height = 0, delay = 10, frames = 0;
  bool closed = false;
  LzwTable table;

  void write(const std::vector<uint8_t>& bytes) { file->write(bytes.data(), bytes.size()); }
};

GifWriter::GifWriter(const std::string& path, int width, int height, int delay_centiseconds)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.path = path;
  if (width < 1 || height < 1 || width > 65535 || height > 65535)
    throw Error("cannot write GIF " + quoted(path) + ": frame size " + std::to_string(width) + "x" +
                std::to_string(height) + " is not in 1 to 65535 pixels");
  if (delay_centiseconds < 0 || delay_centiseconds > 65535)
    throw Error("cannot write GIF " + quoted(path) + ": delay " +
                std::to_string(delay_centiseconds) + " is not in 0 to 65535 centiseconds");
  m.width = width;
  m.height = height;
  m.delay = delay_centiseconds;
  m.file = std::make_unique<OutputFile>(path, "GIF");

  std::vector<uint8_t> head = {'G', 'I', 'F', '8', '9', 'a'};
  put16(head, width);
  put16(head, height);
  head.push_back(0xF7);  // global colour table, 8-bit colour resolution, 2^(7+1) entries
  head.push_back(0);     // background colour index
  head.push_back(0);     // pixel aspect ratio: not given
  for (const auto& c : palette().rgb) head.insert(head.end(), c.begin(), c.end());
  // NETSCAPE2.0 application extension: loop count 0 = forever.
  const char* app = "NETSCAPE2.0";
  head.insert(head.end(), {0x21, 0xFF, 0x0B});
  head.insert(head.end(), app, app + 11);
  head.insert(head.end(), {0x03, 0x01, 0x00, 0x00, 0x00});
  m.write(head);
}

GifWriter::~GifWriter() = default;

int GifWriter::frames() const { return impl_->frames; }

void GifWriter::add_frame(const Image& frame) {
  Impl& m = *impl_;
  if (m.closed) throw Error("cannot write GIF " + quoted(m.path) + ": already closed");
  if (frame.width != m.width || frame.height != m.height)
    throw Error("cannot write GIF " + quoted(m.path) + ": frame " + std::to_string(m.frames) +
                " is " + std::to_string(frame.width) + "x" + std::to_string(frame.height) +
                ", the animation is " + std::to_string(m.width) + "x" + std::to_string(m.height));
  if (frame.channels != 1 && frame.channels != 3 && frame.channels != 4)
    throw Error("cannot write GIF " + quoted(m.path) + ": frame " + std::to_string(m.frames) +
                " has " + std::to_string(frame.channels) + " channels (expected 1, 3 or 4)");
  if (frame.data.size() != size_t(frame.width) * frame.height * frame.channels)
    throw Error("cannot write GIF " + quoted(m.path) + ": frame " + std::to_string(m.frames) +
                " has " + std::to_string(frame.data.size()) + " values, " + frame_shape(frame) +
                " needs " + std::to_string(size_t(frame.width) * frame.height * frame.channels));

  std::vector<uint8_t> out;
  // Graphic control extension: disposal 1 (leave in place), no transparency, the delay.
  out.insert(out.end(), {0x21, 0xF9, 0x04, 0x04});
  put16(out, m.delay);
  out.insert(out.end(), {0x00, 0x00});
  // Image descriptor: the whole screen, no local colour table, not interlaced.
  out.push_back(0x2C);
  put16(out, 0);
  put16(out, 0);
  put16(out, m.width);
  put16(out, m.height);
  out.push_back(0x00);
  out.push_back(uint8_t(kMinCodeSize));
  const std::vector<uint8_t> data = lzw_encode(quantize(frame), m.table);
  for (size_t i = 0; i < data.size(); i += 255) {
    const size_t n = std::min<size_t>(255, data.size() - i);
    out.push_back(uint8_t(n));
    out.insert(out.end(), data.begin() + std::ptrdiff_t(i), data.begin() + std::ptrdiff_t(i + n));
  }
  out.push_back(0x00);  // block terminator
  m.write(out);
  ++m.frames;
}

void GifWriter::close() {
  Impl& m = *impl_;
  if (m.closed) return;
  if (m.frames == 0) throw Error("cannot write GIF " + quoted(m.path) + ": no frames");
  m.write({0x3B});
  m.closed = true;
  m.file->commit();
}

void save_gif(const std::vector<Image>& frames, const std::string& path, int delay_centiseconds) {
  if (frames.empty()) throw Error("cannot write GIF " + quoted(path) + ": no frames");
  const Image& first = frames.front();
  for (size_t i = 0; i < frames.size(); ++i) {
    const Image& f = frames[i];
    if (f.width != first.width || f.height != first.height)
      throw Error("cannot write GIF " + quoted(path) + ": frame " + std::to_string(i) + " is " +
                  std::to_string(f.width) + "x" + std::to_string(f.height) + ", frame 0 is " +
                  std::to_string(first.width) + "x" + std::to_string(first.height));
    if (f.channels != 1 && f.channels != 3 && f.channels != 4)
      throw Error("cannot write GIF " + quoted(path) + ": frame " + std::to_string(i) + " has " +
                  std::to_string(f.channels) + " channels (expected 1, 3 or 4)");
    if (f.data.size() != size_t(f.width) * f.height * f.channels)
      throw Error("cannot write GIF " + quoted(path) + ": frame " + std::to_string(i) + " has " +
                  std::to_string(f.data.size()) + " values, " + frame_shape(f) + " needs " +
                  std::to_string(size_t(f.width) * f.height * f.channels));
  }
  GifWriter writer(path, first.width, first.height, delay_centiseconds);
  for (const Image& f : frames) writer.add_frame(f);
  writer.close();
}

}  // namespace penumbra
