#pragma once
// Files in and out: OBJ meshes, JSON scenes, PNG images, NumPy .npy arrays.
// Every loader throws penumbra::Error with a one-line message naming the file and the problem.
#include <string>

#include "penumbra/image.hpp"
#include "penumbra/scene.hpp"

namespace penumbra {

// OBJ via tinyobjloader; polygons are triangulated; the mesh is validated (penumbra::validate).
// Albedo: per-vertex colours if the OBJ has them, else `default_albedo` per vertex.
Mesh load_obj(const std::string& path, glm::dvec3 default_albedo = {0.8, 0.8, 0.8});
void save_obj(const Mesh& mesh, const std::string& path);

// The scene format is documented in docs/scene-format.md. Mesh paths are relative to the
// scene file. The result is validated.
Scene load_scene(const std::string& path);
Scene parse_scene(const std::string& json_text, const std::string& base_dir);

// PNG: values are clamped to [0,1]; 1 channel → grey, 3 → RGB, 4 → RGBA.
void save_png(const Image& image, const std::string& path);
// Any format stb_image reads; channels = the file's channel count unless `channels` > 0.
Image load_image(const std::string& path, int channels = 0);

// .npy (version 1.0, little-endian, C order). Saved as float32 (or float64 when `f64`);
// shape (H, W) for one channel, (H, W, C) otherwise. Loading accepts <f4 and <f8.
void save_npy(const Image& image, const std::string& path, bool f64 = false);
Image load_npy(const std::string& path);
// Plain arrays of N×K values (vertex gradients and the like), shape (N, K).
void save_npy(const std::vector<double>& values, size_t rows, size_t cols,
              const std::string& path, bool f64 = false);

}  // namespace penumbra
