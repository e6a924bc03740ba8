// libFuzzer target: parse_scene on arbitrary bytes. Mesh paths are resolved against a scratch
// folder holding two small meshes, so inputs can name them: "tetra.obj" (a valid tetrahedron)
// and "bad.obj" (an OBJ with an out-of-range index). A successful parse must give a scene that
// passes validate() with every light frustum fitted.
#include <cstdint>
#include <fstream>

#include "fuzz_common.hpp"
#include "penumbra/io.hpp"

namespace {

void write_text(const std::string& path, const char* text) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f << text;
}

const std::string& base_dir() {
  static const std::string dir = [] {
    const std::string d = penumbra::fuzz::scratch_dir();
    write_text(d + "/tetra.obj",
               "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n");
    write_text(d + "/bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n");
    return d;
  }();
  return dir;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace penumbra;
  const std::string text(reinterpret_cast<const char*>(data), size);
  // Mesh paths are the input's: keep the fuzzer away from device files and FIFOs, which never
  // end or block (/dev/zero, /dev/stdin) — reading them is what the user asked for, not a bug.
  for (const char* dir : {"/dev", "/proc", "/sys", "/run"})
    if (text.find(dir) != std::string::npos) return 0;
  try {
    const Scene scene = parse_scene(text, base_dir());
    validate(scene);
    for (const Light& l : scene.lights)
      if (!l.frustum.fitted) fuzz::broken("a light frustum is not fitted");
  } catch (const Error& e) {
    fuzz::check_error(e);
  }
  return 0;
}
