// Program binaries on disk (program_cache.hpp).
#include "cl/program_cache.hpp"

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "penumbra/error.hpp"
#include "penumbra/io.hpp"

namespace penumbra::detail {
namespace {

namespace fs = std::filesystem;

// Bumped whenever the entry layout or the key's contents change.
constexpr char kMagic[8] = {'P', 'N', 'B', 'R', 'C', 'L', 'B', '1'};
constexpr size_t kKeyDigits = 32;
constexpr size_t kHeaderSize = sizeof(kMagic) + kKeyDigits + 8 + 8;

// FNV-1a: small and dependency-free. The entries are not a security boundary (the cache is
// the user's own folder); the hash only has to tell programs apart.
uint64_t fnv1a(const std::string& bytes, uint64_t h = 0xcbf29ce484222325ull) {
  for (unsigned char c : bytes) h = (h ^ c) * 0x100000001b3ull;
  return h;
}

// A second, differently built 64-bit hash (splitmix64 finaliser over 8-byte words), so that the
// 128-bit key does not rest on one function.
uint64_t mix(const std::string& bytes) {
  uint64_t h = 0x9e3779b97f4a7c15ull ^ bytes.size();
  for (size_t i = 0; i < bytes.size(); i += 8) {
    uint64_t w = 0;
    for (size_t j = i; j < i + 8 && j < bytes.size(); ++j)
      w |= uint64_t(static_cast<unsigned char>(bytes[j])) << (8 * (j - i));
    h ^= w + 0x9e3779b97f4a7c15ull + (h << 6) + (h >> 2);
    h ^= h >> 30, h *= 0xbf58476d1ce4e5b9ull, h ^= h >> 27, h *= 0x94d049bb133111ebull,
        h ^= h >> 31;
  }
  return h;
}

std::string hex(uint64_t v) {
  char s[17];
  std::snprintf(s, sizeof s, "%016llx", static_cast<unsigned long long>(v));
  return s;
}

std::string le64(uint64_t v) {
  std::string s(8, '\0');
  for (int i = 0; i < 8; ++i) s[i] = char((v >> (8 * i)) & 0xff);
  return s;
}

uint64_t read_le64(const std::string& s, size_t at) {
  uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v |= uint64_t(static_cast<unsigned char>(s[at + i])) << (8 * i);
  return v;
}

// Each field with its length first, so that no two different field lists hash the same text.
void field(std::string& out, const std::string& value) {
  out += std::to_string(value.size()) + ":" + value + ";";
}

void warn_once(const std::string& message) {
  static std::atomic<bool> warned{false};
  if (warned.exchange(true)) return;
  std::fprintf(stderr, "penumbra: warning: %s (compiled kernels are not cached)\n",
               message.c_str());
}

std::string entry_path(const std::string& dir, const std::string& key) {
  return (fs::path(dir) / (key + ".clbin")).string();
}

}  // namespace

std::string program_cache_dir() {
  if (const char* dir = std::getenv("PENUMBRA_CACHE_DIR"); dir && *dir)
    return std::string(dir) == "off" ? "" : dir;
  if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg && *xdg)
    return std::string(xdg) + "/penumbra";
  if (const char* home = std::getenv("HOME"); home && *home)
    return std::string(home) + "/.cache/penumbra";
  return "";  // nowhere sensible to keep it
}

std::string program_cache_key(const cl::Device& device, const std::string& source,
                              const std::string& options) {
  std::string text;
  field(text, std::string(kMagic, sizeof kMagic));
  field(text, device.getInfo<CL_DEVICE_NAME>());
  field(text, device.getInfo<CL_DEVICE_VENDOR>());
  field(text, device.getInfo<CL_DEVICE_VERSION>());
  field(text, device.getInfo<CL_DRIVER_VERSION>());
  field(text, cl::Platform(device.getInfo<CL_DEVICE_PLATFORM>()).getInfo<CL_PLATFORM_VERSION>());
  field(text, source);
  field(text, options);
  return hex(fnv1a(text)) + hex(mix(text));
}

std::string encode_program_entry(const std::string& key, const std::string& binary) {
  std::string key_digits = key;
  key_digits.resize(kKeyDigits, '\0');
  return std::string(kMagic, sizeof kMagic) + key_digits + le64(binary.size()) +
         le64(fnv1a(binary)) + binary;
}

std::optional<std::string> decode_program_entry(const std::string& key, const std::string& bytes) {
  if (bytes.size() < kHeaderSize || bytes.compare(0, sizeof kMagic, kMagic, sizeof kMagic) != 0)
    return std::nullopt;
  std::string key_digits = key;
  key_digits.resize(kKeyDigits, '\0');
  if (bytes.compare(sizeof kMagic, kKeyDigits, key_digits) != 0) return std::nullopt;
  const uint64_t size = read_le64(bytes, sizeof kMagic + kKeyDigits);
  if (size == 0 || size != bytes.size() - kHeaderSize) return std::nullopt;
  std::string binary = bytes.substr(kHeaderSize);
  if (fnv1a(binary) != read_le64(bytes, sizeof kMagic + kKeyDigits + 8)) return std::nullopt;
  return binary;
}

std::optional<std::string> load_program_binary(const std::string& dir, const std::string& key) {
  std::ifstream in(entry_path(dir, key), std::ios::binary);
  if (!in) return std::nullopt;
  std::ostringstream bytes;
  bytes << in.rdbuf();
  if (in.bad()) return std::nullopt;
  return decode_program_entry(key, bytes.str());
}

void store_program_binary(const std::string& dir, const std::string& key,
                          const std::string& binary) noexcept {
  try {
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec) {
      warn_once("cannot create the kernel cache folder '" + dir + "': " + ec.message());
      return;
    }
    write_file(entry_path(dir, key), encode_program_entry(key, binary), "kernel cache entry",
               FileKind::cache);
  } catch (const std::exception& e) {
    warn_once(e.what());
  }
}

}  // namespace penumbra::detail
