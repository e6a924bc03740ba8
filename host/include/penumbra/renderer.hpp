#pragma once
// The differentiable renderer: forward (render) and backward (gradients) on an OpenCL device.
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "penumbra/context.hpp"
#include "penumbra/image.hpp"
#include "penumbra/scene.hpp"
#include "penumbra/tuning.hpp"

namespace penumbra {

enum class Precision { Float, Double };

// dL/d(scene parameters), laid out like the scene.
struct SceneGrads {
  std::vector<std::vector<glm::dvec3>> vertices;  // [mesh][vertex]
  std::vector<std::vector<glm::dvec3>> albedo;    // [mesh][albedo entry]
  std::vector<glm::dvec3> light_position;         // [light] (direction for directional lights)
  std::vector<glm::dvec3> light_color;            // [light]
  std::vector<double> light_size;                 // [light] D_L (soft shadows)
  glm::dvec3 ambient{0.0};
};

// The device memory a render() of `scene` needs (with `backward`, and the backward() after
// it), estimated from the scene's sizes before anything is allocated: the geometry, every
// camera's view and every light's shadow-map view, 1.25 fragments per pixel of a camera's view
// and 1.5 per texel of a map (how many there are is known only once they are counted; the
// fragments' memory is then checked again), the penumbra maps and the batches of the paper
// model's exact hard-shadow lookups (whose weight matrices, forward and backward, a camera's
// fragments keep for the next call's). With `tuning` (Renderer::tuning() after a render), the
// exact backend `auto` is the one that tuning picks; without, it is counted as CLBlast, whose
// GEMM needs a temporary the direct kernels do not. render() and backward() refuse a scene whose
// estimate, with their tuning, exceeds Context::memory_limit().
size_t estimate_device_memory(const Scene& scene, Precision precision, bool backward = false,
                              const Tuning* tuning = nullptr);

// `scene` with every length multiplied by `factor`: vertices, cameras (eye, target, near, far,
// orthographic half-height), lights (position, size, frustum), γ_s, β and depth_unit. The
// renderer renders a scene whose bounding radius is far from 1 (outside [2^-12, 2^12]) scaled
// by a power of two that brings it near 1, and maps depths and gradients back.
Scene scale_scene(const Scene& scene, double factor);
// `scene` with every point moved by `offset`: vertices, cameras' eyes and targets, lights'
// positions and frustum targets (directions stay). The renderer renders a scene whose centre is
// far from the origin for its size (more than 2^6 bounding radii away) moved to the origin,
// where float keeps its precision; depths and gradients do not change with a translation.
Scene translate_scene(const Scene& scene, glm::dvec3 offset);

// Bytes of device memory in the renderers' buffers (every context of the process): `live` not
// freed yet; `peak` the most at once of the buffers made since reset_device_memory_peak() (or
// since the process started). Buffers the BLAS library allocates itself are not counted.
struct DeviceMemoryUse {
  size_t live = 0, peak = 0;
};
DeviceMemoryUse device_memory_use();
void reset_device_memory_peak();

// A program a Renderer builds: kernels/<file>, its includes expanded
// (Context::kernel_source), compiled with `options` exactly as given to the OpenCL compiler.
struct KernelVariant {
  std::string file, options;
};
// Every program a Renderer can build on a device like `device` (its type, cl_khr_fp64 and
// work-group limit decide): float and, with fp64, double; every sampling's variant; the launch
// parameters of the database's pick, of a default Tuning and of every candidate the tuner tries
// (penumbra tune), each raster tuning also with brute_force. In file order, no duplicates. For
// compiling every variant offline (`penumbra kernels`, scripts/spir_check.sh).
std::vector<KernelVariant> kernel_variants(const DeviceInfo& device);
// Fills the kernel cache (Context::program) with every program a Renderer on ctx's device
// builds with the tuning it picks by itself (Tuning not given: the database's entry, or the
// heuristic's for any scene): float and, with fp64, double, every shadow model, sampling and
// part. A later process then loads them instead of compiling (`penumbra kernels --warm`, run
// by the build). `done(k, n)` after each program. Throws penumbra::Error when the cache is off.
std::vector<KernelVariant> warm_kernel_cache(
    Context& ctx, const std::function<void(size_t, size_t)>& done = nullptr);

// Where a render() or backward() is, for progress reports (Renderer::set_progress): the call,
// the pass (a light's shadow-map pass or a camera's view, 1-based of how many), the stage, and
// for a stage run in parts (the exact shadow lookups, in batches of fragments) the part,
// 1-based of `parts` (0 of 0 otherwise). `fraction` is how far the call is, 0 to 1, counting
// each pass alike.
struct RenderProgress {
  const char* call = "render";  // "render", "backward" (or "finite differences": gradcheck)
  const char* pass = "view";    // "light" (its shadow-map pass) or "view" (a camera's)
  int index = 1, count = 1;
  const char* stage = "";
  int part = 0, parts = 0;
  double fraction = 0;
};
using ProgressObserver = std::function<void(const RenderProgress&)>;

// A Renderer may be shared by several threads: its calls run one at a time, each waiting for
// the one in progress (a backward() differentiates the most recent render() of any thread).
// Its Context must outlive it.
class Renderer {
 public:
  // Launch parameters chosen from the tuning database (TuningDatabase::load_default: a tuned
  // entry for this device, else the heuristic for the scene), at the first render and again when
  // the faces, the first camera or the coverage cut-off change.
  explicit Renderer(Context& context, Precision precision = Precision::Float);
  // Fixed launch parameters (validated for the device).
  Renderer(Context& context, Precision precision, const Tuning& tuning);
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  // Renders every camera of the scene (validated first; faces of zero area are allowed and
  // contribute nothing). A light whose frustum is given (fitted before the call) and leaves
  // out some of the faces that cast its shadows gets one warning line on stderr, once per
  // renderer: those shadows are cut off at the frustum's edge.
  std::vector<RenderOutput> render(const Scene& scene);
  // render(), camera c's outputs written into out[c] (one per camera, each of its camera's
  // size) in the caller's precision, straight from the device: no double Image is made. A
  // count that differs from the cameras' or a null pointer is refused before anything runs.
  void render_into(const Scene& scene, const std::vector<OutputBuffers<float>>& out);
  void render_into(const Scene& scene, const std::vector<OutputBuffers<double>>& out);

  // Gradients of a scalar loss given dL/d(outputs) for every camera, by the exact derivative of
  // the most recent render(), which must have been of this same scene (same sizes and values).
  // Every gradient value must be finite.
  SceneGrads backward(const Scene& scene, const std::vector<OutputGrads>& grads);
  // backward() given dL/d(outputs) in the caller's memory, one GradBuffers per camera, each
  // buffer of its camera's size (W·H·3 colour, W·H silhouette and depth values), read once
  // into the device's precision: no Image is made.
  SceneGrads backward(const Scene& scene, const std::vector<GradBuffers<float>>& grads);
  SceneGrads backward(const Scene& scene, const std::vector<GradBuffers<double>>& grads);

  // The shadow map S of every light (math.md §4.2) from the most recent render() with shadows on
  // (empty otherwise), W_s × H_s, light-view depth; a light mapped on a cube has six, its faces
  // in the order of LightFrustum::cube_face (cube_faces).
  std::vector<Image> shadow_maps() const;
  // The penumbra map P of every light (math.md §4.3) from the most recent render() with soft
  // shadows (empty otherwise), one per shadow map as shadow_maps().
  std::vector<Image> penumbra_maps() const;

  // How many fragments each camera's view kept in the most recent render() (empty before one):
  // the (pixel, face) pairs whose aggregation weight is at least weight_eps times the pixel's
  // largest, which the colour, depth, shadow lookups and backward work on. Read back from the
  // device.
  std::vector<size_t> fragment_counts() const;

  // Calls `observer` at the start of every stage of every pass of render() and backward(),
  // and of every part of a stage run in parts, after the device has finished the work before
  // it (so that what it reports is what runs; without an observer nothing waits). Outputs are
  // the same with or without one. Empty: none.
  void set_progress(ProgressObserver observer);
  // Calls `check` at the start of every stage of render() and backward(), without waiting for
  // the device; it may throw to abandon the call (the Python module raises KeyboardInterrupt
  // so). A call that throws once past the checks of its input waits for the device, then
  // leaves the renderer as if it had never rendered (backward() asks for a render first); a
  // refused input leaves the last render as it was. Empty: none.
  void set_interrupt_check(std::function<void()> check);

  Precision precision() const;
  // The launch parameters of the most recent render() (or the fixed ones).
  const Tuning& tuning() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace penumbra
