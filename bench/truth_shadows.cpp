// penumbra_truth_shadows: fit-shadows targets ray-traced by the ground truth (truth.cpp), not
// rendered by penumbra. For each light direction it builds fit-shadows' wall scene
// (optim::wall_scene: the shape, a wall across a directional light, a camera looking at the
// wall) and writes the wall's ray-traced shadow as a target image: dark where the shadow ray
// from the wall point is blocked, light elsewhere.
//
//   penumbra_truth_shadows MESH.obj SIZE OUT_DIR [x,y,z ...]
//
// Writes OUT_DIR/shadow_0.png, shadow_1.png, ... (SIZE × SIZE; OUT_DIR is made if missing), one
// per direction (default: 0,0,-1 and -1,0,0, fit-shadows' first two lights), and prints one line
// per file with the shadow's pixel count.
#include <cstdio>
#include <exception>
#include <filesystem>
#include <string>
#include <vector>

#include "penumbra/error.hpp"
#include "penumbra/image_io.hpp"
#include "penumbra/io.hpp"
#include "penumbra/optim.hpp"
#include "truth.hpp"

namespace {

using namespace penumbra;

glm::dvec3 parse_direction(const std::string& text) {
  glm::dvec3 d;
  char tail = 0;
  if (std::sscanf(text.c_str(), "%lf,%lf,%lf%c", &d.x, &d.y, &d.z, &tail) != 3)
    throw Error("direction '" + text + "' is not x,y,z");
  return d;
}

// The wall's shadow: 0 (dark) where the wall point's shadow ray is blocked, 1 elsewhere.
Image truth_shadow(const Mesh& shape, const glm::dvec3& direction, int size) {
  const RenderParams params = optim::ShadowProblem::default_shadow_fit_params();
  const Scene scene = optim::wall_scene(shape, direction, size, params);
  const bench::GroundTruth t = bench::ray_trace(scene, bench::TruthLight::Point);
  Image out(size, size, 1, 1.0);
  for (size_t i = 0; i < out.data.size(); ++i)
    if (t.mesh[i] >= 0 && t.vis[i] < 0.5) out.data[i] = 0.0;
  return out;
}

int run(int argc, char** argv) {
  if (argc < 4) throw Error("usage: penumbra_truth_shadows MESH.obj SIZE OUT_DIR [x,y,z ...]");
  const Mesh shape = load_obj(argv[1]);
  const int size = std::stoi(argv[2]);
  if (size < 16 || size > 1024)
    throw Error("SIZE must be 16 to 1024 (got " + std::string(argv[2]) + ")");
  std::vector<glm::dvec3> directions = {{0, 0, -1}, {-1, 0, 0}};
  if (argc > 4) directions.clear();
  for (int i = 4; i < argc; ++i) directions.push_back(parse_direction(argv[i]));
  std::error_code ec;  // OUT_DIR is made as the tool's other commands make theirs
  std::filesystem::create_directories(argv[3], ec);
  if (ec) throw Error("cannot create the folder " + std::string(argv[3]) + ": " + ec.message());
  for (size_t v = 0; v < directions.size(); ++v) {
    const Image shadow = truth_shadow(shape, directions[v], size);
    const std::string path = std::string(argv[3]) + "/shadow_" + std::to_string(v) + ".png";
    save_png(shadow, path);
    size_t dark = 0;
    for (double x : shadow.data) dark += x < 0.5;
    std::printf("%s: %zu shadow pixels of %d\n", path.c_str(), dark, size * size);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "penumbra_truth_shadows: error: %s\n", e.what());
    return 1;
  }
}
