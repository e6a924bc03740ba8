// libFuzzer target: load_obj on arbitrary bytes (written to a scratch .obj file).
// A successful load must give a mesh that passes validate() with one albedo per vertex.
#include <cstdint>

#include "fuzz_common.hpp"
#include "penumbra/io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace penumbra;
  const std::string path = fuzz::write_input(data, size, "input.obj");
  try {
    const Mesh mesh = load_obj(path);
    validate(mesh);  // throws penumbra::Error (caught below, but a valid mesh must not throw)
    if (mesh.albedo.size() != mesh.vertices.size()) fuzz::broken("albedo count != vertex count");
  } catch (const Error& e) {
    fuzz::check_error(e);
  }
  return 0;
}
