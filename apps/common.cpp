#include "common.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <utility>
#include <vector>

#include <unistd.h>

#include "penumbra/error.hpp"
#include "penumbra/io.hpp"

namespace fs = std::filesystem;

namespace penumbra::cli {

std::string data_dir() {
  if (const char* env = std::getenv("PENUMBRA_DATA_DIR"); env != nullptr && *env != '\0')
    return env;
#ifdef PENUMBRA_BIN_TO_DATA_DIR
  {  // an installed tool: <prefix>/bin/penumbra and <prefix>/share/penumbra
    std::error_code ec;
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    const fs::path installed = exe.parent_path() / PENUMBRA_BIN_TO_DATA_DIR;
    if (!ec && fs::is_directory(installed / "scenes", ec)) return installed.lexically_normal();
  }
#endif
#ifdef PENUMBRA_SOURCE_DIR
  {
    std::string compiled = std::string(PENUMBRA_SOURCE_DIR) + "/data";
    std::error_code ec;
    if (fs::is_directory(compiled, ec)) return compiled;
  }
#endif
  return "data";
}

std::string default_scene_path() { return data_dir() + "/scenes/turnaround.json"; }

Scene load_scene_source(const SceneSource& source) {
  if (!source.mesh_path.empty())
    return framed_scene(load_mesh(
        source.mesh_path, glm::dvec3(0.8),
        source.refuse_degenerate ? DegenerateFacePolicy::Refuse : DegenerateFacePolicy::Drop));
  std::string path = source.scene_path;
  if (path.empty()) {
    path = default_scene_path();
    std::error_code ec;
    if (!fs::exists(path, ec)) {
      throw Error("the bundled scene " + path +
                  " was not found; set PENUMBRA_DATA_DIR to the data folder or name a scene");
    }
  }
  return load_scene(path);
}

std::string view_path(const std::string& path, size_t view) {
  if (view == 0) return path;
  const fs::path p(path);
  return (p.parent_path() /
          (p.stem().string() + "_" + std::to_string(view) + p.extension().string()))
      .string();
}

std::string view_file(const std::string& dir, const std::string& stem, size_t view) {
  const std::string name = view == 0 ? stem + ".npy" : stem + "_" + std::to_string(view) + ".npy";
  return (fs::path(dir) / name).string();
}

void make_dirs(const std::string& dir) {
  if (dir.empty()) return;
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir)) {
    throw Error("cannot create the folder " + dir + (ec ? ": " + ec.message() : std::string()));
  }
}

void make_parent_dirs(const std::string& file) { make_dirs(fs::path(file).parent_path().string()); }

std::string joined(const std::vector<std::string>& words) {
  std::string out;
  for (const std::string& w : words) out += (out.empty() ? "" : ",") + w;
  return out;
}

std::string one_line(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (char c : text) {
    if (c == '\r') continue;
    if (c == '\n') {
      if (!out.empty() && out.back() != ' ') out += "; ";
      continue;
    }
    out += c;
  }
  while (!out.empty() && (out.back() == ' ' || out.back() == ';')) out.pop_back();
  return out;
}

}  // namespace penumbra::cli
