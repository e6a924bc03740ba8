#pragma once
// The ray-traced ground truth of the accuracy benchmarks and their test, on the CPU with
// Embree 3 (Debian: libembree-dev; compiled only where CMake finds it, PENUMBRA_HAVE_EMBREE).
//
// It renders camera 0 of a scene with one primary ray through every pixel centre (math.md §1
// screen units), the same shading as penumbra (math.md §3: flat face normal turned to the camera,
// albedo interpolated with the hit's barycentrics, C = a ⊙ I_a + Σ_L v_L · a ⊙ I_L ·
// max(0, n·l), l towards the light's centre, the ambient term unshadowed) and visibility v_L
// from shadow rays:
//   point   one shadow ray to the light's position (the hard-shadow truth);
//   sphere  a sphere light of radius D_L/2 centred at the light's position: v is the fraction
//           of 256 stratified points on the light's disc facing the receiver that the
//           receiver sees (the soft-shadow truth). A directional light gets one shadow ray
//           along its direction in both.
// A receiver facing away from a light gets visibility 0 from it.
#include <vector>

#include "penumbra/scene.hpp"

namespace penumbra::bench {

enum class TruthLight { Point, Sphere };

struct GroundTruth {
  int W = 0, H = 0;
  std::vector<double> color;      // H·W·3
  std::vector<int> mesh;          // mesh hit by the primary ray, −1 for the background
  std::vector<glm::dvec3> point;  // the hit point (world), 0 for the background
  std::vector<double> vis;        // visibility of the lights (min over lights), 1 where nothing hit
};

// Ray-traces camera 0 of `scene` on every hardware thread.
GroundTruth ray_trace(const Scene& scene, TruthLight light);

}  // namespace penumbra::bench
