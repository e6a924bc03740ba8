// Animated GIF writer (io.hpp): GIF89a through giflib, with one fixed global palette (the
// frames are mapped to it here, so every frame shares it), the NETSCAPE2.0 looping extension
// and a graphic control extension (delay) per frame. giflib writes through a callback into an
// OutputFile, so the file appears only when complete.
#include <gif_lib.h>
#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <exception>
#include <fstream>
#include <vector>

#include "io/text.hpp"
#include "penumbra/error.hpp"
#include "penumbra/image_io.hpp"
#include "penumbra/io.hpp"

namespace penumbra {

namespace {

// A 6×6×6 colour cube and 40 greys between its 6 greys: rendered scenes are mostly grey
// (ground, background, shadow), and greys taken from the cube alone would band and tint them.
constexpr int kRedLevels = 6, kGreenLevels = 6, kBlueLevels = 6;
constexpr int kCubeSize = kRedLevels * kGreenLevels * kBlueLevels;  // 216
constexpr int kGreyCount = 40;
static_assert(kCubeSize + kGreyCount == 256, "the palette has 256 entries");

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

std::string frame_shape(const Image& f) {
  return std::to_string(f.width) + "x" + std::to_string(f.height) + "x" +
         std::to_string(f.channels);
}

}  // namespace

struct GifWriter::Impl {
  std::string path;
  std::unique_ptr<OutputFile> file;
  GifFileType* gif = nullptr;
  int width = 0, height = 0, delay = 10, frames = 0;
  bool closed = false;
  std::exception_ptr write_error;  // what OutputFile threw inside giflib's callback

  // giflib's output callback: a short count makes giflib fail; the reason is kept.
  static int write(GifFileType* gif, const GifByteType* bytes, int n) {
    Impl& m = *static_cast<Impl*>(gif->UserData);
    try {
      m.file->write(bytes, size_t(n));
      return n;
    } catch (...) {
      m.write_error = std::current_exception();
      return 0;
    }
  }
  // Throws the write error behind a giflib failure, else giflib's own message.
  void check(int status, const char* step) {
    if (status != GIF_ERROR) return;
    if (write_error) std::rethrow_exception(write_error);
    throw Error("cannot write GIF " + quoted_path(path) + ": " + step + ": " +
                GifErrorString(gif->Error));
  }
};

GifWriter::GifWriter(const std::string& path, int width, int height, int delay_centiseconds)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.path = path;
  if (width < 1 || height < 1 || width > 65535 || height > 65535)
    throw Error("cannot write GIF " + quoted_path(path) + ": frame size " + std::to_string(width) +
                "x" + std::to_string(height) + " is not in 1 to 65535 pixels");
  if (delay_centiseconds < 0 || delay_centiseconds > 65535)
    throw Error("cannot write GIF " + quoted_path(path) + ": delay " +
                std::to_string(delay_centiseconds) + " is not in 0 to 65535 centiseconds");
  m.width = width;
  m.height = height;
  m.delay = delay_centiseconds;
  m.file = std::make_unique<OutputFile>(path, "GIF");
  int error = 0;
  m.gif = EGifOpen(&m, &Impl::write, &error);
  if (!m.gif) throw Error("cannot write GIF " + quoted_path(path) + ": " + GifErrorString(error));
  EGifSetGifVersion(m.gif, true);
  std::array<GifColorType, 256> colours;
  for (size_t i = 0; i < colours.size(); ++i)
    colours[i] = {palette().rgb[i][0], palette().rgb[i][1], palette().rgb[i][2]};
  ColorMapObject* map = GifMakeMapObject(256, colours.data());
  const int status = EGifPutScreenDesc(m.gif, width, height, 8, 0, map);
  GifFreeMapObject(map);
  m.check(status, "screen descriptor");
  // NETSCAPE2.0 application extension: loop count 0 = forever.
  const GifByteType loop[3] = {1, 0, 0};
  m.check(EGifPutExtensionLeader(m.gif, APPLICATION_EXT_FUNC_CODE), "loop extension");
  m.check(EGifPutExtensionBlock(m.gif, 11, "NETSCAPE2.0"), "loop extension");
  m.check(EGifPutExtensionBlock(m.gif, 3, loop), "loop extension");
  m.check(EGifPutExtensionTrailer(m.gif), "loop extension");
}

GifWriter::~GifWriter() {
  if (impl_->gif) EGifCloseFile(impl_->gif, nullptr);  // frees it; the file is discarded
}

int GifWriter::frames() const { return impl_->frames; }

void GifWriter::add_frame(const Image& frame) {
  Impl& m = *impl_;
  if (m.closed) throw Error("cannot write GIF " + quoted_path(m.path) + ": already closed");
  if (frame.width != m.width || frame.height != m.height)
    throw Error("cannot write GIF " + quoted_path(m.path) + ": frame " + std::to_string(m.frames) +
                " is " + std::to_string(frame.width) + "x" + std::to_string(frame.height) +
                ", the animation is " + std::to_string(m.width) + "x" + std::to_string(m.height));
  if (frame.channels != 1 && frame.channels != 3 && frame.channels != 4)
    throw Error("cannot write GIF " + quoted_path(m.path) + ": frame " + std::to_string(m.frames) +
                " has " + std::to_string(frame.channels) + " channels (expected 1, 3 or 4)");
  if (frame.data.size() != size_t(frame.width) * frame.height * frame.channels)
    throw Error("cannot write GIF " + quoted_path(m.path) + ": frame " + std::to_string(m.frames) +
                " has " + std::to_string(frame.data.size()) + " values, " + frame_shape(frame) +
                " needs " + std::to_string(size_t(frame.width) * frame.height * frame.channels));
  // Disposal 1 (leave in place), no transparency, the delay; the whole screen, global colours.
  GraphicsControlBlock gcb{DISPOSE_DO_NOT, false, m.delay, NO_TRANSPARENT_COLOR};
  GifByteType ext[4];
  const int n = int(EGifGCBToExtension(&gcb, ext));
  m.check(EGifPutExtension(m.gif, GRAPHICS_EXT_FUNC_CODE, n, ext), "frame delay");
  m.check(EGifPutImageDesc(m.gif, 0, 0, m.width, m.height, false, nullptr), "frame");
  std::vector<uint8_t> indices = quantize(frame);
  for (int y = 0; y < m.height; ++y)
    m.check(EGifPutLine(m.gif, indices.data() + size_t(y) * m.width, m.width), "frame");
  ++m.frames;
}

void GifWriter::close() {
  Impl& m = *impl_;
  if (m.closed) return;
  if (m.frames == 0) throw Error("cannot write GIF " + quoted_path(m.path) + ": no frames");
  GifFileType* gif = m.gif;
  m.gif = nullptr;  // EGifCloseFile frees it, whatever it returns
  int error = 0;
  if (EGifCloseFile(gif, &error) == GIF_ERROR) {
    if (m.write_error) std::rethrow_exception(m.write_error);
    throw Error("cannot write GIF " + quoted_path(m.path) + ": " + GifErrorString(error));
  }
  m.closed = true;
  m.file->commit();
}

void save_gif(const std::vector<Image>& frames, const std::string& path, int delay_centiseconds) {
  if (frames.empty()) throw Error("cannot write GIF " + quoted_path(path) + ": no frames");
  const Image& first = frames.front();
  for (size_t i = 0; i < frames.size(); ++i) {
    const Image& f = frames[i];
    if (f.width != first.width || f.height != first.height)
      throw Error("cannot write GIF " + quoted_path(path) + ": frame " + std::to_string(i) +
                  " is " + std::to_string(f.width) + "x" + std::to_string(f.height) +
                  ", frame 0 is " + std::to_string(first.width) + "x" +
                  std::to_string(first.height));
    if (f.channels != 1 && f.channels != 3 && f.channels != 4)
      throw Error("cannot write GIF " + quoted_path(path) + ": frame " + std::to_string(i) +
                  " has " + std::to_string(f.channels) + " channels (expected 1, 3 or 4)");
    if (f.data.size() != size_t(f.width) * f.height * f.channels)
      throw Error("cannot write GIF " + quoted_path(path) + ": frame " + std::to_string(i) +
                  " has " + std::to_string(f.data.size()) + " values, " + frame_shape(f) +
                  " needs " + std::to_string(size_t(f.width) * f.height * f.channels));
  }
  GifWriter writer(path, first.width, first.height, delay_centiseconds);
  for (const Image& f : frames) writer.add_frame(f);
  writer.close();
}

}  // namespace penumbra
