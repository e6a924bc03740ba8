#pragma once
// Pictures in and out, in the application library (libpenumbra_app, target penumbra::app; the
// rendering core links no image library): PNG through stb, GIF animations through giflib.
// Errors throw penumbra::Error naming the file; writers go through OutputFile (io.hpp).
#include <memory>
#include <string>
#include <vector>

#include "penumbra/image.hpp"
#include "penumbra/io.hpp"

namespace penumbra {

// PNG: values are clamped to [0,1]; 1 channel → grey, 3 → RGB, 4 → RGBA.
void save_png(const Image& image, const std::string& path);
// The bytes save_png writes; `path` only names the file in error messages.
std::string png_bytes(const Image& image, const std::string& path);
// Any format stb_image reads; channels = the file's channel count unless `channels` > 0.
Image load_image(const std::string& path, int channels = 0);

// Animated GIF (GIF89a), looping forever (NETSCAPE2.0 extension). Every frame is mapped by
// nearest colour (Euclidean in 8-bit RGB, ties to the lower index) to one fixed global palette
// of 256 colours — a 6×6×6 RGB cube, index 36·r + 6·g + b for levels 0, 51, ..., 255, then 40
// greys round((k + 1/2)·255/40), k = 0..39 — and LZW-compressed. Values are clamped to
// [0, 1] and rounded to 8 bits as by save_png; 1 channel → grey, 3 → RGB, 4 → RGB (alpha
// ignored). Each frame shows for `delay_centiseconds` (10 → 10 frames per second). Throws
// penumbra::Error for an empty list, frames of different sizes or channel counts other than
// 1, 3, 4, and unwritable paths.
void save_gif(const std::vector<Image>& frames, const std::string& path,
              int delay_centiseconds = 10);

// The same file written one frame at a time, so that a long animation need not be held in
// memory: the constructor opens the file and writes the header, add_frame appends a frame of
// the given size, close() writes the trailer (it throws if no frame was added) and puts the
// file in place (OutputFile). A writer destroyed without close() leaves nothing.
class GifWriter {
 public:
  GifWriter(const std::string& path, int width, int height, int delay_centiseconds = 10);
  ~GifWriter();
  GifWriter(const GifWriter&) = delete;
  GifWriter& operator=(const GifWriter&) = delete;
  void add_frame(const Image& frame);
  void close();
  int frames() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace penumbra
