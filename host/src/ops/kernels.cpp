// Kernel programs: the -D options each is built with (the one place that decides them), the
// variants the stages ask for, every variant a device can build (kernel_variants, for the
// offline SPIR check), and the kernel objects of one precision and tuning (ops.hpp).
#include <functional>
#include <set>
#include <string>
#include <vector>

#include "ops/ops.hpp"
#include "penumbra/error.hpp"
#include "penumbra/renderer.hpp"
#include "shadow_models.hpp"
#include "tuning/stages.hpp"

namespace penumbra {
namespace detail {

const std::map<std::string, std::string>& embedded_kernels();

Tuning for_device(Tuning t, const DeviceInfo& device) {
  if (t.raster.pixels_per_item == 0)
    t.raster.pixels_per_item = device_defaults(device).pixels_per_item;
  if (t.raster.face_lanes == 0) t.raster.face_lanes = device_defaults(device).face_lanes;
  if (t.gather.group == 0) t.gather.group = device_defaults(device).gather_group;
  if (t.gather.width == 0) t.gather.width = device_defaults(device).gather_width;
  if (t.gather.height == 0) t.gather.height = device_defaults(device).gather_height;
  return t;
}

Kernels::Kernels(Context& ctx, Precision precision, const Tuning& tuning)
    : ctx_(ctx), precision_(precision), tuning_(tuning) {}

std::string program_options(const std::string& file, Precision precision, const Tuning& tuning,
                            const DeviceInfo& device, const std::string& variant, KernelPart part) {
  std::string o = precision_options(precision);
  const RasterTuning& r = tuning.raster;
  if (file == "raster.cl") {
    const int lanes =
        part == KernelPart::Backward ? raster_backward_lanes(r.pixels_per_item) : r.pixels_per_item;
    o += " -DTILE=" + std::to_string(r.tile) + " -DPPW=" + std::to_string(lanes) +
         " -DBLOCK_W=" + std::to_string(raster_block_width(lanes)) +
         " -DBRUTE_FORCE=" + std::to_string(r.brute_force ? 1 : 0) +
         " -DFACE_LANES=" + std::to_string(r.face_lanes);
  }
  if (lookup_file_model(file) != nullptr) {  // the gathers' program: the tuning's block
    const GatherTuning& g = tuning.gather;
    o += part == KernelPart::Gather
             ? " -DROW=" + std::to_string(g.width) + " -DGATHER_ROWS=" + std::to_string(g.height) +
                   " -DGATHER_GROUP=" + std::to_string(g.group)
             : " -DROW=" + std::to_string(device_defaults(device).shadow_row);
    o += " -DGATHER_CHUNK=" + std::to_string(kGatherChunk);
  }
  if (file == "paper_soft_map.cl") o += " -DPPW=" + std::to_string(soft_map_lanes(device, tuning));
  if (file == "bin.cl") o += " -DSORT_GROUP=" + std::to_string(device_defaults(device).sort_group);
  if (file == "paper_hard_exact.cl")
    o += " -DMM_VW=" + std::to_string(tuning.exact.vector_width) +
         " -DMM_RB=" + std::to_string(tuning.exact.row_block);
  if (is_oclgrind(device)) o += " -DPENUMBRA_OCLGRIND";
  if (is_pocl_cpu(device)) o += " -DPENUMBRA_POCL_CPU";
  o += " " + variant;
  if (part == KernelPart::Gather) return o + " -DGATHER_KERNELS";
  return part == KernelPart::Backward ? o + " -DBACKWARD_KERNELS" : o;
}

std::vector<std::string> program_variants(const std::string& file, const Tuning& tuning) {
  if (file == "bin.cl") {  // the raster's bins (unless brute force), the penumbra map's, texels
    std::vector<std::string> v = {bin_define(tuning.soft_map.tile), bin_define(1)};
    if (!tuning.raster.brute_force) v.push_back(bin_define(tuning.raster.tile));
    return v;
  }
  if (const ShadowModelPasses* model = lookup_file_model(file)) {
    std::vector<std::string> v;
    if (model->unsampled_variant) v.push_back("");  // paper_lookups.cl's hard-shadow kernels
    for (const SamplingMethod& m : sampling_methods()) v.push_back(sampling_define(m.value));
    return v;
  }
  return {""};
}

Kernels::Entry& Kernels::get(const std::string& file, const std::string& name,
                             const std::string& variant, KernelPart part) {
  const std::string opts = program_options(file, precision_, tuning_, ctx_.info(), variant, part);
  auto key = file + ":" + name + ":" + opts;
  auto it = kernels_.find(key);
  if (it != kernels_.end()) return it->second;
  cl::Program& program = ctx_.program(file, opts);
  return kernels_.emplace(key, Entry{cl::Kernel(program, name.c_str())}).first->second;
}

}  // namespace detail

namespace {

// The kernel files and the parts (forward, backward, gathers) each holds.
std::vector<std::pair<std::string, std::vector<detail::KernelPart>>> kernel_files() {
  std::vector<std::pair<std::string, std::vector<detail::KernelPart>>> files;
  for (const auto& [name, text] : detail::embedded_kernels())
    if (name.find('/') == std::string::npos && name.size() > 3 &&
        name.compare(name.size() - 3, 3, ".cl") == 0) {
      files.push_back({name, {detail::KernelPart::Forward}});
      if (text.find("BACKWARD_KERNEL") != std::string::npos)
        files.back().second.push_back(detail::KernelPart::Backward);
      if (text.find("GATHER_KERNEL") != std::string::npos)
        files.back().second.push_back(detail::KernelPart::Gather);
    }
  return files;
}

// Every program the tunings legal on `device` build there, float and (with fp64) double, with
// the options as Context::program takes them; in file order, no duplicates.
std::vector<KernelVariant> programs_of(const DeviceInfo& device,
                                       const std::vector<Tuning>& tunings) {
  std::vector<Precision> precisions = {Precision::Float};
  if (device.fp64) precisions.push_back(Precision::Double);
  std::set<std::pair<std::string, std::string>> seen;
  std::vector<KernelVariant> out;
  for (const auto& [file, parts] : kernel_files())
    for (Precision precision : precisions)
      for (const Tuning& tuning : tunings) {
        try {
          validate(tuning, device);
        } catch (const Error&) {  // not legal on this device: never built there
          continue;
        }
        for (const std::string& variant : detail::program_variants(file, tuning))
          for (detail::KernelPart part : parts) {
            const std::string options =
                detail::program_options(file, precision, tuning, device, variant, part);
            if (seen.insert({file, options}).second) out.push_back({file, options});
          }
      }
  return out;
}

// The tunings a renderer picks by itself on `device` (no Tuning given): the database's, and
// where the heuristic decides, its pick with each raster tile it may choose for a scene.
std::vector<Tuning> own_tunings(const DeviceInfo& device) {
  const Tuning pick = TuningDatabase::load_default().lookup(device, WorkloadStats{});
  std::vector<Tuning> out = {pick};
  if (pick.source.rfind("heuristic", 0) == 0)
    for (int tile : detail::kRasterTiles) {
      out.push_back(pick);
      out.back().raster.tile = tile;
    }
  return out;
}

}  // namespace

std::vector<KernelVariant> kernel_variants(const DeviceInfo& device) {
  // The tunings a renderer can run with: its own picks, a fixed default Tuning, and every
  // candidate the tuner tries from those; each raster tuning also with brute_force.
  std::vector<Tuning> starts = own_tunings(device);
  starts.push_back(detail::for_device(Tuning{}, device));
  std::vector<Tuning> tunings;
  for (const Tuning& start : starts) {
    tunings.push_back(start);
    for (const detail::TuneStage& stage : detail::tune_stages(device, start, false))
      tunings.insert(tunings.end(), stage.candidates.begin(), stage.candidates.end());
  }
  for (size_t i = 0, n = tunings.size(); i < n; ++i) {
    Tuning t = tunings[i];
    t.raster.brute_force = !t.raster.brute_force;
    tunings.push_back(t);
  }
  std::vector<KernelVariant> out = programs_of(device, tunings);
  for (KernelVariant& v : out) v.options = Context::build_options(v.options);
  return out;
}

std::vector<KernelVariant> warm_kernel_cache(Context& ctx,
                                             const std::function<void(size_t, size_t)>& done) {
  if (Context::cache_dir().empty())
    throw Error("the kernel cache is off (PENUMBRA_CACHE_DIR=off): nothing to fill");
  std::vector<KernelVariant> programs = programs_of(ctx.info(), own_tunings(ctx.info()));
  for (size_t i = 0; i < programs.size(); ++i) {
    ctx.program(programs[i].file, programs[i].options);
    if (done) done(i + 1, programs.size());
  }
  for (KernelVariant& v : programs) v.options = Context::build_options(v.options);
  return programs;
}

}  // namespace penumbra
