// Images in and out (io.hpp): PNG through stb, NumPy .npy written and read here.
//
// .npy layout (format version 1.0): the magic "\x93NUMPY", two version bytes (1, 0), a
// little-endian uint16 header length, then the header: a Python dict literal such as
//   {'descr': '<f4', 'fortran_order': False, 'shape': (64, 64, 3), }
// padded with spaces and ended by '\n' so that magic + version + length + header is a
// multiple of 64 bytes; the data follow in C order. Versions 2.0 and 3.0 (uint32 length)
// are accepted when loading.
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

#include "penumbra/error.hpp"
#include "penumbra/io.hpp"
#include "text.hpp"

namespace penumbra {
namespace {

std::string quoted(const std::string& path) { return "'" + path + "'"; }

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

void check_image(const Image& image, const std::string& what, const std::string& path) {
  if (image.width <= 0 || image.height <= 0 || image.channels <= 0)
    throw Error("cannot write " + what + " " + quoted(path) + ": image is empty (" +
                std::to_string(image.width) + "x" + std::to_string(image.height) + "x" +
                std::to_string(image.channels) + ")");
  const size_t want = size_t(image.width) * size_t(image.height) * size_t(image.channels);
  if (image.data.size() != want)
    throw Error("cannot write " + what + " " + quoted(path) + ": image has " +
                std::to_string(image.data.size()) + " values, " + std::to_string(image.width) +
                "x" + std::to_string(image.height) + "x" + std::to_string(image.channels) +
                " needs " + std::to_string(want));
}

// ---- .npy writing -------------------------------------------------------------------------

void put_le(std::string& out, uint64_t bits, int bytes) {
  for (int i = 0; i < bytes; ++i) out.push_back(char((bits >> (8 * i)) & 0xff));
}

std::string npy_encode(const double* values, const std::vector<size_t>& shape,
                       const std::string& path, bool f64) {
  std::string shape_text = "(";
  for (size_t i = 0; i < shape.size(); ++i) {
    if (i) shape_text += ", ";
    shape_text += std::to_string(shape[i]);
  }
  if (shape.size() == 1) shape_text += ",";
  shape_text += ")";
  std::string header = std::string("{'descr': '") + (f64 ? "<f8" : "<f4") +
                       "', 'fortran_order': False, 'shape': " + shape_text + ", }";
  const size_t prefix = 10;  // magic (6) + version (2) + header length (2)
  const size_t total = (prefix + header.size() + 1 + 63) / 64 * 64;
  header.append(total - prefix - header.size() - 1, ' ');
  header.push_back('\n');
  if (header.size() > 0xffff)
    throw Error("cannot write NumPy file " + quoted(path) + ": header too long");

  size_t count = 1;
  for (size_t d : shape) count *= d;
  std::string out;
  out.reserve(total + count * (f64 ? 8 : 4));
  out.append("\x93NUMPY", 6);
  out.push_back(char(1));
  out.push_back(char(0));
  put_le(out, header.size(), 2);
  out += header;
  for (size_t i = 0; i < count; ++i) {
    if (f64) {
      uint64_t bits;
      const double v = values[i];
      std::memcpy(&bits, &v, 8);
      put_le(out, bits, 8);
    } else {
      uint32_t bits;
      const float v = static_cast<float>(values[i]);
      std::memcpy(&bits, &v, 4);
      put_le(out, bits, 4);
    }
  }
  return out;
}

// ---- .npy reading -------------------------------------------------------------------------

uint64_t get_le(const unsigned char* p, int bytes) {
  uint64_t v = 0;
  for (int i = bytes - 1; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}

// A minimal reader for the header dict: string keys; values are strings, True/False, or
// tuples of non-negative integers.
class HeaderParser {
 public:
  HeaderParser(const std::string& text, const std::string& path) : s_(text), path_(path) {}

  std::string descr;
  bool fortran_order = false;
  std::vector<size_t> shape;

  void parse() {
    bool has_descr = false, has_order = false, has_shape = false;
    expect('{');
    for (;;) {
      skip();
      if (peek() == '}') break;
      const std::string key = string();
      expect(':');
      if (key == "descr") {
        descr = string();
        has_descr = true;
      } else if (key == "fortran_order") {
        fortran_order = boolean();
        has_order = true;
      } else if (key == "shape") {
        shape = tuple();
        has_shape = true;
      } else {
        fail("unexpected header key '" + printable(key) + "'");
      }
      skip();
      if (peek() == ',') {
        ++i_;
        continue;
      }
      skip();
      if (peek() != '}') fail("malformed header dict");
    }
    if (!has_descr || !has_order || !has_shape)
      fail("header lacks one of 'descr', 'fortran_order', 'shape'");
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    throw Error("cannot read NumPy file " + quoted(path_) + ": " + what);
  }
  void skip() {
    while (i_ < s_.size() && std::isspace(static_cast<unsigned char>(s_[i_]))) ++i_;
  }
  char peek() const { return i_ < s_.size() ? s_[i_] : '\0'; }
  void expect(char c) {
    skip();
    if (peek() != c) fail(std::string("malformed header (expected '") + c + "')");
    ++i_;
  }
  std::string string() {
    skip();
    const char q = peek();
    if (q != '\'' && q != '"') fail("malformed header (expected a quoted string)");
    const size_t end = s_.find(q, i_ + 1);
    if (end == std::string::npos) fail("malformed header (unterminated string)");
    std::string out = s_.substr(i_ + 1, end - i_ - 1);
    i_ = end + 1;
    return out;
  }
  bool boolean() {
    skip();
    if (s_.compare(i_, 4, "True") == 0) {
      i_ += 4;
      return true;
    }
    if (s_.compare(i_, 5, "False") == 0) {
      i_ += 5;
      return false;
    }
    fail("malformed header (fortran_order must be True or False)");
  }
  std::vector<size_t> tuple() {
    std::vector<size_t> out;
    expect('(');
    for (;;) {
      skip();
      if (peek() == ')') {
        ++i_;
        return out;
      }
      if (!std::isdigit(static_cast<unsigned char>(peek())))
        fail("malformed header (shape must be a tuple of non-negative integers)");
      size_t v = 0;
      while (std::isdigit(static_cast<unsigned char>(peek()))) {
        const size_t digit = size_t(s_[i_++] - '0');
        if (v > (std::numeric_limits<size_t>::max() - digit) / 10) fail("shape value too large");
        v = v * 10 + digit;
      }
      out.push_back(v);
      skip();
      if (peek() == ',')
        ++i_;
      else if (peek() != ')')
        fail("malformed header (shape must be a tuple of integers)");
    }
  }

  const std::string& s_;
  const std::string& path_;
  size_t i_ = 0;
};

std::string shape_string(const std::vector<size_t>& shape) {
  std::string out = "(";
  for (size_t i = 0; i < shape.size(); ++i) out += (i ? ", " : "") + std::to_string(shape[i]);
  return out + ")";
}

// ---- PNG and other images -----------------------------------------------------------------

// stbi_write_png_to_func's sink: appends to a std::string.
void append_bytes(void* context, void* data, int size) {
  static_cast<std::string*>(context)->append(static_cast<const char*>(data), size_t(size));
}

}  // namespace

std::string png_bytes(const Image& image, const std::string& path) {
  check_image(image, "PNG", path);
  if (image.channels > 4)
    throw Error("cannot write PNG " + quoted(path) + ": " + std::to_string(image.channels) +
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
    throw Error("cannot write PNG " + quoted(path) + ": encoding failed");
  return png;
}

void save_png(const Image& image, const std::string& path) {
  write_file(path, png_bytes(image, path), "PNG");
}

Image load_image(const std::string& path, int channels) {
  if (channels < 0 || channels > 4)
    throw Error("cannot read image " + quoted(path) + ": requested " + std::to_string(channels) +
                " channels (0 for the file's own, or 1 to 4)");
  auto fail = [&](const std::string& why) {
    return Error("cannot read image " + quoted(path) + ": " + why);
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

std::string npy_bytes(const Image& image, const std::string& path, bool f64) {
  check_image(image, "NumPy file", path);
  std::vector<size_t> shape = {size_t(image.height), size_t(image.width)};
  if (image.channels != 1) shape.push_back(size_t(image.channels));
  return npy_encode(image.data.data(), shape, path, f64);
}

std::string npy_bytes(const std::vector<double>& values, size_t rows, size_t cols,
                      const std::string& path, bool f64) {
  if (values.size() != rows * cols)
    throw Error("cannot write NumPy file " + quoted(path) + ": " + std::to_string(values.size()) +
                " values do not fill shape (" + std::to_string(rows) + ", " + std::to_string(cols) +
                ")");
  return npy_encode(values.data(), {rows, cols}, path, f64);
}

void save_npy(const Image& image, const std::string& path, bool f64) {
  write_file(path, npy_bytes(image, path, f64), "NumPy file");
}

void save_npy(const std::vector<double>& values, size_t rows, size_t cols, const std::string& path,
              bool f64) {
  write_file(path, npy_bytes(values, rows, cols, path, f64), "NumPy file");
}

Image load_npy(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw Error("cannot open NumPy file " + quoted(path) + ": " + std::strerror(errno));
  std::ostringstream s;
  s << f.rdbuf();
  const std::string bytes = s.str();
  const auto* p = reinterpret_cast<const unsigned char*>(bytes.data());
  auto bad = [&](const std::string& what) {
    return Error("cannot read NumPy file " + quoted(path) + ": " + what);
  };

  if (bytes.size() < 10 || bytes.compare(0, 6, "\x93NUMPY", 6) != 0)
    throw bad("not a .npy file (bad magic)");
  const int major = p[6];
  size_t header_len = 0, header_start = 0;
  if (major == 1) {
    header_len = get_le(p + 8, 2);
    header_start = 10;
  } else if (major == 2 || major == 3) {
    if (bytes.size() < 12) throw bad("truncated header");
    header_len = get_le(p + 8, 4);
    header_start = 12;
  } else {
    throw bad("unsupported format version " + std::to_string(major) + "." +
              std::to_string(int(p[7])));
  }
  if (bytes.size() < header_start + header_len) throw bad("truncated header");

  const std::string header = bytes.substr(header_start, header_len);
  HeaderParser hp(header, path);
  hp.parse();
  if (hp.fortran_order) throw bad("Fortran-order arrays are not supported (C order expected)");
  size_t item = 0;
  if (hp.descr == "<f4")
    item = 4;
  else if (hp.descr == "<f8")
    item = 8;
  else if (hp.descr == ">f4" || hp.descr == ">f8")
    throw bad("big-endian data ('" + hp.descr + "') is not supported");
  else
    throw bad("unsupported dtype '" + printable(hp.descr) + "' (expected '<f4' or '<f8')");
  if (hp.shape.size() != 2 && hp.shape.size() != 3)
    throw bad("shape " + shape_string(hp.shape) + " is not 2-D (H, W) or 3-D (H, W, C)");
  const size_t limit = size_t(std::numeric_limits<int>::max());
  size_t count = 1;
  for (size_t d : hp.shape) {
    if (d > limit) throw bad("shape " + shape_string(hp.shape) + " is too large");
    if (d != 0 && count > std::numeric_limits<size_t>::max() / d / 8)
      throw bad("shape " + shape_string(hp.shape) + " is too large");
    count *= d;
  }
  const size_t data_start = header_start + header_len;
  const size_t have = bytes.size() - data_start;
  if (have != count * item)
    throw bad(std::string(have < count * item ? "truncated data" : "trailing data") + ": shape " +
              shape_string(hp.shape) + " needs " + std::to_string(count * item) +
              " bytes, the file has " + std::to_string(have));

  const int h = int(hp.shape[0]), w = int(hp.shape[1]);
  const int c = hp.shape.size() == 3 ? int(hp.shape[2]) : 1;
  Image image;
  image.width = w;
  image.height = h;
  image.channels = c;
  image.data.resize(count);
  const unsigned char* d = p + data_start;
  for (size_t i = 0; i < count; ++i) {
    if (item == 8) {
      const uint64_t bits = get_le(d + 8 * i, 8);
      double v;
      std::memcpy(&v, &bits, 8);
      image.data[i] = v;
    } else {
      const uint32_t bits = uint32_t(get_le(d + 4 * i, 4));
      float v;
      std::memcpy(&v, &bits, 4);
      image.data[i] = v;
    }
  }
  return image;
}

}  // namespace penumbra
