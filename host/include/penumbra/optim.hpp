#pragma once
// Shape optimisation (math.md §9): image losses with their gradients with respect to the rendered
// images, mesh regularisers with their gradients with respect to the vertices, Adam, mesh
// refinement, and the target images, views and visual hull of the applications
// (`penumbra fit-silhouette`, `fit-shadows`, `shadow-art`; docs/applications.md).
//
// Every loss and regulariser returns its value and, when `grad` is given, ADDS weight × its
// gradient to `grad` (so several terms accumulate into one buffer); the returned value is
// weight × the term.
#include <functional>
#include <glm/glm.hpp>
#include <string>
#include <vector>

#include "penumbra/image.hpp"
#include "penumbra/renderer.hpp"
#include "penumbra/scene.hpp"

namespace penumbra::optim {

// ---------------------------------------------------------------------------------------------
// Image losses. `rendered` and `target` are one-channel images of the same size (values in
// [0, 1]); `grad`, when given, must be empty or of that size: it is sized and zero-filled when
// empty, then weight × dL/d(rendered) is added.

// Soft IoU: 1 − Σ A·T / Σ (A + T − A·T). 0 for a perfect match. Both images empty → 0.
double soft_iou_loss(const Image& rendered, const Image& target, Image* grad = nullptr,
                     double weight = 1.0);
// Mean squared error: Σ (A − T)² / N over the N pixels.
double mse_loss(const Image& rendered, const Image& target, Image* grad = nullptr,
                double weight = 1.0);
// Intersection over union of the binary masks (value > threshold): |A ∩ B| / |A ∪ B|; 1 when
// both are empty.
double binary_iou(const Image& a, const Image& b, double threshold = 0.5);

// ---------------------------------------------------------------------------------------------
// Mesh connectivity for the regularisers.
struct Topology {
  std::vector<std::vector<int>> neighbours;  // per vertex: the vertices sharing an edge, sorted
  std::vector<glm::ivec2> edges;             // every undirected edge once, (a, b) with a < b
  // Edges shared by exactly two faces: (face 0, face 1). Edges with one face (a border) or
  // more than two (non-manifold) have no hinge.
  std::vector<glm::ivec2> hinges;
};
Topology topology(const std::vector<glm::ivec3>& faces, size_t vertex_count);

// Uniform Laplacian: Σ_v ‖v − mean(neighbours(v))‖² (vertices with no neighbour add nothing).
double laplacian_loss(const std::vector<glm::dvec3>& vertices, const Topology& topo,
                      std::vector<glm::dvec3>* grad = nullptr, double weight = 1.0);

// Edge-length regulariser. Variance: (1/E) Σ_e (ℓ_e − mean ℓ)², favours edges of one length.
// SquaredLength: (1/E) Σ_e ℓ_e², favours short edges.
enum class EdgeLoss { Variance, SquaredLength };
double edge_loss(const std::vector<glm::dvec3>& vertices, const Topology& topo, EdgeLoss kind,
                 std::vector<glm::dvec3>* grad = nullptr, double weight = 1.0);

// Normal consistency (flatten): Σ over hinges of (1 − cos θ), θ the angle between the two
// faces' normals (faces consistently oriented). Degenerate faces contribute nothing.
double normal_consistency_loss(const std::vector<glm::dvec3>& vertices,
                               const std::vector<glm::ivec3>& faces, const Topology& topo,
                               std::vector<glm::dvec3>* grad = nullptr, double weight = 1.0);

// ---------------------------------------------------------------------------------------------
// Adam (Kingma & Ba), with bias correction.
struct AdamOptions {
  double lr = 0.01;
  double beta1 = 0.9, beta2 = 0.999, eps = 1e-8;
};

class Adam {
 public:
  explicit Adam(size_t size = 0, AdamOptions options = {});
  // Forgets the moments and the step count (for example after the parameters were remeshed).
  void reset(size_t size);
  // x ← x − lr · m̂ / (√v̂ + eps), elementwise over `size` values.
  void step(double* x, const double* grad);
  void step(std::vector<double>& x, const std::vector<double>& grad);
  void step(std::vector<glm::dvec3>& x, const std::vector<glm::dvec3>& grad);
  void set_lr(double lr) { options_.lr = lr; }
  double lr() const { return options_.lr; }
  size_t size() const { return m_.size(); }
  long steps() const { return t_; }
  // The moments and the step count, to continue exactly where it stopped (checkpoints).
  struct State {
    std::vector<double> m, v;
    long t = 0;
  };
  State state() const { return {m_, v_, t_}; }
  void restore(const State& state);

 private:
  AdamOptions options_;
  std::vector<double> m_, v_;
  long t_ = 0;
};

// ---------------------------------------------------------------------------------------------
// Mesh refinement.

// Midpoint subdivision: every triangle into four; the shape is unchanged. Per-vertex albedo is
// interpolated, per-face albedo copied to the four children.
Mesh subdivide(const Mesh& mesh);
// Mean length of the mesh's edges.
double mean_edge_length(const Mesh& mesh);

// ---------------------------------------------------------------------------------------------
// Targets: binary masks of the shape to reach, read from images.

// Reads a target image: the shape is where the luminance is below 0.5 (dark on a light
// background, like a shadow on a wall or ink on paper); pixels with alpha below 0.5 are
// background. Returns 1 on the shape, 0 elsewhere. Throws penumbra::Error naming the file for
// an unreadable file, a non-square image, an image with no shape (all light) or no background
// (all dark).
Image load_target(const std::string& path);
// Checks a list of targets: at least one, all the same size (throws otherwise, naming both
// files and sizes). `names` label the targets in messages.
void check_targets(const std::vector<Image>& targets, const std::vector<std::string>& names);
// The largest image size r ≤ cap that divides `size` (so that a target of `size` pixels box-
// filters to r exactly), if it is at least min(16, size); otherwise `size`.
int stage_resolution(int size, int cap);
// Box-filter downsampling of a mask by an integer factor (fraction covered, in [0, 1]).
Image downsample(const Image& image, int factor);
// Binary mask: 1 where value > threshold.
Image binarize(const Image& image, double threshold = 0.5);

// ---------------------------------------------------------------------------------------------
// Views along a direction, as used by the applications: an orthographic camera at `distance`
// from `center` looking along `direction`. Image "up" is the world +y projected onto the image
// plane, or world −z when the direction is (anti)parallel to y (looking down, +x is right and
// −z is up, like a map). With this rule the front view (direction −z) has +x right and +y up,
// the side view (direction −x) has −z right and +y up.
glm::dvec3 view_up(const glm::dvec3& direction);
Camera ortho_camera(const glm::dvec3& direction, double half_height, int size,
                    const glm::dvec3& center = {0, 0, 0}, double distance = 10.0, double near = 0.1,
                    double far = 100.0);
// Direction of a named view: front (−z, the camera at +z), side (−x, the camera at +x),
// top (−y, the camera above). Throws for other names.
glm::dvec3 named_view(const std::string& name);
// "x,y,z" → a non-zero direction (throws otherwise).
glm::dvec3 parse_direction(const std::string& text);

// ---------------------------------------------------------------------------------------------
// Visual hull: the voxels of [−half, half]³ (a grid of n³) whose orthographic projection along
// every direction falls on the target; each target is seen as by ortho_camera(direction,
// half_height, target size). Returns n³ occupancies (x fastest, then y, then z; 1 inside).
std::vector<unsigned char> visual_hull(const std::vector<Image>& targets,
                                       const std::vector<glm::dvec3>& directions,
                                       double half_height, int n, double half);
// A closed triangle mesh of the boundary of an occupancy grid (as returned by visual_hull) by
// surface nets: one vertex per boundary cell at the mean of its edge crossings, a quad per
// grid edge that crosses the boundary (wound outwards; where voxels touch only along an edge
// or a corner the mesh is not manifold there), then `smooth_steps` steps of Laplacian
// smoothing (each vertex halfway to the mean of its neighbours). Throws for an empty grid.
Mesh surface_nets(const std::vector<unsigned char>& occupancy, int n, double half,
                  int smooth_steps = 2, glm::dvec3 albedo = {0.8, 0.8, 0.8});

// ---------------------------------------------------------------------------------------------
// Output helpers.

// Grey masks and colour images side by side in one RGB row, `gap` pixels of `gap_value` apart;
// images of different heights are centred vertically.
Image side_by_side(const std::vector<Image>& images, int gap = 4, double gap_value = 0.5);
// Nearest-neighbour upscaling by an integer factor.
Image upscale(const Image& image, int factor);
// A mask drawn as a picture: shape dark on light (1 − mask), 3 channels.
Image mask_picture(const Image& mask);

// ---------------------------------------------------------------------------------------------
// Regularisers combined, as the applications use them.
struct RegulariserWeights {
  double laplacian = 0.0;  // × laplacian_loss
  double edge = 0.0;       // × edge_loss(kind)
  double normal = 0.0;     // × normal_consistency_loss
  EdgeLoss edge_kind = EdgeLoss::Variance;
};
// Σ weight × term over the three terms, gradients added to `grad` (sized when empty).
double regularise(const Mesh& mesh, const Topology& topo, const RegulariserWeights& weights,
                  std::vector<glm::dvec3>* grad);

// ---------------------------------------------------------------------------------------------
// Fitting a mesh to orthographic silhouettes (fit-silhouette, shadow-art): the vertices move by
// Adam on Σ_views soft IoU(silhouette, target) + the regularisers, in stages from coarse to fine.
struct SilhouetteStage {
  int resolution = 64;  // view size in pixels; the targets are box-filtered to it
  int iterations = 100;
  double sigma = 1e-4;   // coverage sharpness σ of the views (screen units²)
  double lr = 0.01;      // Adam step (world units)
  int subdivisions = 0;  // midpoint subdivisions of the mesh before the stage
  RegulariserWeights weights;
};

struct SilhouetteProblem {
  std::vector<Image> targets;          // binary masks (1 on the shape), square, one size
  std::vector<glm::dvec3> directions;  // view direction of each target (ortho_camera)
  double half_height = 1.0;            // half the visible height of every view (world units)
};

// Reported after every iteration.
struct FitProgress {
  int iteration = 0, total = 0;  // 1-based iteration over all stages
  int stage = 0;
  double loss = 0.0;           // image loss (Σ over the views)
  double regulariser = 0.0;    // the regularisers' weighted sum
  std::vector<double> ious;    // binary IoU of each view against its target, at the stage's
                               // resolution, `images` thresholded at 0.5
  const Mesh* mesh = nullptr;  // the mesh that was rendered
  // What the loss compared with the targets: the soft silhouettes (fit_silhouettes) or the
  // shadow images (fit_shadows), 1 on the shape or in shadow.
  const std::vector<Image>* images = nullptr;
};
using FitObserver = std::function<void(const FitProgress&)>;

// A fit between two iterations: what it takes to go on exactly where it stopped.
struct FitState {
  int iteration = 0;  // iterations done, over all stages
  int stage = 0;      // the stage the last of them belongs to
  Mesh mesh;          // the mesh after them, subdivided as that stage has it
  Adam::State adam;   // that stage's optimiser
};
// Checkpoints of a fit: `save` gets the state after every `every`-th iteration and after the
// last (0: never); with `resume` the fit starts from that state instead of the beginning, and
// goes on exactly as the run that saved it would have.
struct FitCheckpoints {
  int every = 0;
  std::function<void(const FitState&)> save;
  const FitState* resume = nullptr;
};
// A checkpoint file's text: the state and `run`, a description of the run it belongs to.
std::string checkpoint_text(const FitState& state, const std::string& run);
// Reads it back; throws penumbra::Error naming `path` when the text is not a checkpoint or was
// written for another run than `run`.
FitState parse_checkpoint(const std::string& text, const std::string& path, const std::string& run);

// Render parameters of a silhouette view: no lights, no shadows, σ as given.
Scene silhouette_scene(const Mesh& mesh, const std::vector<glm::dvec3>& directions,
                       double half_height, int size, double sigma);
// Runs the stages and returns the final mesh.
Mesh fit_silhouettes(Renderer& renderer, Mesh mesh, const SilhouetteProblem& problem,
                     const std::vector<SilhouetteStage>& stages, const FitObserver& observer,
                     const FitCheckpoints& checkpoints = {});
// The mesh's hard silhouettes (binary: 1 where the coverage exceeds 0.5, rendered with a tiny σ
// so that a pixel is 1 exactly when its centre is covered), `size` pixels.
std::vector<Image> hard_silhouettes(Renderer& renderer, const Mesh& mesh,
                                    const std::vector<glm::dvec3>& directions, double half_height,
                                    int size);

// ---------------------------------------------------------------------------------------------
// Shadows on walls (fit-shadows, shadow-art): the scene of one directional light. The shape
// (mesh 0, around the origin) casts its shadow along the light's direction onto a square wall
// (mesh 1) perpendicular to the light, `wall_distance` behind the origin; an orthographic
// camera between the shape and the wall, `camera_distance` behind the origin, looks along the
// light at the wall, so it sees the shadow and never the shape (the shape is behind it). The
// camera's image is oriented as ortho_camera's. The wall is white, lit head-on by a white light
// with no ambient light: its colour is the shadow term s. The light's shadow-map frustum is
// set once, explicitly: an orthographic box of half-size `map_half_size` around the origin,
// from `light_distance` before it to past the wall, so that it holds the shape however it
// changes within the view.
struct WallSetup {
  double half_height = 1.0;      // half the visible height of the camera (world units)
  double wall_distance = 2.5;    // the wall is this far behind the origin
  double wall_half_size = 2.0;   // half the side of the square wall
  double camera_distance = 1.5;  // the camera is this far behind the origin
  double light_distance = 5.0;   // the light's map camera is this far before the origin
  double map_half_size = 1.3;    // half-size of the light's orthographic map
};
// `with_shape` false gives the wall alone (mesh 0 is then the wall): the reference image of a
// fully lit wall.
Scene wall_scene(const Mesh& shape, const glm::dvec3& direction, int size,
                 const RenderParams& params, const WallSetup& setup = {}, bool with_shape = true);
// Shadow image of a wall: 1 − C/C_ref per pixel (C the rendered wall colour, averaged over the
// channels, C_ref that of the fully lit wall), 0 where lit, 1 in full shadow; with dL/dC from
// dL/d(shadow image) for the backward pass.
Image shadow_image(const Image& color, const Image& reference);
Image shadow_image_backward(const Image& grad_shadow, const Image& reference);
// Render parameters of a crisp, classic hard shadow: a tiny σ and γ_s, the light pass sharp,
// the map `map_size` texels.
RenderParams hard_shadow_params(int map_size);
// The shape's hard shadow on each wall (binary: the shadow image thresholded at 0.5), `size`
// pixels, rendered with hard_shadow_params at four times `size` texels.
std::vector<Image> hard_shadows(Renderer& renderer, const Mesh& shape,
                                const std::vector<glm::dvec3>& directions, int size,
                                const WallSetup& setup = {});

// The whole setup in one scene, for pictures: the shape (mesh 0, albedo `shape_albedo`), one
// wall per light meeting the others at the room's corner (each `setup.wall_distance` behind the
// origin along its light, as large as that distance), every light, hard shadows, seen by a
// perspective camera from the open side of the room. Only for mutually orthogonal directions
// (each wall is then lit by its own light alone; see orthogonal()).
Scene room_scene(const Mesh& shape, const std::vector<glm::dvec3>& directions, int width,
                 int height, const WallSetup& setup = {},
                 glm::dvec3 shape_albedo = {0.85, 0.45, 0.3});
// Whether every pair of directions is orthogonal (to 1e-6).
bool orthogonal(const std::vector<glm::dvec3>& directions);

// Fitting a mesh to the shadows it casts (fit-shadows): for each light the wall scene is
// rendered with shadows, the shadow image compared with the target by mean squared error, and
// the vertices move by Adam on the sum plus the regularisers, in stages from coarse to fine.
// The shape is never seen by the cameras: every gradient reaches it through the shadows.
struct ShadowStage {
  int resolution = 48;  // camera image size; the targets are box-filtered to it
  int iterations = 100;
  int map_size = 64;          // shadow-map size (texels)
  double light_sigma = 3e-4;  // σ_L of the light pass (light screen units²)
  double lr = 0.01;           // Adam step (world units)
  int subdivisions = 0;       // midpoint subdivisions of the mesh before the stage
  RegulariserWeights weights;
  double light_size = 0.0;  // D_L of every light (soft shadows)
};

struct ShadowProblem {
  std::vector<Image> targets;          // binary masks (1 in shadow), square, one size
  std::vector<glm::dvec3> directions;  // light direction of each target
  WallSetup setup;
  // Shadow mode (Hard or Soft), sampling, γ_L, σ_s, γ_s, β, γ_P of the fit; σ_L and the map
  // size come from the stages.
  RenderParams params = default_shadow_fit_params();
  // The shadow parameters of the fit for `model` (hard shadows, truncated sampling).
  static RenderParams default_shadow_fit_params(ShadowModel model = ShadowModel::Accurate);
};

Mesh fit_shadows(Renderer& renderer, Mesh mesh, const ShadowProblem& problem,
                 const std::vector<ShadowStage>& stages, const FitObserver& observer,
                 const FitCheckpoints& checkpoints = {});

// ---------------------------------------------------------------------------------------------
// Progress of an optimisation on stderr: on a terminal one line redrawn in place after every
// iteration, otherwise a plain line every `every` iterations (default a tenth of the run, and
// the last). Lines read
//   <name> [##########..........] 120/240  loss 0.0312  iou [0.951,0.962]  12.3 s
class ProgressPrinter {
 public:
  ProgressPrinter(std::string name, int total, int every = 0);
  void update(int iteration, double loss, const std::vector<double>& ious, double seconds);

 private:
  std::string name_;
  int total_, every_;
  bool tty_;
};
// "[0.981,0.975]": IoUs with three decimals, as the applications' last line prints them.
std::string iou_list(const std::vector<double>& ious);

}  // namespace penumbra::optim
