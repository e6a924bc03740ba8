#pragma once
// Pieces the device tests share: the OpenCL context and renderers, small scene builders
// (icosphere, ground grid, lights, the front camera, the shadow parameters) and image and
// gradient comparisons. Every builder's defaults give the scene the tests were tuned on; a test
// that needs another variant passes it explicitly, since tolerances depend on the exact scene.
#include <gtest/gtest.h>

#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "penumbra/context.hpp"
#include "penumbra/gradcheck.hpp"
#include "penumbra/image.hpp"
#include "penumbra/renderer.hpp"
#include "penumbra/scene.hpp"

namespace penumbra_tests {

// ---------------------------------------------------------------------------------------------
// Device.

// One Context for the whole binary, created on first use; null (with the reason in `error`)
// when no OpenCL device is usable. A missing device fails the tests; it never skips them.
penumbra::Context* shared_context(std::string* error);

#define REQUIRE_CONTEXT(ctx)                                             \
  std::string ctx##_error;                                               \
  penumbra::Context* ctx = penumbra_tests::shared_context(&ctx##_error); \
  ASSERT_NE(ctx, nullptr) << "cannot create an OpenCL context: " << ctx##_error

// One renderer per precision for the whole binary (programs are built once).
penumbra::Renderer& shared_renderer(penumbra::Context& ctx, penumbra::Precision precision);

const char* name_of(penumbra::Sampling s);

// The ways the tests sum the shadow filter: truncated, exact (on the exact backend the tuning
// picks, `auto`) and gemm (exact on CLBlast, exact backend `clblast`).
enum class Method { Truncated, Exact, Gemm };
const char* name_of(Method m);
// Sets p.sampling and p.exact_backend for `m`.
void set_method(penumbra::RenderParams& p, Method m);
const char* name_of(penumbra::Precision p);

// ---------------------------------------------------------------------------------------------
// Scene builders.

// Per-vertex albedo of an icosphere: base + gain·(x, y, −z) of the point on the unit sphere.
struct SphereAlbedo {
  glm::dvec3 base{0.6, 0.5, 0.45}, gain{0.25, 0.2, 0.2};
};

// Unit icosahedron subdivided `levels` times (once: 42 vertices, 80 faces), scaled and moved;
// counter-clockwise seen from outside; smoothly varying per-vertex albedo.
penumbra::Mesh icosphere(glm::dvec3 center, double radius, int levels = 1,
                         const std::string& name = "occluder", const SphereAlbedo& albedo = {});

// Horizontal n×n grid in y = 0 over [−half, half]², facing +y; per-vertex albedo varying by
// `variation` across it (0: uniform grey 0.7).
penumbra::Mesh ground(double half, int n, double variation = 0.05);

penumbra::Light point_light(glm::dvec3 position, glm::dvec3 color, double size = 0.0);
penumbra::Light directional_light(glm::dvec3 direction, glm::dvec3 color, double size = 0.0);

// A 48×40 camera seeing the ground around the origin from the front and above (all lengths
// times `scale`).
penumbra::Camera front_camera(bool ortho, double scale = 1.0);

// The shadow parameters of the shadow and penumbra scenes: σ = 3e-4, γ = 3e-3, 32² maps
// (fitted frusta ≈ 0.13–0.2 world units per texel on the ground), β = 0.2 and γ_s = 0.04 in
// depth units (lit ground keeps s ≈ sigmoid(5)); ambient and background colours.
void shadow_params(penumbra::Scene& s, penumbra::Shadows shadows, penumbra::Sampling sampling,
                   penumbra::ShadowModel model = penumbra::ShadowModel::Paper);
void shadow_params(penumbra::Scene& s, penumbra::Shadows shadows, Method method,
                   penumbra::ShadowModel model = penumbra::ShadowModel::Paper);

// The pixel a world point projects to in camera `cam` (math.md §1), rounded to the nearest centre.
std::pair<int, int> pixel_of(const penumbra::Camera& cam, glm::dvec3 X);

struct NamedScene {
  std::string name;
  penumbra::Scene scene;
};

struct GradCase {
  std::string name;
  penumbra::Scene scene;
  uint64_t seed;
};

// ---------------------------------------------------------------------------------------------
// Comparisons.

size_t count_non_finite(const penumbra::Image& img);
void expect_finite(const penumbra::Image& img, const std::string& what);

// max |got − want| (relative to |want| when `relative`); the worst value named in `where`.
double max_error(const penumbra::Image& got, const penumbra::Image& want, bool relative = false,
                 std::string* where = nullptr);

// Expects the same layout, finite values and max error ≤ tol; returns the max error.
double expect_close(const penumbra::Image& got, const penumbra::Image& want, double tol,
                    bool relative, const std::string& what);

struct Tolerance {
  double color, silhouette, depth_rel;
};

// Renders `scene` and compares every view with the reference; returns the largest colour error.
double expect_matches_reference(penumbra::Renderer& renderer, const penumbra::Scene& scene,
                                Tolerance tol, const std::string& name);

// A gradient check's entries, one a line, for failure messages.
std::string describe(const penumbra::GradCheckResult& r);
// Whether an entry's name starts with `prefix`.
bool has_entry(const penumbra::GradCheckResult& r, const std::string& prefix);

// Bit-for-bit equality of two gradients (light sizes too when `with_light_size`).
void expect_identical(const penumbra::SceneGrads& a, const penumbra::SceneGrads& b,
                      const std::string& what, bool with_light_size = false);

// ---------------------------------------------------------------------------------------------
// Files.

// An empty folder TempDir()/penumbra_<name> for one test (emptied if it exists).
std::string fresh_temp_dir(const std::string& name);
// The names of the entries of folder `dir`, sorted.
std::vector<std::string> names_in(const std::string& dir);

// The message of the penumbra::Error that `fn` throws ("" when it throws none).
std::string error_of(const std::function<void()>& fn);

// ---------------------------------------------------------------------------------------------
// Kernel variants: the project's kernels with one passage changed, to show that a shortcut
// changes no bit (against kernels without it) and that it is taken (kernels that poison it).

// kernels/ copied to the folder `name` under the test temp dir with `from` in `file` replaced
// by `to` (the test fails if `from` is not there); returns the folder.
std::string patched_kernels(const std::string& name, const std::string& file,
                            const std::string& from, const std::string& to);
// The same with several passages changed, in order.
struct KernelEdit {
  std::string file, from, to;
};
std::string patched_kernels(const std::string& name, const std::vector<KernelEdit>& edits);

// The images and gradients of a render and backward of `scene`, with the kernels of
// `kernel_dir` (empty: the project's), in a context of their own (built after the variable is
// set).
struct Results {
  std::vector<penumbra::RenderOutput> images;
  penumbra::SceneGrads grads;
};
Results results_with(const std::string& kernel_dir, const penumbra::Scene& scene,
                     penumbra::Precision p, const std::vector<penumbra::OutputGrads>& weights);
penumbra::SceneGrads grads_with(const std::string& kernel_dir, const penumbra::Scene& scene,
                                penumbra::Precision p,
                                const std::vector<penumbra::OutputGrads>& weights);

bool same_images(const std::vector<penumbra::RenderOutput>& a,
                 const std::vector<penumbra::RenderOutput>& b);
bool finite_image(const penumbra::Image& im);
// Whether every vertex gradient is finite.
bool all_finite(const penumbra::SceneGrads& g);
// Sets the left half of an image (columns below width / 2) to 0: a loss weight that leaves it out.
void clear_left_half(penumbra::Image& im);

// The project's kernels with no lookup skipped for a fragment facing away from the light
// (faces_away_in_map never true), in the folder `name` (one per test: ctest runs tests side by
// side); returns the folder.
std::string kernels_looking_up_every_fragment(const std::string& name);

// A lookup skipped where it cannot matter changes no bit: `scene` gives the same images and
// gradients (random loss weights) with the project's kernels and with `looking_up`'s, which
// skip nothing.
void expect_skip_changes_no_bit(const std::string& looking_up, const penumbra::Scene& scene,
                                penumbra::Precision p, const std::string& what);
// The skip happens: the first view's colour is finite with the project's kernels and not with
// `poisoned`'s, which store NaN as a skipped fragment's s (s·0 is NaN).
void expect_skip_taken(const std::string& poisoned, const penumbra::Scene& scene,
                       const std::string& what);

}  // namespace penumbra_tests
