// NumPy .npy files in and out (io.hpp), written and read here.
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

#include "penumbra/error.hpp"
#include "penumbra/io.hpp"
#include "text.hpp"

namespace penumbra {
namespace {

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
    throw Error("cannot write NumPy file " + quoted_path(path) + ": header too long");

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
    throw Error("cannot read NumPy file " + quoted_path(path_) + ": " + what);
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

}  // namespace

std::string npy_bytes(const Image& image, const std::string& path, bool f64) {
  check_image(image, "NumPy file", path);
  std::vector<size_t> shape = {size_t(image.height), size_t(image.width)};
  if (image.channels != 1) shape.push_back(size_t(image.channels));
  return npy_encode(image.data.data(), shape, path, f64);
}

std::string npy_bytes(const std::vector<double>& values, size_t rows, size_t cols,
                      const std::string& path, bool f64) {
  if (values.size() != rows * cols)
    throw Error("cannot write NumPy file " + quoted_path(path) + ": " +
                std::to_string(values.size()) + " values do not fill shape (" +
                std::to_string(rows) + ", " + std::to_string(cols) + ")");
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
  const std::string bytes = read_whole_file(path, "NumPy file");
  const auto* p = reinterpret_cast<const unsigned char*>(bytes.data());
  auto bad = [&](const std::string& what) {
    return Error("cannot read NumPy file " + quoted_path(path) + ": " + what);
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
