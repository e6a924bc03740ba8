#pragma once
// The renderer's state between render() and backward(), and the stages of both pipelines:
// renderer.cpp runs the forward pipeline, backward.cpp its mirror.
#include <functional>
#include <mutex>
#include <optional>
#include <vector>

#include "ops/ops.hpp"
#include "penumbra/renderer.hpp"
#include "tuning/stages.hpp"

namespace penumbra {

// The scene's faces and albedo with all meshes concatenated, in the layouts the kernels read
// (the vertices go to the device straight from the meshes: write_vertices).
struct Packed {
  int nv = 0, nf = 0, na = 0;  // na: albedo entries (a mesh's per vertex or per face)
  std::vector<double> albedo;  // 3·nf × 4
  std::vector<int> faces;      // nf × 4
  std::vector<size_t> vertex_offset, face_offset, albedo_offset;
};
// What a render's meshes keep of the last render's: the faces (same_faces: so the device keeps
// them, and the backward's grouping of their corners), and the albedo (same_albedo) too.
enum class Kept { Nothing, Faces, FacesAndAlbedo };
// Fills `p` with the scene's meshes, reusing its storage: counts and offsets, and what `kept`
// says `p` does not hold already.
void pack(const Scene& s, Packed& p, Kept kept);
// The meshes' vertices, concatenated, as the device's reals (x, y, z, 0), written into `buffer`
// (mapped where the device shares the host's memory): one pass, no host copy between.
void write_vertices(Context& ctx, Precision p, cl::Buffer& buffer, const std::vector<Mesh>& meshes,
                    size_t nv);
// Whether pack() writes the same faces for meshes `a` as for meshes `b`: the same faces, vertex
// counts and albedo modes and counts, mesh by mesh; same_albedo: and the same albedo.
bool same_faces(const std::vector<Mesh>& a, const std::vector<Mesh>& b);
bool same_albedo(const std::vector<Mesh>& a, const std::vector<Mesh>& b);
// validate(scene, DegenerateFaces::Allow) but for the faces or albedo known to have passed it
// before, unchanged since; returns the bounds of the vertices, taken in the same pass as their
// checks (scene.cpp).
Bounds validated_bounds(const Scene& scene, bool faces_known, bool albedo_known);

// What the backward pass sums over cameras and lights before it becomes SceneGrads: on the
// device dL/d(vertices) (nv × real4) and dL/d(albedo) (na × real4); on the host (the per-face
// and per-vertex rows in sum_rows's parts) the per-light terms of the faces (6·nl + 1 vec4s),
// dL/dD_L, each light's dL/d(shadow map) and dL/d(penumbra map), and dL/d(its frame) from its
// own pass.
struct BackwardSums {
  cl::Buffer vertices, albedo;
  std::vector<double> lights, light_size;
  std::vector<std::vector<double>> maps, penumbra_maps, covers, frames;
};

// The stages' outputs of one view, from render(), kept for backward().
struct ViewPass {
  detail::View view;
  detail::ScreenGeometry screen;
  detail::Fragments fragments;
  detail::Resolved resolved;
};

// A light's pass: its view (whose resolved depth is the shadow map S and cover the coverage A)
// and, for the paper model's soft shadows, its penumbra map.
struct LightPass : ViewPass {
  detail::SoftMap penumbra;
  detail::LightMaps maps() const {
    return {view.W, view.H, resolved.depth, resolved.cover, penumbra.map};
  }
};

struct Renderer::Impl {
  Context& ctx;
  Precision precision;
  bool automatic;  // choose the tuning from the database (TunedFor: when)
  TuningDatabase database;
  // What the automatic tuning was chosen for: the heuristic reads the faces as the first camera
  // sees them, with the coverage cut-off (workload_stats, a pass over every face). It is chosen
  // again when the faces, that camera or the cut-off change, not when only vertices move (every
  // tile gives the same bits).
  struct TunedFor {
    Camera camera;
    double sigma = 0, dist_eps = 0;
    static TunedFor of(const Scene& s);
    bool operator==(const TunedFor& o) const;
  };
  std::optional<TunedFor> tuned_for;
  detail::Kernels kernels;
  // State of the most recent render(), kept for backward().
  // As rendered: light frusta fitted, the lights as drawn (drawn_lights), then normalised
  // (`norm`); light_of[l] is the given light that scene.lights[l] comes from.
  Scene scene;
  std::vector<int> light_of;
  // The lights of `s` as the passes draw them: a cube's faces as lights of their own
  // (cube_faces), but with shadows off every light as it is (no map, so one light).
  static std::vector<Light> drawn_lights(const Scene& s, std::vector<int>* light_of);
  // The meshes as given, which backward() must be given again: scene.meshes, or where the
  // scene was normalised (its meshes moved), given_meshes (empty otherwise: not copied twice).
  std::vector<Mesh> given_meshes;
  bool meshes_normalised = false;
  const std::vector<Mesh>& meshes_as_given() const {
    return meshes_normalised ? given_meshes : scene.meshes;
  }
  detail::Normalisation norm;        // device points = (world points − norm.origin) · norm.scale
  std::vector<LightFrustum> frusta;  // the lights' frusta as fitted, in world units
  Packed packed;
  detail::DeviceGeometry geometry;
  bool geometry_current = false;        // packed and geometry hold these meshes' faces and albedo
  Kept kept = Kept::Nothing;            // what this render's meshes keep of the last's
  std::vector<ViewPass> camera_passes;  // one per camera
  std::vector<LightPass> light_passes;  // one per light, when shadows are on
  std::vector<std::vector<double>> view_P;

  // Progress (set_progress): the observer, where the call is, and which pass of how many.
  ProgressObserver observer;
  RenderProgress progress;
  int pass_done = 0, pass_total = 1;
  std::function<void()> interrupt_check;  // set_interrupt_check
  std::mutex busy;                        // held by each public call: one at a time
  bool warned_frustum = false;            // check_frusta's warning, once per renderer

  // Waits for the device and forgets the last render: what a call that threw leaves once it
  // had `started` (past the checks of its input, which leave the last render as it was).
  void abandon();
  bool started = false;
  // Runs one public call alone (`busy`), abandoning it on an exception once it started.
  template <class Call>
  auto exclusive(Call&& call) {
    const std::lock_guard<std::mutex> lock(busy);
    started = false;
    try {
      return call();
    } catch (...) {
      if (started) abandon();
      throw;
    }
  }
  // Warns (once) where a light's given frustum leaves out faces that cast its shadows.
  // One warning line per renderer where a light's frustum in `s` leaves out faces that cast its
  // shadows: one `given` fixed, or one fitted at its widest (a light among the objects).
  void check_frusta(const Scene& given, const Scene& s);

  Impl(Context& c, Precision p, bool automatic_, const Tuning& t);

  void begin_pass(const char* call, const char* pass, int index, int count, int done, int total);
  void report(double within);
  // A stage of `call` ("render" or "backward"): reported to the observer and, with
  // PENUMBRA_PROFILE, timed (mark: timed only; null ends the call's last stage).
  void stage(const char* name);
  void mark(const char* name);
  const char* call = "render";
  // Begins `call` with its stage `first`; its last stage ends when the call returns or throws.
  struct CallProfile {
    Impl& m;
    CallProfile(Impl& impl, const char* call, const char* first) : m(impl) {
      m.call = call;
      m.mark(first);
    }
    ~CallProfile() { m.mark(nullptr); }
    CallProfile(const CallProfile&) = delete;
    CallProfile& operator=(const CallProfile&) = delete;
  };

  // Forward (renderer.cpp), in order: `deliver(c, pass)` reads camera c's outputs from its pass.
  using Deliver = std::function<void(int camera, const ViewPass& pass)>;
  void render(const Scene& scene, const Deliver& deliver);
  // Checked, frusta fitted, normalised, tuned, packed; returns its device memory estimate.
  size_t prepare(const Scene& scene);
  void upload_geometry();
  // Each pass is given its view's fragments from the last render (`spare`), whose buffers its
  // raster reuses where they fit (reuse_or_alloc).
  void shadow_map_pass(int light, detail::Fragments spare);  // the shadow map (and penumbra map)
  void camera_pass(int camera, detail::Fragments spare);     // the image, shadows looked up
  void rasterise(ViewPass& vp, int W, int H, int nlights, const std::vector<double>& P,
                 detail::Fragments spare);
  RenderOutput download(const ViewPass& cp);
  template <class Real>
  void write_outputs(const ViewPass& cp, const OutputBuffers<Real>& out);
  // Renderer::render_into: `out` checked, then render() writing each camera's outputs there.
  template <class Real>
  void render_into(const Scene& scene, const std::vector<OutputBuffers<Real>>& out);

  // Backward (backward.cpp), in order.
  SceneGrads backward(const Scene& scene, const std::vector<OutputGrads>& grads);
  template <class Real>
  SceneGrads backward(const Scene& scene, const std::vector<GradBuffers<Real>>& grads);
  // The scene is the last render's, and there is a gradient per camera, each finite.
  template <class Real>
  void check_backward(const Scene& scene, const std::vector<GradBuffers<Real>>& grads);
  // Zero sums: the vertices' and albedo's zeroed by the device, the host's in the last
  // backward's storage; the face corners grouped by vertex and by albedo entry on the device,
  // once per set of faces.
  BackwardSums& start_backward();
  BackwardSums backward_sums;
  void build_adjacency();
  template <class Real>
  void camera_backward(int camera, const GradBuffers<Real>& grads, BackwardSums& sums);
  void light_backward(int light, BackwardSums& sums);
  SceneGrads scene_grads(const BackwardSums& sums) const;
  void sum_face_grads(const ViewPass& vp, const detail::FaceGrads& fg, BackwardSums& sums,
                      std::vector<double>* glights, std::vector<double>* gframe);
};

}  // namespace penumbra
