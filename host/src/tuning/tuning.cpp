// Tuning database, heuristic and validation (the tuner is in tuner.cpp).
#include "penumbra/tuning.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>

#include "cl/device.hpp"
#include "io/text.hpp"
#include "ops/ops.hpp"
#include "penumbra/error.hpp"
#include "penumbra/io.hpp"
#include "penumbra/scene.hpp"
#include "tuning/stages.hpp"

namespace penumbra {
namespace detail {
const std::map<std::string, std::string>& embedded_kernels();
}

namespace {

using json = nlohmann::json;

const char* type_key(const DeviceInfo& d) { return d.is_gpu ? "gpu" : "cpu"; }

// CLBlast's Xgemm parameters: null (CLBlast's defaults) or an object with every field, each
// named as CLBlast names it.
std::optional<XgemmParameters> read_xgemm(const json& j) {
  if (j.is_null()) return std::nullopt;
  if (!j.is_object()) throw std::runtime_error("\"xgemm\" must be an object or null");
  XgemmParameters x;
  for (const auto& [name, field] : XgemmParameters::fields()) {
    if (!j.contains(name)) throw std::runtime_error(std::string("\"xgemm\" lacks ") + name);
    x.*field = j.at(name).get<int>();
  }
  if (j.size() != XgemmParameters::fields().size())
    throw std::runtime_error("\"xgemm\" has fields other than CLBlast's Xgemm parameters");
  return x;
}

json xgemm_json(const std::optional<XgemmParameters>& x) {
  if (!x) return nullptr;
  json j = json::object();
  for (const auto& [name, field] : XgemmParameters::fields()) j[name] = (*x).*field;
  return j;
}

// The fields present in `j` override `t` (so that class entries can give only some of them).
void read_into(const json& j, Tuning& t) {
  auto get = [](const json& obj, const char* key, auto& out) {
    if (obj.contains(key)) out = obj.at(key).get<std::remove_reference_t<decltype(out)>>();
  };
  if (j.contains("raster")) {
    const json& r = j.at("raster");
    get(r, "tile", t.raster.tile);
    get(r, "pixels_per_item", t.raster.pixels_per_item);
    get(r, "face_lanes", t.raster.face_lanes);
  }
  if (j.contains("exact")) {
    const json& e = j.at("exact");
    get(e, "clblast", t.exact.clblast);
    get(e, "vector_width", t.exact.vector_width);
    get(e, "row_block", t.exact.row_block);
    get(e, "min_indirect_size", t.exact.min_indirect_size);
    if (e.contains("xgemm")) t.exact.xgemm = read_xgemm(e.at("xgemm"));
  }
  // "penumbra" is the name databases written before "soft_map" gave the stage.
  for (const char* key : {"penumbra", "soft_map"})
    if (j.contains(key)) get(j.at(key), "tile", t.soft_map.tile);
  if (j.contains("gather")) {
    get(j.at("gather"), "group", t.gather.group);
    get(j.at("gather"), "width", t.gather.width);
    get(j.at("gather"), "height", t.gather.height);
  }
}

json to_json(const Tuning& t) {
  return {{"raster",
           {{"tile", t.raster.tile},
            {"pixels_per_item", t.raster.pixels_per_item},
            {"face_lanes", t.raster.face_lanes}}},
          {"exact",
           {{"clblast", t.exact.clblast},
            {"vector_width", t.exact.vector_width},
            {"row_block", t.exact.row_block},
            {"min_indirect_size", t.exact.min_indirect_size},
            {"xgemm", xgemm_json(t.exact.xgemm)}}},
          {"soft_map", {{"tile", t.soft_map.tile}}},
          {"gather",
           {{"group", t.gather.group}, {"width", t.gather.width}, {"height", t.gather.height}}}};
}

void warn(const std::string& message) {
  std::fprintf(stderr, "penumbra: warning: %s\n", message.c_str());
}

}  // namespace

const std::vector<XgemmParameters::Field>& XgemmParameters::fields() {
  using X = XgemmParameters;
  static const std::vector<Field> all = {
      {"GEMMK", &X::GEMMK}, {"KREG", &X::KREG},   {"KWG", &X::KWG}, {"KWI", &X::KWI},
      {"MDIMA", &X::MDIMA}, {"MDIMC", &X::MDIMC}, {"MWG", &X::MWG}, {"NDIMB", &X::NDIMB},
      {"NDIMC", &X::NDIMC}, {"NWG", &X::NWG},     {"SA", &X::SA},   {"SB", &X::SB},
      {"STRM", &X::STRM},   {"STRN", &X::STRN},   {"VWM", &X::VWM}, {"VWN", &X::VWN}};
  return all;
}

bool XgemmParameters::operator==(const XgemmParameters& o) const {
  return std::all_of(fields().begin(), fields().end(),
                     [&](const Field& f) { return this->*f.second == o.*f.second; });
}

std::string XgemmParameters::describe() const {
  std::ostringstream s;
  s << "MWG " << MWG << " NWG " << NWG << " KWG " << KWG << " MDIMC " << MDIMC << " NDIMC " << NDIMC
    << " VWM " << VWM << " VWN " << VWN << " SA " << SA << " SB " << SB;
  if (GEMMK) s << " GEMMK 1 KREG " << KREG;
  return s.str();
}

void validate(const XgemmParameters& x, const DeviceInfo& device) {
  auto fail = [&](const std::string& why) {
    throw Error("CLBlast Xgemm parameters (" + x.describe() + "): " + why);
  };
  auto str = [](size_t v) { return std::to_string(v); };
  for (const auto& [name, field] : XgemmParameters::fields()) {
    const int v = x.*field;
    const std::string n = name;
    const bool flag = n == "GEMMK" || n == "SA" || n == "SB" || n == "STRM" || n == "STRN";
    if (flag ? (v != 0 && v != 1) : v < 1)
      fail(n + " is " + std::to_string(v) + "; expected " +
           (flag ? "0 or 1" : "a positive integer"));
  }
  for (int vw : {x.VWM, x.VWN})
    if (vw > 16 || (vw & (vw - 1))) fail("VWM and VWN must be 1, 2, 4, 8 or 16");
  // The constraints of CLBlast's Xgemm tuner: whole numbers of vectors per thread, of threads
  // per tile when loading A and B, and of KWI unrolled steps per KWG.
  auto multiple = [&](int a, const char* an, int b, const std::string& bn) {
    if (b == 0 || a % b)
      fail(std::string(an) + " " + str(a) + " must be a multiple of " + bn + " = " + str(b));
  };
  multiple(x.KWG, "KWG", x.KWI, "KWI");
  multiple(x.MWG, "MWG", x.MDIMC * x.VWM, "MDIMC·VWM");
  multiple(x.NWG, "NWG", x.NDIMC * x.VWN, "NDIMC·VWN");
  multiple(x.MWG, "MWG", x.MDIMA * x.VWM, "MDIMA·VWM");
  multiple(x.NWG, "NWG", x.NDIMB * x.VWN, "NDIMB·VWN");
  if (x.GEMMK == 0) {
    multiple(x.MDIMC * x.NDIMC, "MDIMC·NDIMC", x.MDIMA, "MDIMA");
    multiple(x.MDIMC * x.NDIMC, "MDIMC·NDIMC", x.NDIMB, "NDIMB");
    multiple(x.KWG, "KWG", x.MDIMC * x.NDIMC / x.MDIMA, "MDIMC·NDIMC/MDIMA");
    multiple(x.KWG, "KWG", x.MDIMC * x.NDIMC / x.NDIMB, "MDIMC·NDIMC/NDIMB");
  } else {
    multiple(x.KREG, "KREG", x.VWN, "VWN");
    if (x.MDIMA != x.MDIMC || x.NDIMB != x.NDIMC)
      fail("GEMMK 1 needs MDIMA = MDIMC and NDIMB = NDIMC");
  }
  const size_t group = size_t(x.MDIMC) * x.NDIMC;
  if (group > device.max_work_group)
    fail("MDIMC·NDIMC = " + str(group) + " work-items per group; device '" + device.name +
         "' allows " + str(device.max_work_group));
  const size_t local = (size_t(x.SA) * x.MWG + size_t(x.SB) * x.NWG) * x.KWG * sizeof(double);
  if (device.device() && local > device.device.getInfo<CL_DEVICE_LOCAL_MEM_SIZE>())
    fail(str(local) + " bytes of local memory (in double); device '" + device.name + "' has " +
         str(device.device.getInfo<CL_DEVICE_LOCAL_MEM_SIZE>()));
}

void validate(const Tuning& t, const DeviceInfo& device) {
  const RasterTuning& r = t.raster;
  const bool ppw_legal = r.pixels_per_item >= 1 && r.pixels_per_item <= 16 &&
                         (r.pixels_per_item & (r.pixels_per_item - 1)) == 0;
  if (!ppw_legal)
    throw Error("raster tuning: pixels_per_item (" + std::to_string(r.pixels_per_item) +
                ") must be a power of two up to 16");
  // A work-item's pixels are a block (raster_block_width wide): the tile holds whole blocks.
  const int block_w = detail::raster_block_width(r.pixels_per_item),
            block_h = r.pixels_per_item / block_w;
  if (r.tile < 1 || r.tile % block_w || r.tile % block_h)
    throw Error("raster tuning: tile (" + std::to_string(r.tile) + ") must be a positive " +
                "multiple of the " + std::to_string(block_w) + "×" + std::to_string(block_h) +
                " block of " + std::to_string(r.pixels_per_item) + " pixel(s) per work-item");
  const size_t group = size_t(r.tile) * r.tile / r.pixels_per_item;
  if (group > device.max_work_group)
    throw Error("raster tuning: a " + std::to_string(r.tile) + "-pixel tile with " +
                std::to_string(r.pixels_per_item) + " pixel(s) per work-item needs " +
                std::to_string(group) + " work-items per group; device '" + device.name +
                "' allows " + std::to_string(device.max_work_group));
  if (r.face_lanes < 0 || (r.face_lanes & (r.face_lanes - 1)) || size_t(r.face_lanes) > 256 ||
      size_t(r.face_lanes) > device.max_work_group)
    throw Error("raster tuning: face_lanes (" + std::to_string(r.face_lanes) +
                ") must be 0 (the device's default) or a power of two up to 256 and to the " +
                "device's work-group size (" + std::to_string(device.max_work_group) + ")");
  const int vw = t.exact.vector_width;
  if (!(vw == 1 || vw == 2 || vw == 4 || vw == 8 || vw == 16) || t.exact.row_block < 1 ||
      t.exact.row_block > 8)
    throw Error("exact-sum tuning: vector_width " + std::to_string(vw) +
                " must be 1, 2, 4, 8 or 16 and row_block " + std::to_string(t.exact.row_block) +
                " in 1 to 8");
  if (t.exact.min_indirect_size < 0)
    throw Error("exact-sum tuning: min_indirect_size " + std::to_string(t.exact.min_indirect_size) +
                " must be 0 (CLBlast's default) or positive");
  if (t.exact.xgemm) validate(*t.exact.xgemm, device);
  if (t.soft_map.tile < 1 || t.soft_map.tile > 256)
    throw Error("soft map tuning: tile " + std::to_string(t.soft_map.tile) +
                " must be in 1 to 256");
  const int g = t.gather.group;
  if (g < 0 || g > 16 || size_t(g) * size_t(g) > device.max_work_group)
    throw Error("gather tuning: group " + std::to_string(g) +
                " must be 0 (the device's default) or 1 to 16, its square at most the device's " +
                "work-group size (" + std::to_string(device.max_work_group) + ")");
  const int w = t.gather.width, h = t.gather.height;
  if (!(w == 0 || w == 4 || w == 8 || w == 16) ||
      !(h == 0 || h == 1 || h == 2 || h == 4 || h == 8 || h == 16))
    throw Error("gather tuning: width " + std::to_string(w) + " must be 4, 8 or 16 and height " +
                std::to_string(h) + " 1, 2, 4, 8 or 16 (0: the device's default)");
}

WorkloadStats workload_stats(const Scene& scene) {
  WorkloadStats w;
  for (const Mesh& m : scene.meshes) w.faces += m.faces.size();
  if (scene.cameras.empty()) return w;
  const Camera& c = scene.cameras.front();
  w.width = c.width;
  w.height = c.height;
  w.cutoff_pixels =
      std::sqrt(scene.params.sigma * std::log(1 / scene.params.dist_eps - 1)) * c.height / 2;
  // Mean projected area: project the vertices as the camera does (faces behind it skipped).
  const glm::dvec3 f = glm::normalize(c.target - c.eye), r = glm::normalize(glm::cross(f, c.up)),
                   u = glm::cross(r, f);
  const bool ortho = c.projection == Projection::Orthographic;
  const double scale = ortho ? c.half_height : std::tan(c.fov_deg * 3.14159265358979323846 / 360);
  double total = 0;
  size_t counted = 0;
  std::vector<glm::dvec2> p;  // each vertex projected once, not once per face corner
  std::vector<char> in_front;
  for (const Mesh& m : scene.meshes) {
    p.resize(m.vertices.size());
    in_front.resize(m.vertices.size());
    for (size_t v = 0; v < m.vertices.size(); ++v) {
      const glm::dvec3 d = m.vertices[v] - c.eye;
      const double z = glm::dot(d, f);
      in_front[v] = !(z < c.near);
      const double s = (ortho ? 1 / scale : 1 / (z * scale)) * c.height / 2;
      p[v] = {glm::dot(d, r) * s, glm::dot(d, u) * s};
    }
    for (const glm::ivec3& F : m.faces) {
      if (!in_front[F.x] || !in_front[F.y] || !in_front[F.z]) continue;
      const glm::dvec2 a = p[F.y] - p[F.x], b = p[F.z] - p[F.x];
      total += std::min(0.5 * std::abs(a.x * b.y - a.y * b.x), double(c.width) * c.height);
      ++counted;
    }
  }
  w.mean_face_pixels = counted ? total / counted : 0;
  return w;
}

Tuning heuristic_tuning(const DeviceInfo& device, const WorkloadStats& w) {
  Tuning t;
  t.source = "heuristic";
  const detail::DeviceDefaults defaults = detail::device_defaults(device);
  t.raster.pixels_per_item = defaults.pixels_per_item;
  t.raster.face_lanes = defaults.face_lanes;
  t.gather.group = defaults.gather_group;
  t.gather.width = defaults.gather_width;
  t.gather.height = defaults.gather_height;
  // Cost of a tile size T: (pixel, face) pairs visited, each face touching the pixels of every
  // tile its box overlaps, plus a fixed cost per (tile, face) entry of the bins.
  const double box = std::sqrt(std::max(w.mean_face_pixels, 0.0)) + 2 * w.cutoff_pixels + 2;
  double best = INFINITY;
  for (int tile : detail::kRasterTiles) {
    if (size_t(tile) * tile / t.raster.pixels_per_item > device.max_work_group) continue;
    const double tiles_per_face = std::pow((box + tile) / tile, 2);
    const double cost = w.faces * (tiles_per_face * tile * tile + 64 * tiles_per_face);
    if (cost < best) best = cost, t.raster.tile = tile;
  }
  t.exact.clblast = defaults.exact_on_clblast;
  return t;
}

ExactBackend exact_backend_in_force(const RenderParams& p, const Tuning& tuning) {
  if (p.exact_backend != ExactBackend::Auto) return p.exact_backend;
  return tuning.exact.clblast ? ExactBackend::CLBlast : ExactBackend::Kernels;
}

std::string TuningDatabase::device_key(const DeviceInfo& d) { return d.name; }
std::string TuningDatabase::model_key(const DeviceInfo& d) {
  static const std::regex clock(R"( *@ *[0-9.]+ *[GM]Hz *$)");
  return std::regex_replace(d.name, clock, "");
}
std::string TuningDatabase::class_key(const DeviceInfo& d) { return d.vendor + "/" + type_key(d); }

std::string TuningDatabase::user_path() {
  const char* xdg = std::getenv("XDG_CACHE_HOME");
  const char* home = std::getenv("HOME");
  std::string base = xdg && *xdg ? xdg : std::string(home && *home ? home : ".") + "/.cache";
  return base + "/penumbra/tuning.json";
}

void TuningDatabase::merge_json(const std::string& text, const std::string& origin) {
  try {
    const json doc = parse_json(text);
    if (!doc.is_object() || !doc.contains("entries") || !doc.at("entries").is_object())
      throw std::runtime_error("no \"entries\" object");
    for (const auto& item : doc.at("entries").items()) {
      const std::string& key = item.key();
      const auto& value = item.value();
      Tuning t;
      auto it =
          std::find_if(entries_.begin(), entries_.end(), [&](auto& e) { return e.first == key; });
      if (it != entries_.end()) t = it->second;
      read_into(value, t);
      t.source = key;
      set(key, t);
    }
  } catch (const std::exception& e) {
    warn("ignoring tuning database " + origin + " (" + printable(e.what(), 200) +
         "); using defaults");
  }
}

TuningDatabase TuningDatabase::load(const std::vector<std::string>& paths) {
  TuningDatabase db;
  for (const std::string& path : paths) {
    std::ifstream in(path);
    if (!in) {
      warn("tuning database " + path + " not found; using defaults");
      continue;
    }
    std::stringstream ss;
    ss << in.rdbuf();
    db.merge_json(ss.str(), path);
  }
  return db;
}

TuningDatabase TuningDatabase::load_default() {
  TuningDatabase db;
  const auto& embedded = detail::embedded_kernels();
  auto it = embedded.find("../data/tuning/defaults.json");
  if (it != embedded.end()) db.merge_json(it->second, "data/tuning/defaults.json");
  const std::string user = user_path();
  if (std::filesystem::exists(user)) {
    std::ifstream in(user);
    std::stringstream ss;
    ss << in.rdbuf();
    db.merge_json(ss.str(), user);
  }
  if (const char* extra = std::getenv("PENUMBRA_TUNING"); extra && *extra) {
    TuningDatabase more = load({extra});
    for (auto& [key, t] : more.entries_) db.set(key, t);
  }
  return db;
}

bool TuningDatabase::has(const std::string& key) const {
  return std::any_of(entries_.begin(), entries_.end(), [&](auto& e) { return e.first == key; });
}

void TuningDatabase::set(const std::string& key, const Tuning& tuning) {
  for (auto& e : entries_)
    if (e.first == key) {
      e.second = tuning;
      return;
    }
  entries_.push_back({key, tuning});
}

Tuning TuningDatabase::lookup(const DeviceInfo& device, const WorkloadStats& workload) const {
  return lookup(device, [&] { return workload; });
}

Tuning TuningDatabase::lookup(const DeviceInfo& device,
                              const std::function<WorkloadStats()>& workload_of) const {
  auto find = [&](const std::string& key) -> const Tuning* {
    for (auto& e : entries_)
      if (e.first == key) return &e.second;
    return nullptr;
  };
  // A tuned entry for this very device, else for its processor model, decides everything.
  const std::string key = find(device_key(device)) ? device_key(device) : model_key(device);
  if (const Tuning* t = find(key)) {
    Tuning out = detail::for_device(*t, device);  // fields the entry leaves at 0
    out.source = "tuned:" + key;
    try {
      validate(out, device);
      return out;
    } catch (const Error& e) {
      warn(std::string("ignoring tuned entry '") + key + "' for '" + device.name +
           "': " + e.what());
    }
  }
  // Otherwise the heuristic, with the stage parameters of the device's class where shipped.
  const WorkloadStats workload = workload_of();
  Tuning out = heuristic_tuning(device, workload);
  const RasterTuning raster = out.raster;
  for (const std::string& key : {class_key(device), std::string(type_key(device))})
    if (const Tuning* t = find(key)) {
      out = detail::for_device(*t, device);
      out.raster.tile = raster.tile;
      out.source = "heuristic+" + key;
      break;
    }
  try {
    validate(out, device);
  } catch (const Error& e) {
    warn(std::string("ignoring shipped tuning for '") + device.name + "': " + e.what());
    out = heuristic_tuning(device, workload);
  }
  return out;
}

std::string TuningDatabase::updated_text(const std::string& existing, const std::string& origin,
                                         const std::string& key, const Tuning& tuning) {
  using ordered = nlohmann::ordered_json;
  ordered doc = {{"version", 1}, {"entries", ordered::object()}};
  if (!existing.empty()) {
    try {
      parse_json(existing);  // for its checks (duplicate keys); the order is kept below
      doc = ordered::parse(existing);
      if (!doc.is_object() || !doc.contains("entries") || !doc.at("entries").is_object())
        throw std::runtime_error("no \"entries\" object");
    } catch (const std::exception& e) {
      throw Error("cannot update the tuning database " + origin + ": " + printable(e.what(), 200) +
                  "; move it away or name another file with -o");
    }
  }
  doc["entries"][key] = ordered::parse(to_json(tuning).dump());
  return doc.dump(2) + "\n";
}

void TuningDatabase::save(const std::string& path) const {
  json doc = {{"version", 1}, {"entries", json::object()}};
  for (auto& [key, t] : entries_) doc["entries"][key] = to_json(t);
  std::error_code ec;
  std::filesystem::create_directories(std::filesystem::path(path).parent_path(), ec);
  write_file(path, doc.dump(2) + "\n", "tuning database");
}

}  // namespace penumbra
