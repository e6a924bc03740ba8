// Checkpoints of the fits (optim.hpp: FitState, FitCheckpoints) and where a resumed fit enters
// its stages (stages.hpp).
//
// A checkpoint is JSON: {"format": "penumbra-checkpoint", "version": 1, "run": "...",
// "iteration", "stage", "mesh": {"name", "vertices", "faces", "albedo", "per_vertex"},
// "adam": {"t", "m", "v"}}, arrays flat. Doubles are written with 17 significant digits, so
// that they read back bit for bit and a resumed fit goes on exactly as the interrupted one.
#include <nlohmann/json.hpp>
#include <string>

#include "optim/stages.hpp"
#include "penumbra/error.hpp"

namespace penumbra::optim {
namespace {

using json = nlohmann::json;

constexpr const char* kFormat = "penumbra-checkpoint";

std::vector<double> flat(const std::vector<glm::dvec3>& values) {
  std::vector<double> out;
  out.reserve(3 * values.size());
  for (const glm::dvec3& v : values) out.insert(out.end(), {v.x, v.y, v.z});
  return out;
}

std::vector<glm::dvec3> vectors(const std::vector<double>& values) {
  if (values.size() % 3 != 0) throw Error("an array of vectors has a length not a multiple of 3");
  std::vector<glm::dvec3> out(values.size() / 3);
  for (size_t i = 0; i < out.size(); ++i)
    out[i] = {values[3 * i], values[3 * i + 1], values[3 * i + 2]};
  return out;
}

}  // namespace

std::string checkpoint_text(const FitState& s, const std::string& run) {
  std::vector<int> faces;
  for (const glm::ivec3& f : s.mesh.faces) faces.insert(faces.end(), {f.x, f.y, f.z});
  const json doc = {{"format", kFormat},
                    {"version", 1},
                    {"run", run},
                    {"iteration", s.iteration},
                    {"stage", s.stage},
                    {"mesh",
                     {{"name", s.mesh.name},
                      {"vertices", flat(s.mesh.vertices)},
                      {"faces", faces},
                      {"albedo", flat(s.mesh.albedo)},
                      {"per_vertex", s.mesh.albedo_mode == AlbedoMode::PerVertex}}},
                    {"adam", {{"t", s.adam.t}, {"m", s.adam.m}, {"v", s.adam.v}}}};
  return doc.dump() + "\n";
}

FitState parse_checkpoint(const std::string& text, const std::string& path,
                          const std::string& run) {
  const std::string what = "checkpoint " + path;
  json doc;
  try {
    doc = json::parse(text);
  } catch (const std::exception&) {
    throw Error(what + " is not a checkpoint (not JSON; a file cut short?)");
  }
  if (!doc.is_object() || doc.value("format", "") != kFormat || doc.value("version", 0) != 1)
    throw Error(what + " is not a penumbra checkpoint of version 1");
  if (doc.value("run", "") != run)
    throw Error(what + " was written by another run (" + doc.value("run", "") +
                "), not by this one (" + run + "); resume with the same options");
  FitState s;
  try {
    s.iteration = doc.at("iteration").get<int>();
    s.stage = doc.at("stage").get<int>();
    const json& m = doc.at("mesh");
    s.mesh.name = m.at("name").get<std::string>();
    s.mesh.vertices = vectors(m.at("vertices").get<std::vector<double>>());
    const std::vector<int> faces = m.at("faces").get<std::vector<int>>();
    if (faces.size() % 3 != 0) throw Error("the faces are not triples");
    for (size_t i = 0; i < faces.size(); i += 3)
      s.mesh.faces.emplace_back(faces[i], faces[i + 1], faces[i + 2]);
    s.mesh.albedo = vectors(m.at("albedo").get<std::vector<double>>());
    s.mesh.albedo_mode =
        m.at("per_vertex").get<bool>() ? AlbedoMode::PerVertex : AlbedoMode::PerFace;
    const json& a = doc.at("adam");
    s.adam = {a.at("m").get<std::vector<double>>(), a.at("v").get<std::vector<double>>(),
              a.at("t").get<long>()};
    validate(s.mesh);
  } catch (const std::exception& e) {
    throw Error(what + " is damaged: " + e.what());
  }
  if (s.adam.m.size() != 3 * s.mesh.vertices.size() || s.adam.v.size() != s.adam.m.size())
    throw Error(what + " is damaged: its optimiser does not match its mesh");
  return s;
}

void check_resume(const FitCheckpoints& c, size_t stages, int total) {
  if (c.resume == nullptr) return;
  if (c.resume->stage < 0 || size_t(c.resume->stage) >= stages || c.resume->iteration < 0 ||
      c.resume->iteration > total)
    throw Error("the checkpoint's stage " + std::to_string(c.resume->stage) + " and iteration " +
                std::to_string(c.resume->iteration) + " are not in this fit (" +
                std::to_string(stages) + " stages, " + std::to_string(total) + " iterations)");
}

bool stage_done(const FitCheckpoints& c, size_t stage) {
  return c.resume != nullptr && int(stage) < c.resume->stage;
}

int enter_stage(const FitCheckpoints& c, size_t stage, int iteration, int iterations,
                int subdivisions, Mesh& mesh) {
  if (c.resume == nullptr || int(stage) != c.resume->stage) {
    for (int k = 0; k < subdivisions; ++k) mesh = subdivide(mesh);
    return 0;
  }
  const int first = c.resume->iteration - iteration;
  if (first < 0 || first > iterations)
    throw Error("the checkpoint's iteration " + std::to_string(c.resume->iteration) +
                " is not in its stage " + std::to_string(stage) + " (iterations " +
                std::to_string(iteration) + " to " + std::to_string(iteration + iterations) + ")");
  mesh = c.resume->mesh;
  return first;
}

Adam stage_optimiser(const FitCheckpoints& c, size_t stage, size_t values, double lr) {
  Adam adam(values, AdamOptions{lr});
  if (c.resume != nullptr && int(stage) == c.resume->stage) adam.restore(c.resume->adam);
  return adam;
}

void after_step(const FitCheckpoints& c, int iteration, int total, size_t stage, const Mesh& mesh,
                const Adam& adam) {
  if (c.every <= 0 || !c.save || (iteration % c.every != 0 && iteration != total)) return;
  c.save(FitState{iteration, int(stage), mesh, adam.state()});
}

}  // namespace penumbra::optim
