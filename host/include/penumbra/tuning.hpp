#pragma once
// Launch parameters of the kernels, chosen per device and per workload: named structs per
// stage, a database of tuned values (shipped defaults in data/tuning/, the user's results in a
// cache folder), a heuristic from scene statistics, and a tuner that times candidates.
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "penumbra/context.hpp"
#include "penumbra/scene.hpp"

namespace penumbra {

struct Scene;

// kernels/raster.cl. Every legal combination gives the same images bit for bit: they change
// the schedule, never the summation order.
struct RasterTuning {
  int tile = 16;             // screen tile edge in pixels (binning; one work-group per tile)
  int pixels_per_item = 0;   // pixels per work-item along x; 0: 8 on CPUs, 1 on GPUs
  bool brute_force = false;  // ignore the bins: every pixel visits every face
  int face_lanes = 0;        // work-items per face in the backward (bands of its box's rows,
                             // summed in a fixed order); a power of two, 0: 1 on CPUs, 32 on GPUs
};

// The parameters of CLBlast's Xgemm kernel, in CLBlast's names (its tuner's documentation
// explains each): work-group tile MWG × NWG × KWG, threads MDIMC × NDIMC, vector widths VWM and
// VWN, local-memory caching SA and SB, and so on. The defaults are CLBlast 1.5's own for
// PoCL in float.
struct XgemmParameters {
  int GEMMK = 0, KREG = 1, KWG = 32, KWI = 2, MDIMA = 8, MDIMC = 8, MWG = 32, NDIMB = 16,
      NDIMC = 16, NWG = 32, SA = 1, SB = 1, STRM = 0, STRN = 0, VWM = 4, VWN = 2;

  // Every field with its name, in CLBlast's order: one table for storage, comparison, printing.
  using Field = std::pair<const char*, int XgemmParameters::*>;
  static const std::vector<Field>& fields();
  bool operator==(const XgemmParameters& o) const;
  bool operator!=(const XgemmParameters& o) const { return !(*this == o); }
  std::string describe() const;  // "MWG 64 NWG 64 KWG 32 ...": the fields that matter most
};

// kernels/paper_hard_exact.cl and CLBlast: the products of exact-sum hard shadows. Changing them
// changes the summation order of those sums (results agree to rounding).
struct ExactSumTuning {
  // Exact backend `auto` (RenderParams::exact_backend): CLBlast's GEMM instead of penumbra's
  // kernels. An explicit `kernels` or `clblast` ignores it.
  bool clblast = false;
  int vector_width = 8;  // MM_VW: 1, 2, 4, 8 or 16
  int row_block = 4;     // MM_RB: rows per work-item of the products (matmul_tn: twice), 1 to 8
  // CLBlast's GEMM (exact backend `clblast`, or `auto` with clblast), set with
  // clblast::OverrideParameters. Unset: CLBlast's built-in parameters for the device.
  std::optional<XgemmParameters> xgemm;
  // CLBlast runs its Xgemm kernel when m·n·k ≥ min_indirect_size³ and its direct kernel (which
  // xgemm does not affect) below. 0: CLBlast's default (896 in float on PoCL); 1: always Xgemm.
  int min_indirect_size = 0;
};

// kernels/paper_soft_map.cl: map tile of the per-face culling (same result for every value).
struct SoftMapTuning {
  int tile = 16;
};

// The backward's texel gathers (shadow_gather, soft_gather, pcf_gather) with truncated sampling.
struct GatherTuning {
  // Work-groups of group × group work-items that read their texel buckets' fragments together
  // through local memory (the same sums, bit for bit); 1: each work-item reads its own buckets.
  // At most 16; 0: 2 on GPUs, 1 on CPUs.
  int group = 0;
  // A gather work-item's block of texels: `width` of a map row (the gathers' ROW: 4, 8 or 16)
  // by `height` rows (GATHER_ROWS: 1, 2, 4, 8 or 16). Each texel adds its fragments in bucket
  // order whatever the block, so the sums are the same bit for bit. 0: the device's (8 × 8 on
  // CPUs, 4 × 1 on GPUs).
  int width = 0;
  int height = 0;
};

struct Tuning {
  RasterTuning raster;
  ExactSumTuning exact;
  SoftMapTuning soft_map;
  GatherTuning gather;
  std::string source = "default";  // where it came from: default, heuristic, database entry…

  Tuning() = default;
  Tuning(const RasterTuning& r) : raster(r), source("given") {}  // NOLINT: implicit on purpose
};

// Throws penumbra::Error naming the first illegal value for this device.
void validate(const Tuning& tuning, const DeviceInfo& device);

// The exact backend that computes the exact sum of the paper model's hard shadows under
// `tuning`: p.exact_backend when given (kernels or clblast), else (auto) CLBlast where
// tuning.exact.clblast and penumbra's kernels otherwise. Never Auto.
ExactBackend exact_backend_in_force(const RenderParams& p, const Tuning& tuning);
// The same for CLBlast's Xgemm parameters, with the checks of CLBlast's own tuner (local
// memory counted for double, the widest real, so that a legal set is legal in both precisions).
void validate(const XgemmParameters& xgemm, const DeviceInfo& device);

// Statistics of a workload that the heuristic looks at.
struct WorkloadStats {
  size_t faces = 0;
  double mean_face_pixels = 0;  // mean projected face area, pixels (over the first camera)
  double cutoff_pixels = 0;     // coverage cut-off radius, pixels
  int width = 0, height = 0;
};
WorkloadStats workload_stats(const Scene& scene);

// Tuned values per device. Lookup: the exact device name, then its processor model (the name
// without a trailing clock), then "<vendor>/<cpu|gpu>", then "<cpu|gpu>", then the heuristic. A
// missing or corrupt file is skipped with a warning on stderr, never an error.
class TuningDatabase {
 public:
  // The shipped defaults (embedded from data/tuning/defaults.json at build time), then the
  // user's cache file (user_path(); entries there win), then $PENUMBRA_TUNING if set.
  static TuningDatabase load_default();
  // An empty database, then the given files (later files win).
  static TuningDatabase load(const std::vector<std::string>& paths);
  static std::string user_path();  // $XDG_CACHE_HOME or ~/.cache, /penumbra/tuning.json

  // The tuning for this device and workload (raster tile and pixels per item, exact-sum and
  // penumbra parameters); `source` says which entry (or "heuristic") decided.
  Tuning lookup(const DeviceInfo& device, const WorkloadStats& workload) const;
  // The same, calling `workload` only where the statistics decide (no valid entry for this very
  // device): a renderer computes them for every render, ~10 ms at a million faces.
  Tuning lookup(const DeviceInfo& device, const std::function<WorkloadStats()>& workload) const;
  bool has(const std::string& key) const;
  void set(const std::string& key, const Tuning& tuning);
  size_t size() const { return entries_.size(); }
  // Writes every entry as JSON (creating the folder); throws penumbra::Error on failure.
  void save(const std::string& path) const;
  // The text of a database file `existing` (named `origin` in messages; empty: a new
  // database) with the entry `key` set to `tuning` and everything else kept as it was: the
  // other entries' keys, order and values, so that an entry written by penumbra stays
  // byte-identical. Throws penumbra::Error when `existing` is not a tuning database.
  static std::string updated_text(const std::string& existing, const std::string& origin,
                                  const std::string& key, const Tuning& tuning);

  static std::string device_key(const DeviceInfo& device);  // the exact device name
  // The device name without a trailing clock ("... Xeon(R) Processor @ 2.50GHz" → "... Xeon(R)
  // Processor"): the same processor model, which PoCL names with or without the clock.
  static std::string model_key(const DeviceInfo& device);
  static std::string class_key(const DeviceInfo& device);  // "<vendor>/<cpu|gpu>"

 private:
  void merge_json(const std::string& text, const std::string& origin);
  std::vector<std::pair<std::string, Tuning>> entries_;
};

// The heuristic for workloads with no tuned entry: small tiles for many small faces on large
// images, large tiles for few large faces; vectors of pixels on CPUs.
Tuning heuristic_tuning(const DeviceInfo& device, const WorkloadStats& workload);

// The tuner: times every legal candidate of every stage on this device (a warm-up, then the
// median of several runs) on the bundled scene, checks each candidate's output against the
// default configuration (a candidate that differs is rejected and reported), and stores the
// winners for this device in the database.
struct TuneOptions {
  bool quick = false;  // fewer candidates and runs
  int runs = 5;        // timed runs per candidate (quick: 3)
  // Above 0: first CLBlast's own Xgemm tuner (clblast::TuneXgemm) searches this fraction of its
  // parameter space (1e-4: about 20 s on a 2-core CPU), and its fastest set joins the exact
  // stage's candidates, timed and checked like them.
  double clblast_fraction = 0;
};
struct TuneReport {
  struct Candidate {
    std::string stage, name;
    double median_ms = 0;
    bool accepted = true;
    std::string note;  // why rejected
  };
  std::vector<Candidate> candidates;
  Tuning best;
};
TuneReport tune(Context& context, const Scene& scene, const TuneOptions& options = {});

// The CLBlast Xgemm parameter sets the tuner tries (chosen for CPUs with wide vectors; quick:
// fewer). Each is legal wherever 64 work-items per group and 32 KiB of local memory are.
std::vector<XgemmParameters> xgemm_candidates(bool quick);

}  // namespace penumbra
