// Images in and out (image_io.hpp): PNG written and images read through stb.
#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include <stb_image.h>
#include <stb_image_write.h>

#include "io/text.hpp"
#include "penumbra/error.hpp"
#include "penumbra/image_io.hpp"

namespace penumbra {
namespace {

// ---- image formats ------------------------------------------------------------------------
//
// load_image decodes through stb_image, as Debian ships it (2.27). Fuzzing it (tests/fuzz,
// fuzz_image) found memory corruption in two of its decoders: JPEG (a Huffman table declaring
// more than 256 codes overflows the decoder's table) and PNM with more than 8 bits per sample
// (converted as if 8-bit: a heap overflow). Those formats are refused before stb sees a byte,
// and so is anything whose first bytes name no format (stb would try it as TGA, its only
// format without a signature). The formats read are recognised by their signature.
constexpr const char* kImageFormats = "PNG, BMP, GIF, PSD, HDR";
constexpr int kMaxImageSide = 16384;         // as for rendered images (scene.hpp)
constexpr double kMaxImagePixels = 1 << 24;  // 16 Mi pixels: 512 MiB as a 4-channel Image

bool starts_with(const unsigned char* p, size_t n, const char* magic, size_t m) {
  return n >= m && std::memcmp(p, magic, m) == 0;
}

bool known_format(const unsigned char* p, size_t n) {
  return starts_with(p, n, "\x89PNG\r\n\x1a\n", 8) || starts_with(p, n, "BM", 2) ||
         starts_with(p, n, "GIF87a", 6) || starts_with(p, n, "GIF89a", 6) ||
         starts_with(p, n, "8BPS", 4) || starts_with(p, n, "#?RADIANCE\n", 11) ||
         starts_with(p, n, "#?RGBE\n", 7);
}

// The name of a format stb_image reads that load_image refuses, or nullptr.
const char* refused_format(const unsigned char* p, size_t n) {
  if (starts_with(p, n, "\xff\xd8", 2)) return "JPEG";
  if (n >= 2 && p[0] == 'P' && (p[1] == '5' || p[1] == '6')) return "PNM (PGM/PPM)";
  return nullptr;
}

// PNG: every chunk's declared length must fit in the file. stb_image grows its buffer for the
// compressed data to a chunk's declared length before reading it, so a 60-byte file declaring
// a 2 GB IDAT chunk made it allocate 2 GiB (found by fuzz_image). Returns an error or "".
std::string check_png_chunks(const unsigned char* p, size_t n) {
  size_t at = 8;  // after the signature
  while (at + 8 <= n) {
    const size_t length = (size_t(p[at]) << 24) | (size_t(p[at + 1]) << 16) |
                          (size_t(p[at + 2]) << 8) | size_t(p[at + 3]);
    const std::string type(reinterpret_cast<const char*>(p + at + 4), 4);
    if (length > n - at - 8 || n - at - 8 - length < 4)  // data and CRC
      return "corrupt PNG: chunk '" + printable(type) + "' declares " + std::to_string(length) +
             " bytes, the file has " + std::to_string(n - at - 8) + " left";
    if (type == "IEND") return "";
    at += 12 + length;
  }
  return "";  // truncated before IEND: stb_image reports it
}

// The PNG without its empty IDAT chunks, which carry no data. stb_image copies the first IDAT
// chunk into a buffer it has not yet allocated when that chunk is empty: memcpy(NULL, src, 0),
// undefined behaviour (found by fuzz_image). Call after check_png_chunks.
std::string without_empty_idat(const std::string& png) {
  std::string out = png.substr(0, 8);
  size_t at = 8;
  while (at + 12 <= png.size()) {
    const auto* p = reinterpret_cast<const unsigned char*>(png.data() + at);
    const size_t length = (size_t(p[0]) << 24) | (size_t(p[1]) << 16) | (size_t(p[2]) << 8) | p[3];
    if (length != 0 || png.compare(at + 4, 4, "IDAT") != 0) out.append(png, at, 12 + length);
    at += 12 + length;
  }
  return out + png.substr(std::min(at, png.size()));  // a truncated tail, for stb to report
}

// stb_image's reason for the last failure, made printable (some quote bytes of the file).
std::string failure_reason() {
  const char* reason = stbi_failure_reason();
  return reason ? printable(reason, 80) : std::string("unknown error");
}

void append_bytes(void* context, void* data, int size) {
  static_cast<std::string*>(context)->append(static_cast<const char*>(data), size_t(size));
}

}  // namespace

std::string png_bytes(const Image& image, const std::string& path) {
  check_image(image, "PNG", path);
  if (image.channels > 4)
    throw Error("cannot write PNG " + quoted_path(path) + ": " + std::to_string(image.channels) +
                " channels (PNG holds 1 to 4)");
  std::vector<unsigned char> bytes(image.data.size());
  for (size_t i = 0; i < bytes.size(); ++i) {
    double v = image.data[i];
    v = std::isnan(v) ? 0.0 : std::min(1.0, std::max(0.0, v));
    bytes[i] = static_cast<unsigned char>(std::lround(v * 255.0));
  }
  const int stride = image.width * image.channels;
  std::string png;
  if (!stbi_write_png_to_func(append_bytes, &png, image.width, image.height, image.channels,
                              bytes.data(), stride))
    throw Error("cannot write PNG " + quoted_path(path) + ": encoding failed");
  return png;
}

void save_png(const Image& image, const std::string& path) {
  write_file(path, png_bytes(image, path), "PNG");
}

Image load_image(const std::string& path, int channels) {
  if (channels < 0 || channels > 4)
    throw Error("cannot read image " + quoted_path(path) + ": requested " +
                std::to_string(channels) + " channels (0 for the file's own, or 1 to 4)");
  auto fail = [&](const std::string& why) {
    return Error("cannot read image " + quoted_path(path) + ": " + why);
  };
  // The whole file, read once: the format checks and the decoder see the same bytes.
  std::ifstream f(path, std::ios::binary);
  if (!f) throw fail(std::strerror(errno));
  std::ostringstream s;
  s << f.rdbuf();
  if (f.bad()) throw fail("read failed");
  std::string bytes = s.str();
  const stbi_uc* p = reinterpret_cast<const stbi_uc*>(bytes.data());
  if (bytes.size() > size_t(std::numeric_limits<int>::max())) throw fail("file too large");

  const char* refused = refused_format(p, bytes.size());
  if (refused) throw fail(std::string(refused) + " files are not read (" + kImageFormats + " are)");
  if (!known_format(p, bytes.size()))
    throw fail(std::string("unknown image format (") + kImageFormats + " are read)");
  if (p[0] == 0x89) {  // PNG
    if (const std::string why = check_png_chunks(p, bytes.size()); !why.empty()) throw fail(why);
    bytes = without_empty_idat(bytes);
    p = reinterpret_cast<const stbi_uc*>(bytes.data());
  }

  const int len = int(bytes.size());
  // Pixel counts come from the header, before anything is decoded: a few bytes of header can
  // declare a huge image (stb_image would allocate it, several times over for GIF).
  int w = 0, h = 0, n = 0;
  if (!stbi_info_from_memory(p, len, &w, &h, &n)) throw fail(failure_reason());
  if (w <= 0 || h <= 0)  // stb_image accepts some headers that declare no pixels
    throw fail("it has no pixels (" + std::to_string(w) + "x" + std::to_string(h) + ")");
  if (w > kMaxImageSide || h > kMaxImageSide || double(w) * h > kMaxImagePixels)
    throw fail(std::to_string(w) + "x" + std::to_string(h) + " pixels is too large (at most " +
               std::to_string(kMaxImageSide) + " a side and " +
               std::to_string(long(kMaxImagePixels)) + " in all)");

  Image image;
  auto take = [&](auto* data, double scale) {
    if (!data) throw fail(failure_reason());
    if (w <= 0 || h <= 0 || w > kMaxImageSide || h > kMaxImageSide) {
      stbi_image_free(data);
      throw fail("it has no pixels (" + std::to_string(w) + "x" + std::to_string(h) + ")");
    }
    const int c = channels > 0 ? channels : n;
    image = Image(w, h, c);
    for (size_t i = 0; i < image.data.size(); ++i) image.data[i] = data[i] * scale;
    stbi_image_free(data);
  };
  if (stbi_is_hdr_from_memory(p, len))
    take(stbi_loadf_from_memory(p, len, &w, &h, &n, channels), 1.0);
  else if (stbi_is_16_bit_from_memory(p, len))
    take(stbi_load_16_from_memory(p, len, &w, &h, &n, channels), 1.0 / 65535.0);
  else
    take(stbi_load_from_memory(p, len, &w, &h, &n, channels), 1.0 / 255.0);
  return image;
}

// ---- NumPy --------------------------------------------------------------------------------

}  // namespace penumbra
