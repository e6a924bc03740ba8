// Renders penumbra's bundled scene, then takes the gradient of the mean brightness of the image
// with respect to every vertex, albedo entry, light and the ambient light.
#include <penumbra/error.hpp>
#include <penumbra/image_io.hpp>
#include <penumbra/io.hpp>
#include <penumbra/renderer.hpp>
#include <penumbra/version.hpp>

#include <algorithm>
#include <cstdio>
#include <vector>

int main(int argc, char** argv) try {
  penumbra::Scene scene = penumbra::load_scene(argc > 1 ? argv[1] : SCENE);
  penumbra::Context context;  // $PENUMBRA_DEVICE, else the first GPU, else the first device
  penumbra::Renderer renderer(context);
  std::vector<penumbra::RenderOutput> views = renderer.render(scene);
  penumbra::save_png(views[0].color, "render.png");

  // L = mean of the colour image, so dL/dcolour is 1/size everywhere (empty images: zero).
  const penumbra::Image& color = views[0].color;
  std::vector<penumbra::OutputGrads> dL(views.size());
  dL[0].color = penumbra::Image(color.width, color.height, 3, 1.0 / color.size());
  penumbra::SceneGrads grads = renderer.backward(scene, dL);

  double largest = 0;
  for (const glm::dvec3& g : grads.vertices[0]) largest = std::max(largest, glm::length(g));
  const glm::dvec3 light = grads.light_position[0];
  std::printf(
      "penumbra %s rendered %dx%d on %s; |dL/dvertex| up to %.3g; dL/dlight = (%.3g, %.3g, "
      "%.3g)\n",
      PENUMBRA_VERSION, color.width, color.height, context.info().name.c_str(), largest, light.x,
      light.y, light.z);
  return 0;
} catch (const penumbra::Error& e) {
  std::fprintf(stderr, "example: error: %s\n", e.what());
  return 1;
}
