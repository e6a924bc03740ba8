#pragma once
// Files in and out: meshes (OBJ, PLY, STL, glTF, OFF), JSON scenes, NumPy .npy arrays (PNG images
// and GIF animations: image_io.hpp, in the application library). Every loader throws
// penumbra::Error with a one-line message naming the file and the problem. Every writer goes
// through OutputFile: a failed write leaves nothing at the destination and an earlier file there
// untouched.
#include <memory>
#include <string>
#include <vector>

#include "penumbra/image.hpp"
#include "penumbra/scene.hpp"

namespace penumbra {

// A file written atomically: to a temporary file in the destination's folder, every write and
// the close checked, then renamed over `path` by commit(). On any failure (and when destroyed
// before commit()) the temporary file is removed, and the failures throw penumbra::Error
// "cannot write <what> '<path>': <reason>" (the reason from strerror). A destination that
// exists and is not a regular file (/dev/null, /dev/full, a named pipe) is written directly,
// with the same checks. A symbolic link to a file keeps pointing at the new file.
// A file the call produces, or a cache entry (not counted among the outputs an interruption
// keeps, penumbra/interrupt.hpp).
enum class FileKind { output, cache };

class OutputFile {
 public:
  // `what` names the kind of file in messages: "PNG", "NumPy file", ...
  OutputFile(const std::string& path, const std::string& what, FileKind kind = FileKind::output);
  ~OutputFile();
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;
  void write(const void* data, size_t size);
  void write(const std::string& bytes);
  void close();   // closes and checks; the file is not yet in place
  void commit();  // close(), then rename into place
  const std::string& path() const { return path_; }

 private:
  void discard() noexcept;
  [[noreturn]] void fail(const std::string& reason);
  std::string path_, what_, target_, temporary_;
  FileKind kind_;
  int fd_ = -1;
  bool committed_ = false;
};

// One whole file through OutputFile.
void write_file(const std::string& path, const std::string& bytes, const std::string& what,
                FileKind kind = FileKind::output);
// Throws what OutputFile would for `path` (a folder that takes no new file, ...), leaving
// nothing: for a check before long work whose result is written at its end.
void check_writable(const std::string& path, const std::string& what);
// Several files, all or none: every file is written and closed to its temporary first, and
// only when all of them succeeded are they renamed into place.
struct FileContent {
  std::string path, bytes, what;
};
void write_files(const std::vector<FileContent>& files);

// What a mesh reader does with a face of zero area (corners on one line, or a corner repeated),
// which scans and exports often hold: `Drop` it, with one warning line on stderr (how many,
// and the first by its place in the file), or `Refuse` the file, naming that face.
enum class DegenerateFacePolicy { Drop, Refuse };

// A mesh file, by its extension (any case): .obj through load_obj; .ply, .stl, .gltf, .glb and
// .off through Assimp, polygons triangulated, the scene's meshes put together in world space,
// corners at one position with one colour joined into one vertex. Albedo: per-vertex colours
// where every vertex has one, else `default_albedo`. Throws penumbra::Error naming the file
// and the problem: an unknown extension, a format error (Assimp's message), no faces.
Mesh load_mesh(const std::string& path, glm::dvec3 default_albedo = {0.8, 0.8, 0.8},
               DegenerateFacePolicy degenerate = DegenerateFacePolicy::Drop);

// OBJ via tinyobjloader, vertices in the file's order; polygons are triangulated by ear
// clipping (a concave one keeps its shape); UTF-8 or (ASCII) UTF-16 text; the mesh is
// validated (penumbra::validate). Albedo: per-vertex colours if the OBJ has them, else
// `default_albedo` per vertex. Dropped faces are named by their line.
Mesh load_obj(const std::string& path, glm::dvec3 default_albedo = {0.8, 0.8, 0.8},
              DegenerateFacePolicy degenerate = DegenerateFacePolicy::Drop);
void save_obj(const Mesh& mesh, const std::string& path);
std::string obj_text(const Mesh& mesh);  // what save_obj writes

// The scene format is documented in docs/scene-format.md. Mesh paths are relative to the
// scene file. The result is validated.
Scene load_scene(const std::string& path);
Scene parse_scene(const std::string& json_text, const std::string& base_dir);

// .npy (version 1.0, little-endian, C order). Saved as float32 (or float64 when `f64`);
// shape (H, W) for one channel, (H, W, C) otherwise. Loading accepts <f4 and <f8.
void save_npy(const Image& image, const std::string& path, bool f64 = false);
Image load_npy(const std::string& path);
// Plain arrays of N×K values (vertex gradients and the like), shape (N, K).
void save_npy(const std::vector<double>& values, size_t rows, size_t cols, const std::string& path,
              bool f64 = false);
// The bytes the save_npy above write; `path` only names the file in error messages.
std::string npy_bytes(const Image& image, const std::string& path, bool f64 = false);
std::string npy_bytes(const std::vector<double>& values, size_t rows, size_t cols,
                      const std::string& path, bool f64 = false);

}  // namespace penumbra
