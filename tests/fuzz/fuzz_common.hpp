// Shared by the libFuzzer targets: the loaders read files, so each input is written to a
// scratch file first; and the contract every loader must keep whatever the bytes.
#pragma once
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <string>

#include "penumbra/error.hpp"

namespace penumbra::fuzz {

// A scratch folder of this process under $TMPDIR (or /tmp), made once and removed at exit
// (a process killed by a crash leaves it behind).
inline const std::string& scratch_dir() {
  // Never destroyed, so that the exit handler can still read it.
  static const std::string* dir = [] {
    const char* tmp = std::getenv("TMPDIR");
    std::filesystem::path p = std::filesystem::path(tmp && *tmp ? tmp : "/tmp") /
                              ("penumbra_fuzz_" + std::to_string(::getpid()));
    std::filesystem::create_directories(p);
    auto* d = new std::string(p.string());
    std::atexit([] {
      std::error_code ec;
      std::filesystem::remove_all(scratch_dir(), ec);
    });
    return d;
  }();
  return *dir;
}

// Writes the input to `name` in the scratch folder and returns its path.
inline std::string write_input(const uint8_t* data, size_t size, const std::string& name) {
  const std::string path = scratch_dir() + "/" + name;
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f.write(reinterpret_cast<const char*>(data), std::streamsize(size));
  f.close();
  if (!f) {
    std::fprintf(stderr, "fuzz: cannot write %s\n", path.c_str());
    std::abort();
  }
  return path;
}

// The loaders' contract (io.hpp, error.hpp): every failure is a penumbra::Error with a one-line
// message. Any other exception escapes the fuzz target and libFuzzer reports it as a crash.
inline void check_error(const Error& e) {
  const char* m = e.what();
  if (m[0] == '\0' || std::strchr(m, '\n') != nullptr || std::strchr(m, '\r') != nullptr) {
    std::fprintf(stderr, "fuzz: error message is empty or spans lines: [%s]\n", m);
    std::abort();
  }
}

// A broken invariant of a successful load.
[[noreturn]] inline void broken(const char* what) {
  std::fprintf(stderr, "fuzz: %s\n", what);
  std::abort();
}

}  // namespace penumbra::fuzz
