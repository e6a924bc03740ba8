#pragma once
// Compiled OpenCL programs kept on disk between processes (Context::program), so that a new
// process loads a binary instead of compiling the kernels' source again.
//
// Where: $PENUMBRA_CACHE_DIR if set ("off" disables the cache), else $XDG_CACHE_HOME/penumbra,
// else $HOME/.cache/penumbra; one file `<key>.clbin` per program under `kernels/` there.
// The key hashes everything that can change the binary: the device's name and vendor, the
// driver and platform versions, the kernel source with its includes expanded and the build
// options. Each file starts with a header (magic, key, payload length and checksum), so that a
// truncated or damaged entry is noticed and rebuilt. A cache problem never fails a build: a
// directory that cannot be written costs one warning line on stderr per process.
#include <CL/opencl.hpp>
#include <cstdint>
#include <optional>
#include <string>

namespace penumbra::detail {

// The folder holding the binaries, or "" when the cache is off.
std::string program_cache_dir();

// 32 hex digits naming the program built from `source` with `options` for `device`.
std::string program_cache_key(const cl::Device& device, const std::string& source,
                              const std::string& options);

// A file's bytes for `binary` under `key` (the header, then the binary).
std::string encode_program_entry(const std::string& key, const std::string& binary);
// The binary in `bytes`, or nothing when they are not a whole, intact entry for `key`.
std::optional<std::string> decode_program_entry(const std::string& key, const std::string& bytes);

// The stored binary for `key` in `dir`, or nothing (missing, unreadable or damaged).
std::optional<std::string> load_program_binary(const std::string& dir, const std::string& key);
// Stores `binary` atomically (a temporary file, then a rename); never throws. A failure warns
// once per process on stderr.
void store_program_binary(const std::string& dir, const std::string& key,
                          const std::string& binary) noexcept;

}  // namespace penumbra::detail
